//! The observations a policy visits, for calibrating its integer version
//! (`weights::quant`): the activations it must represent are those of the states it meets,
//! not those of states it never reaches.
//!
//! The set is fixed: [`CALIBRATION_EPISODES`] episodes of 500 steps in every row of the
//! default robustness set on the policy's machine, from seed [`CALIBRATION_SEED`] (not the evaluation's seed, so the
//! evaluation's episodes are not the calibration's), the policy told its dead time as in the
//! evaluation. So the trainer's export and the simulator quantise a policy identically.

use std::ops::Range;

use firmware::controller::{Duty, Greedy, Policy};
use firmware::network::{Mlp, OBS_DIM};
use weights::Weights;
use weights::quant::{Granularity, Quantised, quantise};
use weights::shape::{ForShape, by_shape};

use crate::lockstep::run_episode;
use crate::machine::Machine;
use crate::scenario::Scenario;

/// Seed of the calibration episodes.
pub const CALIBRATION_SEED: u64 = 0xCA11_B8A7E;
/// Episodes per row of the default set.
pub const CALIBRATION_EPISODES: u64 = 4;
/// Steps per calibration episode at most.
pub const CALIBRATION_HORIZON: u32 = 500;

/// A policy that remembers what it was asked.
struct Recording<'a, P> {
    inner: P,
    seen: &'a mut Vec<[f32; OBS_DIM]>,
}

impl<P: Policy> Policy for Recording<'_, P> {
    type Scores = P::Scores;
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> P::Scores {
        self.seen.push(*obs);
        self.inner.scores(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.inner.duty(i)
    }
    fn drive(&self, q: &P::Scores, i: usize) -> Option<Duty> {
        self.inner.drive(q, i)
    }
}

/// Every observation `policy` is asked about in episodes `episodes` of each of `scenarios`
/// under `seed`, in order (what its network sees: after the dead-time predictor).
pub fn visited<P: Policy + Copy>(
    policy: P,
    scenarios: &[Scenario],
    episodes: Range<u64>,
    horizon: u32,
    seed: u64,
) -> Vec<[f32; OBS_DIM]> {
    let mut seen = Vec::new();
    for s in scenarios {
        for e in episodes.clone() {
            let rec = Recording {
                inner: policy,
                seen: &mut seen,
            };
            run_episode(rec, s, horizon, seed, e, true, |_| {});
        }
    }
    seen
}

/// The calibration set of the float policy `w` on `machine` (see [the module](self)).
pub fn calibration_states(w: &Weights, machine: &Machine) -> weights::Result<Vec<[f32; OBS_DIM]>> {
    struct States<'a>(&'a Weights, &'a Machine);
    impl ForShape for States<'_> {
        type Output = weights::Result<Vec<[f32; OBS_DIM]>>;
        fn run<const H: usize, const A: usize>(self) -> Self::Output {
            let net: Box<Mlp<H, A>> = self.0.to_mlp()?;
            let levels = self.0.to_levels()?;
            Ok(visited(
                Greedy { net: &*net, levels },
                &Scenario::default_set_on(self.1),
                0..CALIBRATION_EPISODES,
                CALIBRATION_HORIZON,
                CALIBRATION_SEED,
            ))
        }
    }
    by_shape(w.width(), w.outputs(), States(w, machine))?
}

/// `w` quantised on its calibration set on `machine`: what `policy-export export --quant
/// int8` writes and `host-sim eval --controller policy-int` runs.
pub fn quantise_policy(
    w: &Weights,
    granularity: Granularity,
    machine: &Machine,
) -> weights::Result<Quantised> {
    quantise(w, &calibration_states(w, machine)?, granularity)
}
