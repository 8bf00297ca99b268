//! The control step: read the state, sanitise it, run the policy, drive the motor.
//!
//! [`Controller::step`] is everything a board does once per control period
//! ([`CONTROL_PERIOD_S`], the plant's tau): it reads `[x, x_dot, theta, theta_dot]` through a
//! [`StateSensor`], checks every channel, asks a [`Policy`] for its two scores and drives an
//! H-bridge through embedded-hal 1.0: a direction [`OutputPin`] (high pushes towards +x) and
//! an enable [`SetDutyCycle`] whose full duty is the plant's full 10 N push. The same code
//! runs on the microcontroller against real pins and in `host-sim` against a digital twin.
//!
//! This module is not a scheduler: the caller decides when a period starts (a timer
//! interrupt, `DelayNs`, or a simulation loop). It is not a filter either: it acts on the
//! reading it is given (`crate::estimator` turns encoder counts into one). With a known
//! actuator dead time, [`Controller::with_predictor`] makes it decide on the state its
//! command will meet ([`predict`]).
//!
//! # Faults and the fallback
//!
//! A reading is rejected when the sensor returns an error, or when any channel is NaN,
//! infinite, or outside [`Limits`]. A rejected reading never reaches the policy: the
//! controller *coasts* (duty cycle off, the motor pushes neither way), counts the fault in
//! [`FaultCounters`] and flags it in the telemetry record. Coasting is the one command that
//! cannot make a wrong reading worse; one coasting period in a balanced run costs a small
//! fraction of a push. An actuator error is counted too, and the next command re-sends the
//! whole pin sequence because the bridge's state is then unknown.
//!
//! # Pin sequence
//!
//! Changing direction is break-before-make: duty off, then the direction pin, then full duty,
//! so the bridge never drives the old way with the new direction's half-bridge. Repeating the
//! current command writes nothing.
//!
//! ```
//! use core::convert::Infallible;
//! use embedded_hal::{digital::{ErrorType as PinErrorType, OutputPin},
//!                    pwm::{ErrorType as PwmErrorType, SetDutyCycle}};
//! use firmware::controller::{Command, Controller, Limits, StateSensor};
//! use firmware::{policy::POLICY, Action};
//!
//! struct Level(bool);
//! impl PinErrorType for Level { type Error = Infallible; }
//! impl OutputPin for Level {
//!     fn set_low(&mut self) -> Result<(), Infallible> { self.0 = false; Ok(()) }
//!     fn set_high(&mut self) -> Result<(), Infallible> { self.0 = true; Ok(()) }
//! }
//! struct Duty(u16);
//! impl PwmErrorType for Duty { type Error = Infallible; }
//! impl SetDutyCycle for Duty {
//!     fn max_duty_cycle(&self) -> u16 { 1000 }
//!     fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> { self.0 = duty; Ok(()) }
//! }
//! struct Tilted;
//! impl StateSensor for Tilted {
//!     type Error = ();
//!     fn read(&mut self) -> Result<[f32; 4], ()> { Ok([0.0, 0.0, 0.05, 0.2]) }
//! }
//!
//! let mut c: Controller<_, _, _, _, 16> =
//!     Controller::new(&POLICY, Tilted, Level(false), Duty(0), Limits::default());
//! // The pole leans towards +x, so the cart must move under it: a push to the right.
//! assert_eq!(c.step(), Command::Push(Action::Right));
//! let (_, _, dir, duty) = c.release();
//! assert!(dir.0);
//! assert_eq!(duty.0, 1000);
//! ```

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use heapless::HistoryBuf;

use crate::cartpole::Action;
use crate::network::int::{QMlp, fixed_obs};
use crate::network::{Mlp, N_ACTIONS, OBS_DIM, argmax};

pub mod predict;

pub use predict::{Model, Predictor};

/// The control period in seconds: the plant's Euler step, 50 Hz.
pub const CONTROL_PERIOD_S: f64 = 0.02;

