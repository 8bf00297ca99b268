//! The fit, in three stages, each a Levenberg-Marquardt minimisation of the simulation
//! error ([`super::lm`]):
//!
//! 1. the swing logs alone: the pole's effective length and the pivot's friction (a held
//!    cart's pendulum depends on nothing else), from the length the swing's period gives;
//! 2. the cart logs alone, the pole as stage 1 found it: the stall force, the damping and
//!    the cart's friction, from an equation-error regression. First on the cart logs' first
//!    [`pieces::SCREEN_S`] at each dead time from 0 to [`MAX_DEAD_TIME`], the dead time the
//!    one whose fit leaves the least sum of squares; then on every piece at that dead time,
//!    the pieces whose simulation fell the other way cut ([`pieces`]);
//! 3. every log at that dead time, every unknown free, each log's residuals weighted by the
//!    inverse of its own scatter in the stages before (a pole count and a cart count are
//!    not the same error), from where stages 1 and 2 ended.
//!
//! Each stage's work and memory grow in proportion to its logs ([`super::lm`]); the dead
//! time's search costs the same however long they are.

use std::cell::Cell;
use std::ops::Range;

use firmware::cartpole::Params;
use twin::Machine;

use super::channel::{Channel, ROUNDING_SD, WINDOW_S};
use super::lm::{Problem, Residuals, Solution};
use super::log::Log;
use super::model::{self, CartData, SHARED, Setup, SwingData, Weights};
use super::{pieces, start};

/// The longest dead time searched, periods.
pub const MAX_DEAD_TIME: usize = 8;
/// Most iterations of a fit to convergence.
const ITERATIONS: usize = 60;
/// Iterations each dead time's cart fit is given before only the best two go on: a wrong
/// dead time leaves a sum of squares many times the right one's within a few.
const SCREENING: usize = 8;
/// How many dead times are fitted to convergence.
const FINALISTS: usize = 2;
/// The two-sided 95% point of the normal distribution.
const Z95: f64 = 1.959_963_984_540_054;

/// One shared unknown's estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The value.
    pub value: f64,
    /// Half the width of its 95% confidence interval; `None` where the value is at a bound
    /// (the interval is then not the Jacobian's) or the fit cannot tell the unknowns apart.
    pub half_width: Option<f64>,
}

/// A log's measured and simulated counts at the estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Trace {
    /// Which log (its index among those given).
    pub log: usize,
    /// The log's first period compared.
    pub start: usize,
    /// Its encoders' counts.
    pub channels: Vec<Channel>,
}

/// What the fit found.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// The rig's physics with the estimates in.
    pub params: Params,
    /// The dead time, periods.
    pub dead_time: u32,
    /// Each shared unknown's estimate, in [`model`]'s order.
    pub estimates: [Estimate; SHARED],
    /// Stage 2's sum of squares at each dead time from 0, on the cart logs' first
    /// [`pieces::SCREEN_S`].
    pub dead_time_sse: Vec<f64>,
    /// Each log's measured and simulated counts.
    pub traces: Vec<Trace>,
    /// How many residuals the minimisations evaluated, each a period simulated: the fit's
    /// work.
    pub evaluated: u64,
}

fn problem<'s>(setup: &'s Setup, eval: Residuals<'s>) -> Problem<'s> {
    let bounds = setup.bounds();
    Problem {
        eval,
        shared: setup.free.len(),
        blocks: setup.blocks(),
        lower: bounds.iter().map(|b| b.0).collect(),
        upper: bounds.iter().map(|b| b.1).collect(),
        scale: bounds.iter().map(|b| b.2).collect(),
    }
}

/// Minimises `setup`'s sum of squares from `x0`, adding the residuals evaluated to `work`.
fn solve(setup: &Setup, x0: &[f64], iterations: usize, work: &Cell<u64>) -> Solution {
    let eval = |x: &[f64], b: usize, out: &mut [f64]| setup.eval(x, b, out, false);
    let s = problem(setup, &eval).solve(x0, iterations);
    work.set(work.get() + s.evaluated);
    s
}

/// Stage 1: the pole's length and friction, and each swing's nuisance parameters.
fn swings(
    base: &Params,
    machine: &Machine,
    swings: &[SwingData],
    work: &Cell<u64>,
) -> (Params, Vec<f64>) {
    let free = vec![model::POLE_FRICTION, model::LENGTH];
    let setup = Setup::new(*base, machine.integration, (&[], swings), 0, free);
    let (length, friction) = swings
        .iter()
        .find_map(|s| start::swing(s, base))
        .unwrap_or((base.length, base.pole_friction));
    let x0: Vec<f64> = [friction, length]
        .into_iter()
        .chain(setup.nuisance_start())
        .collect();
    let s = solve(&setup, &x0, ITERATIONS, work);
    (setup.params(&s.x), s.x[2..].to_vec())
}

