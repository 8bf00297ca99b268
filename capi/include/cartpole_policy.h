/* cartpole_policy.h: the shipped cart-pole balance policy (4-64-64-2 Q-network, 4,610
 * float parameters in flash), from the Rust crate `firmware`. Link libcartpole_policy.a
 * (cargo build --release -p capi --target <your target>).
 *
 * Call once per 20 ms control period with the state [x (m), x_dot (m/s), theta (rad),
 * theta_dot (rad/s)]; push the cart right (+x) with the full force iff q[1] > q[0].
 * Allocation-free, no global state, safe to call from an interrupt; about 750 bytes of stack
 * on a Cortex-M4F. The caller checks its readings: a NaN gives NaN Q-values (and "left").
 */
#ifndef CARTPOLE_POLICY_H
#define CARTPOLE_POLICY_H

#ifdef __cplusplus
extern "C" {
#endif

/* obs: 4 floats, read only; q: 2 floats, written. Neither may be NULL. */
void cartpole_policy_forward(const float obs[4], float q[2]);

#ifdef __cplusplus
}
#endif

#endif /* CARTPOLE_POLICY_H */
