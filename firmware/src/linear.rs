//! The plant linearised about the upright equilibrium, and the two designs made on it: the
//! LQR state feedback the simulator compares the policy with, and the steady-state Kalman
//! gain of the encoder [`Observer`](crate::estimator::Observer).
//!
//! Both gains solve a discrete algebraic Riccati equation by iterating its map from a
//! positive start until no entry moves by more than 1e-12 of the largest; the iterations converge
//! because the linearised plant is controllable from the motor and observable from the two
//! encoders. Everything is f64 (software on a Cortex-M4F): a board computes its gains once,
//! at start-up, or takes them from the host.

// 4x4 matrix algebra reads as the textbook formulas with explicit indices.
#![allow(clippy::needless_range_loop)]

use crate::cartpole::Params;

/// A 4x4 matrix over the state `[x, x_dot, theta, theta_dot]`, rows first.
pub type Mat = [[f64; 4]; 4];
/// A 4-vector over the state.
pub type Vec4 = [f64; 4];

/// The Euler-discretised linearisation of the plant about the upright equilibrium:
/// `s' = A s + B F` with `s = [x, x_dot, theta, theta_dot]` and `F` a force on the cart in
/// newtons (the motor's, or any other).
///
/// The plant's equations ([`crate::cartpole::Plant::derivative`]) at `theta = theta_dot = 0`
/// give, with `M = masscart + masspole`, `m l = masspole * length` and
/// `d = length * (4/3 - masspole / M)`: `theta_acc = (g theta - F / M - mu_p theta_dot /
/// (m l)) / d` and `x_acc = F / M - (m l / M) theta_acc`, where the motor's force loses
/// `motor_damping * x_dot` and `mu_p` is the pivot's viscous friction; the cart's Coulomb
/// friction has no derivative at rest and is left out. The Euler step then adds `tau` times
/// the derivative to each state.
pub fn linearise(p: &Params) -> (Mat, Vec4) {
    let m = p.total_mass();
    let d = p.length * (4.0 / 3.0 - p.masspole / m);
    let ml_m = p.polemass_length() / m;
    // Continuous-time: d/dt s = Ac s + Bc F.
    let mut ac = [[0.0; 4]; 4];
    let mut bc = [0.0; 4];
    ac[0][1] = 1.0;
    ac[2][3] = 1.0;
    ac[3][2] = p.gravity / d;
    bc[3] = -1.0 / (m * d);
    ac[1][2] = -ml_m * p.gravity / d;
    bc[1] = 1.0 / m + ml_m / (m * d);
    // The motor's damping is a force against x_dot; the pivot's friction a torque against
    // theta_dot, which the cart feels through the pole.
    for i in [1, 3] {
        ac[i][1] -= p.motor_damping * bc[i];
    }
    ac[3][3] -= p.pole_friction / (p.polemass_length() * d);
    ac[1][3] -= ml_m * ac[3][3];
    let mut a = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            a[i][j] = f64::from(u8::from(i == j)) + p.tau * ac[i][j];
        }
    }
    (a, bc.map(|b| p.tau * b))
}

/// The LQR gain `K` (`u = -K s`) for state weight `q` (diagonal) and input weight `r`,
/// from `P = Q + A'PA - A'PB (R + B'PB)^-1 B'PA`, iterated from `P = Q`.
pub fn lqr_gain(p: &Params, q: Vec4, r: f64) -> Vec4 {
    let (a, b) = linearise(p);
    let pm = solve(diag(q), |pm| riccati_step(&a, &b, pm, q, r));
    gain(&a, &b, &pm, r)
}

/// The LQR that balances: `Q = I`, `R = 1` on `p`'s plant. The simulator's LQR baseline and
/// the runtime monitor's fallback ([`crate::controller::monitor`]) both use it.
pub fn balance_gain(p: &Params) -> Vec4 {
    lqr_gain(p, [1.0; 4], 1.0)
}

/// One application of the control Riccati map to `p`.
fn riccati_step(a: &Mat, b: &Vec4, p: &Mat, q: Vec4, r: f64) -> Mat {
    let k = gain(a, b, p, r);
    let bpa = vec_mat(&vec_mat(b, p), a);
    let pa = mat_mul(p, a);
    let mut next = diag(q);
    for i in 0..4 {
        for j in 0..4 {
            let apa: f64 = (0..4).map(|k| a[k][i] * pa[k][j]).sum();
            next[i][j] += apa - bpa[i] * k[j];
        }
    }
    symmetrise(next)
}

