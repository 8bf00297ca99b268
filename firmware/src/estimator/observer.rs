//! The model-based observer ([`Observer`]).

use crate::cartpole::{Params, Plant};
use crate::config::{ConfigError, check, positive};
use crate::controller::predict::{self, DeadTime};
use crate::linear::{kalman_gain, linearise};

use super::{Encoders, wrap};

/// The observer's process noise: how far it expects the plant to stray from its nominal
/// model in one period. Larger values trust the encoders more and the model less: faster to
/// follow a push or a plant unlike the nominal one, noisier under coarse quantisation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tuning {
    /// Standard deviation of an unmodelled force on the cart, N (pushes, friction, a motor
    /// stronger or weaker than nominal): it enters as the motor's force does.
    pub force_sd: f64,
    /// Standard deviations of unmodelled accelerations of the cart (m/s^2) and the pole
    /// (rad/s^2): a pole or cart unlike the nominal one.
    pub accel_sd: [f64; 2],
}

impl Tuning {
    /// The tuning the twin and the shipped recipe use: the middle of the settings tried, and
    /// one that holds every encoder row the policy can hold (`docs/CONTROL.md`, "The
    /// observer's tuning").
    pub const DEFAULT: Tuning = Tuning {
        force_sd: 5.0,
        accel_sd: [2.0, 4.0],
    };
}

impl Tuning {
    /// `self`, if every standard deviation is finite and above zero: without process noise
    /// the gain is zero and the observer never looks at the counts.
    pub const fn check(self) -> Result<Tuning, ConfigError> {
        check!(positive(self.force_sd, "tuning.force_sd"));
        check!(positive(self.accel_sd[0], "tuning.accel_sd[0]"));
        check!(positive(self.accel_sd[1], "tuning.accel_sd[1]"));
        Ok(self)
    }
}

impl Default for Tuning {
    fn default() -> Tuning {
        Tuning::DEFAULT
    }
}

/// The model-based observer: predict with the nominal plant and the command sent, correct by
/// the steady-state Kalman gain.
///
/// Each period it advances its estimate one Euler step of the nominal plant
/// ([`Plant::euler`] in f32, as the predictor does) under the motor duty that acted during
/// the period just ended, then corrects by `L (y - C s)`, where `y` are the two encoders' readings
/// (each count's midpoint, so that floor quantisation adds no bias) and `L` is the
/// steady-state Kalman gain of the linearised plant ([`kalman_gain`]) for the encoders'
/// quantisation noise and a process noise set by [`Tuning`].
///
/// The command must be the board's own: what it sent to the motor, as a fraction of full
/// force, one period after another ([`Observer::command`]; behind a
/// [`Controller`](crate::controller::Controller), from
/// [`StateSensor::commanded`](crate::controller::StateSensor::commanded)). With actuator
/// dead time the observer holds the commands in flight itself, in the same [`DeadTime`]
/// line as the predictor and the twin's actuator, and applies each when it reaches the
/// motor.
///
/// The counts are taken as differences from the last ones, in wrapping arithmetic, so a
/// hardware counter that wraps through `i32::MAX` moves the estimate by the counts it moved,
/// not by 2^32. The pole's count is kept in the revolution about upright, the estimate's
/// angle moved with it by whole turns, and the angle handed out is in (-pi, pi]: a pole
/// that turns a whole revolution reads upright again.
///
/// Fixed-size, allocation-free, panic-free for any counts and commands: a non-finite
/// estimate restarts it from the next counts.
#[derive(Clone, Debug, PartialEq)]
pub struct Observer {
    enc: Encoders,
    plant: Plant<f32>,
    gain: [[f32; 2]; 4],
    /// Metres per cart count, radians per pole count.
    per_count: [f32; 2],
    estimate: [f32; 4],
    /// The counts last read `(cart, pole)`, as the counter gave them; `None` before the
    /// first.
    last: Option<(i32, i32)>,
    /// The cart's count since the start, unwrapped.
    cart: i64,
    /// The pole's count in the revolution about upright ([`wrap::count`]).
    pole: i64,
    /// Commands (fractions of full force) on their way to the motor.
    line: DeadTime<f32>,
    /// The command that acted during the period now ending.
    acting: f32,
    started: bool,
    /// Whether a repeated pair of counts that the model says cannot repeat is taken for a
    /// frozen encoder ([`Observer::watching`]).
    watch: bool,
    /// Whether the last update found the encoders frozen.
    frozen: bool,
    /// The running mean of the residuals' size, in counts (only while watching).
    residual: f32,
    /// Added to the pole's angle as its counts give it, rad ([`Observer::trim`]).
    trim: f32,
}

