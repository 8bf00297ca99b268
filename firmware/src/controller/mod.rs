//! The control period: read the state, sanitise it, run the policy, drive the motor.
//!
//! [`Controller::step`] is everything a board does once per control period (the rig's
//! [`Params::tau`](crate::cartpole::Params::tau)), and the one period every caller runs: the
//! trainer's episodes, the simulator's evaluation, the QEMU self-test and the boards. It reads
//! `[x, x_dot, theta, theta_dot]` through a [`StateSensor`], checks every channel against its
//! [`Limits`], asks a [`Policy`] for its two scores and drives the motor through an
//! [`Actuator`], normally a [`Bridge`]: an H-bridge behind embedded-hal 1.0's direction
//! `OutputPin` (high pushes towards +x) and enable `SetDutyCycle` (full duty is the full
//! push). Readings come in one of two formats ([`Reading`]): `[f32; 4]` in SI units for the
//! float network, or `[i16; 4]` in Q3.12 ([`crate::fixed`]) for the integer one. The integer
//! network runs in integers only, but the steps before it need not: the model-based
//! observer estimates in f32 and hands over Q3.12 ([`Observer::fixed_state`]), and with a
//! dead time the predictor takes the Q3.12 reading back to f32, advances it and rounds it
//! again. Only the alpha-beta filter without a dead time keeps the whole path from counts
//! to decision in integers.
//!
//! [`Observer::fixed_state`]: crate::estimator::Observer::fixed_state
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
//! infinite, or outside [`Limits`] (whose bounds are checked when they are built:
//! [`Limits::new`] refuses a NaN, infinite or negative one). A rejected reading never reaches the policy: the
//! controller *coasts* (duty cycle off, the motor pushes neither way), counts the fault in
//! [`FaultCounters`] and flags it in the telemetry record. Coasting is the one command that
//! cannot make a wrong reading worse; one coasting period in a balanced run costs a small
//! fraction of a push. An actuator error is counted too, and the next command re-sends the
//! whole pin sequence because the bridge's state is then unknown.
//!
//! ```
//! use core::convert::Infallible;
//! use embedded_hal::{digital::{ErrorType as PinErrorType, OutputPin},
//!                    pwm::{ErrorType as PwmErrorType, SetDutyCycle}};
//! use firmware::controller::{Bridge, Command, Controller, Duty, StateSensor};
//! use shipped::policy::{POLICY, RIG};
//!
//! struct Pin(bool);
//! impl PinErrorType for Pin { type Error = Infallible; }
//! impl OutputPin for Pin {
//!     fn set_low(&mut self) -> Result<(), Infallible> { self.0 = false; Ok(()) }
//!     fn set_high(&mut self) -> Result<(), Infallible> { self.0 = true; Ok(()) }
//! }
//! struct Pwm(u16);
//! impl PwmErrorType for Pwm { type Error = Infallible; }
//! impl SetDutyCycle for Pwm {
//!     fn max_duty_cycle(&self) -> u16 { 1000 }
//!     fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> { self.0 = duty; Ok(()) }
//! }
//! struct Tilted;
//! impl StateSensor for Tilted {
//!     type Reading = [f32; 4];
//!     type Error = ();
//!     fn read(&mut self) -> Result<[f32; 4], ()> { Ok([0.0, 0.0, 0.05, 0.2]) }
//! }
//!
//! let mut c = Controller::new(&POLICY, Tilted, Bridge::new(Pin(false), Pwm(0)), RIG.limits()?);
//! // The pole leans towards +x, so the cart must move under it: a push to the right.
//! assert_eq!(c.step(), Command::Drive(Duty::RIGHT));
//! let (_, _, bridge) = c.release();
//! let (dir, duty) = bridge.release();
//! assert!(dir.0);
//! assert_eq!(duty.0, 1000);
//! # Ok::<(), firmware::ConfigError>(())
//! ```

use heapless::HistoryBuf;

use crate::network::{N_ACTIONS, OBS_DIM};

mod bridge;
mod faults;
mod hold;
mod levels;
pub mod monitor;
mod policy;
pub mod predict;
mod reading;
mod refine;

