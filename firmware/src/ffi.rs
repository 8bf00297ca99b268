//! The C ABI: the shipped policy's forward pass for C firmware (STM32Cube, Zephyr, ...).
//!
//! ```c
//! void cartpole_policy_forward(const float obs[4], float q[2]);
//! ```
//!
//! declared in `capi/include/cartpole_policy.h`; the `capi` crate builds the static library.
//! Rust references are non-null and aligned, as C callers must guarantee for these pointers.

use crate::policy::POLICY;

/// `q = [Q(obs, left), Q(obs, right)]` of the shipped policy; push right iff `q[1] > q[0]`.
/// Allocation-free and panic-free; about 600 bytes of stack.
// SAFETY: exporting an unmangled symbol is `unsafe` because two such symbols with one name
// would clash at link time; this is the only definition of `cartpole_policy_forward`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_policy_forward(obs: &[f32; 4], q: &mut [f32; 2]) {
    *q = POLICY.forward(obs);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::selftest::PROBES;

    #[test]
    fn the_c_entry_point_is_the_forward_pass() {
        for obs in &PROBES {
            let mut q = [f32::NAN; 2];
            cartpole_policy_forward(obs, &mut q);
            assert_eq!(q.map(f32::to_bits), POLICY.forward(obs).map(f32::to_bits));
        }
    }
}
