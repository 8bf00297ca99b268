//! Levenberg-Marquardt least squares with a finite-difference Jacobian and box bounds:
//! K. Levenberg, "A method for the solution of certain non-linear problems in least
//! squares", Quarterly of Applied Mathematics 2 (1944); D. W. Marquardt, "An algorithm for
//! least-squares estimation of nonlinear parameters", SIAM Journal on Applied Mathematics
//! 11 (1963). Each step solves `(J'J + lambda diag(J'J)) delta = -J'r` (Marquardt's scaling,
//! which makes the step independent of the parameters' units), is clipped to the bounds,
//! and is kept only if it lowers the sum of squares; `lambda` shrinks after a kept step and
//! grows after a refused one.

use std::ops::Range;

/// Fills block `b`'s residuals at a point: `eval(x, b, out)`.
pub type Residuals<'a> = &'a dyn Fn(&[f64], usize, &mut [f64]);

/// A least-squares problem whose residuals come in blocks, each depending on some of the
/// parameters: `eval(x, b, out)` fills block `b`'s residuals. A finite-difference column
/// re-evaluates only the blocks its parameter enters.
pub struct Problem<'a> {
    /// Block `b`'s residuals at a point.
    pub eval: Residuals<'a>,
    /// Each block's rows among the residuals, in order and contiguous from 0.
    pub rows: Vec<Range<usize>>,
    /// The blocks each parameter enters.
    pub enters: Vec<Vec<usize>>,
    /// The lowest value of each parameter.
    pub lower: Vec<f64>,
    /// The highest value of each parameter.
    pub upper: Vec<f64>,
    /// A typical size of each parameter, for the finite differences' steps.
    pub scale: Vec<f64>,
}

/// Where the iteration stopped.
#[derive(Clone, Debug)]
pub struct Solution {
    /// The parameters.
    pub x: Vec<f64>,
    /// The sum of squared residuals there.
    pub sse: f64,
    /// The Jacobian there, row-major `m x n`.
    pub jacobian: Vec<f64>,
}

