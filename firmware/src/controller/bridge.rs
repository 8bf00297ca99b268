//! The motor's side of the period: an [`Actuator`] takes each [`Command`]; a [`Bridge`] is
//! one over an H-bridge's embedded-hal pins.

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

use super::Command;
use crate::cartpole::Action;

/// A pin or duty-cycle write failed; the actuator's state is then unknown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ActuatorError;

/// What drives the motor: each period's command goes here.
pub trait Actuator {
    /// Brings the motor to `command`.
    fn drive(&mut self, command: Command) -> Result<(), ActuatorError>;
}

/// What the bridge is known to be doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Drive {
    Unknown,
    Off,
    Pushing(Action),
}

/// An H-bridge: a direction pin (high pushes towards +x) and an enable whose full duty is
/// the motor's full push.
///
/// Changing direction is break-before-make: duty off, then the direction pin, then full
/// duty, so the bridge never drives the old way with the new direction's half-bridge.
/// Repeating the current command writes nothing. After a failed write the bridge's state is
/// unknown, so the next command sends its whole sequence.
pub struct Bridge<D, E> {
    direction: D,
    enable: E,
    drive: Drive,
}

impl<D: OutputPin, E: SetDutyCycle> Bridge<D, E> {
    /// A bridge not yet driven: its first command sends the whole pin sequence.
    pub fn new(direction: D, enable: E) -> Self {
        Bridge {
            direction,
            enable,
            drive: Drive::Unknown,
        }
    }

    /// The pins, as they are now: `(direction, enable)`.
    pub fn pins(&self) -> (&D, &E) {
        (&self.direction, &self.enable)
    }

    /// The pins back: `(direction, enable)`.
    pub fn release(self) -> (D, E) {
        (self.direction, self.enable)
    }

    fn off(&mut self) -> Result<(), ActuatorError> {
        self.enable
            .set_duty_cycle_fully_off()
            .map_err(|_| ActuatorError)?;
        self.drive = Drive::Off;
        Ok(())
    }

    fn sequence(&mut self, command: Command) -> Result<(), ActuatorError> {
        match command {
            Command::Coast if self.drive != Drive::Off => self.off(),
            Command::Push(action) if self.drive != Drive::Pushing(action) => {
                if self.drive != Drive::Off {
                    self.off()?;
                }
                match action {
                    Action::Right => self.direction.set_high(),
                    Action::Left => self.direction.set_low(),
                }
                .map_err(|_| ActuatorError)?;
                self.enable
                    .set_duty_cycle_fully_on()
                    .map_err(|_| ActuatorError)?;
                self.drive = Drive::Pushing(action);
                Ok(())
            }
            _ => Ok(()),
        }
    }
}

impl<D: OutputPin, E: SetDutyCycle> Actuator for Bridge<D, E> {
    fn drive(&mut self, command: Command) -> Result<(), ActuatorError> {
        let done = self.sequence(command);
        if done.is_err() {
            self.drive = Drive::Unknown;
        }
        done
    }
}
