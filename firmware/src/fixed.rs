//! The fixed-point format of the integer pipeline: Q3.12, a value in SI units (m, m/s, rad,
//! rad/s) times 4096 as an `i16`, so 1/4096 of a unit over +-8 units.
//!
//! The integer network ([`crate::network::int`]) takes its observation in this format, the
//! integer alpha-beta filter ([`crate::estimator::AlphaBeta`]) keeps its sub-count state with
//! the same fraction bits and hands its estimate out in it, and the controller checks a
//! fixed-point reading against its limits in it.
//!
//! ```
//! use firmware::fixed;
//! assert_eq!(fixed::from_state(&[0.5, -1.0, 0.05, 8.5]), [2048, -4096, 205, 32767]);
//! assert_eq!(fixed::to_state(&[2048, -4096, 0, 1]), [0.5, -1.0, 0.0, 1.0 / 4096.0]);
//! ```

/// Fraction bits: one unit is `1 << FRACTION_BITS`.
pub const FRACTION_BITS: u32 = 12;
/// One unit (1 m, 1 rad, ...) in the format.
pub const ONE: f32 = (1u32 << FRACTION_BITS) as f32;

/// `v` in the format: times 4096, rounded to nearest (ties away from zero), saturated to the
/// `i16` range; NaN reads as 0.
#[inline]
pub fn from_f32(v: f32) -> i16 {
    // `as` saturates and maps NaN to 0.
    libm::roundf(v * ONE) as i16
}

/// A float state in the format, channel by channel ([`from_f32`]). The one float step of an
/// integer controller that is handed float readings; a board whose estimator is the integer
/// alpha-beta filter skips it.
#[inline]
pub fn from_state(obs: &[f32; 4]) -> [i16; 4] {
    obs.map(from_f32)
}

/// A fixed-point state back in floats (exact: every `i16` times 2^-12 is an f32).
#[inline]
pub fn to_state(q: &[i16; 4]) -> [f32; 4] {
    q.map(|v| f32::from(v) / ONE)
}
