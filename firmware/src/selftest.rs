//! What the microcontroller checks about itself at start-up, and what the host compares it
//! with: Q-values of fixed observations (bit-exactness) and closed-loop episodes against the
//! `no_std` plant.
//!
//! The firmware binary prints the results; `host-sim probes` prints the host's values in the
//! same format, and an end-to-end test runs both and compares the text.

use rand_core::SeedableRng;
use rand_pcg::Pcg32;

use crate::cartpole::{CartPole, Params};
use crate::loopback::{Outcome, run};
use crate::network::Mlp;

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

/// Writes the self-test report, one line per `line` call: the probe lines (Q-values from
/// `forward`, the entry point under test), then one line per episode and a verdict. Returns
/// whether every episode balanced.
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
    line(format_args!(
        "self-test: {balanced} of {EPISODES} episodes balanced for {EPISODE_STEPS} steps"
    ));
    balanced == EPISODES
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