/// The relative decrease of the sum of squares below which the iteration has converged:
/// far below what separates two fits statistically (a sum of `m` squared residuals of unit
/// variance scatters by `sqrt(2 m)`), and above the finite differences' noise.
const TOLERANCE: f64 = 1e-6;
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
        self.rows.last().map_or(0, |r| r.end)
    }

    fn clamp(&self, x: &mut [f64]) {
        for (i, v) in x.iter_mut().enumerate() {
            *v = v.clamp(self.lower[i], self.upper[i]);
        }
    }

    /// Every residual at `x`.
    pub fn residuals(&self, x: &[f64], out: &mut [f64]) {
        for (b, rows) in self.rows.iter().enumerate() {
            (self.eval)(x, b, &mut out[rows.clone()]);
        }
    }

    /// The forward-difference Jacobian at `x`, whose residuals are `r`; a step that would
    /// leave the bounds is taken the other way.
    pub fn jacobian(&self, x: &[f64], r: &[f64]) -> Vec<f64> {
        let (m, n) = (self.m(), x.len());
        let mut jac = vec![0.0; m * n];
        let mut probe = x.to_vec();
        let mut out = vec![0.0; m];
        for j in 0..n {
            let mut h = RELATIVE_STEP * x[j].abs().max(self.scale[j]);
            if x[j] + h > self.upper[j] {
                h = -h;
            }
            probe[j] = x[j] + h;
            for &b in &self.enters[j] {
                let rows = self.rows[b].clone();
                (self.eval)(&probe, b, &mut out[rows.clone()]);
                for i in rows {
                    jac[i * n + j] = (out[i] - r[i]) / h;
                }
            }
            probe[j] = x[j];
        }
        jac
    }

    /// Minimises the sum of squares from `x0` (clipped to the bounds), in at most
    /// `iterations` Jacobians.
    pub fn solve(&self, x0: &[f64], iterations: usize) -> Solution {
        let (m, n) = (self.m(), x0.len());
        let mut x = x0.to_vec();
        self.clamp(&mut x);
        let mut r = vec![0.0; m];
        self.residuals(&x, &mut r);
        let mut sse = sum_of_squares(&r);
        let mut lambda = 1e-3;
        let mut trial = vec![0.0; m];
        let mut jac = self.jacobian(&x, &r);
        for _ in 0..iterations {
            let (a, g) = normal_equations(&jac, &r, m, n);
            let minus_g: Vec<f64> = g.iter().map(|v| -v).collect();
            let mut improved = None;
            while lambda < 1e12 {
                let mut damped = a.clone();
                for i in 0..n {
                    damped[i * n + i] += lambda * a[i * n + i].max(1e-300);
                }
                if let Some(delta) = solve_spd(&damped, &minus_g, n) {
                    let mut next: Vec<f64> = x.iter().zip(&delta).map(|(x, d)| x + d).collect();
                    self.clamp(&mut next);
                    self.residuals(&next, &mut trial);
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
            let converged = sse - s <= TOLERANCE * sse;
            x = next;
            sse = s;
            std::mem::swap(&mut r, &mut trial);
            jac = self.jacobian(&x, &r);
            if converged {
                break;
            }
        }
        Solution {
            x,
            sse,
            jacobian: jac,
        }
    }
}

/// `J'J` (row-major `n x n`) and `J'r`.
fn normal_equations(jac: &[f64], r: &[f64], m: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut a = vec![0.0; n * n];
    let mut g = vec![0.0; n];
    for i in 0..m {
        let row = &jac[i * n..(i + 1) * n];
        for p in 0..n {
            g[p] += row[p] * r[i];
            for q in p..n {
                a[p * n + q] += row[p] * row[q];
            }
        }
    }
    for p in 0..n {
        for q in 0..p {
            a[p * n + q] = a[q * n + p];
        }
    }
    (a, g)
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

/// The solution of `a x = b` for a symmetric positive definite `a`.
pub fn solve_spd(a: &[f64], b: &[f64], n: usize) -> Option<Vec<f64>> {
    let l = cholesky(a, n)?;
    let mut y = vec![0.0; n];
    for i in 0..n {
        y[i] = (b[i] - (0..i).map(|k| l[i * n + k] * y[k]).sum::<f64>()) / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        x[i] = (y[i] - (i + 1..n).map(|k| l[k * n + i] * x[k]).sum::<f64>()) / l[i * n + i];
    }
    Some(x)
}

/// `(J'J)^-1` over the parameters `free` selects (the others held where they are), row-major
/// over the selected ones, or `None` if they are not identifiable from these residuals (a
/// singular `J'J`).
pub fn inverse_normal(jac: &[f64], m: usize, n: usize, free: &[usize]) -> Option<Vec<f64>> {
    let k = free.len();
    let sub: Vec<f64> = (0..m)
        .flat_map(|i| free.iter().map(move |&j| jac[i * n + j]))
        .collect();
    let (a, _) = normal_equations(&sub, &vec![0.0; m], m, k);
    let mut inv = vec![0.0; k * k];
    for c in 0..k {
        let e: Vec<f64> = (0..k).map(|i| if i == c { 1.0 } else { 0.0 }).collect();
        let col = solve_spd(&a, &e, k)?;
        for (i, v) in col.into_iter().enumerate() {
            inv[i * k + c] = v;
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A problem with a known answer: the exponential decay `a exp(-b t) + c` through
    /// points made from `a = 2, b = 0.7, c = -0.3`, found from a start far off, and the
    /// inverse normal matrix against the one written out for a straight line.
    #[test]
    fn finds_a_known_minimum_and_inverts_the_normal_matrix() {
        let t: Vec<f64> = (0..40).map(|i| f64::from(i) * 0.1).collect();
        // Two blocks, the first half of the points and the second, both depending on all
        // three parameters.
        let f = |x: &[f64], b: usize, out: &mut [f64]| {
            for (o, t) in out.iter_mut().zip(&t[b * 20..]) {
                *o = x[0] * (-x[1] * t).exp() + x[2] - (2.0 * (-0.7 * t).exp() - 0.3);
            }
        };
        let p = Problem {
            eval: &f,
            rows: vec![0..20, 20..40],
            enters: vec![vec![0, 1]; 3],
            lower: vec![-10.0, 0.0, -10.0],
            upper: vec![10.0, 10.0, 10.0],
            scale: vec![1.0; 3],
        };
        let s = p.solve(&[0.5, 3.0, 1.0], 100);
        for (got, want) in s.x.iter().zip([2.0, 0.7, -0.3]) {
            assert!((got - want).abs() < 1e-6, "{:?}", s.x);
        }
        // A bound holds the answer at the bound.
        let bounded = Problem {
            lower: vec![-10.0, 0.0, 0.0],
            ..p
        };
        assert_eq!(bounded.solve(&[0.5, 3.0, 1.0], 100).x[2], 0.0);

        // For residuals x0 + x1 t_i, J'J = [[n, sum t], [sum t, sum t^2]], whose inverse is
        // [[sum t^2, -sum t], [-sum t, n]] / (n sum t^2 - (sum t)^2).
        let jac: Vec<f64> = t.iter().flat_map(|&t| [1.0, t]).collect();
        let inv = inverse_normal(&jac, t.len(), 2, &[0, 1]).unwrap();
        let (n, st, stt) = (
            t.len() as f64,
            t.iter().sum::<f64>(),
            t.iter().map(|t| t * t).sum::<f64>(),
        );
        let det = n * stt - st * st;
        for (got, want) in inv.iter().zip([stt / det, -st / det, -st / det, n / det]) {
            assert!((got - want).abs() < 1e-12 * want.abs().max(1.0), "{inv:?}");
        }
        // A parameter the residuals do not depend on is not identifiable.
        assert!(inverse_normal(&[1.0, 0.0, 2.0, 0.0], 2, 2, &[0, 1]).is_none());
    }
}
