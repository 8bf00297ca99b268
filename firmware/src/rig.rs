//! The machine a controller runs on, as one description: the plant's physics, the encoders,
//! the dead time, the track's end stops and the observer's tuning. A board gives it once and
//! takes from it everything that must agree with the machine: the observer
//! ([`Rig::observer`]), the dead-time predictor ([`Rig::predictor`]) and the limits
//! ([`Rig::limits`]). A policy file exported for a rig carries its `RIG` beside the weights,
//! so a board runs the model of the machine its policy was trained for.
//!
//! ```
//! use firmware::controller::Controller;
//! use firmware::rig::Rig;
//! let rig = Rig::GYMNASIUM;
//! assert_eq!(rig.params.tau, 0.02);
//! assert_eq!(rig.limits().max_abs[0], 2.4);
//! assert_eq!(rig.predictor().delay(), 0);
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
//! use firmware::controller::Controller;
//! use firmware::estimator::ObserverSensor;
//! use firmware::loopback::{duty, pins};
//! use firmware::policy_int::{POLICY_INT, RIG};
//!
//! let mut plant = CartPole::new(RIG.params, 500);
//! plant.reset_to(State::from_array([0.02, 0.0, 0.03, 0.0]));
//! let counts = |s: State| RIG.encoders.counts(s.x, s.theta);
//! let latest = Cell::new(counts(plant.state()));
//! let sensor = ObserverSensor::<_, [i16; 4]>::new(RIG.observer(), || latest.get());
//! let mut controller =
//!     Controller::new(&POLICY_INT, sensor, pins(), RIG.limits()).with_predictor(RIG.predictor());
//! // One pass per control period: on a board, `RIG.params.tau` apart on a timer.
//! for period in 0..500 {
//!     controller.step();
//!     let t = plant.advance(duty(controller.actuator()), 0.0);
//!     latest.set(counts(plant.state()));
//!     assert!(!t.terminated, "the pole fell in period {period}");
//! }
//! assert!(plant.state().theta.abs() < 0.05);
//! assert_eq!(controller.faults().rejected_readings, 0);
//! ```

use crate::cartpole::{GYMNASIUM, Params};
use crate::controller::{Limits, Predictor};
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

    /// The encoder observer for this machine: its plant, its encoders, its dead time, its
    /// tuning. Solves the observer's gain (a Riccati iteration in f64): call it once, at
    /// start-up.
    pub fn observer(&self) -> Observer {
        Observer::new(
            self.encoders,
            &self.params,
            self.tuning,
            self.dead_time as usize,
        )
    }

    /// The dead-time predictor for this machine.
    pub fn predictor(&self) -> Predictor {
        Predictor::new(&self.params, self.dead_time as usize)
    }

    /// The readings a controller accepts on this machine: the track's end stops less the
    /// margin ([`Limits::track`]).
    pub fn limits(&self) -> Limits {
        Limits::track(self.params.x_threshold as f32, self.end_stop_margin as f32)
    }
}
