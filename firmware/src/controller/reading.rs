//! The two formats a reading comes in: `[f32; 4]` in SI units for the float network, and
//! `[i16; 4]` in Q3.12 ([`crate::fixed`]) for the integer one.

use super::faults::{FaultFlags, Limits};
use super::predict::Predictor;
use crate::fixed;
use crate::network::OBS_DIM;

/// A reading's format: how it is checked against the limits, advanced over the dead time,
/// and fed back through a linear gain.
pub trait Reading: Copy {
    /// What a period records when the sensor returned an error.
    const ZERO: Self;
    /// The channels that are not finite or beyond `limits`.
    fn flags(&self, limits: &Limits) -> FaultFlags;
    /// The reading advanced over `p`'s dead time.
    fn predicted(&self, p: &Predictor) -> Self;
    /// The reading in SI units.
    fn state(&self) -> [f32; OBS_DIM];
    /// Linear state feedback `u = -gain . self` (in SI units, summed in channel order): the
    /// LQR's command.
    fn lqr(&self, gain: &[f32; OBS_DIM]) -> f32 {
        self.state().iter().zip(gain).map(|(s, k)| -k * s).sum()
    }
}

impl Reading for [f32; OBS_DIM] {
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

    fn state(&self) -> [f32; OBS_DIM] {
        *self
    }
}

impl Reading for [i16; OBS_DIM] {
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

    /// Exact: every Q3.12 value is an f32.
    fn state(&self) -> [f32; OBS_DIM] {
        fixed::to_state(self)
    }
}