/// The steady-state Kalman gain `L` (4 x 2) of an observer that measures `x` and `theta`
/// with noise variances `r` and updates `s = s_pred + L (y - C s_pred)` once per period,
/// for process noise covariance `q` (per period). From the filter's Riccati map on the
/// predicted covariance, `P' = A (P - P C' S^-1 C P) A' + Q` with `S = C P C' + R`,
/// iterated from `P = Q`; then `L = P C' S^-1`.
pub fn kalman_gain(a: &Mat, q: &Mat, r: [f64; 2]) -> [[f64; 2]; 4] {
    let pm = solve(*q, |pm| filter_step(a, pm, q, r));
    kalman_of(pm, r)
}

/// One application of the filter Riccati map to the predicted covariance `p`.
fn filter_step(a: &Mat, p: &Mat, q: &Mat, r: [f64; 2]) -> Mat {
    let l = kalman_of(*p, r);
    // The updated covariance `P - L C P`, where `C P` is rows 0 and 2 of `P`.
    let mut upd = *p;
    for i in 0..4 {
        for j in 0..4 {
            upd[i][j] -= l[i][0] * p[0][j] + l[i][1] * p[2][j];
        }
    }
    let mut next = mat_mul(&mat_mul(a, &upd), &transpose(a));
    for i in 0..4 {
        for j in 0..4 {
            next[i][j] += q[i][j];
        }
    }
    symmetrise(next)
}

/// `L = P C' (C P C' + R)^-1` for `C` selecting `x` and `theta`.
fn kalman_of(p: Mat, r: [f64; 2]) -> [[f64; 2]; 4] {
    let s = [[p[0][0] + r[0], p[0][2]], [p[2][0], p[2][2] + r[1]]];
    let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
    let inv = [
        [s[1][1] / det, -s[0][1] / det],
        [-s[1][0] / det, s[0][0] / det],
    ];
    let mut l = [[0.0; 2]; 4];
    for i in 0..4 {
        for j in 0..2 {
            l[i][j] = p[i][0] * inv[0][j] + p[i][2] * inv[1][j];
        }
    }
    l
}

/// Iterates `step` from `start` until no entry moves by more than 1e-12 of the largest
/// entry (at most a million times), or until an entry is no longer finite: from there it
/// would spin through every iteration on NaN, and the caller refuses a non-finite gain. Relative to the whole matrix, not to each entry: a
/// covariance's entries span many orders of magnitude (1e-9 m^2 beside 1 rad^2/s^2), and
/// one near zero may keep moving in digits that do not matter.
fn solve(start: Mat, step: impl Fn(&Mat) -> Mat) -> Mat {
    let mut pm = start;
    for _ in 0..1_000_000 {
        let next = step(&pm);
        if !next.iter().flatten().all(|v| v.is_finite()) {
            return next;
        }
        let (mut delta, mut scale): (f64, f64) = (0.0, 0.0);
        for i in 0..4 {
            for j in 0..4 {
                delta = delta.max((next[i][j] - pm[i][j]).abs());
                scale = scale.max(next[i][j].abs());
            }
        }
        pm = next;
        if delta <= 1e-12 * scale {
            break;
        }
    }
    pm
}

/// The exact maps keep `P` symmetric; rounding does not, and the open loop's unstable mode
/// amplifies the asymmetric part until the iteration diverges, so restore symmetry.
fn symmetrise(mut m: Mat) -> Mat {
    for i in 0..4 {
        for j in 0..i {
            let v = 0.5 * (m[i][j] + m[j][i]);
            m[i][j] = v;
            m[j][i] = v;
        }
    }
    m
}

/// A diagonal matrix.
fn diag(q: Vec4) -> Mat {
    let mut m = [[0.0; 4]; 4];
    for i in 0..4 {
        m[i][i] = q[i];
    }
    m
}

fn mat_mul(a: &Mat, b: &Mat) -> Mat {
    let mut c = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            c[i][j] = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

fn transpose(a: &Mat) -> Mat {
    let mut t = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            t[i][j] = a[j][i];
        }
    }
    t
}

fn vec_mat(v: &Vec4, m: &Mat) -> Vec4 {
    let mut out = [0.0; 4];
    for (vi, row) in v.iter().zip(m) {
        for (o, mij) in out.iter_mut().zip(row) {
            *o += vi * mij;
        }
    }
    out
}

/// `a . b`.
pub fn dot(a: &Vec4, b: &Vec4) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `K = (R + B'PB)^-1 B'PA`, a row vector because there is one input.
fn gain(a: &Mat, b: &Vec4, p: &Mat, r: f64) -> Vec4 {
    let bp = vec_mat(b, p);
    let bpa = vec_mat(&bp, a);
    let s = r + dot(&bp, b);
    bpa.map(|v| v / s)
}

#[cfg(test)]
pub(crate) mod tests;
