//! What goes wrong in a real loop, as parts of a scenario (`glitch`, `stuck`, `drop`,
//! `late`, `weak`, `reset`; [`crate::grammar::PARTS`] documents each): an encoder that
//! jumps for a period or freezes, a reading that never arrives, a period that overruns, a
//! motor that gives less than it should, a controller that restarts. The world applies the sensing and motor faults
//! ([`crate::world::World`]); the episode applies the controller's ([`crate::run::Episode`]).
//! Each comes in stretches at fixed periods ([`Window`]), so every controller meets the same
//! faults at the same moments.

use firmware::estimator::Encoders;

use crate::world::Measurement;

/// A stretch of `periods` consecutive periods at the end of every `every` periods (periods
/// counted from 0): with `periods` 1, the periods `every - 1`, `2 every - 1`, ... as pushes
/// come.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// Length of each stretch (all of them, if it is `every` or more).
    pub periods: u32,
    /// Periods from the start of one stretch to the next.
    pub every: u32,
}

impl Window {
    /// One period every `every`.
    pub const fn every(every: u32) -> Window {
        Window { periods: 1, every }
    }

    /// Whether period `k` lies in a stretch.
    pub fn holds(&self, k: u32) -> bool {
        let every = self.every.max(1);
        k % every >= every.saturating_sub(self.periods)
    }
}

/// A scenario's faults; the default is none.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Faults {
    /// The pole encoder reads this many counts off, in the window's periods (with exact
    /// sensing, the angle is off by as many of the rig's pole counts).
    pub glitch: Option<(u32, Window)>,
    /// The readings repeat the last one before each stretch.
    pub stuck: Option<Window>,
    /// The sensor returns an error instead of a reading.
    pub drop: Option<Window>,
    /// The command misses its period (an overrun): the motor holds the previous one.
    pub late: Option<Window>,
    /// The motor gives this fraction of its force.
    pub weak: Option<(f64, Window)>,
    /// The controller restarts at the start of the period (after the first).
    pub reset: Option<Window>,
}

impl Faults {
    /// Whether the board's controller restarts before period `k` (never before the first).
    pub fn resets(&self, k: u32) -> bool {
        k > 0 && self.reset.is_some_and(|w| w.holds(k))
    }

    /// Sets the fault of part `key` from its values (`value(i)` the `i`th field, its
    /// default filled in); false if `key` is no fault's part.
    pub(crate) fn apply(&mut self, key: &str, value: impl Fn(usize) -> Option<f64>) -> bool {
        let whole = |i: usize| value(i).map_or(1, |v| v as u32);
        let window = |i: usize| Window {
            periods: whole(i),
            every: whole(i + 1).max(1),
        };
        match key {
            "glitch" => self.glitch = Some((whole(0), Window::every(whole(1).max(1)))),
            "stuck" => self.stuck = Some(window(0)),
            "drop" => self.drop = Some(Window::every(whole(0).max(1))),
            "late" => self.late = Some(Window::every(whole(0).max(1))),
            "weak" => self.weak = Some((value(0).unwrap_or(1.0), window(1))),
            "reset" => self.reset = Some(Window::every(whole(0).max(1))),
            _ => return false,
        }
        true
    }

    /// `m`, period `k`'s true measurement, as the faulty sensor gives it: off by the
    /// glitch. Stuck and dropped readings are the world's (they need what came before).
    pub(crate) fn corrupt(&self, m: Measurement, k: u32, encoders: &Encoders) -> Measurement {
        let glitch = match self.glitch {
            Some((n, w)) if w.holds(k) => n,
            _ => return m,
        };
        match m {
            Measurement::Counts(cart, pole) => {
                Measurement::Counts(cart, pole.wrapping_add_unsigned(glitch))
            }
            Measurement::State(mut s) => {
                let count = core::f64::consts::TAU / f64::from(encoders.pole_counts_per_rev);
                s[2] = (f64::from(s[2]) + f64::from(glitch) * count) as f32;
                Measurement::State(s)
            }
            Measurement::Missing => m,
        }
    }
}

#[cfg(test)]
mod tests;
