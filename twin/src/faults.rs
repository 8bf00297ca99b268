//! What goes wrong in a real loop, as parts of a scenario (`zero`, `glitch`, `stuck`,
//! `drop`, `late`, `weak`, `reset`; [`crate::grammar::PARTS`] documents each): an encoder
//! zeroed off the true zero, one that jumps for a period or freezes, a reading that never
//! arrives, a period that overruns, a motor that gives less than it should, a controller
//! that restarts. The world applies the sensing and motor faults ([`crate::world::World`]);
//! the episode applies the controller's ([`crate::run::Episode`]). Each but the zero comes
//! in stretches at fixed periods ([`Window`]), so every controller meets the same faults at
//! the same moments.

use firmware::estimator::Encoders;

use crate::grammar::Values;
use crate::scenario::Scenario;
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

    /// Whether it holds in every period: a stretch as long as its interval.
    pub fn always(&self) -> bool {
        self.periods >= self.every.max(1)
    }
}

/// A scenario's faults; the default is none.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Faults {
    /// The encoders' zeros are off: every reading of the pole angle is this many radians,
    /// and every reading of the cart this many metres, more than the truth (through
    /// encoders, in the nearest whole counts).
    pub zero: Option<(f64, f64)>,
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

    /// `m`, period `k`'s true measurement, as the faulty sensor gives it: off by the zero
    /// errors and the glitch. Stuck and dropped readings are the world's (they need what
    /// came before).
    pub(crate) fn corrupt(&self, m: Measurement, k: u32, encoders: &Encoders) -> Measurement {
        let (theta, x) = self.zero.unwrap_or((0.0, 0.0));
        let glitch = match self.glitch {
            Some((n, w)) if w.holds(k) => n,
            _ => 0,
        };
        if (theta, x, glitch) == (0.0, 0.0, 0) {
            return m;
        }
        match m {
            Measurement::Counts(cart, pole) => {
                let (dx, dtheta) = zero_counts((theta, x), encoders);
                Measurement::Counts(
                    cart.wrapping_add(dx),
                    pole.wrapping_add(dtheta).wrapping_add_unsigned(glitch),
                )
            }
            Measurement::State(mut s) => {
                // A channel with nothing to add is left alone, its bits (a -0.0) too.
                if x != 0.0 {
                    s[0] = (f64::from(s[0]) + x) as f32;
                }
                let theta = theta + f64::from(glitch) * pole_count(encoders);
                if theta != 0.0 {
                    s[2] = (f64::from(s[2]) + theta) as f32;
                }
                Measurement::State(s)
            }
            Measurement::Missing => m,
        }
    }
}

/// The counts `(cart, pole)` a zero error of `(theta, x)` (radians, metres) adds to what
/// `encoders` read: the nearest whole counts, so that an error within half a count of each
/// adds none.
pub fn zero_counts((theta, x): (f64, f64), encoders: &Encoders) -> (i32, i32) {
    let counts = |v: f64| v.round() as i32;
    (
        counts(x * f64::from(encoders.cart_counts_per_m)),
        counts(theta / pole_count(encoders)),
    )
}

/// A zero error of `(theta, x)` (radians, metres) as `encoders` read it: the whole counts
/// it adds ([`zero_counts`]), in radians and metres.
pub(crate) fn zero_read(zero: (f64, f64), encoders: &Encoders) -> (f64, f64) {
    let (cart, pole) = zero_counts(zero, encoders);
    (
        f64::from(pole) * pole_count(encoders),
        f64::from(cart) / f64::from(encoders.cart_counts_per_m),
    )
}

/// One count of the pole encoder, radians.
fn pole_count(encoders: &Encoders) -> f64 {
    core::f64::consts::TAU / f64::from(encoders.pole_counts_per_rev)
}

/// Stretches of `periods` (field `i`) every `every` (field `i + 1`).
fn window(v: &Values, i: usize) -> Window {
    Window {
        periods: v.whole(i),
        every: v.whole(i + 1).max(1),
    }
}

/// One period every field `i`'s.
fn every(v: &Values, i: usize) -> Window {
    Window::every(v.whole(i).max(1))
}

/// `zero=DEG/MM`.
pub(crate) fn zero(s: &mut Scenario, v: &Values) {
    let (deg, mm) = (v.get(0).unwrap_or(0.0), v.get(1).unwrap_or(0.0));
    s.faults.zero = Some((deg.to_radians(), mm / 1000.0));
}

/// `glitch=N/EVERY`.
pub(crate) fn glitch(s: &mut Scenario, v: &Values) {
    s.faults.glitch = Some((v.whole(0), every(v, 1)));
}

/// `stuck=K/EVERY`.
pub(crate) fn stuck(s: &mut Scenario, v: &Values) {
    s.faults.stuck = Some(window(v, 0));
}

/// `drop=EVERY`.
pub(crate) fn drop(s: &mut Scenario, v: &Values) {
    s.faults.drop = Some(every(v, 0));
}

/// `late=EVERY`.
pub(crate) fn late(s: &mut Scenario, v: &Values) {
    s.faults.late = Some(every(v, 0));
}

/// `weak=F/K/EVERY`.
pub(crate) fn weak(s: &mut Scenario, v: &Values) {
    s.faults.weak = Some((v.get(0).unwrap_or(1.0), window(v, 1)));
}

/// `reset=EVERY`.
pub(crate) fn reset(s: &mut Scenario, v: &Values) {
    s.faults.reset = Some(every(v, 0));
}

#[cfg(test)]
mod tests;
