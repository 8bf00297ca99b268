//! Encoder counts to the controller's state `[x, x_dot, theta, theta_dot]`, the way a board
//! computes it once per control period.
//!
//! A real cart-pole measures two angles, not four state variables: an incremental encoder on
//! the cart's drive (counts per metre of travel) and one on the pole's pivot (counts per
//! revolution, zero when upright). Positions are quantised to one count; velocities must be
//! estimated. Two estimators do it:
//!
//! - [`Observer`] (the one to use): a model-based observer. It predicts each period with the
//!   nominal plant and the command the board sent, then corrects by the steady-state Kalman
//!   gain ([`crate::linear::kalman_gain`]). Most of a bang-bang controlled pole's motion is
//!   the motor's known push, so it recovers velocities that no count difference can: with a
//!   128-count pole encoder the shipped policy and LQR balance through it where they fail
//!   through the alpha-beta filter (`docs/CONTROL.md`). f32 arithmetic, gains computed once
//!   in f64.
//! - [`AlphaBeta`]: one model-free alpha-beta filter per channel, in integers. It knows
//!   nothing of the plant or the commands, so it lags behind every push; kept for boards that
//!   cannot tell the observer what they command, and as the reference the observer is
//!   measured against.
//!
//! Behind a controller, an [`ObserverSensor`] (or an [`AlphaBetaSensor`]) is the
//! [`StateSensor`](crate::controller::StateSensor): counts in, a reading out, and the
//! commands the controller sends passed on to the observer. The twin, the loopback and every
//! board read their encoders through it.
//!
//! ```
//! use firmware::estimator::{Encoders, Observer, Tuning};
//! use firmware::cartpole::{Params, State, advance};
//! let enc = Encoders { cart_counts_per_m: 20_480, pole_counts_per_rev: 4_096 };
//! let p = Params::default();
//! let mut obs = Observer::new(enc, &p, Tuning::DEFAULT, 0)?;
//! // The cart coasts at 0.5 m/s under an upright pole; the observer is told the duty (0).
//! let mut s = State { x_dot: 0.5, ..State::default() };
//! let mut est = [0.0; 4];
//! for _ in 0..100 {
//!     let (cart, pole) = enc.counts(s.x, s.theta);
//!     est = obs.update(cart, pole);
//!     obs.command(0.0);
//!     s = advance(&p, &s, 0.0, 0.0);
//! }
//! assert!((est[1] - 0.5).abs() < 1e-3, "{est:?}");
//! # Ok::<(), firmware::ConfigError>(())
//! ```

mod alpha_beta;
mod observer;
mod sensor;
pub(crate) mod wrap;

pub use alpha_beta::AlphaBeta;
pub use observer::{Observer, Tuning};
pub use sensor::{AlphaBetaSensor, Counter, Estimate, ObserverSensor, Zeroed};

use crate::config::ConfigError;

/// The two encoders' resolutions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Encoders {
    /// Cart encoder counts per metre of travel (e.g. 2,000 counts per revolution on a pulley
    /// of 20 cm circumference: 10,000).
    pub cart_counts_per_m: u32,
    /// Pole encoder counts per revolution of the pivot (quadrature: 4 x lines).
    pub pole_counts_per_rev: u32,
}

impl Encoders {
    /// `self`, if both resolutions are above zero: a zero count per unit makes a count
    /// infinitely large.
    pub const fn check(self) -> Result<Encoders, ConfigError> {
        if self.cart_counts_per_m == 0 {
            return Err(ConfigError::NotPositive("encoders.cart_counts_per_m"));
        }
        if self.pole_counts_per_rev == 0 {
            return Err(ConfigError::NotPositive("encoders.pole_counts_per_rev"));
        }
        Ok(self)
    }

    /// A count's size: metres per cart count, radians per pole count.
    pub fn per_count(self) -> [f64; 2] {
        [
            1.0 / f64::from(self.cart_counts_per_m),
            core::f64::consts::TAU / f64::from(self.pole_counts_per_rev),
        ]
    }

    /// The counts these encoders read at cart position `x` (m) and pole angle `theta`
    /// (rad), each [`quantise`]d.
    pub fn counts(self, x: f64, theta: f64) -> (i32, i32) {
        (
            quantise(x, f64::from(self.cart_counts_per_m)),
            quantise(
                theta,
                f64::from(self.pole_counts_per_rev) / core::f64::consts::TAU,
            ),
        )
    }
}

/// What an encoder reads for a true position: the count below it, `floor(value * per_unit)`,
/// saturated to the `i32` range. Counts per metre for the cart, per radian
/// (`counts_per_rev / 2 pi`) for the pole.
pub fn quantise(value: f64, counts_per_unit: f64) -> i32 {
    let c = libm::floor(value * counts_per_unit);
    if c.is_nan() {
        0
    } else {
        c.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_floors_and_saturates() {
        assert_eq!(quantise(0.01234, 10_000.0), 123);
        assert_eq!(quantise(-0.00001, 10_000.0), -1);
        assert_eq!(quantise(1e300, 10_000.0), i32::MAX);
        assert_eq!(quantise(f64::NAN, 10_000.0), 0);
    }
}
