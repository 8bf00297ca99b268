//! What a reading may be, what went wrong in a period, and the totals.

use crate::config::{ConfigError, check};
use crate::network::OBS_DIM;

/// The largest magnitude accepted on each channel `[x, x_dot, theta, theta_dot]`, each
/// bound finite and not negative: built only by [`Limits::new`] or [`Limits::track`], which
/// refuse any other.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    max_abs: [f32; OBS_DIM],
    /// The bounds in Q3.12 for a fixed-point reading, computed once: a core without an FPU
    /// would otherwise convert four floats every period.
    fixed: [i16; OBS_DIM],
}

/// The bound on both rates: far beyond any a balancing run reaches before it fails, so a
/// reading beyond it is a sensor fault, not a state.
const MAX_RATE: f32 = 20.0;
/// The bound on the pole's angle: twice the 12 degree failure angle, room for noise. Past it
/// the pole is down.
const MAX_ANGLE: f32 = 0.42;

/// The channels' names, as a refusal names them.
const CHANNELS: [&str; OBS_DIM] = [
    "limits.max_abs[0]",
    "limits.max_abs[1]",
    "limits.max_abs[2]",
    "limits.max_abs[3]",
];

impl Limits {
    /// Per-channel bounds on `|reading|`, inclusive. Refused: a NaN or infinite bound (NaN
    /// compares as nothing, so it would reject every reading or, compared the other way
    /// round, none) and a negative one (which accepts nothing).
    pub const fn new(max_abs: [f32; OBS_DIM]) -> Result<Limits, ConfigError> {
        let mut i = 0;
        let mut fixed = [0; OBS_DIM];
        while i < OBS_DIM {
            let v = max_abs[i];
            if !v.is_finite() {
                return Err(ConfigError::NotFinite(CHANNELS[i]));
            }
            if v < 0.0 {
                return Err(ConfigError::Negative(CHANNELS[i]));
            }
            fixed[i] = fixed_bound(v);
            i += 1;
        }
        Ok(Limits { max_abs, fixed })
    }

    /// For a track whose end stops are `half_length_m` from the centre: the cart's reading
    /// is accepted only while the cart is more than `margin_m` from a stop, so near the ends
    /// the controller coasts (duty off) instead of driving into them: an end-of-track
    /// interlock. Past the pole's bound the controller coasts too.
    /// Refused: a length not above zero, a negative margin, a margin that leaves no track,
    /// anything not finite.
    pub const fn track(half_length_m: f32, margin_m: f32) -> Result<Limits, ConfigError> {
        if !half_length_m.is_finite() {
            return Err(ConfigError::NotFinite("params.x_threshold"));
        }
        if half_length_m <= 0.0 {
            return Err(ConfigError::NotPositive("params.x_threshold"));
        }
        if !margin_m.is_finite() {
            return Err(ConfigError::NotFinite("end_stop_margin"));
        }
        if margin_m < 0.0 {
            return Err(ConfigError::Negative("end_stop_margin"));
        }
        if margin_m >= half_length_m {
            return Err(ConfigError::NoTrack);
        }
        let x = half_length_m - margin_m;
        Ok(check!(Limits::new([x, MAX_RATE, MAX_ANGLE, MAX_RATE])))
    }

    /// Per-channel bound on `|reading|`, inclusive.
    pub const fn max_abs(&self) -> [f32; OBS_DIM] {
        self.max_abs
    }

    /// Per-channel bound on `|reading|` of a Q3.12 reading, inclusive: each bound rounded
    /// to the format ([`crate::fixed::from_f32`]), and below the format's largest value,
    /// which a saturated channel reads as.
    pub const fn fixed(&self) -> [i16; OBS_DIM] {
        self.fixed
    }
}

/// `v` (finite, not negative) in Q3.12 as [`crate::fixed::from_f32`] rounds it, at most
/// `i16::MAX - 1`; a `const fn`, so that a board's limits are converted as it compiles.
const fn fixed_bound(v: f32) -> i16 {
    let scaled = v * crate::fixed::ONE;
    // Half away from zero is half up for a value not below zero; below 2^23 adding a half
    // is exact in f32, and beyond the format saturates anyway.
    if scaled >= (i16::MAX - 1) as f32 {
        i16::MAX - 1
    } else {
        (scaled + 0.5) as i16
    }
}

