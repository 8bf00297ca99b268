//! Levenberg-Marquardt least squares with a finite-difference Jacobian and box bounds:
//! K. Levenberg, "A method for the solution of certain non-linear problems in least
//! squares", Quarterly of Applied Mathematics 2 (1944); D. W. Marquardt, "An algorithm for
//! least-squares estimation of nonlinear parameters", SIAM Journal on Applied Mathematics
//! 11 (1963). Each step solves `(J'J + lambda diag(J'J)) delta = -J'r` (Marquardt's scaling,
//! which makes the step independent of the parameters' units), is clipped to the bounds,
//! and is kept only if it lowers the sum of squares; `lambda` shrinks after a kept step and
//! grows after a refused one.
//!
//! The residuals come in blocks, each depending on a few shared parameters and on its own
//! ones, which no other block sees: `J'J` is then bordered block-diagonal. It is never
//! formed whole, nor is `J`: each block's Jacobian is taken, folded into the shared
//! parameters' normal equations and its own small blocks, and dropped, and a step
//! eliminates each block's own parameters through the Schur complement (the "reduced
//! camera system" of bundle adjustment: B. Triggs et al., "Bundle Adjustment — A Modern
//! Synthesis", Vision Algorithms: Theory and Practice, LNCS 1883, Springer, 2000,
//! section 6.1). Time and memory grow with the number of residuals and blocks, not with
//! their product.

use std::ops::Range;

/// Fills block `b`'s residuals at a point: `eval(x, b, out)`.
pub type Residuals<'a> = &'a dyn Fn(&[f64], usize, &mut [f64]);

/// One block of residuals and the parameters it depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// Its rows among the residuals; the blocks' rows are in order and contiguous from 0.
    pub rows: Range<usize>,
    /// The shared parameters it depends on, ascending, each below [`Problem::shared`].
    pub shared: Vec<usize>,
    /// Its own parameters, which no other block depends on; the blocks' own parameters
    /// follow the shared ones in the vector, in the blocks' order, without gaps.
    pub own: Range<usize>,
}

/// A least-squares problem whose residuals come in [`Block`]s: `eval(x, b, out)` fills block
/// `b`'s residuals. A finite-difference column re-evaluates only the blocks its parameter
/// enters.
pub struct Problem<'a> {
    /// Block `b`'s residuals at a point.
    pub eval: Residuals<'a>,
    /// How many shared parameters there are: the vector's first entries.
    pub shared: usize,
    /// The blocks.
    pub blocks: Vec<Block>,
    /// The lowest value of each parameter.
    pub lower: Vec<f64>,
    /// The highest value of each parameter.
    pub upper: Vec<f64>,
    /// A typical size of each parameter, for the finite differences' steps.
    pub scale: Vec<f64>,
}

/// One block's part of the normal equations.
#[derive(Clone, Debug, PartialEq)]
struct Part {
    /// `J_s'J_b`: row-major, shared x own.
    cross: Vec<f64>,
    /// `J_b'J_b`: row-major, own x own.
    own: Vec<f64>,
    /// `J_b'r`.
    gradient: Vec<f64>,
}

/// The normal equations `J'J` and `J'r` of a block problem, in its structure: the shared
/// parameters' square and each block's part.
#[derive(Clone, Debug, PartialEq)]
pub struct Normal {
    shared: usize,
    /// `J_s'J_s`: row-major, shared x shared.
    square: Vec<f64>,
    /// `J_s'r`.
    gradient: Vec<f64>,
    parts: Vec<Part>,
}

/// Where the iteration stopped.
#[derive(Clone, Debug)]
pub struct Solution {
    /// The parameters.
    pub x: Vec<f64>,
    /// The sum of squared residuals there.
    pub sse: f64,
    /// The normal equations there.
    pub normal: Normal,
    /// How many residuals were evaluated in all, Jacobians' and refused steps' included:
    /// the work done, each residual a simulated period.
    pub evaluated: u64,
}

