//! What the microcontroller checks about itself at start-up, and what the host compares it
//! with: Q-values of fixed observations (bit-exactness) and closed-loop episodes against the
//! `no_std` plant.
//!
//! The firmware binary prints the results; `host-sim probes` prints the host's values in the
//! same format, and an end-to-end test runs both and compares the text.

use rand_core::{Rng, SeedableRng};
use rand_pcg::Pcg32;

use crate::cartpole::{CartPole, Params};
use crate::estimator::Encoders;
use crate::loopback::{Outcome, run, run_with_encoders};
use crate::network::{Mlp, dot, dot_portable};

/// Observations whose Q-values must agree bit for bit on every target: a balanced state,
/// leaning states, the edges of the failure box, large rates, and values with long mantissas.
pub const PROBES: [[f32; 4]; 8] = [
    [0.0, 0.0, 0.0, 0.0],
    [0.01, -0.02, 0.03, 0.04],
    [-0.04, 0.03, -0.02, 0.01],
    [2.4, 0.0, 0.2094395, 0.0],
    [-2.4, -1.5, -0.2094395, -2.0],
    [0.5, 1.0, 0.1, 1.5],
    [1.0e-7, -3.3333333, 0.12345679, -0.9876543],
    [-1.1754944e-38, 19.99, -0.41, 19.99],
];

/// Random vector pairs per length in [`dot_check`].
pub const DOT_CASES: u32 = 200;

/// How many of [`DOT_CASES`] seeded random vector pairs, at each of the lengths 4, 8, 16, 24
/// and 64, give a different result from [`dot`] (the target's own path, hand-written VFP code on
/// a Cortex-M4F) and from [`dot_portable`] (the order's definition, compiled by LLVM). Bits
/// must be equal; two NaNs count as equal, since which operand's payload survives is not part
/// of the order. Half the pairs are raw random bit patterns (NaNs, infinities, subnormals,
/// signed zeros), half are moderate values whose sums cancel.
pub fn dot_check() -> u32 {
    let mut rng = Pcg32::seed_from_u64(0xD07);
    mismatches::<4>(&mut rng)
        + mismatches::<8>(&mut rng)
        + mismatches::<16>(&mut rng)
        + mismatches::<24>(&mut rng)
        + mismatches::<64>(&mut rng)
}

fn mismatches<const N: usize>(rng: &mut Pcg32) -> u32 {
    let mut bad = 0;
    for case in 0..DOT_CASES {
        let mut value = || {
            let bits = rng.next_u32();
            if case % 2 == 0 {
                f32::from_bits(bits)
            } else {
                // Sign and mantissa random, exponent within 2^-8 .. 2^8.
                f32::from_bits((bits & 0x807f_ffff) | ((127 - 8 + (bits >> 23) % 17) << 23))
            }
        };
        let w: [f32; N] = core::array::from_fn(|_| value());
        let x: [f32; N] = core::array::from_fn(|_| value());
        let (a, b) = (dot(&w, &x), dot_portable(&w, &x));
        if a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan()) {
            bad += 1;
        }
    }
    bad
}

/// Self-test episodes run by the firmware binary.
pub const EPISODES: u32 = 5;
/// Their length, Gymnasium's `CartPole-v1`.
pub const EPISODE_STEPS: u32 = crate::cartpole::V1_EPISODE_STEPS;

/// One probe line: index, the observation's bits and the Q-values' bits, in hex. Both sides
/// format with this, so a bit difference shows as a text difference.
pub fn probe_line<W: core::fmt::Write>(
    out: &mut W,
    index: usize,
    obs: &[f32; 4],
    q: &[f32; 2],
) -> core::fmt::Result {
    write!(out, "probe {index}")?;
    for v in obs {
        write!(out, " {:08x}", v.to_bits())?;
    }
    write!(out, " ->")?;
    for v in q {
        write!(out, " {:08x}", v.to_bits())?;
    }
    Ok(())
}