/// What went wrong in one period, and who decided, as bits: per channel `i`, bit `i` is
/// "not finite" and bit `4 + i` "out of range"; then a sensor error and an actuator error;
/// then the runtime monitor's ([`super::monitor`]) fallback and stop, and a reading that
/// came from the model alone.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct FaultFlags(pub u16);

impl FaultFlags {
    /// The sensor returned an error.
    pub const SENSOR_ERROR: FaultFlags = FaultFlags(1 << 8);
    /// The direction pin or the duty cycle returned an error.
    pub const ACTUATOR_ERROR: FaultFlags = FaultFlags(1 << 9);
    /// The monitor's fallback decided the period.
    pub const FALLBACK: FaultFlags = FaultFlags(1 << 10);
    /// The monitor has stopped the controller: duty off.
    pub const STOPPED: FaultFlags = FaultFlags(1 << 11);
    /// The reading came from the estimator's model alone, its encoders found frozen
    /// ([`StateSensor::model_only`](super::StateSensor::model_only)); it was acted on.
    pub const MODEL_ONLY: FaultFlags = FaultFlags(1 << 12);
    /// The flags that reject a reading: the channels' and the sensor's error.
    const REJECTING: u16 = (1 << 9) - 1;

    /// Channel `channel` (0..4) was NaN or infinite.
    pub const fn non_finite(channel: usize) -> FaultFlags {
        FaultFlags(1 << (channel % OBS_DIM))
    }

    /// Channel `channel` (0..4) was finite but beyond its limit.
    pub const fn out_of_range(channel: usize) -> FaultFlags {
        FaultFlags(1 << (OBS_DIM + channel % OBS_DIM))
    }

    /// No flag set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Every flag of `other` is set in `self`.
    pub const fn contains(self, other: FaultFlags) -> bool {
        self.0 & other.0 == other.0
    }

    /// Any reading fault: an error, a non-finite or an out-of-range channel.
    pub const fn reading_rejected(self) -> bool {
        self.0 & Self::REJECTING != 0
    }

    /// Both sets of flags.
    pub const fn with(self, other: FaultFlags) -> FaultFlags {
        FaultFlags(self.0 | other.0)
    }
}

/// Totals since the controller started; they saturate rather than wrap. `repr(C)`: the C
/// API's `cartpole_counters_t` holds them after its period count, field for field.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct FaultCounters {
    /// Periods whose reading was rejected (and so coasted).
    pub rejected_readings: u32,
    /// Sensor errors.
    pub sensor_errors: u32,
    /// Channels read as NaN or infinite.
    pub non_finite: u32,
    /// Channels read beyond their limit.
    pub out_of_range: u32,
    /// Periods in which a pin or duty-cycle write failed.
    pub actuator_errors: u32,
    /// Timer ticks that arrived while a period's step still ran (reported by the loop that
    /// paces the controller, `Controller::record_overruns`): each is a period the
    /// controller started late.
    pub overruns: u32,
    /// Readings that came from the estimator's model alone (a frozen encoder), and were
    /// acted on.
    pub model_only: u32,
    /// Switches from the policy to the monitor's fallback.
    pub fallbacks: u32,
    /// Switches back from the fallback to the policy.
    pub recoveries: u32,
    /// Periods the fallback decided.
    pub fallback_periods: u32,
    /// Periods whose policy gave no decision a duty could rest on: scores that are not
    /// finite, or an output beyond its levels (the monitor's fallback decided them, or
    /// without a monitor the motor coasted).
    pub non_finite_scores: u32,
    /// Times the monitor stopped the controller (at most one per controller built).
    pub safe_stops: u32,
}

impl FaultCounters {
    /// Counts one period without a decision ([`FaultCounters::non_finite_scores`]).
    pub(super) fn count_undecided(&mut self) {
        self.non_finite_scores = self.non_finite_scores.saturating_add(1);
    }

    /// Counts one rejected reading with its flags.
    pub(super) fn count_rejected(&mut self, flags: FaultFlags) {
        self.rejected_readings = self.rejected_readings.saturating_add(1);
        if flags.contains(FaultFlags::SENSOR_ERROR) {
            self.sensor_errors = self.sensor_errors.saturating_add(1);
        }
        let non_finite = (flags.0 & 0x0f).count_ones();
        let out_of_range = ((flags.0 >> OBS_DIM) & 0x0f).count_ones();
        self.non_finite = self.non_finite.saturating_add(non_finite);
        self.out_of_range = self.out_of_range.saturating_add(out_of_range);
    }
}
