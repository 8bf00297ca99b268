//! The machine a controller runs on, as one description: the plant's physics, the encoders,
//! the dead time, the track's end stops and the observer's tuning. A board gives it once and
//! takes from it everything that must agree with the machine: the observer
//! ([`Rig::observer`]), the dead-time predictor ([`Rig::predictor`]), the limits
//! ([`Rig::limits`]), the runtime monitor's assurance ([`Rig::assurance`]), and the
//! controller built from them ([`Rig::controller`]). A policy file exported for a rig carries
//! its `RIG` beside the weights,
//! so a board runs the model of the machine its policy was trained for.
//!
//! ```
//! use firmware::rig::Rig;
//! let rig = Rig::GYMNASIUM;
//! assert_eq!(rig.params.tau, 0.02);
//! assert_eq!(rig.limits()?.max_abs()[0], 2.4);
//! assert_eq!(rig.predictor()?.delay(), 0);
//! # Ok::<(), firmware::ConfigError>(())
//! ```
//!
//! A board's whole loop, closed here against the plant in place of the hardware
//! ([`crate::loopback`]'s pins): encoder counts read through a closure (a board loads them
//! from its timers or PIO counters there) into the observer, the integer policy, the
//! predictor and the limits, everything that must agree with the machine taken from the
//! `RIG` exported beside the policy.
//!
//! ```
//! use core::cell::Cell;
//! use firmware::cartpole::{CartPole, State};
//! use firmware::estimator::ObserverSensor;
//! use firmware::loopback::{duty, pins};
//! use shipped::policy_int::{POLICY_INT, RIG};
//! use firmware::rig::Options;
//!
//! let mut plant = CartPole::new(RIG.params, 500);
//! plant.reset_to(State::from_array([0.02, 0.0, 0.03, 0.0]));
//! let counts = |s: State| RIG.encoders.counts(s.x, s.theta);
//! let latest = Cell::new(counts(plant.state()));
//! let sensor = ObserverSensor::<_, [i16; 4]>::new(RIG.observer()?, || latest.get());
//! let options = Options { predict: true, monitor: None };
//! let mut controller = RIG.controller(&POLICY_INT, sensor, pins(), options)?;
//! // One pass per control period: on a board, `RIG.params.tau` apart on a timer.
//! for period in 0..500 {
//!     controller.step();
//!     let t = plant.advance(duty(controller.actuator()), 0.0);
//!     latest.set(counts(plant.state()));
//!     assert!(!t.terminated, "the pole fell in period {period}");
//! }
//! assert!(plant.state().theta.abs() < 0.05);
//! assert_eq!(controller.faults().rejected_readings, 0);
//! # Ok::<(), firmware::ConfigError>(())
//! ```

use crate::cartpole::{GYMNASIUM, Params};
use crate::config::{ConfigError, check};
use crate::controller::predict::dead_time;
use crate::controller::{Actuator, Assurance, Controller, Limits, Policy, Predictor, StateSensor};
use crate::estimator::{Encoders, Observer, Tuning};

/// A cart-pole machine as its board sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rig {
    /// The physics: masses, lengths, the motor, friction, the control period (`tau`), and
    /// where the cart and pole fail (`x_threshold` is the end stops' distance from the
    /// centre).
    pub params: Params,
    /// The two encoders' resolutions.
    pub encoders: Encoders,
    /// Periods between the reading a command is decided on and the period the motor
    /// applies it.
    pub dead_time: u32,
    /// How near an end stop the controller stops pushing and coasts, m.
    pub end_stop_margin: f64,
    /// The observer's process noise.
    pub tuning: Tuning,
}

impl Rig {
    /// Gymnasium's machine, read with 4,096-count encoders on the pivot and 20,480 counts per
    /// metre on the cart (the same encoder on a 20 cm drive pulley), no dead time, no margin.
    pub const GYMNASIUM: Rig = Rig {
        params: GYMNASIUM,
        encoders: Encoders {
            cart_counts_per_m: 20_480,
            pole_counts_per_rev: 4_096,
        },
        dead_time: 0,
        end_stop_margin: 0.0,
        tuning: Tuning::DEFAULT,
    };

    /// `self`, if every part of it is one a machine can have: the physics
    /// ([`Params::check`]), the encoders ([`Encoders::check`]), the tuning
    /// ([`Tuning::check`]), a dead time the predictor's line holds, and a margin that leaves
    /// some track ([`Limits::track`]). A `const fn`, so that a board's `RIG` can be checked
    /// as it is compiled: `const _: () = assert!(RIG.check().is_ok());`.
    pub const fn check(self) -> Result<Rig, ConfigError> {
        check!(self.params.check());
        check!(self.encoders.check());
        check!(self.tuning.check());
        check!(dead_time(self.dead_time as usize));
        check!(self.limits());
        Ok(self)
    }

    /// The encoder observer for this machine: its plant, its encoders, its dead time, its
    /// tuning. Solves the observer's gain (a Riccati iteration in f64): call it once, at
    /// start-up. Refused as [`Observer::new`] refuses.
    pub fn observer(&self) -> Result<Observer, ConfigError> {
        Observer::new(
            self.encoders,
            &self.params,
            self.tuning,
            self.dead_time as usize,
        )
    }

    /// The dead-time predictor for this machine; refused as [`Predictor::new`] refuses.
    pub fn predictor(&self) -> Result<Predictor, ConfigError> {
        Predictor::new(&self.params, self.dead_time as usize)
    }