/// The relative decrease of the sum of squares below which the iteration has converged:
/// far below what separates two fits statistically (a sum of `m` squared residuals of unit
/// variance scatters by `sqrt(2 m)`), and above the finite differences' noise.
const TOLERANCE: f64 = 1e-6;
/// The largest Gauss-Newton step of every shared parameter, in standard errors, and the
/// largest relative decrease of the sum of squares, at which the iteration has converged
/// however much a block's own parameters still move. A block whose simulation is all but chaotic
/// (a pole passing the upright slowly) lies in a long, narrow valley its own parameters
/// creep along, lowering the sum of squares a little each iteration long after the shared
/// parameters have stopped moving.
const SHARED_TOLERANCE: (f64, f64) = (1e-2, 1e-3);
/// The finite differences' step relative to a parameter's size: about the cube root of
/// f64's epsilon, a compromise between the truncation of a one-sided difference and the
/// rounding of a simulation's residuals.
const RELATIVE_STEP: f64 = 1e-6;

fn sum_of_squares(r: &[f64]) -> f64 {
    let s: f64 = r.iter().map(|v| v * v).sum();
    if s.is_finite() { s } else { f64::INFINITY }
}

impl Problem<'_> {
    /// How many residuals there are.
    pub fn m(&self) -> usize {
        self.blocks.last().map_or(0, |b| b.rows.end)
    }

    fn clamp(&self, x: &mut [f64]) {
        for (i, v) in x.iter_mut().enumerate() {
            *v = v.clamp(self.lower[i], self.upper[i]);
        }
    }

    /// Every residual at `x`, counting them into `evaluated`.
    fn residuals(&self, x: &[f64], out: &mut [f64], evaluated: &mut u64) {
        for (b, block) in self.blocks.iter().enumerate() {
            (self.eval)(x, b, &mut out[block.rows.clone()]);
            *evaluated += block.rows.len() as u64;
        }
    }

    /// The forward-difference step of parameter `j` at `x`: taken the other way where it
    /// would leave the bounds.
    fn step_of(&self, x: &[f64], j: usize) -> f64 {
        let h = RELATIVE_STEP * x[j].abs().max(self.scale[j]);
        if x[j] + h > self.upper[j] { -h } else { h }
    }

    /// Block `b`'s forward-difference Jacobian at `x` (`probe` holding `x` on entry and on
    /// return), whose residuals are `r`: row-major, its shared columns then its own.
    fn block_jacobian(
        &self,
        b: usize,
        probe: &mut [f64],
        r: &[f64],
        evaluated: &mut u64,
    ) -> Vec<f64> {
        let block = &self.blocks[b];
        let columns: Vec<usize> = block
            .shared
            .iter()
            .copied()
            .chain(block.own.clone())
            .collect();
        let (rows, n) = (r.len(), columns.len());
        let mut jac = vec![0.0; rows * n];
        let mut out = vec![0.0; rows];
        for (c, &j) in columns.iter().enumerate() {
            let (x, h) = (probe[j], self.step_of(probe, j));
            probe[j] = x + h;
            (self.eval)(probe, b, &mut out);
            *evaluated += rows as u64;
            probe[j] = x;
            for i in 0..rows {
                jac[i * n + c] = (out[i] - r[i]) / h;
            }
        }
        jac
    }

    /// The normal equations at `x`, whose residuals are `r`, one block's Jacobian at a time.
    fn normal(&self, x: &[f64], r: &[f64], evaluated: &mut u64) -> Normal {
        let s = self.shared;
        let mut square = vec![0.0; s * s];
        let mut gradient = vec![0.0; s];
        let mut probe = x.to_vec();
        let mut parts = Vec::with_capacity(self.blocks.len());
        for (b, block) in self.blocks.iter().enumerate() {
            let r = &r[block.rows.clone()];
            let jac = self.block_jacobian(b, &mut probe, r, evaluated);
            let (ns, k) = (block.shared.len(), block.own.len());
            let mut part = Part {
                cross: vec![0.0; s * k],
                own: vec![0.0; k * k],
                gradient: vec![0.0; k],
            };
            for (row, &ri) in jac.chunks_exact(ns + k).zip(r) {
                let (rs, rn) = row.split_at(ns);
                for (a, &p) in block.shared.iter().enumerate() {
                    gradient[p] += rs[a] * ri;
                    for (c, &q) in block.shared.iter().enumerate().skip(a) {
                        square[p * s + q] += rs[a] * rs[c];
                    }
                    for (c, v) in rn.iter().enumerate() {
                        part.cross[p * k + c] += rs[a] * v;
                    }
                }
                for a in 0..k {
                    part.gradient[a] += rn[a] * ri;
                    for c in a..k {
                        part.own[a * k + c] += rn[a] * rn[c];
                    }
                }
            }
            mirror(&mut part.own, k);
            parts.push(part);
        }
        mirror(&mut square, s);
        Normal {
            shared: s,
            square,
            gradient,
            parts,
        }
    }

    /// Whether the Gauss-Newton step from `x`, whose normal equations are `normal`, clipped
    /// to the bounds, moves every shared parameter by at most [`SHARED_TOLERANCE`] of its
    /// standard error, the residuals' variance `variance`: how far the shared parameters
    /// still are from the local model's minimum, whatever the damping of the last step.
    fn settled(&self, normal: &Normal, x: &[f64], variance: f64) -> bool {
        let all: Vec<usize> = (0..self.shared).collect();
        let (Some(step), Some(inverse)) = (normal.step(0.0), normal.shared_inverse(&all)) else {
            return false;
        };
        all.iter().all(|&i| {
            let sd = (inverse[i * self.shared + i] * variance).sqrt();
            let moved = (x[i] + step[i]).clamp(self.lower[i], self.upper[i]) - x[i];
            moved.abs() <= SHARED_TOLERANCE.0 * sd
        })
    }

    /// Minimises the sum of squares from `x0` (clipped to the bounds), in at most
    /// `iterations` Jacobians.
    pub fn solve(&self, x0: &[f64], iterations: usize) -> Solution {
        let mut evaluated = 0;
        let mut x = x0.to_vec();
        self.clamp(&mut x);
        let mut r = vec![0.0; self.m()];
        self.residuals(&x, &mut r, &mut evaluated);
        let mut sse = sum_of_squares(&r);
        let mut lambda = 1e-3;
        let mut trial = vec![0.0; r.len()];
        let mut normal = self.normal(&x, &r, &mut evaluated);
        for _ in 0..iterations {
            let mut improved = None;
            while lambda < 1e12 {
                if let Some(delta) = normal.step(lambda) {
                    let mut next: Vec<f64> = x.iter().zip(&delta).map(|(x, d)| x + d).collect();
                    self.clamp(&mut next);
                    self.residuals(&next, &mut trial, &mut evaluated);
                    let s = sum_of_squares(&trial);
                    if s < sse {
                        improved = Some((next, s));
                        lambda = (lambda / 3.0).max(1e-12);
                        break;
                    }
                }
                lambda *= 4.0;
            }
            let Some((next, s)) = improved else { break };
            let decrease = (sse - s) / sse;
            x = next;
            sse = s;
            std::mem::swap(&mut r, &mut trial);
            normal = self.normal(&x, &r, &mut evaluated);
            let variance = sse / (r.len() as f64 - x.len() as f64).max(1.0);
            if decrease <= TOLERANCE
                || (decrease <= SHARED_TOLERANCE.1 && self.settled(&normal, &x, variance))
            {
                break;
            }
        }
        Solution {
            x,
            sse,
            normal,
            evaluated,
        }
    }
}