/// Episode `episode` of the self-test: a Gymnasium-style random start from a seeded PCG32,
/// then `net` through the controller until the pole falls or [`EPISODE_STEPS`] pass.
pub fn episode<const H: usize>(net: &Mlp<H>, episode: u32) -> Outcome {
    let mut plant = CartPole::new(Params::default(), EPISODE_STEPS);
    plant.reset(&mut Pcg32::seed_from_u64(u64::from(episode)));
    run(net, &mut plant, || {})
}

/// The encoders of the self-test's estimator episode: 4,096 counts per revolution on the
/// pole, 20,480 per metre on the cart (the same encoder on a 20 cm drive pulley).
pub const ENCODERS: Encoders = Encoders {
    cart_counts_per_m: 20_480,
    pole_counts_per_rev: 4_096,
};

/// Episode `episode` of the self-test read through [`ENCODERS`] and the estimator (discount
/// 0.5), as a board reads its plant.
pub fn encoder_episode<const H: usize>(net: &Mlp<H>, episode: u32) -> Outcome {
    let mut plant = CartPole::new(Params::default(), EPISODE_STEPS);
    plant.reset(&mut Pcg32::seed_from_u64(u64::from(episode)));
    run_with_encoders(net, &mut plant, ENCODERS, 0.5, || {})
}

/// Writes the self-test report, one line per `line` call: the probe lines (Q-values from
/// `forward`, the entry point under test), the [`dot_check`] result, then one line per
/// episode, an episode through encoders and the estimator, and a verdict. Returns whether
/// every episode balanced and no dot product differed.
pub fn report<const H: usize>(
    net: &Mlp<H>,
    forward: impl Fn(&[f32; 4], &mut [f32; 2]),
    mut line: impl FnMut(core::fmt::Arguments<'_>),
) -> bool {
    line(format_args!(
        "cartpole-ddqn self-test: 4-{H}-{H}-2 policy, {} parameters",
        Mlp::<H>::PARAMS
    ));
    for (i, obs) in PROBES.iter().enumerate() {
        let mut q = [0.0; 2];
        forward(obs, &mut q);
        let mut text = heapless::String::<96>::new();
        // 96 bytes hold a probe line (64 characters); a truncated line is still a mismatch the
        // host test reports, never a panic.
        let _ = probe_line(&mut text, i, obs, &q);
        line(format_args!("{text}"));
    }
    let dot_bad = dot_check();
    line(format_args!(
        "dot: {dot_bad} of {} random vector pairs differ from the portable order",
        5 * DOT_CASES
    ));
    let mut balanced = 0;
    for e in 0..EPISODES {
        let o = episode(net, e);
        balanced += u32::from(o.success);
        line(format_args!(
            "episode {e}: {} steps, {}, {} faults",
            o.steps,
            if o.success { "balanced" } else { "FELL" },
            o.faults
        ));
    }
    let enc = encoder_episode(net, 0);
    line(format_args!(
        "estimator episode: {} steps through {}-count encoders, {}",
        enc.steps,
        ENCODERS.pole_counts_per_rev,
        if enc.success { "balanced" } else { "FELL" }
    ));
    line(format_args!(
        "self-test: {balanced} of {EPISODES} episodes balanced for {EPISODE_STEPS} steps"
    ));
    balanced == EPISODES && dot_bad == 0 && enc.success
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::POLICY;

    #[test]
    fn the_shipped_policy_passes_the_self_test_on_the_host() {
        for e in 0..EPISODES {
            let o = episode(&POLICY, e);
            assert!(
                o.success && o.steps == EPISODE_STEPS && o.faults == 0,
                "{e}: {o:?}"
            );
        }
    }

    #[test]
    fn probe_lines_show_every_bit() {
        struct S(heapless::String<128>);
        impl core::fmt::Write for S {
            fn write_str(&mut self, s: &str) -> core::fmt::Result {
                self.0.push_str(s).map_err(|_| core::fmt::Error)
            }
        }
        let mut s = S(heapless::String::new());
        probe_line(&mut s, 3, &[1.0, -0.0, 0.5, 2.0], &[1.5, -2.0]).unwrap();
        assert_eq!(
            s.0.as_str(),
            "probe 3 3f800000 80000000 3f000000 40000000 -> 3fc00000 c0000000"
        );
    }
}
