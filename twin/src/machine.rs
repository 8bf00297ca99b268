//! The machine a world simulates: a rig (what its board knows: physics, encoders, dead time,
//! track) and how the world advances the plant over a control period.
//!
//! Gymnasium's machine is advanced as Gymnasium advances it, one Euler step per period, so
//! every replay test keeps its bits. A real rig is a continuous-time machine: its world
//! integrates the same equations ([`firmware::cartpole::Plant::derivative`]) with classic
//! fourth-order Runge-Kutta steps of a millisecond or less, under the duty held over the
//! whole period (a zero-order hold), so that a policy is judged in a world that is not the
//! discretisation it may have been trained in.

use firmware::cartpole::{Plant, Real, State};
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
    /// The length of one step over a period of `tau` seconds.
    pub fn step(self, tau: f64) -> f64 {
        match self {
            Integration::Euler => tau,
            Integration::Rk4 { substeps } => tau / f64::from(substeps),
        }
    }

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
    /// How far its identified values may be off.
    pub uncertainty: Uncertainty,
}

/// `n` control periods in words: "1 period", "2 periods".
pub fn periods(n: u32) -> String {
    if n == 1 {
        "1 period".into()
    } else {
        format!("{n} periods")
    }
}

/// Refuses a board whose control period is not its world's: a board runs at its world's
/// period, and every count of periods (dead time, windows, horizons) means the world's.
pub fn same_period(world: &Rig, board: &Rig) -> Result<(), String> {
    let (w, b) = (world.params.tau, board.params.tau);
    if w == b {
        Ok(())
    } else {
        Err(format!(
            "expected the board's control period to be its world's, {w} s; found {b} s"
        ))
    }
}

impl Machine {
    /// Gymnasium's machine, advanced by Gymnasium's Euler steps.
    pub const GYMNASIUM: Machine = Machine {
        rig: Rig::GYMNASIUM,
        integration: Integration::Euler,
        uncertainty: Uncertainty::NONE,
    };
}

/// How far identification could pin a machine's fitted values down: the half-width of each
/// value's 95% confidence interval, relative to the value. Zero for what was weighed,
/// measured or given (Gymnasium's machine is exact); training for a machine randomises each
/// value at least this far around it (`policy_export::config::Config::deploy_on`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Uncertainty {
    /// The motor's stall force.
    pub stall_force: f64,
    /// The motor's damping.
    pub damping: f64,
    /// The pole's length to its centre of mass.
    pub pole_com: f64,
}