pub use bridge::{Actuator, ActuatorError, Bridge};
pub use faults::{FaultCounters, FaultFlags, Limits};
pub use levels::{Command, Duty, Levels, Rises, between, check_levels, nearest};
pub use monitor::{Assurance, Mode, Monitor};
pub use policy::{Answer, Greedy, Policy, Scores, answer};
pub use predict::Predictor;
pub use reading::Reading;
pub use refine::{Refinable, RefineRefused, Refined};

/// Where the controller gets the plant's state, once per period: encoders through an
/// estimator on a board, the simulated plant in the twin. Units as in Gymnasium: m, m/s, rad,
/// rad/s, in the format of [`StateSensor::Reading`].
pub trait StateSensor {
    /// The reading's format: `[f32; 4]`, or `[i16; 4]` in Q3.12.
    type Reading: Reading;
    /// Why a reading failed (a bus error, a timeout); it only gets counted.
    type Error;
    /// One reading of `[x, x_dot, theta, theta_dot]`.
    fn read(&mut self) -> Result<Self::Reading, Self::Error>;

    /// Told once a period, after the reading, what the controller sent the motor (on an
    /// actuator error, what it tried to send). A sensor that estimates the velocities with
    /// a model of the plant, as [`Observer`](crate::estimator::Observer) does, needs the
    /// force that will act; a sensor that measures them ignores it.
    #[inline]
    fn commanded(&mut self, command: Command) {
        let _ = command;
    }

    /// Whether the last reading came from the estimator's model alone, its measurement not
    /// believed (an [`Observer`](crate::estimator::Observer) that found its encoders frozen,
    /// [`Observer::watching`](crate::estimator::Observer::watching)). The controller acts on
    /// it, and counts and flags it.
    #[inline]
    fn model_only(&self) -> bool {
        false
    }
}

/// A period's reading, sanitised and predicted: the first half of
/// [`Controller::step`], which [`Controller::act`] completes.
#[derive(Clone, Copy, Debug)]
pub struct Sensed<O> {
    obs: O,
    seen: O,
    flags: FaultFlags,
    model_only: bool,
}

impl<O: Copy> Sensed<O> {
    /// What the policy will be shown: the reading, advanced over the dead time when the
    /// controller predicts; `None` when the reading is rejected (the motor coasts).
    pub fn shown(&self) -> Option<O> {
        (!self.flags.reading_rejected()).then_some(self.seen)
    }

    /// The reading as the sensor gave it (zero when the sensor failed).
    pub fn reading(&self) -> O {
        self.obs
    }
}

/// One period, as the telemetry ring keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record<O = [f32; OBS_DIM], Q = [f32; N_ACTIONS]> {
    /// Period number, from 0.
    pub step: u32,
    /// The reading as received (zeros if the sensor returned an error).
    pub obs: O,
    /// The policy's scores; [`Scores::UNSCORED`] when the policy did not score the period.
    pub q: Q,
    /// What the motor was asked to do.
    pub command: Command,
    /// What went wrong, if anything.
    pub faults: FaultFlags,
}

#[cfg(feature = "defmt")]
impl<O: defmt::Format, Q: defmt::Format> defmt::Format for Record<O, Q> {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(
            f,
            "Record {{ step: {}, obs: {}, q: {}, command: {}, faults: {} }}",
            self.step,
            self.obs,
            self.q,
            self.command,
            self.faults
        )
    }
}

/// The balance controller: owns its policy, its sensor, its actuator and a ring of the last
/// `N` [`Record`]s (the last one unless a board keeps more to log). Everything is
/// fixed-size; [`Controller::step`] cannot panic. A board builds it from its rig
/// ([`Rig::controller`](crate::rig::Rig::controller)).
pub struct Controller<P, S, A, const N: usize = 1>
where
    P: Policy<S::Reading>,
    S: StateSensor,
{
    policy: P,
    sensor: S,
    actuator: A,
    limits: Limits,
    steps: u32,
    faults: FaultCounters,
    telemetry: HistoryBuf<Record<S::Reading, P::Scores>, N>,
    predictor: Option<Predictor>,
    monitor: Option<Monitor>,
}

