//! The experiments as the fit simulates them: each log's measured positions, the plant
//! built from a parameter vector, and the residuals between the simulated and the logged
//! counts.

use std::ops::Range;

use firmware::cartpole::{Params, Plant, State};
use firmware::identify::Experiment;
use twin::machine::{self, Integration};

use super::held;
use super::lm;
use super::log::{self, Log};

/// The shared unknowns, in the parameter vector's order.
pub const FORCE: usize = 0;
/// The motor's damping.
pub const DAMPING: usize = 1;
/// The cart's Coulomb friction.
pub const CART_FRICTION: usize = 2;
/// The pivot's viscous friction.
pub const POLE_FRICTION: usize = 3;
/// The pole's effective length.
pub const LENGTH: usize = 4;
/// How many shared unknowns there are.
pub const SHARED: usize = 5;

/// Each shared unknown's bounds (those of a rig file, so that the result is one) and
/// typical size.
pub const BOUNDS: [(f64, f64, f64); SHARED] = [
    (1e-3, 1e4, 1.0),
    (0.0, 1e4, 1.0),
    (0.0, 1.0, 0.01),
    (0.0, 0.1, 1e-4),
    (1e-3, 100.0, 0.1),
];

/// How long each piece of a cart log is that is simulated from a state of its own, s. A
/// hanging pole under a strong motor is pumped over the top and its motion is chaotic:
/// within a few seconds, a simulation from parameters a fraction of a percent off parts
/// from the measurement as far as one from parameters far off, and the sum of squares says
/// nothing about them. Pieces short against that (multiple shooting, the pieces not tied
/// to each other) keep it a measure of the parameters.
pub const SEGMENT_S: f64 = 2.0;

/// A cart log: the logged duties, the cart's and the pole's measured positions (counts:
/// each count's midpoint, the pole's from hanging), and the pieces it is simulated in.
pub struct CartData {
    /// The duty of each period.
    pub duty: Vec<f64>,
    /// The cart's position at each period, counts.
    pub counts: Vec<f64>,
    /// The pole's angle from hanging at each period, counts.
    pub pole: Vec<f64>,
    /// Counts per metre.
    pub per_m: f64,
    /// Pole counts per radian.
    pub per_rad: f64,
    /// The pieces, each simulated from its own starting state.
    pub segments: Vec<Range<usize>>,
}

/// A swing log from its release: the pole's measured angle (counts from hanging: each
/// count's midpoint).
pub struct SwingData {
    /// The pole's angle at each period from the release, counts.
    pub counts: Vec<f64>,
    /// The first period fitted.
    pub start: usize,
    /// Counts per radian.
    pub per_rad: f64,
}

impl CartData {
    /// The data of a checked cart log.
    pub fn new(log: &Log) -> CartData {
        let n = log.duty.len();
        let per = ((SEGMENT_S / log.period_s).round() as usize).max(2);
        // A short last piece joins the one before it.
        let pieces = (n / per).max(1);
        let segments = (0..pieces)
            .map(|i| i * per..if i + 1 == pieces { n } else { (i + 1) * per })
            .collect();
        CartData {
            duty: log.duty.clone(),
            counts: log.cart.iter().map(|&c| f64::from(c) + 0.5).collect(),
            pole: log::doubled_midpoints(log)
                .iter()
                .map(|&c| c as f64 / 2.0)
                .collect(),
            per_m: f64::from(log.encoders.cart_counts_per_m),
            per_rad: f64::from(log.encoders.pole_counts_per_rev) / core::f64::consts::TAU,
            segments,
        }
    }

    /// The duty the motor applies in period `k` after a dead time of `dead` periods.
    pub fn acting(&self, k: usize, dead: usize) -> f64 {
        k.checked_sub(dead).map_or(0.0, |j| self.duty[j])
    }

    /// The state at period `k` the counts suggest: positions from the counts, rates from
    /// their central differences, in metres and radians.
    fn state_at(&self, k: usize, tau: f64) -> [f64; 4] {
        let (lo, hi) = (k.saturating_sub(1), (k + 1).min(self.counts.len() - 1));
        let dt = (hi - lo).max(1) as f64 * tau;
        [
            self.counts[k] / self.per_m,
            (self.counts[hi] - self.counts[lo]) / dt / self.per_m,
            self.pole[k] / self.per_rad,
            (self.pole[hi] - self.pole[lo]) / dt / self.per_rad,
        ]
    }
}

