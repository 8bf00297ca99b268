//! A plant in place of the hardware: a sensor and an H-bridge's two pins that the caller
//! reads and sets between periods, so the [`Controller`] can close the loop against
//! [`cartpole`](crate::cartpole) on the microcontroller (the self-test) and in the host's
//! twin with exactly the code that drives real pins.
//!
//! This module is the wiring only, with the exact state or with encoders and the observer
//! as sensors. Scenarios (noise, dead time, pushes) belong to the `twin` crate.

use core::convert::Infallible;
use core::marker::PhantomData;

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

use crate::cartpole::{CartPole, State};
use crate::config::ConfigError;
use crate::controller::{Actuator, Bridge, Command, Controller, Limits, Policy, StateSensor};
use crate::estimator::{Counter, Estimate, ObserverSensor};
use crate::rig::{Options, Rig};

/// Full scale of [`Duty`].
pub const MAX_DUTY: u16 = 1000;

/// Reads the plant's true state, rounded to f32 like its observation, in the reading format
/// `O`: the state the caller last put here.
pub struct PlantSensor<O = [f32; 4]>(pub State, PhantomData<O>);

impl<O: Estimate> StateSensor for PlantSensor<O> {
    type Reading = O;
    type Error = Infallible;
    #[inline]
    fn read(&mut self) -> Result<O, Infallible> {
        Ok(O::exact(&self.0.observation()))
    }
}

/// The counts the caller last put here, `(cart, pole)`: the [`Counter`] of a simulated
/// board's encoders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Latest(pub (i32, i32));

impl Counter for Latest {
    #[inline]
    fn counts(&mut self) -> (i32, i32) {
        self.0
    }
}

/// A direction pin: high pushes towards +x.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Level(pub bool);

impl PinErrorType for Level {
    type Error = Infallible;
}

impl OutputPin for Level {
    #[inline]
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.0 = false;
        Ok(())
    }
    #[inline]
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.0 = true;
        Ok(())
    }
}

/// An enable's duty cycle, out of [`MAX_DUTY`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Duty(pub u16);

impl PwmErrorType for Duty {
    type Error = Infallible;
}

impl SetDutyCycle for Duty {
    #[inline]
    fn max_duty_cycle(&self) -> u16 {
        MAX_DUTY
    }
    #[inline]
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.0 = duty.min(MAX_DUTY);
        Ok(())
    }
}

/// An H-bridge over a [`Level`] and a [`Duty`]: what a simulated board drives.
pub type Pins = Bridge<Level, Duty>;

/// A bridge not yet driven.
pub fn pins() -> Pins {
    Bridge::new(Level::default(), Duty::default())
}

/// The motor duty the bridge's pins set: `-1` to `1`.
#[inline]
pub fn duty(bridge: &Pins) -> f64 {
    let (Level(direction), Duty(duty)) = bridge.pins();
    let sign = if *direction { 1.0 } else { -1.0 };
    match *duty {
        0 => 0.0,
        MAX_DUTY => sign,
        d => sign * f64::from(d) / f64::from(MAX_DUTY),
    }
}

/// The motor duty a bridge driven with `command` sets ([`duty`]): what a simulated world
/// applies, whether the controller ran beside it or on a target across a link.
pub fn command_duty(command: Command) -> f64 {
    let mut bridge = pins();
    // The simulated pins cannot fail.
    let _ = bridge.drive(command);
    duty(&bridge)
}

/// How one closed-loop episode ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// Periods survived.
    pub steps: u32,
    /// Reached the plant's step limit without failing.
    pub success: bool,
    /// Periods that coasted on a rejected reading.
    pub faults: u32,
    /// Timer ticks that arrived while a step still ran, as `wait` reported them.
    pub overruns: u32,
}

/// Runs `policy` through a [`Controller`] against `plant` from its current state until it
/// terminates or truncates, reading the exact state in the format `O` its policy takes, with
/// `limits`. `wait` runs before every period: a real-time loop sleeps there until its timer
/// fires and returns how many ticks arrived while the previous step still ran (its
/// overruns); a simulation passes `|| 0`.
pub fn run<O: Estimate, P: Policy<O>>(
    policy: P,
    plant: &mut CartPole,
    limits: Limits,
    wait: impl FnMut() -> u32,
) -> Outcome {
    let sensor = PlantSensor(plant.state(), PhantomData);
    // No rig here, only its limits (a board's `static`, built as it compiles): the plant's
    // own state needs neither an observer nor a predictor.
    let c = Controller::new(policy, sensor, pins(), limits);
    run_with(c, plant, |s, state| s.0 = state, wait)
}