/// Where the controller gets the plant's state, once per period: encoders on a board, the
/// simulated plant in `host-sim`. Units as in Gymnasium: m, m/s, rad, rad/s.
pub trait StateSensor {
    /// Why a reading failed (a bus error, a timeout); it only gets counted.
    type Error;
    /// One reading of `[x, x_dot, theta, theta_dot]`.
    fn read(&mut self) -> Result<[f32; OBS_DIM], Self::Error>;

    /// Told once a period, after the reading, what the controller sent the bridge (on an
    /// actuator error, what it tried to send). A sensor that estimates the velocities with
    /// a model of the plant, as [`Observer`](crate::estimator::Observer) does, needs the
    /// force that will act; a sensor that measures them ignores it.
    #[inline]
    fn commanded(&mut self, command: Command) {
        let _ = command;
    }
}

/// Maps a sanitised observation to two scores, `[left, right]`; the controller pushes right
/// only if the right score is strictly larger (ties and NaN push left, see
/// [`argmax`]). The Q-network's scores are its Q-values; a baseline's
/// may be anything with that meaning.
pub trait Policy {
    /// Scores for `[Left, Right]`.
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> [f32; N_ACTIONS];
}

impl<const H: usize> Policy for &Mlp<H> {
    #[inline]
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> [f32; N_ACTIONS] {
        self.forward(obs)
    }
}

/// The integer network behind a float sensor: the reading is rounded to Q3.12
/// ([`fixed_obs`]), the forward pass is integer-only, and the scores are the integer outputs
/// as f32, exact below 2^24 (which every exported network's outputs are, by construction), so
/// the controller decides as `q[1] > q[0]` does. A board with encoders can skip the float
/// reading altogether: `QMlp::forward` on `AlphaBeta::fixed_state`.
impl<const H: usize> Policy for &QMlp<H> {
    #[inline]
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> [f32; N_ACTIONS] {
        self.forward(&fixed_obs(obs)).map(|q| q as f32)
    }
}

/// What the controller asked of the motor in one period.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// Full duty in this direction: the plant's +-10 N.
    Push(Action),
    /// Duty off: the fallback for a rejected reading.
    Coast,
}

impl Command {
    /// The command as a fraction of full force, as the encoder
    /// [`Observer`](crate::estimator::Observer) takes it: `1` right, `-1` left, `0` coasting.
    pub fn level(self) -> f32 {
        match self {
            Command::Push(Action::Right) => 1.0,
            Command::Push(Action::Left) => -1.0,
            Command::Coast => 0.0,
        }
    }
}

/// The largest magnitude accepted on each channel `[x, x_dot, theta, theta_dot]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Per-channel bound on `|reading|`, inclusive.
    pub max_abs: [f32; OBS_DIM],
}

impl Limits {
    /// For the simulated plant: twice what a balancing run can reach, twice the 2.4 m track
    /// half-length and twice the 12 degree failure angle, and 20 m/s and 20 rad/s, far
    /// beyond any rate the plant reaches before it fails. A reading outside them is a sensor
    /// fault, not a state. On hardware, use [`Limits::track`].
    pub const fn simulation() -> Limits {
        Limits {
            max_abs: [4.8, 20.0, 0.42, 20.0],
        }
    }

    /// For a real track whose end stops are `half_length_m` from the centre: the cart's
    /// reading is accepted only while the cart is more than `margin_m` from a stop, so near
    /// the ends the controller coasts (duty off) instead of driving into them: an
    /// end-of-track interlock. Past the failure angle (12 degrees, twice it for noise) the
    /// pole is down and the controller coasts too. Rates as in [`Limits::simulation`].
    /// A length under the margin, or NaN, leaves no track (every reading coasts); a negative
    /// or NaN margin counts as none.
    pub fn track(half_length_m: f32, margin_m: f32) -> Limits {
        // `max` drops a NaN operand.
        let x = (half_length_m - margin_m.max(0.0)).max(0.0);
        Limits {
            max_abs: [x, 20.0, 0.42, 20.0],
        }
    }
}

