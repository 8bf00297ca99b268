//! The swing experiment: the pole's free swing with the cart held.

use super::{Detail, Experiment, Header, Row, Step};
use crate::estimator::Encoders;
use crate::rig::Rig;

/// Where the swing experiment is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Waiting for the pole to be raised.
    Armed,
    /// Held up; the highest point so far, counts off hanging.
    Raised {
        peak: u32,
    },
    /// Released; periods still to log.
    Swinging {
        left: u32,
    },
    Done,
}

/// The swing experiment: the pole's free swing with the cart held (see [the module](super)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Swing {
    counts_per_rev: u32,
    raise: u32,
    release: u32,
    periods: u32,
    period: u32,
    phase: Phase,
}

impl Swing {
    /// How far off hanging the pole must be raised for logging to start, degrees.
    pub const RAISE_DEG: u32 = 10;

    /// A swing logged for `periods` periods after the release, read with `encoders`.
    pub fn new(encoders: Encoders, periods: u32) -> Swing {
        // At least one count a revolution, so that the thresholds below exist for any encoders.
        let per_rev = encoders.pole_counts_per_rev.max(1);
        Swing {
            counts_per_rev: per_rev,
            raise: (u64::from(per_rev) * u64::from(Self::RAISE_DEG) / 360).max(1) as u32,
            release: (per_rev / 360).max(2),
            periods,
            period: 0,
            phase: Phase::Armed,
        }
    }

    /// The log's comment lines for this experiment on `rig`.
    pub fn header(&self, rig: &Rig) -> Header {
        Header {
            experiment: Experiment::Swing,
            period_s: rig.params.tau,
            encoders: rig.encoders,
            detail: Detail::Swing {
                periods: self.periods,
            },
        }
    }

    /// How far the pole is off hanging, counts, whatever revolution it is in.
    fn off_hanging(&self, pole_counts: i32) -> u32 {
        let per_rev = i64::from(self.counts_per_rev);
        let r = i64::from(pole_counts).rem_euclid(per_rev);
        r.min(per_rev - r) as u32
    }

    /// This period, from the counts just read; the duty is always 0.
    pub fn step(&mut self, cart_counts: i32, pole_counts: i32) -> Step {
        let off = self.off_hanging(pole_counts);
        self.phase = match self.phase {
            Phase::Armed if off >= self.raise => Phase::Raised { peak: off },
            Phase::Raised { peak } if off.saturating_add(self.release) <= peak => {
                Phase::Swinging { left: self.periods }
            }
            Phase::Raised { peak } => Phase::Raised {
                peak: peak.max(off),
            },
            Phase::Swinging { left: 0 } => Phase::Done,
            Phase::Swinging { left } => Phase::Swinging { left: left - 1 },
            other => other,
        };
        match self.phase {
            Phase::Armed => Step::Wait,
            Phase::Done => Step::Done,
            Phase::Raised { .. } | Phase::Swinging { .. } => {
                let row = Row {
                    period: self.period,
                    duty: 0,
                    cart_counts,
                    pole_counts,
                };
                self.period = self.period.saturating_add(1);
                Step::Log(row)
            }
        }
    }
}