impl SwingData {
    /// The data of a checked swing log.
    pub fn new(log: &Log) -> SwingData {
        let doubled = log::doubled_midpoints(log);
        let start = log::release(&doubled).unwrap_or(0);
        SwingData {
            counts: doubled[start..].iter().map(|&c| c as f64 / 2.0).collect(),
            start,
            per_rad: f64::from(log.encoders.pole_counts_per_rev) / core::f64::consts::TAU,
        }
    }
}

/// Each log's weights: a cart log's for its cart and its pole residuals, a swing log's.
#[derive(Clone, Debug, PartialEq)]
pub struct Weights {
    /// Each cart log's `[cart, pole]` weights.
    pub carts: Vec<[f64; 2]>,
    /// Each swing log's weight.
    pub swings: Vec<f64>,
}

impl Weights {
    /// Every residual weighted 1.
    pub fn unit(carts: usize, swings: usize) -> Weights {
        Weights {
            carts: vec![[1.0; 2]; carts],
            swings: vec![1.0; swings],
        }
    }
}

/// What one block of residuals simulates.
#[derive(Clone, Debug, PartialEq)]
enum Source {
    /// A piece of cart log `log`: its cart residuals, then its pole residuals.
    Cart { log: usize, periods: Range<usize> },
    /// Swing log `log`.
    Swing { log: usize },
}

#[derive(Clone, Debug, PartialEq)]
struct Block {
    source: Source,
    rows: Range<usize>,
    nuisance: usize,
}

/// A fit's logs and parameters. The vector holds the shared unknowns fitted, then the
/// nuisance parameters: each cart piece's starting state (m, m/s, rad from hanging,
/// rad/s), each swing log's starting angle (rad from hanging) and rate (rad/s) and its
/// encoder's zero offset (counts).
pub struct Setup<'a> {
    /// The rig's known values and the shared unknowns not being fitted.
    pub base: Params,
    /// How the world advances.
    pub integration: Integration,
    /// The cart logs fitted.
    pub carts: &'a [CartData],
    /// The swing logs fitted.
    pub swings: &'a [SwingData],
    /// The dead time the carts' duties are shifted by, periods.
    pub dead: usize,
    /// The shared unknowns fitted, the first entries of the vector.
    pub free: Vec<usize>,
    /// The residuals' weights.
    pub weights: Weights,
    blocks: Vec<Block>,
}

/// Nuisance parameters per cart piece.
pub const CART_NUISANCE: usize = 4;
/// Nuisance parameters per swing log.
const SWING_NUISANCE: usize = 3;

/// Sets the shared unknown `i` of `p` to `v`.
pub fn set(p: &mut Params, i: usize, v: f64) {
    match i {
        FORCE => p.force_mag = v,
        DAMPING => p.motor_damping = v,
        CART_FRICTION => p.cart_friction = v,
        POLE_FRICTION => p.pole_friction = v,
        _ => p.length = v,
    }
}

/// The shared unknown `i` of `p`.
pub fn get(p: &Params, i: usize) -> f64 {
    [
        p.force_mag,
        p.motor_damping,
        p.cart_friction,
        p.pole_friction,
        p.length,
    ][i]
}

