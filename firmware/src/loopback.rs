//! A plant in place of the hardware: a sensor and two actuator outputs that read and write
//! shared cells, so the [`Controller`] can close the loop
//! against [`cartpole`](crate::cartpole) on the microcontroller (the self-test) and in
//! `host-sim` (the digital twin) with exactly the code that drives real pins.
//!
//! This module is the wiring only, with the exact state or with encoders and the observer
//! as sensors. Scenarios (noise, dead time, pushes) belong to the `twin` crate.

use core::cell::Cell;
use core::convert::Infallible;

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

use crate::cartpole::{CartPole, Params, State};
use crate::controller::{Command, Controller, Limits, Policy, StateSensor};
use crate::estimator::{Encoders, Observer, Tuning};

/// Full scale of [`CellDuty`].
pub const MAX_DUTY: u16 = 1000;

/// Reads the plant's true state, rounded to f32 like its observation.
pub struct PlantSensor<'a>(pub &'a Cell<State>);

impl StateSensor for PlantSensor<'_> {
    type Error = Infallible;
    #[inline]
    fn read(&mut self) -> Result<[f32; 4], Infallible> {
        Ok(self.0.get().observation())
    }
}

/// Reads the plant the way a board reads its own: two encoders (the true cart position and
/// pole angle floored to counts) through the [`Observer`], told each command the controller
/// sends.
pub struct EncoderSensor<'a> {
    state: &'a Cell<State>,
    observer: Observer,
}

impl<'a> EncoderSensor<'a> {
    /// Encoders of resolution `enc` on the plant whose state `state` holds; the observer
    /// models the plant as `nominal`.
    pub fn new(state: &'a Cell<State>, enc: Encoders, nominal: &Params) -> Self {
        EncoderSensor {
            state,
            observer: Observer::new(enc, nominal, Tuning::DEFAULT, 0),
        }
    }
}

impl StateSensor for EncoderSensor<'_> {
    type Error = Infallible;
    #[inline]
    fn read(&mut self) -> Result<[f32; 4], Infallible> {
        let s = self.state.get();
        let (cart, pole) = self.observer.encoders().counts(s.x, s.theta);
        Ok(self.observer.update(cart, pole))
    }

    #[inline]
    fn commanded(&mut self, command: Command) {
        self.observer.command(command.level());
    }
}

/// A direction pin whose level is a cell: high pushes towards +x.
pub struct CellPin<'a>(pub &'a Cell<bool>);

impl PinErrorType for CellPin<'_> {
    type Error = Infallible;
}

impl OutputPin for CellPin<'_> {
    #[inline]
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.0.set(false);
        Ok(())
    }
    #[inline]
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.0.set(true);
        Ok(())
    }
}

/// An enable whose duty cycle is a cell, out of [`MAX_DUTY`].
pub struct CellDuty<'a>(pub &'a Cell<u16>);

impl PwmErrorType for CellDuty<'_> {
    type Error = Infallible;
}

impl SetDutyCycle for CellDuty<'_> {
    #[inline]
    fn max_duty_cycle(&self) -> u16 {
        MAX_DUTY
    }
    #[inline]
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.0.set(duty.min(MAX_DUTY));
        Ok(())
    }
}

/// The force the bridge applies for a direction level and duty cycle, in newtons.
#[inline]
pub fn force(direction: bool, duty: u16, force_mag: f64) -> f64 {
    let sign = if direction { 1.0 } else { -1.0 };
    match duty {
        0 => 0.0,
        MAX_DUTY => sign * force_mag,
        d => sign * force_mag * f64::from(d) / f64::from(MAX_DUTY),
    }
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
/// terminates or truncates, reading the exact state. `wait` runs before every period: a
/// real-time loop sleeps there until its timer fires and returns how many ticks arrived
/// while the previous step still ran (its overruns); a simulation passes `|| 0`.
pub fn run<P: Policy>(policy: P, plant: &mut CartPole, wait: impl FnMut() -> u32) -> Outcome {
    let state = Cell::new(plant.state());
    let pins = (Cell::new(false), Cell::new(0));
    run_with(policy, plant, PlantSensor(&state), &state, &pins, wait)
}

/// [`run`], reading the plant through encoders of resolution `enc` and the observer, which
/// models the plant by its own parameters.
pub fn run_with_encoders<P: Policy>(
    policy: P,
    plant: &mut CartPole,
    enc: Encoders,
    wait: impl FnMut() -> u32,
) -> Outcome {
    let state = Cell::new(plant.state());
    let pins = (Cell::new(false), Cell::new(0));
    let sensor = EncoderSensor::new(&state, enc, &plant.params);
    run_with(policy, plant, sensor, &state, &pins, wait)
}

fn run_with<P: Policy, S: StateSensor>(
    policy: P,
    plant: &mut CartPole,
    sensor: S,
    state: &Cell<State>,
    (direction, duty): &(Cell<bool>, Cell<u16>),
    mut wait: impl FnMut() -> u32,
) -> Outcome {
    let mut c: Controller<_, _, _, _, 1> = Controller::new(
        policy,
        sensor,
        CellPin(direction),
        CellDuty(duty),
        Limits::default(),
    );
    loop {
        let late = wait();
        c.record_overruns(late);
        c.step();
        let t = plant.step_force(force(direction.get(), duty.get(), plant.params.force_mag));
        state.set(plant.state());
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
    use crate::policy::POLICY;

    #[test]
    fn loopback_episode_equals_the_plant_under_greedy_actions() {
        let start = State::from_array([0.03, -0.02, 0.04, 0.01]);
        let mut plant = CartPole::new(Params::default(), 300);
        plant.reset_to(start);
        let out = run(&POLICY, &mut plant, || 0);
        let mut reference = CartPole::new(Params::default(), 300);
        let mut obs = reference.reset_to(start);
        loop {
            let t = reference.step(POLICY.greedy_action(&obs));
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
        let enc = Encoders {
            cart_counts_per_m: 20_480,
            pole_counts_per_rev: 4_096,
        };
        let mut plant = CartPole::new(Params::default(), 500);
        plant.reset_to(State::from_array([0.03, -0.02, 0.04, 0.01]));
        let out = run_with_encoders(&POLICY, &mut plant, enc, || 0);
        assert!(out.success && out.faults == 0, "{out:?}");
    }

    #[test]
    fn force_follows_the_pins() {
        assert_eq!(force(true, MAX_DUTY, 10.0), 10.0);
        assert_eq!(force(false, MAX_DUTY, 10.0), -10.0);
        assert_eq!(force(true, 0, 10.0), 0.0);
        assert_eq!(force(false, 500, 10.0), -5.0);
    }

    #[test]
    fn the_overruns_wait_reports_are_counted() {
        let mut plant = CartPole::new(Params::default(), 40);
        plant.reset_to(State::from_array([0.0, 0.0, 0.01, 0.0]));
        // The first period starts on time; from then on every second step overran by two
        // ticks, as a loop whose steps take about two periods would report.
        let mut calls = 0u32;
        let out = run(&POLICY, &mut plant, || {
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