impl Uncertainty {
    /// Values known exactly.
    pub const NONE: Uncertainty = Uncertainty {
        stall_force: 0.0,
        damping: 0.0,
        pole_com: 0.0,
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
    match integration {
        Integration::Euler => State::from_array(plant.euler(&s.to_array(), duty, external)),
        Integration::Rk4 { substeps } => {
            let [next] = rk4_lanes(substeps, [Lane::new(plant, s, duty, external)]);
            next
        }
    }
}

/// One world's period as [`rk4_lanes`] integrates it: its plant, state, and the duty and
/// external force held over the period.
#[derive(Clone, Copy, Debug)]
pub struct Lane {
    plant: Plant<f64>,
    x: [f64; 4],
    duty: f64,
    external: f64,
}

impl Lane {
    /// The period of `plant` from `s` under `duty` and `external`.
    pub fn new(plant: &Plant<f64>, s: &State, duty: f64, external: f64) -> Lane {
        Lane {
            plant: *plant,
            x: s.to_array(),
            duty,
            external,
        }
    }
}

/// `N` worlds' periods of `substeps` Runge-Kutta steps each, side by side: every lane's
/// arithmetic is [`advance`]'s, operation for operation, so each lane's state is what it would
/// be alone, bit for bit. A lone world's step is one chain of dependent operations (a sine,
/// then divisions, four times over); `N` independent chains let an out-of-order core overlap
/// them, which is where a continuous world's time goes.
///
/// Each step computes the angle's sine and cosine once, at its start; its three later
/// stages turn them by the stage's small angle ([`turned`]) instead of computing them afresh.
#[inline(always)]
pub fn rk4_lanes<const N: usize>(substeps: u32, lanes: [Lane; N]) -> [State; N] {
    let n = substeps.max(1);
    let h: [f64; N] = core::array::from_fn(|j| lanes[j].plant.tau() / f64::from(n));
    let half = h.map(|h| h / 2.0);
    let mut x: [[f64; 4]; N] = core::array::from_fn(|j| lanes[j].x);
    for _ in 0..n {
        let start: [(f64, f64); N] = core::array::from_fn(|j| Real::sin_cos(x[j][2]));
        let f = |s: &[[f64; 4]; N], trig: &[(f64, f64); N]| -> [[f64; 4]; N] {
            core::array::from_fn(|j| {
                let l = &lanes[j];
                l.plant.derivative_at(&s[j], trig[j], l.duty, l.external)
            })
        };
        let at = |d: &[[f64; 4]; N], k: &[f64; N]| -> [[f64; 4]; N] {
            core::array::from_fn(|j| core::array::from_fn(|i| x[j][i] + k[j] * d[j][i]))
        };
        // A stage's sine and cosine, turned from the step's by the stage's angle.
        let trig = |s: &[[f64; 4]; N], d: &[[f64; 4]; N], k: &[f64; N]| -> [(f64, f64); N] {
            core::array::from_fn(|j| turned(start[j], k[j] * d[j][2], s[j][2]))
        };
        let k1 = f(&x, &start);
        let s2 = at(&k1, &half);
        let k2 = f(&s2, &trig(&s2, &k1, &half));
        let s3 = at(&k2, &half);
        let k3 = f(&s3, &trig(&s3, &k2, &half));
        let s4 = at(&k3, &h);
        let k4 = f(&s4, &trig(&s4, &k3, &h));
        x = core::array::from_fn(|j| {
            core::array::from_fn(|i| {
                x[j][i] + h[j] / 6.0 * (k1[j][i] + 2.0 * k2[j][i] + 2.0 * k3[j][i] + k4[j][i])
            })
        });
    }
    x.map(State::from_array)
}

/// Beyond this turn (rad) a stage's sine and cosine are computed afresh, where the series of
/// [`turned`] would need more terms: a stage turns this far only when the pole spins at 20
/// rad/s or more under 1 ms steps.
const TURN_LIMIT: f64 = 0.02;

/// `(sin, cos)` of `theta + delta` from `(sin, cos)` of `theta` (`trig`), by the angle-sum
/// rule with `sin delta` and `cos delta` as their Taylor series to the 7th and 8th power: for
/// `|delta| <= TURN_LIMIT` the series' error is below 1e-20, so the result is the true value's
/// to within the rounding of a few multiply-adds (checked against `libm` in the tests), at a
/// fraction of a sine's cost. `stage` is `theta + delta` as the stage's state holds it,
/// computed afresh past the limit.
#[inline(always)]
fn turned((s, c): (f64, f64), delta: f64, stage: f64) -> (f64, f64) {
    if delta.abs() > TURN_LIMIT {
        return Real::sin_cos(stage);
    }
    let d2 = delta * delta;
    // Horner in d2 with the reciprocals folded to constants: a division each would cost
    // more than the sine saved.
    let sin_d =
        delta * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0))));
    let cos_d = 1.0
        - d2 * 0.5
            * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0) * (1.0 - d2 * (1.0 / 56.0))));
    (s * cos_d + c * sin_d, c * cos_d - s * sin_d)
}

/// The most a velocity may decay by in one step (its rate times the step): an explicit
/// Euler step of a decay faster than 2 per step grows it instead, and classic Runge-Kutta
/// stops at 2.79; beyond it the world's state becomes infinite, then NaN, and an episode of
/// NaN never fails.
pub const MAX_DECAY_PER_STEP: f64 = 2.0;

