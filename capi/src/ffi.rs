//! The C ABI, declared in `capi/include/cartpole_policy.h`:
//!
//! ```c
//! void cartpole_policy_forward(const float obs[4], float q[2]);   /* the shipped policy */
//! void cartpole_mlp64_forward(const struct cartpole_mlp64 *w,     /* any exported weights */
//!                             const float obs[4], float q[2]);
//! ```
//!
//! and the integer network's, for cores without an FPU (obs in Q3.12, q in the network's
//! integer scale, see [`crate::network::int`]):
//!
//! ```c
//! void cartpole_policy_forward_int(const int16_t obs[4], int32_t q[2]);  /* the shipped one */
//! void cartpole_qmlp64_forward(const struct cartpole_qmlp64 *w,
//!                              const int16_t obs[4], int32_t q[2]);
//! ```
//!
//! and `cartpole_mlpS_forward`, `cartpole_qmlpS_forward` for every shape of
//! [`firmware::for_each_shape!`], `S` its C name: `64` for the paper's two outputs, `64x7`
//! for seven (`q` then holds seven). `struct cartpole_mlpS` is [`Mlp<H, A>`] (`repr(C)`), as
//! `policy-export export --format c` writes it, and `struct cartpole_qmlpS` is
//! [`QMlp<H, A>`] (`--quant int8`). All of them run the one forward
//! pass of their network ([`Mlp::forward`], [`QMlp::forward`]), so C gets the Rust values bit
//! for bit.
//!
//! Pointers arrive as `Option<&T>`, which has the ABI of a C pointer with NULL as `None`: a
//! NULL argument makes the call write nothing instead of being undefined behaviour. Non-NULL
//! pointers must be valid and aligned, as for any C function taking arrays.

use firmware::network::int::QMlp;
use firmware::network::{Mlp, N_ACTIONS, OBS_DIM};
use shipped::policy::POLICY;
use shipped::policy_int::POLICY_INT;

/// `q` = the outputs `net` gives `obs` (a network's forward pass, in either format); a NULL
/// argument (`None`) makes it write nothing.
fn forward<O, Q>(net: Option<impl FnOnce(&O) -> Q>, obs: Option<&O>, q: Option<&mut Q>) {
    if let (Some(net), Some(obs), Some(q)) = (net, obs, q) {
        *q = net(obs);
    }
}

/// `q = [Q(obs, left), Q(obs, right)]` of the shipped policy; push right iff `q[1] > q[0]`.
/// Allocation-free and panic-free; its stack, per target, is in `docs/QUANTISATION.md`.
// SAFETY: exporting an unmangled symbol is `unsafe` because two such symbols with one name
// would clash at link time; this crate defines each C name once.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_policy_forward(
    obs: Option<&[f32; OBS_DIM]>,
    q: Option<&mut [f32; N_ACTIONS]>,
) {
    forward(Some(|o: &_| POLICY.forward(o)), obs, q);
}

/// `q` = the advantages `Q - mean(Q)` of left and right by the shipped policy's integer
/// version, `obs` in Q3.12; push right iff `q[1] > q[0]`. No floating-point operation; allocation-free and
/// panic-free.
// SAFETY: as for `cartpole_policy_forward`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_policy_forward_int(
    obs: Option<&[i16; OBS_DIM]>,
    q: Option<&mut [i32; N_ACTIONS]>,
) {
    forward(Some(|o: &_| POLICY_INT.forward(o)), obs, q);
}

macro_rules! c_forwards {
    ($($h:literal x $a:literal => $name:ident / $qname:ident / $i:ident / $qi:ident,)*) => { $(
        #[doc = concat!(
            "`q` = the ", stringify!($a), " Q-values of the 4-", stringify!($h), "-",
            stringify!($h), "-", stringify!($a), " network `w`, one per duty level (two: \
             left, right; push right iff `q[1] > q[0]`)."
        )]
        // SAFETY: as for `cartpole_policy_forward`: one definition per C name.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        pub extern "C" fn $name(
            w: Option<&Mlp<$h, $a>>,
            obs: Option<&[f32; OBS_DIM]>,
            q: Option<&mut [f32; $a]>,
        ) {
            forward(w.map(|w| move |o: &_| w.forward(o)), obs, q);
        }

        #[doc = concat!(
            "`q` = the ", stringify!($a), " outputs of the integer 4-", stringify!($h), "-",
            stringify!($h), "-", stringify!($a), " network `w` (as exported: the \
             advantages), `obs` in Q3.12."
        )]
        // SAFETY: as for `cartpole_policy_forward`: one definition per C name.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        pub extern "C" fn $qname(
            w: Option<&QMlp<$h, $a>>,
            obs: Option<&[i16; OBS_DIM]>,
            q: Option<&mut [i32; $a]>,
        ) {
            forward(w.map(|w| move |o: &_| w.forward(o)), obs, q);
        }
    )* };
}
firmware::for_each_shape!(c_forwards);

#[cfg(test)]
mod tests {
    use super::*;

    const OBS: [f32; 4] = [0.01, -0.02, 0.03, 0.04];

    #[test]
    fn a_null_argument_writes_nothing() {
        let mut q = [7.0f32; 2];
        cartpole_policy_forward(None, Some(&mut q));
        cartpole_mlp64_forward(None, Some(&OBS), Some(&mut q));
        cartpole_mlp64_forward(Some(&POLICY), None, Some(&mut q));
        assert_eq!(q, [7.0; 2]);
        cartpole_mlp64_forward(Some(&POLICY), Some(&OBS), None);
        let mut qi = [7i32; 2];
        cartpole_policy_forward_int(None, Some(&mut qi));
        cartpole_qmlp64_forward(None, Some(&[100; 4]), Some(&mut qi));
        cartpole_qmlp64_forward(Some(&POLICY_INT), None, Some(&mut qi));
        assert_eq!(qi, [7; 2]);
        cartpole_policy_forward_int(Some(&[100, -50, 30, 20]), Some(&mut qi));
        assert_eq!(qi, POLICY_INT.forward(&[100, -50, 30, 20]));
    }
}