/// Stage 2 at dead time `dead`: the fitted vector and its sum of squares after at most
/// `iterations`, from `from` or, without it, from the regression's estimate.
fn carts(
    base: &Params,
    machine: &Machine,
    carts: &[CartData],
    dead: usize,
    (from, iterations): (Option<&[f64]>, usize),
    work: &Cell<u64>,
) -> (Vec<f64>, f64) {
    let free = vec![model::FORCE, model::DAMPING, model::CART_FRICTION];
    let setup = Setup::new(*base, machine.integration, (carts, &[]), dead, free);
    let x0: Vec<f64> = match from {
        Some(x) => x.to_vec(),
        None => {
            let (f, b, mu) = carts
                .iter()
                .find_map(|c| start::cart(c, base, dead))
                .unwrap_or((base.force_mag, base.motor_damping, base.cart_friction));
            [f, b, mu]
                .into_iter()
                .chain(setup.nuisance_start())
                .collect()
        }
    };
    let s = solve(&setup, &x0, iterations, work);
    (s.x, s.sse)
}

/// The inverse of each scatter, no less than a count's rounding's.
fn inverse(spread: &Weights) -> Weights {
    let w = |s: f64| 1.0 / s.max(ROUNDING_SD);
    Weights {
        carts: spread.carts.iter().map(|c| c.map(w)).collect(),
        swings: spread.swings.iter().map(|&s| w(s)).collect(),
    }
}

/// Stage 2's dead time on `carts`: every one from 0 to [`MAX_DEAD_TIME`] fitted for
/// [`SCREENING`] iterations, the best [`FINALISTS`] to convergence, the one of least sum of
/// squares chosen; with each dead time's fitted vector and sum of squares.
fn dead_time(
    pole: &Params,
    machine: &Machine,
    carts: &[CartData],
    work: &Cell<u64>,
) -> (usize, Vec<(Vec<f64>, f64)>) {
    let fit =
        |d: usize, from: (Option<&[f64]>, usize)| self::carts(pole, machine, carts, d, from, work);
    let mut runs: Vec<(Vec<f64>, f64)> = (0..=MAX_DEAD_TIME)
        .map(|d| fit(d, (None, SCREENING)))
        .collect();
    let mut order: Vec<usize> = (0..runs.len()).collect();
    order.sort_by(|&a, &b| runs[a].1.total_cmp(&runs[b].1));
    for &d in &order[..FINALISTS] {
        runs[d] = fit(d, (Some(&runs[d].0), ITERATIONS));
    }
    let dead = order[..FINALISTS]
        .iter()
        .copied()
        .min_by(|&a, &b| runs[a].1.total_cmp(&runs[b].1))
        .unwrap_or(0);
    (dead, runs)
}

/// Stage 2 on every piece of `carts` at dead time `dead`, from the fit `x` on their first
/// pieces `screened`; then each lost piece cut in two and the fit repeated
/// ([`pieces::cut_lost`]), [`pieces::CUTS`] times at most. The fitted vector.
fn all_carts(
    pole: &Params,
    machine: &Machine,
    (carts, dead): (&mut [CartData], usize),
    (screened, x): (&[CartData], &[f64]),
    work: &Cell<u64>,
) -> Vec<f64> {
    let free = || vec![model::FORCE, model::DAMPING, model::CART_FRICTION];
    let pieces_of = |c: &[CartData]| -> Vec<Vec<Range<usize>>> {
        c.iter().map(|c| c.segments.clone()).collect()
    };
    let refit = |carts: &[CartData], from: &[Vec<Range<usize>>], x: &[f64]| {
        let setup = Setup::new(*pole, machine.integration, (carts, &[]), dead, free());
        let x0 = pieces::carry((from, x), carts, setup.free.len(), &setup.nuisance_start());
        solve(&setup, &x0, ITERATIONS, work).x
    };
    let mut x = x.to_vec();
    if pieces_of(screened) != pieces_of(carts) {
        x = refit(carts, &pieces_of(screened), &x);
    }
    let shortest = (model::SEGMENT_S / f64::from(1 << pieces::CUTS) / pole.tau).floor() as usize;
    for _ in 0..pieces::CUTS {
        let setup = Setup::new(*pole, machine.integration, (carts, &[]), dead, free());
        let Some(cut) = pieces::cut_lost(&setup, &x, shortest.max(1)) else {
            break;
        };
        let from = pieces_of(carts);
        for (c, s) in carts.iter_mut().zip(cut) {
            c.segments = s;
        }
        x = refit(carts, &from, &x);
    }
    x
}

