//! The motor's side of the period: an [`Actuator`] takes each [`Command`]; a [`Bridge`] is
//! one over an H-bridge's embedded-hal pins.

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

use super::levels::{Command, Duty};

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
    Pushing(Duty),
}

/// An H-bridge: a direction pin (high pushes towards +x) and an enable whose duty cycle is
/// the command's duty (full duty the motor's full push).
///
/// Changing direction is break-before-make: duty off, then the direction pin, then the new
/// duty, so the bridge never drives the old way with the new direction's half-bridge. A new
/// duty the same way writes the duty alone; repeating the current command writes nothing.
/// After a failed write the bridge's state is unknown, so the next command sends its whole
/// sequence.
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
        let duty = match command {
            Command::Drive(d) if d != Duty::OFF => d,
            _ if self.drive == Drive::Off => return Ok(()),
            _ => return self.off(),
        };
        let (was, right) = match self.drive {
            Drive::Pushing(was) if was == duty => return Ok(()),
            Drive::Pushing(was) => (was.direction(), duty.direction()),
            Drive::Off | Drive::Unknown => (None, duty.direction()),
        };
        if was != right {
            if self.drive != Drive::Off {
                self.off()?;
            }
            match right {
                Some(true) => self.direction.set_high(),
                _ => self.direction.set_low(),
            }
            .map_err(|_| ActuatorError)?;
        }
        let on = if duty.magnitude() == Duty::FULL as u16 {
            self.enable.set_duty_cycle_fully_on()
        } else {
            self.enable
                .set_duty_cycle_fraction(duty.magnitude(), Duty::FULL as u16)
        };
        on.map_err(|_| ActuatorError)?;
        self.drive = Drive::Pushing(duty);
        Ok(())
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