    /// The readings a controller accepts on this machine: the track's end stops less the
    /// margin ([`Limits::track`], which refuses a margin that leaves no track).
    pub const fn limits(&self) -> Result<Limits, ConfigError> {
        Limits::track(self.params.x_threshold as f32, self.end_stop_margin as f32)
    }

    /// Where the runtime monitor's fallback can still recover on this machine: the
    /// accepted track ([`Rig::limits`]) and the pole short of its failure angle.
    pub const fn recoverable(&self) -> Result<Limits, ConfigError> {
        let track = check!(self.limits()).max_abs();
        Limits::new([
            track[0],
            track[1],
            self.params.theta_threshold_radians as f32,
            track[3],
        ])
    }

    /// The runtime monitor's assurance on this machine for a policy whose `envelope` was
    /// measured, with the fallback's LQR `gain` ([`Assurance::new`] with
    /// [`Rig::recoverable`]). A `const fn`, so that a board's is checked as it is compiled.
    pub const fn assurance(
        &self,
        envelope: Limits,
        gain: [f32; 4],
    ) -> Result<Assurance, ConfigError> {
        let full_force = self.params.force_mag as f32;
        Assurance::new(envelope, check!(self.recoverable()), gain, full_force)
    }

    /// [`Rig::assurance`] with the fallback designed for this machine's plant here
    /// ([`crate::linear::balance_gain`], a Riccati iteration in f64: once, at start-up).
    pub fn lqr_assurance(&self, envelope: Limits) -> Result<Assurance, ConfigError> {
        let k = crate::linear::balance_gain(&self.params);
        self.assurance(envelope, k.map(|v| v as f32))
    }
}

/// What a controller runs beside its policy, beyond the rig's limits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Options {
    /// Decide on the state the command will meet after the rig's dead time
    /// ([`crate::controller::predict`]); nothing to predict on a rig without one.
    pub predict: bool,
    /// Run under the runtime monitor ([`crate::controller::monitor`]) with this assurance.
    pub monitor: Option<Assurance>,
}

impl Rig {
    /// The controller a board runs on this machine: `policy` on `sensor` driving
    /// `actuator`, accepting the rig's limits, with the rig's predictor and a monitor as
    /// `options` ask. The one recipe every caller builds its controller by: the twin, the
    /// link's target, the C API and the boards. Refused as the rig's limits or predictor
    /// are refused.
    pub fn controller<P, S, A>(
        &self,
        policy: P,
        sensor: S,
        actuator: A,
        options: Options,
    ) -> Result<Controller<P, S, A>, ConfigError>
    where
        P: Policy<S::Reading>,
        S: StateSensor,
        A: Actuator,
    {
        let mut c = Controller::new(policy, sensor, actuator, self.limits()?);
        if options.predict && self.dead_time > 0 {
            c = c.with_predictor(self.predictor()?);
        }
        if let Some(a) = options.monitor {
            c = c.with_monitor(a);
        }
        Ok(c)
    }
}

const _: () = assert!(Rig::GYMNASIUM.check().is_ok());

#[cfg(test)]
mod tests {
    use super::*;

    /// A change that spoils a rig, and the refusal it meets.
    type Spoiled = (fn(&mut Rig), ConfigError);

    #[test]
    fn each_part_of_a_rig_is_checked_and_named() {
        let good = Rig::GYMNASIUM;
        let cases: [Spoiled; 7] = [
            (
                |r| r.params.length = 0.0,
                ConfigError::NotPositive("params.length"),
            ),
            (
                |r| r.params.gravity = f64::NAN,
                ConfigError::NotFinite("params.gravity"),
            ),
            (
                |r| r.params.pole_friction = -1e-9,
                ConfigError::Negative("params.pole_friction"),
            ),
            (
                |r| r.encoders.pole_counts_per_rev = 0,
                ConfigError::NotPositive("encoders.pole_counts_per_rev"),
            ),
            (
                |r| r.tuning.accel_sd[1] = f64::NAN,
                ConfigError::NotFinite("tuning.accel_sd[1]"),
            ),
            (|r| r.dead_time = 17, ConfigError::TooLarge("dead_time")),
            (|r| r.end_stop_margin = 2.4, ConfigError::NoTrack),
        ];
        for (spoil, why) in cases {
            let mut r = good;
            spoil(&mut r);
            assert_eq!(r.check(), Err(why), "{r:?}");
        }
        assert_eq!(good.check(), Ok(good));
    }

    /// The reported failure: a zero length or a NaN tuning gave an observer whose gains
    /// were NaN, and which said nothing.
    #[test]
    fn an_observer_with_nan_gains_is_never_built() {
        let mut short = Rig::GYMNASIUM;
        short.params.length = 0.0;
        assert_eq!(
            short.observer().err(),
            Some(ConfigError::NotPositive("params.length"))
        );
        let mut vague = Rig::GYMNASIUM;
        vague.tuning.force_sd = f64::NAN;
        assert_eq!(
            vague.observer().err(),
            Some(ConfigError::NotFinite("tuning.force_sd"))
        );
        // Every field finite and positive, and still the iteration overflows f64.
        let mut wild = Rig::GYMNASIUM;
        wild.tuning.force_sd = 1e200;
        assert_eq!(wild.observer().err(), Some(ConfigError::GainNotFinite));
        let gain = Rig::GYMNASIUM.observer().unwrap().gain();
        assert!(gain.iter().flatten().all(|g| g.is_finite()));
    }
}
