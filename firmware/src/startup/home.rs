//! Homing: the cart driven gently against the track's -x end stop until it stalls there,
//! which puts the centre the track's half-length away, then driven to the centre. A rig
//! that homes needs nobody to centre its cart by hand before power-on.

use crate::cartpole::Params;
use crate::config::{ConfigError, check, positive};
use crate::controller::{Command, Duty};

/// How the cart finds the centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homing {
    /// The most duty it drives with, a fraction of full: enough to move the cart against its
    /// friction, little enough that stalling against the stop is gentle.
    pub duty: f32,
    /// Periods the driven cart must stay within a count for the stop to be taken as found,
    /// and near the centre (a hundredth of the half-length) for the cart to be taken as
    /// arrived.
    pub stall_periods: u16,
}

impl Homing {
    /// Homing for a rig of period `tau` s: 30% duty, stalled for a quarter of a second.
    pub fn suggested(tau: f64) -> Homing {
        Homing {
            duty: 0.3,
            stall_periods: super::periods(0.25, tau),
        }
    }

    /// `self`, if its duty is in (0, 1] and it watches at least two periods.
    pub const fn check(self) -> Result<Homing, ConfigError> {
        check!(positive(self.duty as f64, "startup.homing.duty"));
        if self.duty > 1.0 {
            return Err(ConfigError::AboveLimit("startup.homing.duty", "at most 1"));
        }
        if self.stall_periods < 2 {
            return Err(ConfigError::TooFew("startup.homing.stall_periods"));
        }
        Ok(self)
    }
}

/// What a period of homing does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Homed {
    /// Still homing: drive this.
    Drive(Command),
    /// Arrived: the raw cart count of the centre.
    Centre(i32),
}

/// A [`Homing`] under way on its rig.
#[derive(Clone, Copy, Debug)]
pub(super) struct Home {
    homing: Homing,
    /// Cart counts from the -x stop to the centre, and within which of it (a hundredth of
    /// that) the cart has arrived: wide enough for a hanging pole's swing, which rocks a light
    /// cart however it is held. Where it then rests matters little: its zero is the centre
    /// found, and the swing-up pulls it there.
    stop: i32,
    near: u32,
    /// The pull to the centre, a fraction of full duty per count from it and per count a
    /// period: a spring of 2 rad/s, critically damped, through the motor's model.
    gains: [f32; 2],
    /// The centre, once the stop is found.
    centre: Option<i32>,
    /// Whether the cart has arrived at the centre.
    arrived: bool,
    /// Whether a count has been read: until then `anchor` and `last` are not.
    started: bool,
    /// The count the cart has stayed within a count of, and for how many periods.
    anchor: i32,
    still: u16,
    /// The last period's count.
    last: i32,
}

impl Home {
    pub(super) fn new(homing: Homing, p: &Params, per_m: f64) -> Home {
        // duty = (m a + damping x_dot) / F with a = -4 x - 4 x_dot, in counts and periods.
        let (m, f) = (p.total_mass(), p.force_mag);
        let gains = [
            4.0 * m / (f * per_m),
            (4.0 * m - p.motor_damping) / (f * per_m * p.tau),
        ];
        Home {
            homing,
            stop: libm::round(p.x_threshold * per_m) as i32,
            near: libm::round(0.01 * p.x_threshold * per_m).max(1.0) as u32,
            gains: gains.map(|g| g as f32),
            centre: None,
            arrived: false,
            started: false,
            anchor: 0,
            still: 0,
            last: 0,
        }
    }

    /// The centre's raw cart count, once the cart has arrived there.
    pub(super) fn arrived(&self) -> Option<i32> {
        self.centre.filter(|_| self.arrived)
    }

    /// One period on the raw cart count `cart`.
    pub(super) fn period(&mut self, cart: i32) -> Homed {
        if !self.started {
            (self.started, self.anchor, self.last) = (true, cart, cart);
        }
        let last = core::mem::replace(&mut self.last, cart);
        let Some(centre) = self.centre else {
            // At the stop: driven, and within a count of one place.
            if cart.wrapping_sub(self.anchor).unsigned_abs() > 1 {
                (self.anchor, self.still) = (cart, 0);
            } else {
                self.still = self.still.saturating_add(1);
            }
            if self.still >= self.homing.stall_periods {
                self.centre = Some(cart.wrapping_add(self.stop));
                self.still = 0;
            }
            return self.drive(-1.0);
        };
        // Arrived: within `near` of the centre for as long.
        let x = cart.wrapping_sub(centre);
        if x.unsigned_abs() <= self.near {
            self.still = self.still.saturating_add(1);
        } else {
            self.still = 0;
        }
        if self.still >= self.homing.stall_periods {
            self.arrived = true;
            return Homed::Centre(centre);
        }
        let dx = cart.wrapping_sub(last);
        self.drive(-self.gains[0] * x as f32 - self.gains[1] * dx as f32)
    }

    /// Drives `fraction` of full duty, within the homing duty either way.
    fn drive(&self, fraction: f32) -> Homed {
        let d = self.homing.duty;
        match Duty::from_fraction(fraction.clamp(-d, d)) {
            Ok(duty) => Homed::Drive(Command::Drive(duty)),
            Err(_) => Homed::Drive(Command::Coast),
        }
    }
}
