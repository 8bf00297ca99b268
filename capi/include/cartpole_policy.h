/* cartpole_policy.h: the C API of the cart-pole balance controller, from the Rust crate
 * `firmware`. Link libcartpole_policy.a (cargo build --release -p capi --target <target>).
 *
 * Call once per control period of the rig the policy was trained for (the shipped
 * policy's is firmware::policy::RIG.params.tau) with the state obs = {x (m), x_dot (m/s),
 * theta (rad), theta_dot (rad/s)}; push the cart right (+x) with the full force iff
 * q[1] > q[0]. Allocation-free, no global state, safe to call from an interrupt; a few
 * hundred bytes of stack (measured per target in docs/QUANTISATION.md). The caller checks
 * its readings: a NaN gives NaN Q-values (and "left"). A NULL argument makes a call write
 * nothing.
 *
 * cartpole_policy_forward runs the policy compiled into the library. cartpole_mlpH_forward
 * runs any weights of width H, such as the `static const struct cartpole_mlpH` that
 * `policy-export export --format c` writes; the structs and functions below are declared as
 * those headers declare them (guarded, so both can be included). Every function computes the
 * Rust firmware's forward pass, bit for bit. cartpole_policy_forward_int and
 * cartpole_qmlpH_forward are the integer network's (`export --quant int8` headers).
 */
#ifndef CARTPOLE_POLICY_H
#define CARTPOLE_POLICY_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* obs: 4 floats, read only; q: 2 floats, written. */
void cartpole_policy_forward(const float obs[4], float q[2]);

/* The same policy in integers, for cores without an FPU: obs in Q3.12 (SI units times 4096,
 * saturated to int16), q = the advantages Q - mean(Q) in the integer network's scale; push
 * right iff q[1] > q[0]. No floating-point operation. */
void cartpole_policy_forward_int(const int16_t obs[4], int32_t q[2]);

#ifdef __cplusplus
}
#endif

/* One macro per network format declares a width's struct and function as every exported
 * header of that width does; each expansion sits under the exported headers' own guard, so
 * either header may come first. The macros are undefined at the end: the header defines no
 * other names. */
#ifdef __cplusplus
#define CARTPOLE_EXTERN_C extern "C"
#else
#define CARTPOLE_EXTERN_C
#endif

/* A 4-H-H-2 Q-network in PyTorch's nn.Linear layout (weight[out][in]); the layout
 * of Rust's firmware::network::Mlp<H>.
 * q = [Q(obs, left), Q(obs, right)] of w, in the Rust firmware's summation order
 * (bit for bit); push right iff q[1] > q[0]. From libcartpole_policy.a. A NULL
 * argument makes it write nothing. */
#define CARTPOLE_DECLARE_MLP(H)                                                         \
    struct cartpole_mlp##H {                                                            \
        float fc1_weight[H][4];                                                         \
        float fc1_bias[H];                                                              \
        float fc2_weight[H][H];                                                         \
        float fc2_bias[H];                                                              \
        float fc3_weight[2][H];                                                         \
        float fc3_bias[2];                                                              \
    };                                                                                  \
    CARTPOLE_EXTERN_C void cartpole_mlp##H##_forward(const struct cartpole_mlp##H *w,   \
                                                     const float obs[4], float q[2])

/* A 4-H-H-2 Q-network in integers (weight[out][in]); the layout of Rust's
 * firmware::network::int::QMlp<H>.
 * q = the two outputs of w (exported policies: the advantages Q - mean(Q)) in its
 * integer scale, obs = {x, x_dot, theta, theta_dot} in Q3.12 (SI units times 4096);
 * push right iff q[1] > q[0]. No floating point. From libcartpole_policy.a; a NULL
 * argument makes it write nothing. */
#define CARTPOLE_DECLARE_QMLP(H)                                                        \
    struct cartpole_qmlp##H {                                                           \
        int32_t fc1_bias[H];                                                            \
        int32_t fc2_bias[H];                                                            \
        int32_t fc3_bias[2];                                                            \
        struct cartpole_requant fc1_requant[H];                                         \
        struct cartpole_requant fc2_requant[H];                                         \
        int8_t fc1_weight[H][4];                                                        \
        int8_t fc2_weight[H][H];                                                        \
        int8_t fc3_weight[2][H];                                                        \
    };                                                                                  \
    CARTPOLE_EXTERN_C void cartpole_qmlp##H##_forward(const struct cartpole_qmlp##H *w, \
                                                      const int16_t obs[4], int32_t q[2])

#ifndef CARTPOLE_MLP16_DEFINED
#define CARTPOLE_MLP16_DEFINED
CARTPOLE_DECLARE_MLP(16);
#endif
#ifndef CARTPOLE_MLP32_DEFINED
#define CARTPOLE_MLP32_DEFINED
CARTPOLE_DECLARE_MLP(32);
#endif
#ifndef CARTPOLE_MLP64_DEFINED
#define CARTPOLE_MLP64_DEFINED
CARTPOLE_DECLARE_MLP(64);
#endif
#ifndef CARTPOLE_MLP128_DEFINED
#define CARTPOLE_MLP128_DEFINED
CARTPOLE_DECLARE_MLP(128);
#endif
#ifndef CARTPOLE_MLP256_DEFINED
#define CARTPOLE_MLP256_DEFINED
CARTPOLE_DECLARE_MLP(256);
#endif

#ifndef CARTPOLE_REQUANT_DEFINED
#define CARTPOLE_REQUANT_DEFINED
#include <stdint.h>
/* acc -> u8 activation: t = min(max(acc, 0) >> pre_shift, 32767);
 * y = min((t * multiplier + (2^post_shift >> 1)) >> post_shift, 255), in uint32_t. */
struct cartpole_requant {
    uint16_t multiplier;
    uint8_t pre_shift;
    uint8_t post_shift;
};
#endif

#ifndef CARTPOLE_QMLP16_DEFINED
#define CARTPOLE_QMLP16_DEFINED
CARTPOLE_DECLARE_QMLP(16);
#endif
#ifndef CARTPOLE_QMLP32_DEFINED
#define CARTPOLE_QMLP32_DEFINED
CARTPOLE_DECLARE_QMLP(32);
#endif
#ifndef CARTPOLE_QMLP64_DEFINED
#define CARTPOLE_QMLP64_DEFINED
CARTPOLE_DECLARE_QMLP(64);
#endif
#ifndef CARTPOLE_QMLP128_DEFINED
#define CARTPOLE_QMLP128_DEFINED
CARTPOLE_DECLARE_QMLP(128);
#endif
#ifndef CARTPOLE_QMLP256_DEFINED
#define CARTPOLE_QMLP256_DEFINED
CARTPOLE_DECLARE_QMLP(256);
#endif

#undef CARTPOLE_DECLARE_QMLP
#undef CARTPOLE_DECLARE_MLP
#undef CARTPOLE_EXTERN_C

#endif /* CARTPOLE_POLICY_H */
