//! Why a configuration was refused: the one error every checked constructor returns
//! ([`Limits`](crate::controller::Limits), [`Observer`](crate::estimator::Observer),
//! [`AlphaBeta`](crate::estimator::AlphaBeta), [`Predictor`](crate::controller::Predictor),
//! and the checks of [`Params`](crate::cartpole::Params),
//! [`Encoders`](crate::estimator::Encoders), [`Tuning`](crate::estimator::Tuning) and
//! [`Rig`](crate::rig::Rig)).
//!
//! A value these refuse would not fail loudly later: a NaN bound or gain compares as
//! nothing, a zero length divides to infinity, and the controller would coast or steer on
//! NaN for ever without a fault to show for it. Refused at construction, the mistake is
//! named once, before the motor is ever driven.

use core::fmt;

/// A configuration value no machine has: which field, and why. The field is named as its
/// struct spells it (`"params.length"`, `"limits.max_abs[2]"`).
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConfigError {
    /// NaN or infinite.
    NotFinite(&'static str),
    /// Zero or negative (a count of zero), where only a positive value has a meaning.
    NotPositive(&'static str),
    /// Negative, where only zero or more has a meaning.
    Negative(&'static str),
    /// Larger than the most the firmware can hold (the dead time's line, a filter's
    /// discount).
    TooLarge(&'static str),
    /// The end-stop margin is not less than the track's half-length: no track is left.
    NoTrack,
    /// Each value is finite, but the observer's Kalman gain is not (the plant and tuning
    /// overflow f64 in its Riccati iteration).
    GainNotFinite,
    /// Outside the range the value is a fraction of (a duty level beyond `[-1, 1]`).
    OutOfRange(&'static str),
    /// Fewer than the least that has a meaning (a policy choosing among one level).
    TooFew(&'static str),
    /// A list that must be strictly increasing is not (duty levels).
    NotIncreasing(&'static str),
    /// Beyond what another value allows (a catch region wider than the release angle):
    /// the field, then what it must be.
    AboveLimit(&'static str, &'static str),
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::NotFinite(field) => write!(f, "{field}: expected a finite number"),
            ConfigError::NotPositive(field) => write!(f, "{field}: expected more than zero"),
            ConfigError::Negative(field) => write!(f, "{field}: expected zero or more"),
            ConfigError::TooLarge(field) => write!(f, "{field}: larger than the firmware holds"),
            ConfigError::NoTrack => {
                f.write_str("end-stop margin: expected less than the track's half-length")
            }
            ConfigError::GainNotFinite => {
                f.write_str("observer: the Kalman gain is not finite for this plant and tuning")
            }
            ConfigError::OutOfRange(field) => write!(f, "{field}: expected within [-1, 1]"),
            ConfigError::TooFew(field) => write!(f, "{field}: expected at least two"),
            ConfigError::NotIncreasing(field) => {
                write!(f, "{field}: expected strictly increasing")
            }
            ConfigError::AboveLimit(field, bound) => write!(f, "{field}: expected {bound}"),
        }
    }
}

/// `v`, if finite and above zero.
pub(crate) const fn positive(v: f64, field: &'static str) -> Result<f64, ConfigError> {
    if !v.is_finite() {
        Err(ConfigError::NotFinite(field))
    } else if v > 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::NotPositive(field))
    }
}

/// `v`, if finite and not below zero (`-0.0` included).
pub(crate) const fn non_negative(v: f64, field: &'static str) -> Result<f64, ConfigError> {
    if !v.is_finite() {
        Err(ConfigError::NotFinite(field))
    } else if v >= 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::Negative(field))
    }
}

/// `?` for the checks, which are `const fn` (where `?` is not yet allowed) so that a board's
/// `static` configuration can be checked as it is compiled.
macro_rules! check {
    ($e:expr) => {
        match $e {
            Ok(v) => v,
            Err(e) => return Err(e),
        }
    };
}
pub(crate) use check;