impl Default for Limits {
    /// [`Limits::simulation`]: what the simulator and the self-test run with.
    fn default() -> Limits {
        Limits::simulation()
    }
}

/// Why one period's reading was rejected, as bits: per channel `i`, bit `i` is "not finite"
/// and bit `4 + i` "out of range"; then a sensor error and an actuator error.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct FaultFlags(pub u16);

impl FaultFlags {
    /// The sensor returned an error.
    pub const SENSOR_ERROR: FaultFlags = FaultFlags(1 << 8);
    /// The direction pin or the duty cycle returned an error.
    pub const ACTUATOR_ERROR: FaultFlags = FaultFlags(1 << 9);

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
        self.0 & !Self::ACTUATOR_ERROR.0 != 0
    }

    const fn with(self, other: FaultFlags) -> FaultFlags {
        FaultFlags(self.0 | other.0)
    }
}

/// Totals since the controller started; they saturate rather than wrap.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
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
    /// paces the controller, [`Controller::record_overruns`]): each is a period the
    /// controller started late.
    pub overruns: u32,
}

/// One period, as the telemetry ring keeps it.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// Period number, from 0.
    pub step: u32,
    /// The reading as received (zeros if the sensor returned an error).
    pub obs: [f32; OBS_DIM],
    /// The policy's scores; NaN when the reading was rejected and the policy did not run.
    pub q: [f32; N_ACTIONS],
    /// What the motor was asked to do.
    pub command: Command,
    /// What went wrong, if anything.
    pub faults: FaultFlags,
}

/// What the bridge is known to be doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Drive {
    Unknown,
    Off,
    Pushing(Action),
}

/// The balance controller: owns its sensor, its two actuator outputs and a ring of the last
/// `N` [`Record`]s. Everything is fixed-size; [`Controller::step`] cannot panic.
pub struct Controller<P, S, D, E, const N: usize> {
    policy: P,
    sensor: S,
    direction: D,
    enable: E,
    limits: Limits,
    drive: Drive,
    steps: u32,
    faults: FaultCounters,
    telemetry: HistoryBuf<Record, N>,
    predictor: Option<Predictor>,
}

