//! Periods the balance controller does not decide: a start-up's zeroing, waiting and
//! swing-up ([`crate::startup`]), and its hand-over to the policy.

use super::faults::FaultFlags;
use super::monitor::Monitor;
use super::policy::Scores;
use super::reading::Reading;
use super::{Actuator, Command, Controller, Policy, StateSensor};

impl<P, S, A, const N: usize> Controller<P, S, A, N>
where
    P: Policy<S::Reading>,
    S: StateSensor,
    A: Actuator,
{
    /// A period whose command something else decided (a start-up coasting while the pole
    /// hangs, or swinging it up): the sensor is read, so that an estimator follows the plant
    /// through it, but the reading is neither held to the limits (a hanging pole lies outside
    /// them by design) nor shown to the policy or the monitor. `command` drives, and the
    /// predictor and the sensor are told of it, as in [`Controller::step`]; a sensor or
    /// actuator error is counted as there.
    pub fn hold(&mut self, command: Command) -> Command {
        let (obs, flags) = match self.sensor.read() {
            Ok(obs) => (obs, FaultFlags::default()),
            Err(_) => {
                self.faults.count_rejected(FaultFlags::SENSOR_ERROR);
                (S::Reading::ZERO, FaultFlags::SENSOR_ERROR)
            }
        };
        self.finish(obs, P::Scores::UNSCORED, command, flags)
    }

    /// Hands the loop to the policy as a controller just built would: a monitor starts
    /// again with the policy driving, a latched stop lifted. A start-up calls it as the
    /// balance controller takes over from a catch; the commands in flight, the counters
    /// and the telemetry go on.
    pub fn rearm(&mut self) {
        if let Some(m) = &mut self.monitor {
            *m = Monitor::new(m.assurance());
        }
    }
}

#[cfg(test)]
mod tests;