impl<P, S, A> Controller<P, S, A>
where
    P: Policy<S::Reading>,
    S: StateSensor,
    A: Actuator,
{
    /// A controller keeping the last period's record, that has not yet driven the motor:
    /// its first command sends the whole pin sequence.
    pub fn new(policy: P, sensor: S, actuator: A, limits: Limits) -> Self {
        Controller::with_history(policy, sensor, actuator, limits)
    }
}

impl<P, S, A, const N: usize> Controller<P, S, A, N>
where
    P: Policy<S::Reading>,
    S: StateSensor,
    A: Actuator,
{
    /// [`Controller::new`], keeping the last `N` periods (`N` from the type).
    pub fn with_history(policy: P, sensor: S, actuator: A, limits: Limits) -> Self {
        Controller {
            policy,
            sensor,
            actuator,
            limits,
            steps: 0,
            faults: FaultCounters::default(),
            telemetry: HistoryBuf::new(),
            predictor: None,
            monitor: None,
        }
    }

    /// The same controller, deciding on the state its command will meet after the
    /// predictor's dead time rather than on the reading itself (see [`predict`]).
    pub fn with_predictor(mut self, predictor: Predictor) -> Self {
        self.predictor = Some(predictor);
        self
    }

    /// The same controller under a runtime monitor ([`monitor`]): the policy drives only
    /// inside `assurance`'s envelope, the LQR fallback elsewhere, and the motor stops where
    /// even the fallback cannot recover.
    pub fn with_monitor(mut self, assurance: Assurance) -> Self {
        self.set_monitor(assurance);
        self
    }

    /// [`Controller::with_monitor`] on a controller in place (one C owns), from its next
    /// period; a monitor it had is replaced, its mode with it.
    pub fn set_monitor(&mut self, assurance: Assurance) {
        self.monitor = Some(Monitor::new(assurance));
    }

    /// The first half of a period ([`Controller::step`] is both): read the sensor, sanitise
    /// the reading against the limits, and advance it over the dead time. A caller that
    /// decides outside (an agent choosing the policy's answer) looks at
    /// [`Sensed::shown`] before calling [`Controller::act`].
    #[inline(always)]
    pub fn sense(&mut self) -> Sensed<S::Reading> {
        let (obs, mut flags) = match self.sensor.read() {
            Ok(obs) => (obs, obs.flags(&self.limits)),
            Err(_) => (S::Reading::ZERO, FaultFlags::SENSOR_ERROR),
        };
        let model_only = !flags.reading_rejected() && self.sensor.model_only();
        if model_only {
            self.faults.model_only = self.faults.model_only.saturating_add(1);
            flags = flags.with(FaultFlags::MODEL_ONLY);
        }
        let seen = match &self.predictor {
            Some(p) if !flags.reading_rejected() => obs.predicted(p),
            _ => obs,
        };
        Sensed {
            obs,
            seen,
            flags,
            model_only,
        }
    }

    /// The second half of a period on what [`Controller::sense`] found, with the output
    /// decided outside the controller (a learner exploring, an agent): `decide` is asked,
    /// on the reading the policy would be shown, only where the policy would drive (a
    /// rejected reading coasts, a monitor's fallback keeps its own command), and the
    /// output's level drives; then actuate, record, tell the sensor. The record's scores
    /// are [`Scores::UNSCORED`]: the controller saw none.
    #[inline(always)]
    pub fn act_with(
        &mut self,
        sensed: Sensed<S::Reading>,
        decide: impl FnOnce(&S::Reading) -> usize,
    ) -> Command {
        self.act_by(sensed, |policy, seen| {
            (P::Scores::UNSCORED, policy.duty(decide(seen)))
        })
    }

    /// The second half of a period: `decide` asked for the scores and the duty (`None`
    /// when there is no decision a duty can rest on) where the policy drives, then the
    /// bridge driven. Without a decision the motor coasts, counted (or, under a monitor,
    /// its fallback drives).
    #[inline(always)]
    fn act_by(
        &mut self,
        sensed: Sensed<S::Reading>,
        decide: impl FnOnce(&mut P, &S::Reading) -> Answer<P::Scores>,
    ) -> Command {
        let Sensed {
            obs,
            seen,
            mut flags,
            model_only,
        } = sensed;
        let policy = &mut self.policy;
        let (q, command) = if flags.reading_rejected() {
            self.faults.count_rejected(flags);
            if let Some(m) = &mut self.monitor {
                m.rejected(flags, &mut self.faults);
            }
            (P::Scores::UNSCORED, Command::Coast)
        } else {
            match &mut self.monitor {
                Some(m) => {
                    let (q, command, who) =
                        m.decide(&obs, &seen, model_only, policy, decide, &mut self.faults);
                    flags = flags.with(who);
                    (q, command)
                }
                None => match decide(policy, &seen) {
                    (q, Some(duty)) => (q, Command::Drive(duty)),
                    (q, None) => {
                        self.faults.count_undecided();
                        (q, Command::Coast)
                    }
                },
            }
        };
        self.finish(obs, q, command, flags)
    }

    /// The end of every period, whoever decided `command`: tell the predictor, drive the
    /// bridge (an error counted and flagged), tell the sensor, record.
    #[inline(always)]
    fn finish(
        &mut self,
        obs: S::Reading,
        q: P::Scores,
        command: Command,
        mut flags: FaultFlags,
    ) -> Command {
        if let Some(p) = &mut self.predictor {
            p.record(command.level());
        }
        if self.actuator.drive(command).is_err() {
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

    /// Starts the loop again after its board's controller restarted (a watchdog, a reset
    /// of the control task): the predictor forgets the commands in flight. The sensor is
    /// the caller's to restart ([`Controller::sensor_mut`]); the period count, the fault
    /// counters and the telemetry go on, so that the restart stays on the record.
    pub fn restart(&mut self) {
        if let Some(p) = &mut self.predictor {
            p.clear();
        }
    }

    /// Periods run so far.
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// Fault totals so far.
    pub fn faults(&self) -> FaultCounters {
        self.faults
    }

    /// Who drives, when a monitor decides ([`Controller::with_monitor`]).
    pub fn mode(&self) -> Option<Mode> {
        self.monitor.as_ref().map(Monitor::mode)
    }

    /// Counts `ticks` timer ticks that arrived while the last step still ran. The
    /// controller does not own the timer, so the loop that waits for it reports them: a
    /// step that overran its period is counted, never hidden.
    pub fn record_overruns(&mut self, ticks: u32) {
        self.faults.overruns = self.faults.overruns.saturating_add(ticks);
    }

    /// The last `N` periods, oldest first.
    pub fn telemetry(&self) -> impl Iterator<Item = &Record<S::Reading, P::Scores>> {
        self.telemetry.oldest_ordered()
    }

    /// The most recent period, if any.
    pub fn last(&self) -> Option<&Record<S::Reading, P::Scores>> {
        self.telemetry.recent()
    }

    /// The policy.
    pub fn policy(&self) -> &P {
        &self.policy
    }

    /// The sensor.
    pub fn sensor(&self) -> &S {
        &self.sensor
    }

    /// The sensor, to hand it the next period's measurement where the caller owns it (a
    /// simulated plant).
    pub fn sensor_mut(&mut self) -> &mut S {
        &mut self.sensor
    }

    /// The actuator, to read back what it drives (a simulated plant's pins).
    pub fn actuator(&self) -> &A {
        &self.actuator
    }

    /// Gives the parts back: `(policy, sensor, actuator)`.
    pub fn release(self) -> (P, S, A) {
        (self.policy, self.sensor, self.actuator)
    }
}

impl<P, S, A, const N: usize> Controller<P, S, A, N>
where
    P: Policy<S::Reading>,
    S: StateSensor,
    A: Actuator,
{
    /// One control period: read, sanitise, decide, actuate, record, tell the sensor.
    #[inline]
    pub fn step(&mut self) -> Command {
        let sensed = self.sense();
        self.act(sensed)
    }

    /// The second half of a period on what [`Controller::sense`] found: decide (the policy,
    /// or the monitor's choice), actuate, record, tell the sensor.
    #[inline(always)]
    pub fn act(&mut self, sensed: Sensed<S::Reading>) -> Command {
        self.act_by(sensed, |policy, seen| answer(policy, seen))
    }
}

#[cfg(test)]
mod tests;