impl<P, S, D, E, const N: usize> Controller<P, S, D, E, N>
where
    P: Policy,
    S: StateSensor,
    D: OutputPin,
    E: SetDutyCycle,
{
    /// A controller that has not yet driven the bridge: its first command sends the whole
    /// pin sequence.
    pub fn new(policy: P, sensor: S, direction: D, enable: E, limits: Limits) -> Self {
        Controller {
            policy,
            sensor,
            direction,
            enable,
            limits,
            drive: Drive::Unknown,
            steps: 0,
            faults: FaultCounters::default(),
            telemetry: HistoryBuf::new(),
            predictor: None,
        }
    }

    /// The same controller, deciding on the state its command will meet after the
    /// predictor's dead time rather than on the reading itself (see [`predict`]).
    pub fn with_predictor(mut self, predictor: Predictor) -> Self {
        self.predictor = Some(predictor);
        self
    }

    /// One control period: read, sanitise, decide, actuate, record.
    #[inline]
    pub fn step(&mut self) -> Command {
        let (obs, mut flags) = match self.sensor.read() {
            Ok(obs) => (obs, sanitise(&obs, &self.limits)),
            Err(_) => ([0.0; OBS_DIM], FaultFlags::SENSOR_ERROR),
        };
        let (q, command) = if flags.is_empty() {
            let q = match &self.predictor {
                Some(p) => self.policy.scores(&p.predict(&obs)),
                None => self.policy.scores(&obs),
            };
            (q, Command::Push(argmax(&q)))
        } else {
            self.count_rejected(flags);
            ([f32::NAN; N_ACTIONS], Command::Coast)
        };
        if let Some(p) = &mut self.predictor {
            match command {
                Command::Push(a) => p.record_push(a),
                Command::Coast => p.record(0.0),
            }
        }
        if self.actuate(command).is_err() {
            self.drive = Drive::Unknown;
            self.faults.actuator_errors = self.faults.actuator_errors.saturating_add(1);
            flags = flags.with(FaultFlags::ACTUATOR_ERROR);
        }
        self.sensor.commanded(command);
        self.telemetry.write(Record {
            step: self.steps,
            obs,
            q,
            command,
            faults: flags,
        });
        self.steps = self.steps.saturating_add(1);
        command
    }

    /// Periods run so far.
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// Fault totals so far.
    pub fn faults(&self) -> FaultCounters {
        self.faults
    }

    /// Counts `ticks` timer ticks that arrived while the last step still ran. The
    /// controller does not own the timer, so the loop that waits for it reports them: a
    /// step that overran its period is counted, never hidden.
    pub fn record_overruns(&mut self, ticks: u32) {
        self.faults.overruns = self.faults.overruns.saturating_add(ticks);
    }

    /// The last `N` periods, oldest first.
    pub fn telemetry(&self) -> impl Iterator<Item = &Record> {
        self.telemetry.oldest_ordered()
    }

    /// The most recent period, if any.
    pub fn last(&self) -> Option<&Record> {
        self.telemetry.recent()
    }

    /// The policy, for inspection.
    pub fn policy(&self) -> &P {
        &self.policy
    }

    /// Gives the peripherals back: `(policy, sensor, direction, enable)`.
    pub fn release(self) -> (P, S, D, E) {
        (self.policy, self.sensor, self.direction, self.enable)
    }

    fn count_rejected(&mut self, flags: FaultFlags) {
        let c = &mut self.faults;
        c.rejected_readings = c.rejected_readings.saturating_add(1);
        if flags.contains(FaultFlags::SENSOR_ERROR) {
            c.sensor_errors = c.sensor_errors.saturating_add(1);
        }
        let non_finite = (flags.0 & 0x0f).count_ones();
        let out_of_range = ((flags.0 >> OBS_DIM) & 0x0f).count_ones();
        c.non_finite = c.non_finite.saturating_add(non_finite);
        c.out_of_range = c.out_of_range.saturating_add(out_of_range);
    }

    /// Brings the bridge to `command`; an error leaves it in an unknown state.
    fn actuate(&mut self, command: Command) -> Result<(), ()> {
        match command {
            Command::Coast => {
                if self.drive != Drive::Off {
                    self.enable.set_duty_cycle_fully_off().map_err(drop)?;
                    self.drive = Drive::Off;
                }
            }
            Command::Push(action) => {
                if self.drive != Drive::Pushing(action) {
                    if self.drive != Drive::Off {
                        self.enable.set_duty_cycle_fully_off().map_err(drop)?;
                        self.drive = Drive::Off;
                    }
                    match action {
                        Action::Right => self.direction.set_high(),
                        Action::Left => self.direction.set_low(),
                    }
                    .map_err(drop)?;
                    self.enable.set_duty_cycle_fully_on().map_err(drop)?;
                    self.drive = Drive::Pushing(action);
                }
            }
        }
        Ok(())
    }
}

/// The flags of one reading: non-finite channels, then finite ones beyond their limit.
pub fn sanitise(obs: &[f32; OBS_DIM], limits: &Limits) -> FaultFlags {
    let mut flags = FaultFlags::default();
    for (i, (&v, &max)) in obs.iter().zip(&limits.max_abs).enumerate() {
        if !v.is_finite() {
            flags = flags.with(FaultFlags::non_finite(i));
        } else if v.abs() > max {
            flags = flags.with(FaultFlags::out_of_range(i));
        }
    }
    flags
}

#[cfg(test)]
mod tests;