/// The larger of residuals `e` (m, rad) in counts of its encoder.
fn counts(e: [f32; 2], per_count: [f32; 2]) -> f32 {
    (e[0] / per_count[0]).abs().max((e[1] / per_count[1]).abs())
}

/// The weight of the newest residual in the running mean of their size: about the last
/// eight periods.
const RESIDUAL_WEIGHT: f32 = 0.125;

/// How far, in counts of either encoder, the model's prediction must have moved from a
/// repeated pair of counts for the pair to read as a frozen encoder. One count would let
/// quantisation alone flag a cart or pole turning round; two do not, on the rigs tried.
const FROZEN_COUNTS: f32 = 2.0;

impl Observer {
    /// An observer for `enc`, modelling the plant as `nominal` (its tau is the period), with
    /// process noise `tuning` and `dead_time` periods between a command and the motor (at
    /// most [`MAX_PREDICT`](crate::controller::predict::MAX_PREDICT)). Solves the Kalman
    /// gain's Riccati equation in f64: a board does this once, at start-up.
    ///
    /// Refused, naming the field: encoders of zero counts, a plant that is no machine
    /// ([`Params::check`]), a tuning without noise ([`Tuning::check`]), a dead time beyond the
    /// line; and [`ConfigError::GainNotFinite`] should the gain still overflow.
    pub fn new(
        enc: Encoders,
        nominal: &Params,
        tuning: Tuning,
        dead_time: usize,
    ) -> Result<Observer, ConfigError> {
        let enc = enc.check()?;
        let nominal = nominal.check()?;
        let tuning = tuning.check()?;
        let dead_time = predict::dead_time(dead_time)?;
        let per_count = enc.per_count();
        let (a, b) = linearise(&nominal);
        let t = nominal.tau;
        let f = tuning.force_sd;
        let [ax, at] = tuning.accel_sd.map(|s| s * t * s * t);
        let mut q = [[0.0; 4]; 4];
        for (i, row) in q.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = f * f * b[i] * b[j];
            }
        }
        q[1][1] += ax;
        q[3][3] += at;
        // A count's error is uniform over one count: variance 1/12 count^2.
        let r = per_count.map(|c| c * c / 12.0);
        let gain = kalman_gain(&a, &q, r).map(|row| row.map(|g| g as f32));
        if !gain.iter().flatten().all(|g| g.is_finite()) {
            return Err(ConfigError::GainNotFinite);
        }
        Ok(Observer {
            enc,
            plant: Plant::new(&nominal),
            gain,
            per_count: per_count.map(|c| c as f32),
            estimate: [0.0; 4],
            last: None,
            cart: 0,
            pole: 0,
            line: DeadTime::new(dead_time),
            acting: 0.0,
            started: false,
            watch: false,
            frozen: false,
            residual: 0.0,
            trim: 0.0,
        })
    }

    /// The same observer, watching for a frozen encoder: when both counts repeat the last
    /// ones while the model's prediction has moved more than two counts from them, the
    /// counts are not believed; the estimate is the prediction alone, and
    /// [`Observer::frozen`] says so. A cable pulled from a quadrature encoder freezes its
    /// counter this way, and an observer corrected towards the frozen counts comes to believe
    /// the cart and pole stopped where they were. A plant at rest repeats its counts too, but
    /// then the prediction does not move.
    pub fn watching(mut self) -> Observer {
        self.watch = true;
        self
    }

    /// Whether the last update found the encoders frozen and went on the model alone.
    pub fn frozen(&self) -> bool {
        self.frozen
    }

    /// Records the command sent this period, as a fraction of full force (`1` full right,
    /// `-1` full left, `0` coasting; clamped, NaN taken as 0). It acts once the dead time has
    /// passed; until then the commands before it do (none before the first).
    pub fn command(&mut self, level: f32) {
        let level = if level.is_nan() {
            0.0
        } else {
            level.clamp(-1.0, 1.0)
        };
        self.acting = self.line.send(level);
    }

    /// Takes one period's counts (cart, pole) and returns the estimated state in SI units.
    /// The first call (and the first after [`Observer::reset`]) starts from the counts at
    /// rest.
    pub fn update(&mut self, cart_counts: i32, pole_counts: i32) -> [f32; 4] {
        let repeated = self.last == Some((cart_counts, pole_counts));
        self.count(cart_counts, pole_counts);
        let yx = (self.cart as f32 + 0.5) * self.per_count[0];
        let yt = (self.pole as f32 + 0.5) * self.per_count[1] + self.trim;
        if !self.started {
            self.frozen = false;
            self.estimate = [yx, 0.0, yt, 0.0];
            self.started = true;
            return self.state();
        }
        let pred = self.plant.euler(&self.estimate, self.acting, 0.0);
        let e = [yx - pred[0], yt - pred[2]];
        self.frozen = self.watch && repeated && self.moved(e);
        if self.frozen && self.quiet() {
            self.estimate = pred;
        } else {
            if self.watch && !self.frozen {
                self.track(e);
            }
            for ((s, p), g) in self.estimate.iter_mut().zip(pred).zip(self.gain) {
                *s = p + g[0] * e[0] + g[1] * e[1];
            }
        }
        if !self.estimate.iter().all(|v| v.is_finite()) {
            self.started = false;
        }
        self.state()
    }

    /// Whether residuals `e` (m, rad) exceed [`FROZEN_COUNTS`] of either encoder.
    fn moved(&self, e: [f32; 2]) -> bool {
        counts(e, self.per_count) > FROZEN_COUNTS
    }

    /// Follows the residuals' size, in counts.
    fn track(&mut self, e: [f32; 2]) {
        self.residual += (counts(e, self.per_count) - self.residual) * RESIDUAL_WEIGHT;
    }

    /// Whether the recent residuals are small enough for the estimate's velocities, and
    /// the prediction made from them, to be trusted over a frozen count.
    fn quiet(&self) -> bool {
        self.residual <= FROZEN_COUNTS
    }

    /// Moves the counts by the counter's change since the last reading: the difference of
    /// two wrapping counter values is the counts moved, whether or not the counter wrapped
    /// between them (as long as it moved fewer than 2^31). When the pole's count passes
    /// into the next revolution, the estimate's angle moves by the same whole turns, so that
    /// the residual between them is the one unwrapped counts would give. (A residual
    /// wrapped instead would let the estimate settle on a spin of one turn a period, which
    /// no count can tell from standstill.)
    fn count(&mut self, cart_counts: i32, pole_counts: i32) {
        let (cart, pole) = match self.last {
            Some((c, p)) => (
                self.cart
                    .saturating_add(i64::from(cart_counts.wrapping_sub(c))),
                // A pole turns less than half a revolution in a period: a larger jump (a
                // glitch) is the same angle whole turns away, taken as the smaller move, so
                // that the estimate is never shifted by turns f32 cannot hold exactly.
                self.pole
                    + wrap::count(
                        i64::from(pole_counts.wrapping_sub(p)),
                        self.enc.pole_counts_per_rev,
                    ),
            ),
            None => (i64::from(cart_counts), i64::from(pole_counts)),
        };
        self.cart = cart;
        self.pole = wrap::count(pole, self.enc.pole_counts_per_rev);
        if self.pole != pole {
            self.estimate[2] += (self.pole - pole) as f32 * self.per_count[1];
        }
        self.last = Some((cart_counts, pole_counts));
    }

    /// The current estimate `[x (m), x_dot (m/s), theta (rad), theta_dot (rad/s)]`, the
    /// angle in (-pi, pi].
    pub fn state(&self) -> [f32; 4] {
        let [x, x_dot, theta, theta_dot] = self.estimate;
        [x, x_dot, wrap::angle(theta), theta_dot]
    }

    /// The current estimate in the integer network's input format, Q3.12
    /// ([`crate::fixed::from_state`]).
    pub fn fixed_state(&self) -> [i16; 4] {
        crate::fixed::from_state(&self.state())
    }

    /// The steady-state Kalman gain `L`, rows `[x, x_dot, theta, theta_dot]`, columns the
    /// cart and pole residuals.
    pub fn gain(&self) -> [[f32; 2]; 4] {
        self.gain
    }

    /// Forgets the estimate, the counts and the commands in flight: the next update starts
    /// afresh.
    pub fn reset(&mut self) {
        self.started = false;
        self.frozen = false;
        self.residual = 0.0;
        self.last = None;
        self.line = DeadTime::new(self.line.delay());
        self.acting = 0.0;
    }

    /// The encoders' resolutions.
    pub fn encoders(&self) -> Encoders {
        self.enc
    }

    /// From the next update on, reads the pole `rad` further from upright than its counts
    /// say: a zero finer than a count. Moved a little a period, it is followed as the pole
    /// moving; a reset keeps it.
    pub fn trim(&mut self, rad: f32) {
        self.trim = if rad.is_finite() { rad } else { 0.0 };
    }
}

#[cfg(test)]
mod tests;