/// Copies the upper triangle of the row-major `n x n` `a` into its lower one.
fn mirror(a: &mut [f64], n: usize) {
    for p in 0..n {
        for q in 0..p {
            a[p * n + q] = a[q * n + p];
        }
    }
}

/// `a` (row-major `n x n`) with `lambda` times its diagonal added to the diagonal.
fn damped(a: &[f64], n: usize, lambda: f64) -> Vec<f64> {
    let mut d = a.to_vec();
    for i in 0..n {
        d[i * n + i] += lambda * a[i * n + i].max(1e-300);
    }
    d
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// A system reduced to some shared parameters: the Schur complement, its right-hand side and
/// each block's Cholesky factor.
type Reduced = (Vec<f64>, Vec<f64>, Vec<Vec<f64>>);

impl Normal {
    /// The Schur complement of every block's own parameters over the shared ones `keep`
    /// selects, each square damped by `lambda`: `S = A_ss - sum_b A_sb A_bb^-1 A_bs`, with
    /// the right-hand side `-g_s + sum_b A_sb A_bb^-1 g_b` and each block's factor of
    /// `A_bb`; `None` if a damped square is not positive definite.
    fn reduced(&self, keep: &[usize], lambda: f64) -> Option<Reduced> {
        let (s, n) = (self.shared, keep.len());
        let square = damped(&self.square, s, lambda);
        let mut schur: Vec<f64> = keep
            .iter()
            .flat_map(|&p| keep.iter().map(|&q| (p, q)).collect::<Vec<_>>())
            .map(|(p, q)| square[p * s + q])
            .collect();
        let mut rhs: Vec<f64> = keep.iter().map(|&p| -self.gradient[p]).collect();
        let mut factors = Vec::with_capacity(self.parts.len());
        for part in &self.parts {
            let k = part.gradient.len();
            let l = cholesky(&damped(&part.own, k, lambda), k)?;
            let row = |p: usize| &part.cross[p * k..(p + 1) * k];
            let solved: Vec<Vec<f64>> = keep
                .iter()
                .map(|&p| solve_factored(&l, row(p), k))
                .collect();
            let g = solve_factored(&l, &part.gradient, k);
            for (a, &p) in keep.iter().enumerate() {
                for (c, y) in solved.iter().enumerate() {
                    schur[a * n + c] -= dot(row(p), y);
                }
                rhs[a] += dot(row(p), &g);
            }
            factors.push(l);
        }
        Some((schur, rhs, factors))
    }

    /// The step `(J'J + lambda diag(J'J)) delta = -J'r` for every parameter, in the vector's
    /// order, or `None` if the damped matrix is not positive definite.
    fn step(&self, lambda: f64) -> Option<Vec<f64>> {
        let all: Vec<usize> = (0..self.shared).collect();
        let (schur, rhs, factors) = self.reduced(&all, lambda)?;
        let mut delta = solve_spd(&schur, &rhs, self.shared)?;
        for (part, l) in self.parts.iter().zip(&factors) {
            let k = part.gradient.len();
            let b: Vec<f64> = (0..k)
                .map(|c| {
                    -part.gradient[c]
                        - (0..self.shared)
                            .map(|p| part.cross[p * k + c] * delta[p])
                            .sum::<f64>()
                })
                .collect();
            delta.extend(solve_factored(l, &b, k));
        }
        Some(delta)
    }

    /// The block of `(J'J)^-1` over the shared parameters `free` selects (ascending; the
    /// other shared ones held where they are, every block's own parameters free), row-major
    /// over the selected ones, or `None` if they are not identifiable from these residuals (a
    /// singular `J'J`).
    pub fn shared_inverse(&self, free: &[usize]) -> Option<Vec<f64>> {
        let k = free.len();
        let (schur, _, _) = self.reduced(free, 0.0)?;
        let mut inv = vec![0.0; k * k];
        for c in 0..k {
            let e: Vec<f64> = (0..k).map(|i| if i == c { 1.0 } else { 0.0 }).collect();
            let col = solve_spd(&schur, &e, k)?;
            for (i, v) in col.into_iter().enumerate() {
                inv[i * k + c] = v;
            }
        }
        Some(inv)
    }
}

/// The Cholesky factor of the symmetric positive definite `a` (row-major `n x n`, lower
/// triangle), or `None` if it is not positive definite.
fn cholesky(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = a[i * n + j] - (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum::<f64>();
            if i == j {
                if s.is_nan() || s <= 0.0 || s.is_infinite() {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// The solution of `L L' x = b` for the Cholesky factor `l`.
fn solve_factored(l: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    let mut y = vec![0.0; n];
    for i in 0..n {
        y[i] = (b[i] - (0..i).map(|k| l[i * n + k] * y[k]).sum::<f64>()) / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        x[i] = (y[i] - (i + 1..n).map(|k| l[k * n + i] * x[k]).sum::<f64>()) / l[i * n + i];
    }
    x
}

/// The solution of `a x = b` for a symmetric positive definite `a`.
pub fn solve_spd(a: &[f64], b: &[f64], n: usize) -> Option<Vec<f64>> {
    Some(solve_factored(&cholesky(a, n)?, b, n))
}

#[cfg(test)]
mod tests;
