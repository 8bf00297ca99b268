//! The energy-based swing-up (K. J. Astrom and K. Furuta, "Swinging up a pendulum by
//! energy control", Automatica 36(2), 2000), kept on the track.
//!
//! The pole's energy about upright, in units of `m g l` (the pole's mass, gravity, the
//! distance to its centre of mass), is `E = (2 l / 3 g) theta_dot^2 + cos theta - 1` for
//! Gymnasium's uniform pole: `0` upright at rest, `-2` hanging at rest. The pivot's
//! acceleration `a` changes it at the rate `-(l / g) a theta_dot cos theta`, so
//! `a = k g E sign(theta_dot cos theta)`, saturated, pumps energy in while it is short and out
//! once it overshoots, and the pole rises to upright along the orbit of zero energy, slowing
//! as it arrives: where a catch can take it. (At rest the sign is taken as `+`, so a pole
//! hanging still is pushed off.) Two terms keep it on the track: a spring and damper to the
//! centre, and full braking once the cart, decelerating at `max_accel`, would no longer stop
//! short of the track's accepted end. The acceleration becomes a duty through the rig's
//! motor model, the pole's reaction on the cart neglected.

use crate::cartpole::Params;
use crate::config::{ConfigError, check, non_negative, positive};
use crate::controller::{Command, Duty};

/// The least rate, rad/s, the law takes the pole's to be (with its sign, `+` at rest): a pole
/// hanging still is pushed off rather than left there.
const STIR: f32 = 1.0;

/// The swing-up's gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Swing {
    /// `k`: the pivot's acceleration per unit of energy short, in units of `g`.
    pub energy_gain: f32,
    /// The most acceleration the swing asks of the cart, m/s^2.
    pub max_accel: f32,
    /// The pull to the centre: acceleration per metre from it (1/s^2) and per m/s (1/s).
    pub centring: [f32; 2],
    /// The energy aimed at, above upright's, in units of `m g l`: a little over zero, so
    /// that the pole arrives at the top still moving rather than slowing to a stop on the way.
    pub overshoot: f32,
}

impl Swing {
    /// `self`, if its gains are finite, the energy gain and the acceleration above zero and
    /// the centring zero or more.
    pub const fn check(self) -> Result<Swing, ConfigError> {
        check!(positive(
            self.energy_gain as f64,
            "startup.swing.energy_gain"
        ));
        check!(positive(self.max_accel as f64, "startup.swing.max_accel"));
        check!(non_negative(
            self.centring[0] as f64,
            "startup.swing.centring[0]"
        ));
        check!(non_negative(
            self.centring[1] as f64,
            "startup.swing.centring[1]"
        ));
        check!(non_negative(
            self.overshoot as f64,
            "startup.swing.overshoot"
        ));
        Ok(self)
    }
}

/// A [`Swing`] on its rig: the constants its law needs, in f32.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pump {
    swing: Swing,
    /// `2 l / 3 g`, s^2.
    kinetic: f32,
    gravity: f32,
    mass: f32,
    force: f32,
    damping: f32,
    /// The track's accepted half-length, m.
    track: f32,
    /// Half the control period, s.
    half_tau: f32,
}

impl Pump {
    pub(super) fn new(swing: Swing, p: &Params, track: f32) -> Pump {
        Pump {
            swing,
            kinetic: (2.0 * p.length / (3.0 * p.gravity)) as f32,
            gravity: p.gravity as f32,
            mass: p.total_mass() as f32,
            force: p.force_mag as f32,
            damping: p.motor_damping as f32,
            track,
            half_tau: (p.tau / 2.0) as f32,
        }
    }

    /// The pole's energy about upright in units of `m g l`.
    pub(super) fn energy(&self, theta: f32, theta_dot: f32) -> f32 {
        self.kinetic * theta_dot * theta_dot + libm::cosf(theta) - 1.0
    }

    /// The command for state `s` (`[x, x_dot, theta, theta_dot]`); the motor coasts on a
    /// state that is not finite.
    pub(super) fn command(&self, s: &[f32; 4]) -> Command {
        let [x, x_dot, theta, theta_dot] = *s;
        let Swing {
            energy_gain,
            max_accel,
            centring,
            overshoot,
        } = self.swing;
        // The rate is the last period's mean: the angle halfway through it goes with it.
        let energy = self.energy(theta - theta_dot * self.half_tau, theta_dot) - overshoot;
        let stir = if theta_dot >= 0.0 {
            theta_dot.max(STIR)
        } else {
            theta_dot.min(-STIR)
        };
        let pump = energy_gain * self.gravity * energy * stir * libm::cosf(theta);
        let mut accel = pump.clamp(-max_accel, max_accel) - centring[0] * x - centring[1] * x_dot;
        let stop = x + x_dot * libm::fabsf(x_dot) / (2.0 * max_accel);
        if libm::fabsf(stop) >= self.track && x_dot * stop > 0.0 {
            accel = -stop.signum() * self.force / self.mass;
        }
        let fraction = (self.mass * accel + self.damping * x_dot) / self.force;
        match Duty::from_fraction(fraction.clamp(-1.0, 1.0)) {
            Ok(duty) => Command::Drive(duty),
            Err(_) => Command::Coast,
        }
    }
}