/// Refuses physics whose motor damping or pivot friction damps the cart's or the pole's
/// velocity faster than steps of `integration` can follow (see [`MAX_DECAY_PER_STEP`]). The
/// rates are the largest over the pole's angle: the damping acts on the cart's mass and a
/// quarter of the pole's, the friction on the pole's inertia about the pivot less what the
/// cart takes back.
pub fn check_integrable(
    p: &firmware::cartpole::Params,
    integration: Integration,
) -> Result<(), String> {
    let step = integration.step(p.tau);
    let m = p.masspole;
    let pole = p.length * p.length * m * (4.0 / 3.0 - m / p.total_mass());
    for (what, rate) in [
        (
            "the motor's damping",
            p.motor_damping / (p.masscart + m / 4.0),
        ),
        ("the pivot's friction", p.pole_friction / pole),
    ] {
        let decay = rate * step;
        if decay.is_nan() || decay > MAX_DECAY_PER_STEP {
            return Err(format!(
                "{what} damps a velocity by {decay:.3e} per integration step of {step} s, \
                 expected at most {MAX_DECAY_PER_STEP} (the world would not stay finite): a \
                 smaller damping or friction, a heavier or longer pole, or shorter steps"
            ));
        }
    }
    Ok(())
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

    /// Classic Runge-Kutta as a textbook writes it, one world at a time, each stage's sine and
    /// cosine computed afresh: the lanes give its states to within a few roundings, and the
    /// same bits whichever block a world is integrated in and whatever its neighbours are.
    #[test]
    fn lanes_give_each_world_the_textbook_steps_and_their_own_bits_in_any_block() {
        let textbook = |p: &Plant<f64>, x: [f64; 4], n: u32, duty: f64, ext: f64| {
            let h = p.tau() / f64::from(n);
            (0..n).fold(x, |x, _| {
                let f = |s: &[f64; 4]| p.derivative(s, duty, ext);
                let at = |d: &[f64; 4], k: f64| -> [f64; 4] {
                    core::array::from_fn(|i| x[i] + k * d[i])
                };
                let k1 = f(&x);
                let k2 = f(&at(&k1, h / 2.0));
                let k3 = f(&at(&k2, h / 2.0));
                let k4 = f(&at(&k3, h));
                core::array::from_fn(|i| {
                    x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
                })
            })
        };
        let lanes: [(Params, [f64; 4], f64, f64); 8] = core::array::from_fn(|j| {
            let k = j as f64;
            let p = Params {
                tau: 0.01,
                masscart: 0.5 + 0.1 * k,
                length: 0.2 + 0.05 * k,
                motor_damping: 0.5 * k,
                // Friction in every other lane: both of the derivative's branches side by side.
                cart_friction: if j % 2 == 0 { 0.0 } else { 0.05 },
                pole_friction: if j % 2 == 0 { 0.0 } else { 0.001 },
                ..Params::default()
            };
            let x = [0.01 * k, -0.1 * k, 0.3 - 0.1 * k, 0.2 * k];
            (p, x, if j % 3 == 0 { -1.0 } else { 0.7 }, 0.5 * k)
        });
        let plants = lanes.map(|(p, ..)| Plant::new(&p));
        let want: [[f64; 4]; 8] =
            core::array::from_fn(|j| textbook(&plants[j], lanes[j].1, 7, lanes[j].2, lanes[j].3));
        let lane = |j: usize| {
            let (_, x, duty, ext) = lanes[j];
            Lane::new(&plants[j], &State::from_array(x), duty, ext)
        };
        let eight = rk4_lanes::<8>(7, core::array::from_fn(lane));
        let two = rk4_lanes::<2>(7, [lane(5), lane(2)]);
        for j in 0..8 {
            for (got, want) in eight[j].to_array().iter().zip(want[j]) {
                assert!(
                    (got - want).abs() <= 1e-14 * want.abs().max(1.0),
                    "lane {j}"
                );
            }
            let (_, x, duty, ext) = lanes[j];
            let rk4 = Integration::Rk4 { substeps: 7 };
            let alone = advance(&plants[j], rk4, &State::from_array(x), duty, ext);
            assert_eq!(alone, eight[j], "lane {j}");
        }
        assert_eq!((two[0], two[1]), (eight[5], eight[2]));
    }

    /// A stage's sine and cosine turned from the step's are the angle's own to within a few
    /// roundings, over every angle and every turn up to the limit, and past it are exactly
    /// `libm`'s.
    #[test]
    fn a_turned_sine_and_cosine_are_the_angles_own() {
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let theta = -7.0 + 14.0 * f64::from(i) / 2000.0;
            for k in -50..=50 {
                let delta = TURN_LIMIT * f64::from(k) / 50.0;
                let (s, c) = turned(Real::sin_cos(theta), delta, theta + delta);
                let (ws, wc) = Real::sin_cos(theta + delta);
                worst = worst.max((s - ws).abs()).max((c - wc).abs());
            }
        }
        assert!(worst < 1e-15, "{worst:e}");
        let past = TURN_LIMIT * 1.5;
        assert_eq!(turned((0.3, 0.4), past, 1.2), Real::sin_cos(1.2));
    }
}
