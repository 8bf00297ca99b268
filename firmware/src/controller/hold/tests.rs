//! Held periods against the plain ones: what is read, counted and recorded.

use super::super::tests::{Script, SignOfTheta};
use super::super::{Controller, FaultCounters, Limits, Mode};
use crate::controller::{Command, Duty};
use crate::loopback::{Pins, duty, pins};
use crate::rig::Rig;

const HANGING: Result<[f32; 4], ()> = Ok([0.0, 0.0, 3.1, 0.0]);
const LEANING: Result<[f32; 4], ()> = Ok([0.0, 0.0, 0.05, 0.0]);

fn monitored(readings: &[Result<[f32; 4], ()>]) -> Controller<SignOfTheta, Script<'_>, Pins, 8> {
    let envelope = Limits::new([1.0, 1.0, 0.1, 1.0]).unwrap();
    let assurance = Rig::GYMNASIUM.assurance(envelope, [1.0, 1.0, 10.0, 1.0]);
    let limits = Rig::GYMNASIUM.limits().unwrap();
    let sensor = Script { readings, next: 0 };
    Controller::with_history(SignOfTheta, sensor, pins(), limits).with_monitor(assurance.unwrap())
}

#[test]
fn a_held_period_drives_its_command_and_counts_no_fault_of_a_hanging_pole() {
    let readings = [HANGING, HANGING, Err(())];
    let mut c = monitored(&readings);
    let half = Command::Drive(Duty::from_thousandths(-400).unwrap());
    assert_eq!(c.hold(half), half);
    assert_eq!(duty(c.actuator()), -0.4);
    assert_eq!(c.hold(Command::Coast), Command::Coast);
    assert_eq!(c.faults(), FaultCounters::default());
    assert_eq!(c.mode(), Some(Mode::Policy));
    // A sensor that fails is a sensor error, held or not.
    c.hold(Command::Coast);
    assert_eq!(c.faults().sensor_errors, 1);
    let mut recorded = c.telemetry().map(|r| (r.obs[2], r.command));
    for expected in [(3.1, half), (3.1, Command::Coast), (0.0, Command::Coast)] {
        assert_eq!(recorded.next(), Some(expected));
    }
    assert_eq!(recorded.next(), None);
}

#[test]
fn rearming_lifts_a_latched_stop_and_the_policy_drives_again() {
    let readings = [HANGING, HANGING, HANGING, LEANING, LEANING];
    let mut c = monitored(&readings);
    // Three readings past the failure angle in a row stop the controller: it coasts.
    for _ in 0..3 {
        c.step();
    }
    assert_eq!(c.mode(), Some(Mode::Stopped));
    assert_eq!(c.step(), Command::Coast);
    c.rearm();
    assert_eq!(c.mode(), Some(Mode::Policy));
    assert_eq!(c.step(), Command::Drive(Duty::RIGHT));
    assert_eq!(c.faults().safe_stops, 1);
}