/// Identifies `machine`'s unknowns from checked `logs`, at least one of each experiment.
pub fn fit(logs: &[Log], machine: &Machine) -> Fit {
    let work = Cell::new(0);
    let (mut cart_data, swing_data) = model::split(logs);
    let base = machine.rig.params;
    let (pole, swing_nuisance) = swings(&base, machine, &swing_data, &work);
    let screen = (pieces::SCREEN_S / base.tau).round() as usize;
    let screened = pieces::prefix(&cart_data, screen);
    let (dead, runs) = dead_time(&pole, machine, &screened, &work);
    let cart_x = all_carts(
        &pole,
        machine,
        (&mut cart_data, dead),
        (&screened, &runs[dead].0),
        &work,
    );
    let mut joint = Setup::new(
        base,
        machine.integration,
        (&cart_data, &swing_data),
        dead,
        (0..SHARED).collect(),
    );
    let mut x0: Vec<f64> = vec![
        cart_x[0],
        cart_x[1],
        cart_x[2],
        pole.pole_friction,
        pole.length,
    ];
    x0.extend(&cart_x[3..]);
    x0.extend(&swing_nuisance);
    joint.weights = inverse(&joint.scatter(&x0));
    let solution = solve(&joint, &x0, ITERATIONS, &work);
    let estimates = intervals(&joint, &solution);
    Fit {
        params: joint.params(&solution.x),
        dead_time: dead as u32,
        estimates,
        dead_time_sse: runs.iter().map(|r| r.1).collect(),
        traces: traces(logs, &joint, &solution.x),
        evaluated: work.get(),
    }
}

/// Each shared unknown with its 95% interval from the Jacobian at the optimum: the
/// residuals taken as independent, of equal variance once weighted, and the model as
/// right, the estimate's covariance is `s^2 (J'J)^-1` with `s^2 = SSE / (m - n)` (Ljung,
/// "System Identification: Theory for the User", 2nd ed., 1999, section 9.3), the dead
/// time held at its value. Unknowns at a bound are held there.
fn intervals(setup: &Setup, s: &Solution) -> [Estimate; SHARED] {
    let (m, n) = (setup.m(), setup.n());
    let bounds = setup.bounds();
    let free: Vec<usize> = (0..SHARED)
        .filter(|&j| s.x[j] > bounds[j].0 && s.x[j] < bounds[j].1)
        .collect();
    let fitted = free.len() + n - SHARED;
    let variance = s.sse / (m.saturating_sub(fitted).max(1)) as f64;
    let inverse = s.normal.shared_inverse(&free);
    core::array::from_fn(|i| {
        let half_width = free.iter().position(|&j| j == i).and_then(|k| {
            let v = inverse.as_ref()?[k * free.len() + k] * variance;
            (v.is_finite() && v >= 0.0).then(|| Z95 * v.sqrt())
        });
        Estimate {
            value: s.x[i],
            half_width,
        }
    })
}

/// Each log's measured and simulated counts at `x`, in the order the logs were given.
fn traces(logs: &[Log], setup: &Setup, x: &[f64]) -> Vec<Trace> {
    let (mut carts, mut swings) = setup.simulated(x);
    let window = (WINDOW_S / setup.base.tau).round() as usize;
    let (mut c, mut s) = (0, 0);
    logs.iter()
        .enumerate()
        .map(|(log, l)| {
            let channels = if l.experiment == firmware::identify::Experiment::Cart {
                let [cart, pole] = std::mem::take(&mut carts[c]);
                let data = &setup.carts[c];
                c += 1;
                vec![
                    Channel::new("cart", data.counts.clone(), cart, window),
                    Channel::new("pole", data.pole.clone(), pole, window),
                ]
            } else {
                let data = &setup.swings[s];
                let sim = std::mem::take(&mut swings[s]);
                s += 1;
                vec![Channel::new("pole", data.counts.clone(), sim, window)]
            };
            let start = if l.experiment == firmware::identify::Experiment::Cart {
                0
            } else {
                setup.swings[s - 1].start
            };
            Trace {
                log,
                start,
                channels,
            }
        })
        .collect()
}