impl<'a> Setup<'a> {
    /// A fit of `free` on `carts` and `swings` at dead time `dead`, the rest of the plant
    /// as `base`.
    pub fn new(
        base: Params,
        integration: Integration,
        (carts, swings): (&'a [CartData], &'a [SwingData]),
        dead: usize,
        free: Vec<usize>,
    ) -> Setup<'a> {
        let mut blocks = Vec::new();
        let (mut row, mut nuisance) = (0, free.len());
        for (log, c) in carts.iter().enumerate() {
            for periods in &c.segments {
                let rows = row..row + 2 * periods.len();
                row = rows.end;
                let source = Source::Cart {
                    log,
                    periods: periods.clone(),
                };
                blocks.push(Block {
                    source,
                    rows,
                    nuisance,
                });
                nuisance += CART_NUISANCE;
            }
        }
        for (log, s) in swings.iter().enumerate() {
            let rows = row..row + s.counts.len();
            row = rows.end;
            blocks.push(Block {
                source: Source::Swing { log },
                rows,
                nuisance,
            });
            nuisance += SWING_NUISANCE;
        }
        Setup {
            base,
            integration,
            carts,
            swings,
            dead,
            free,
            weights: Weights::unit(carts.len(), swings.len()),
            blocks,
        }
    }

    /// How many residuals the fit has.
    pub fn m(&self) -> usize {
        self.blocks.last().map_or(0, |b| b.rows.end)
    }

    /// How many parameters the fit has.
    pub fn n(&self) -> usize {
        self.blocks.last().map_or(self.free.len(), |b| {
            b.nuisance
                + if matches!(b.source, Source::Cart { .. }) {
                    CART_NUISANCE
                } else {
                    SWING_NUISANCE
                }
        })
    }

    /// The blocks as the least-squares problem sees them: a cart piece depends on every
    /// shared unknown fitted, a swing on the pole's alone, each on its own nuisance
    /// parameters.
    pub fn blocks(&self) -> Vec<lm::Block> {
        let all: Vec<usize> = (0..self.free.len()).collect();
        let pole: Vec<usize> = all
            .iter()
            .copied()
            .filter(|&k| matches!(self.free[k], POLE_FRICTION | LENGTH))
            .collect();
        self.blocks
            .iter()
            .map(|b| {
                let (shared, own) = match b.source {
                    Source::Cart { .. } => (all.clone(), CART_NUISANCE),
                    Source::Swing { .. } => (pole.clone(), SWING_NUISANCE),
                };
                lm::Block {
                    rows: b.rows.clone(),
                    shared,
                    own: b.nuisance..b.nuisance + own,
                }
            })
            .collect()
    }

    /// The plant's parameters at `x`.
    pub fn params(&self, x: &[f64]) -> Params {
        let mut p = self.base;
        for (&i, &v) in self.free.iter().zip(x) {
            set(&mut p, i, v);
        }
        p
    }

    /// Block `b`'s weighted residuals (simulated less measured counts) at `x`, or with
    /// `simulated` its simulated counts.
    pub fn eval(&self, x: &[f64], b: usize, out: &mut [f64], simulated: bool) {
        let block = &self.blocks[b];
        let p = self.params(x);
        let n = &x[block.nuisance..];
        let pi = core::f64::consts::PI;
        let keep =
            |w: f64, sim: f64, measured: f64| if simulated { sim } else { w * (sim - measured) };
        match &block.source {
            Source::Cart { log, periods } => {
                let (c, [wc, wp]) = (&self.carts[*log], self.weights.carts[*log]);
                let plant = Plant::new(&p);
                let mut s = State {
                    x: n[0],
                    x_dot: n[1],
                    theta: pi + n[2],
                    theta_dot: n[3],
                };
                let (cart, pole) = out.split_at_mut(periods.len());
                for (i, k) in periods.clone().enumerate() {
                    cart[i] = keep(wc, s.x * c.per_m, c.counts[k]);
                    pole[i] = keep(wp, (s.theta - pi) * c.per_rad, c.pole[k]);
                    s = machine::advance(&plant, self.integration, &s, c.acting(k, self.dead), 0.0);
                }
            }
            Source::Swing { log } => {
                let (w, weight) = (&self.swings[*log], self.weights.swings[*log]);
                let plant = Plant::new(&held(&p));
                let mut s = State {
                    theta: pi + n[0],
                    theta_dot: n[1],
                    ..State::default()
                };
                for (o, &measured) in out.iter_mut().zip(&w.counts) {
                    *o = keep(weight, (s.theta - pi) * w.per_rad + n[2], measured);
                    s = machine::advance(&plant, self.integration, &s, 0.0, 0.0);
                }
            }
        }
    }

    /// Each parameter's bounds and typical size, in the vector's order.
    pub fn bounds(&self) -> Vec<(f64, f64, f64)> {
        let inf = f64::INFINITY;
        let mut out: Vec<(f64, f64, f64)> = self.free.iter().map(|&i| BOUNDS[i]).collect();
        for b in &self.blocks {
            match b.source {
                Source::Cart { .. } => out.extend([
                    (-inf, inf, 1e-4),
                    (-100.0, 100.0, 0.01),
                    (-inf, inf, 0.01),
                    (-200.0, 200.0, 0.1),
                ]),
                Source::Swing { .. } => {
                    out.extend([(-3.2, 3.2, 0.1), (-100.0, 100.0, 0.1), (-1.0, 1.0, 1.0)])
                }
            }
        }
        out
    }

    /// The nuisance parameters' starting values: each piece's state as its counts suggest,
    /// each swing's first angle at rest and no offset.
    pub fn nuisance_start(&self) -> Vec<f64> {
        let tau = self.base.tau;
        let bounds = self.bounds();
        let mut out = Vec::new();
        for b in &self.blocks {
            match &b.source {
                Source::Cart { log, periods } => {
                    out.extend(self.carts[*log].state_at(periods.start, tau))
                }
                Source::Swing { log } => out.extend([
                    self.swings[*log].counts[0] / self.swings[*log].per_rad,
                    0.0,
                    0.0,
                ]),
            }
        }
        let first = self.free.len();
        out.iter()
            .enumerate()
            .map(|(i, v)| v.clamp(bounds[first + i].0, bounds[first + i].1))
            .collect()
    }

    /// Each log's RMS difference (counts) between simulated and measured at `x`: a cart
    /// log's for its cart and its pole.
    pub fn scatter(&self, x: &[f64]) -> Weights {
        let mut sums = Weights {
            carts: vec![[0.0; 2]; self.carts.len()],
            swings: vec![0.0; self.swings.len()],
        };
        for (b, block) in self.blocks.iter().enumerate() {
            let mut out = vec![0.0; block.rows.len()];
            self.eval(x, b, &mut out, true);
            match &block.source {
                Source::Cart { log, periods } => {
                    let c = &self.carts[*log];
                    let (cart, pole) = out.split_at(periods.len());
                    for (i, k) in periods.clone().enumerate() {
                        sums.carts[*log][0] +=
                            (cart[i] - c.counts[k]).powi(2) / c.counts.len() as f64;
                        sums.carts[*log][1] +=
                            (pole[i] - c.pole[k]).powi(2) / c.counts.len() as f64;
                    }
                }
                Source::Swing { log } => {
                    let w = &self.swings[*log];
                    sums.swings[*log] = out
                        .iter()
                        .zip(&w.counts)
                        .map(|(a, b)| (a - b).powi(2))
                        .sum::<f64>()
                        / w.counts.len() as f64;
                }
            }
        }
        Weights {
            carts: sums.carts.iter().map(|v| v.map(f64::sqrt)).collect(),
            swings: sums.swings.iter().map(|v| v.sqrt()).collect(),
        }
    }

    /// Each log's simulated counts at `x`: a cart log's cart counts then its pole counts,
    /// each piece started afresh.
    pub fn simulated(&self, x: &[f64]) -> (Vec<[Vec<f64>; 2]>, Vec<Vec<f64>>) {
        let mut carts: Vec<[Vec<f64>; 2]> = self
            .carts
            .iter()
            .map(|_| [Vec::new(), Vec::new()])
            .collect();
        let mut swings: Vec<Vec<f64>> = vec![Vec::new(); self.swings.len()];
        for (b, block) in self.blocks.iter().enumerate() {
            let mut out = vec![0.0; block.rows.len()];
            self.eval(x, b, &mut out, true);
            match &block.source {
                Source::Cart { log, periods } => {
                    let (cart, pole) = out.split_at(periods.len());
                    carts[*log][0].extend_from_slice(cart);
                    carts[*log][1].extend_from_slice(pole);
                }
                Source::Swing { log } => swings[*log] = out,
            }
        }
        (carts, swings)
    }
}

/// Which experiment each kind of data is.
pub fn split(logs: &[Log]) -> (Vec<CartData>, Vec<SwingData>) {
    let carts = logs
        .iter()
        .filter(|l| l.experiment == Experiment::Cart)
        .map(CartData::new);
    let swings = logs
        .iter()
        .filter(|l| l.experiment == Experiment::Swing)
        .map(SwingData::new);
    (carts.collect(), swings.collect())
}
