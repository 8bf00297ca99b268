//! The machine a world simulates: a rig (what its board knows: physics, encoders, dead time,
//! track) and how the world advances the plant over a control period.
//!
//! Gymnasium's machine is advanced as Gymnasium advances it, one Euler step per period, so
//! every replay test keeps its bits. A real rig is a continuous-time machine: its world
//! integrates the same equations ([`firmware::cartpole::Plant::derivative`]) with classic
//! fourth-order Runge-Kutta steps of a millisecond or less, under the duty held over the
//! whole period (a zero-order hold), so that a policy is judged in a world that is not the
//! discretisation it may have been trained in.

use firmware::cartpole::{Plant, State};
use firmware::rig::Rig;

/// How a world advances the plant over one control period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integration {
    /// One Euler step of the period, Gymnasium's.
    Euler,
    /// `substeps` classic Runge-Kutta steps of `tau / substeps` each.
    Rk4 {
        /// Steps per control period.
        substeps: u32,
    },
}

impl Integration {
    /// Runge-Kutta steps of at most `max_step_s` for a period of `tau` seconds.
    pub fn rk4(tau: f64, max_step_s: f64) -> Integration {
        // A step that divides the period exactly, once rounded, must not add a step.
        let n = (tau / max_step_s * (1.0 - 1e-12)).ceil();
        Integration::Rk4 {
            substeps: if n.is_finite() && n >= 1.0 {
                n.min(10_000.0) as u32
            } else {
                1
            },
        }
    }
}

/// A machine as the twin simulates it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Machine {
    /// What the board knows and has.
    pub rig: Rig,
    /// How its world advances.
    pub integration: Integration,
}

impl Machine {
    /// Gymnasium's machine, advanced by Gymnasium's Euler steps.
    pub const GYMNASIUM: Machine = Machine {
        rig: Rig::GYMNASIUM,
        integration: Integration::Euler,
    };
}

/// The state one period on from `s` under duty `duty` held over the period and an external
/// force `external` (N) on the cart over it, by `integration`.
pub fn advance(
    plant: &Plant<f64>,
    integration: Integration,
    s: &State,
    duty: f64,
    external: f64,
) -> State {
    let x = s.to_array();
    State::from_array(match integration {
        Integration::Euler => plant.euler(&x, duty, external),
        Integration::Rk4 { substeps } => {
            let h = plant.tau() / f64::from(substeps.max(1));
            (0..substeps.max(1)).fold(x, |x, _| rk4_step(plant, &x, h, duty, external))
        }
    })
}

/// One classic Runge-Kutta step of length `h`.
#[inline(always)]
fn rk4_step(plant: &Plant<f64>, x: &[f64; 4], h: f64, duty: f64, external: f64) -> [f64; 4] {
    let f = |s: &[f64; 4]| plant.derivative(s, duty, external);
    let at = |d: &[f64; 4], k: f64| core::array::from_fn(|i| x[i] + k * d[i]);
    let k1 = f(x);
    let k2 = f(&at(&k1, h / 2.0));
    let k3 = f(&at(&k2, h / 2.0));
    let k4 = f(&at(&k3, h));
    core::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::cartpole::Params;

    #[test]
    fn euler_is_gymnasiums_step() {
        let p = Params::default();
        let s = State::from_array([0.1, -0.3, 0.05, 0.4]);
        let got = advance(&Plant::new(&p), Integration::Euler, &s, 1.0, 0.5);
        assert_eq!(got, firmware::cartpole::advance(&p, &s, 1.0, 0.5));
    }

    /// A pole hanging straight down and released from a small angle swings as a pendulum:
    /// with the cart free and no motor, `theta'' = -omega^2 (theta - pi)` with
    /// `omega^2 = g / (l (4/3 - m / M))` about hanging (the plant's equations linearised
    /// there). And the integration is of fourth order: halving the step cuts the error
    /// against a far finer integration sixteenfold.
    #[test]
    fn rk4_swings_a_hanging_pole_as_a_pendulum_at_fourth_order() {
        let p = Params {
            tau: 0.5,
            ..Params::default()
        };
        let plant = Plant::new(&p);
        let m = p.total_mass();
        let omega = (p.gravity / (p.length * (4.0 / 3.0 - p.masspole / m))).sqrt();
        let a = 1e-3;
        let s = State::from_array([0.0, 0.0, core::f64::consts::PI + a, 0.0]);
        let run = |n| advance(&plant, Integration::Rk4 { substeps: n }, &s, 0.0, 0.0).theta;
        let fine = run(4000);
        let linear = core::f64::consts::PI + a * (omega * p.tau).cos();
        assert!((fine - linear).abs() < 1e-8 * 10.0, "{fine} vs {linear}");
        let (e1, e2) = ((run(10) - fine).abs(), (run(20) - fine).abs());
        assert!((e1 / e2 - 16.0).abs() < 1.5, "{e1} {e2}");
        // The step count follows the period.
        assert_eq!(
            Integration::rk4(0.02, 0.001),
            Integration::Rk4 { substeps: 20 }
        );
        assert_eq!(
            Integration::rk4(0.0105, 0.001),
            Integration::Rk4 { substeps: 11 }
        );
    }
}
