//! The two formats a reading comes in: `[f32; 4]` in SI units for the float network, and
//! `[i16; 4]` in Q3.12 ([`crate::fixed`]) for the integer one.

use super::{FaultFlags, Limits, Predictor};
use crate::cartpole::Action;
use crate::fixed;
use crate::network::{N_ACTIONS, OBS_DIM, argmax};

/// A reading's format: how it is checked against the limits, advanced over the dead time,
/// and how its policy's scores decide.
pub trait Reading: Copy {
    /// The policy's two scores in this format.
    type Scores: Copy + PartialEq + core::fmt::Debug;
    /// The scores recorded when the reading was rejected and the policy did not run.
    const UNSCORED: Self::Scores;
    /// What a period records when the sensor returned an error.
    const ZERO: Self;
    /// The channels that are not finite or beyond `limits`.
    fn flags(&self, limits: &Limits) -> FaultFlags;
    /// The reading advanced over `p`'s dead time.
    fn predicted(&self, p: &Predictor) -> Self;
    /// Right only if its score is strictly larger; ties (and NaN) push left, as `argmax`
    /// does in NumPy and PyTorch.
    fn decide(scores: &Self::Scores) -> Action;
    /// Whether every score is a number a decision can rest on.
    fn finite(scores: &Self::Scores) -> bool;
    /// Bang-bang state feedback: right when `-gain . self > 0` (in SI units), else left.
    fn bang_bang(&self, gain: &[f32; OBS_DIM]) -> Action;
}

/// Right when `-gain . s > 0`: the sign of the linear controller's force.
fn bang_bang(s: &[f32; OBS_DIM], gain: &[f32; OBS_DIM]) -> Action {
    let u: f32 = s.iter().zip(gain).map(|(s, k)| -k * s).sum();
    if u > 0.0 { Action::Right } else { Action::Left }
}

impl Reading for [f32; OBS_DIM] {
    type Scores = [f32; N_ACTIONS];
    const UNSCORED: [f32; N_ACTIONS] = [f32::NAN; N_ACTIONS];
    const ZERO: [f32; OBS_DIM] = [0.0; OBS_DIM];

    fn flags(&self, limits: &Limits) -> FaultFlags {
        let mut flags = FaultFlags::default();
        for (i, (&v, max)) in self.iter().zip(limits.max_abs()).enumerate() {
            if !v.is_finite() {
                flags = flags.with(FaultFlags::non_finite(i));
            } else if v.abs() > max {
                flags = flags.with(FaultFlags::out_of_range(i));
            }
        }
        flags
    }

    #[inline]
    fn predicted(&self, p: &Predictor) -> Self {
        p.predict(self)
    }

    #[inline]
    fn decide(scores: &[f32; N_ACTIONS]) -> Action {
        argmax(scores)
    }

    fn finite(scores: &[f32; N_ACTIONS]) -> bool {
        scores.iter().all(|q| q.is_finite())
    }

    fn bang_bang(&self, gain: &[f32; OBS_DIM]) -> Action {
        bang_bang(self, gain)
    }
}

impl Reading for [i16; OBS_DIM] {
    type Scores = [i32; N_ACTIONS];
    const UNSCORED: [i32; N_ACTIONS] = [0; N_ACTIONS];
    const ZERO: [i16; OBS_DIM] = [0; OBS_DIM];

    /// A saturated channel (`i16::MIN` or `MAX`) is out of range whatever the limit: the
    /// value it stands for is unknown.
    fn flags(&self, limits: &Limits) -> FaultFlags {
        let mut flags = FaultFlags::default();
        for (i, (&v, bound)) in self.iter().zip(limits.fixed()).enumerate() {
            if i32::from(v).abs() > i32::from(bound) {
                flags = flags.with(FaultFlags::out_of_range(i));
            }
        }
        flags
    }

    /// Through the float predictor: the one float step of an integer pipeline with dead
    /// time.
    #[inline]
    fn predicted(&self, p: &Predictor) -> Self {
        fixed::from_state(&p.predict(&fixed::to_state(self)))
    }

    #[inline]
    fn decide(scores: &[i32; N_ACTIONS]) -> Action {
        if scores[1] > scores[0] {
            Action::Right
        } else {
            Action::Left
        }
    }

    /// Integers are always numbers.
    fn finite(_: &[i32; N_ACTIONS]) -> bool {
        true
    }

    /// In f32 (exact from Q3.12): four products once a period, and only in the fallback.
    fn bang_bang(&self, gain: &[f32; OBS_DIM]) -> Action {
        bang_bang(&fixed::to_state(self), gain)
    }
}