/// [`run`], reading the plant through `rig`'s encoders and observer (a board's pipeline, in
/// the reading format `O` its policy takes), with `rig`'s limits; refused, before the
/// first period, for a rig [`Rig::observer`] or [`Rig::limits`] refuses.
pub fn run_with_encoders<O: Estimate, P: Policy<O>>(
    policy: P,
    plant: &mut CartPole,
    rig: &Rig,
    wait: impl FnMut() -> u32,
) -> Result<Outcome, ConfigError> {
    let enc = rig.encoders;
    let counts = |s: State| enc.counts(s.x, s.theta);
    let sensor = ObserverSensor::<_, O>::new(rig.observer()?, Latest(counts(plant.state())));
    let set = |s: &mut ObserverSensor<Latest, O>, state| s.counter_mut().0 = counts(state);
    // The plant answers at once (no dead time), so there is nothing to predict.
    let c = rig.controller(policy, sensor, pins(), Options::default())?;
    Ok(run_with(c, plant, set, wait))
}

/// Runs controller `c` against `plant` as [`run`] does, `set` handing each new state to its
/// sensor.
fn run_with<P: Policy<S::Reading>, S: StateSensor>(
    mut c: Controller<P, S, Pins>,
    plant: &mut CartPole,
    set: impl Fn(&mut S, State),
    mut wait: impl FnMut() -> u32,
) -> Outcome {
    loop {
        let late = wait();
        c.record_overruns(late);
        c.step();
        let t = plant.advance(duty(c.actuator()), 0.0);
        set(c.sensor_mut(), plant.state());
        if t.terminated || t.truncated {
            return Outcome {
                steps: plant.steps(),
                success: !t.terminated,
                faults: c.faults().rejected_readings,
                overruns: c.faults().overruns,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cartpole::{Action, Params};
    use crate::shipped::policy::POLICY;

    fn limits() -> Limits {
        Rig::GYMNASIUM.limits().unwrap()
    }

    /// A level the pins set in thousandths reaches the world exactly, not as its f32.
    #[test]
    fn a_commands_duty_is_its_thousandths() {
        use crate::controller::Duty as Level;
        let drive = |t| command_duty(Command::Drive(Level::from_thousandths(t).unwrap()));
        assert_eq!(drive(-150), -0.15);
        assert_ne!(drive(-150), f64::from(-0.15f32));
        assert_eq!((drive(1000), drive(-1000), drive(0)), (1.0, -1.0, 0.0));
        assert_eq!(command_duty(Command::Coast), 0.0);
    }

    #[test]
    fn loopback_episode_equals_the_plant_under_greedy_actions() {
        let start = State::from_array([0.03, -0.02, 0.04, 0.01]);
        let mut plant = CartPole::new(Params::default(), 300);
        plant.reset_to(start);
        let out = run(&POLICY, &mut plant, limits(), || 0);
        let mut reference = CartPole::new(Params::default(), 300);
        let mut obs = reference.reset_to(start);
        loop {
            let t = reference.step(Action::from_index(POLICY.greedy(&obs)));
            obs = t.obs;
            if t.terminated || t.truncated {
                break;
            }
        }
        assert_eq!(reference.state(), plant.state());
        assert_eq!(
            out,
            Outcome {
                steps: 300,
                success: true,
                faults: 0,
                overruns: 0
            }
        );
    }

    #[test]
    fn an_encoder_read_plant_balances_through_the_observer() {
        let mut plant = CartPole::new(Params::default(), 500);
        plant.reset_to(State::from_array([0.03, -0.02, 0.04, 0.01]));
        let out =
            run_with_encoders::<[f32; 4], _>(&POLICY, &mut plant, &Rig::GYMNASIUM, || 0).unwrap();
        assert!(out.success && out.faults == 0, "{out:?}");
    }

    #[test]
    fn the_duty_follows_the_pins() {
        let at = |level, d| duty(&Bridge::new(Level(level), Duty(d)));
        assert_eq!(at(true, MAX_DUTY), 1.0);
        assert_eq!(at(false, MAX_DUTY), -1.0);
        assert_eq!(at(true, 0), 0.0);
        assert_eq!(at(false, 500), -0.5);
    }

    #[test]
    fn the_overruns_wait_reports_are_counted() {
        let mut plant = CartPole::new(Params::default(), 40);
        plant.reset_to(State::from_array([0.0, 0.0, 0.01, 0.0]));
        // The first period starts on time; from then on every second step overran by two
        // ticks, as a loop whose steps take about two periods would report.
        let mut calls = 0u32;
        let out = run(&POLICY, &mut plant, limits(), || {
            calls += 1;
            if calls > 1 && calls.is_multiple_of(2) {
                2
            } else {
                0
            }
        });
        assert_eq!((out.steps, calls), (40, 40));
        assert_eq!(out.overruns, 2 * 20);
    }
}
