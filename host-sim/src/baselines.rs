//! Reference controllers to put the learned policy in context: discrete LQR, a hand-written
//! angle rule and coin flips.
//!
//! Each is a [`Policy`], so it runs through the very same [`Controller`] (sanitising,
//! pin sequence, telemetry) as the network; only the scores differ. The plant's actuator is
//! bang-bang, so LQR acts by the sign of its continuous command `u = -K s`: push right when
//! `u > 0`.
//!
//! [`Controller`]: firmware::controller::Controller

// 4x4 matrix algebra reads as the textbook formulas with explicit indices.
#![allow(clippy::needless_range_loop)]

use firmware::cartpole::{Params, unit_f64};
use firmware::controller::Policy;
use rand_pcg::Pcg64Mcg;
use std::sync::OnceLock;

/// 4x4 and 4-vectors in f64, enough for the Riccati recursion.
type Mat = [[f64; 4]; 4];
type Vec4 = [f64; 4];

/// The Euler-discretised linearisation of the plant about the upright equilibrium:
/// `s' = A s + B F` with `s = [x, x_dot, theta, theta_dot]` and `F` the force in newtons.
///
/// Gymnasium's dynamics at `theta = theta_dot = 0` give, with `M = masscart + masspole`,
/// `m l = masspole * length` and `d = length * (4/3 - masspole / M)`:
/// `theta_acc = (g theta - F / M) / d` and `x_acc = F / M - (m l / M) theta_acc`;
/// the Euler step then adds `tau` times the derivative to each state.
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
    let mut a = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            a[i][j] = f64::from(u8::from(i == j)) + p.tau * ac[i][j];
        }
    }
    (a, bc.map(|b| p.tau * b))
}

/// The LQR gain `K` (`u = -K s`) for state weight `q` (diagonal) and input weight `r`,
/// from the discrete algebraic Riccati equation
/// `P = Q + A'PA - A'PB (R + B'PB)^-1 B'PA`, solved by iterating it from `P = Q` until no
/// entry moves by more than 1e-12 relative (it converges because `(A, B)` is controllable).
pub fn lqr_gain(p: &Params, q: Vec4, r: f64) -> Vec4 {
    let (a, b) = linearise(p);
    let mut pm = diag(q);
    for _ in 0..1_000_000 {
        let next = riccati_step(&a, &b, &pm, q, r);
        let delta = (0..16)
            .map(|k| (next[k / 4][k % 4] - pm[k / 4][k % 4]).abs() / (1.0 + pm[k / 4][k % 4].abs()))
            .fold(0.0, f64::max);
        pm = next;
        if delta < 1e-12 {
            break;
        }
    }
    gain(&a, &b, &pm, r)
}

fn diag(q: Vec4) -> Mat {
    let mut m = [[0.0; 4]; 4];
    for i in 0..4 {
        m[i][i] = q[i];
    }
    m
}

fn mat_vec(m: &Mat, v: &Vec4) -> Vec4 {
    m.map(|row| row.iter().zip(v).map(|(a, b)| a * b).sum())
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

fn dot(a: &Vec4, b: &Vec4) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `K = (R + B'PB)^-1 B'PA`, a row vector because there is one input.
fn gain(a: &Mat, b: &Vec4, p: &Mat, r: f64) -> Vec4 {
    let bp = vec_mat(b, p);
    let bpa = vec_mat(&bp, a);
    let s = r + dot(&bp, b);
    bpa.map(|v| v / s)
}

/// One application of the Riccati map to `p`.
pub fn riccati_step(a: &Mat, b: &Vec4, p: &Mat, q: Vec4, r: f64) -> Mat {
    let k = gain(a, b, p, r);
    let bpa = vec_mat(&vec_mat(b, p), a);
    let mut next = diag(q);
    let pa: Mat = {
        let mut m = [[0.0; 4]; 4];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..4).map(|k| p[i][k] * a[k][j]).sum();
            }
        }
        m
    };
    for i in 0..4 {
        for j in 0..4 {
            let apa: f64 = (0..4).map(|k| a[k][i] * pa[k][j]).sum();
            next[i][j] += apa - bpa[i] * k[j];
        }
    }
    // The exact map keeps P symmetric; rounding does not, and the open loop's unstable mode
    // amplifies the asymmetric part until the iteration diverges, so restore symmetry.
    for i in 0..4 {
        for j in 0..i {
            let m = 0.5 * (next[i][j] + next[j][i]);
            next[i][j] = m;
            next[j][i] = m;
        }
    }
    next
}

/// `A - B K`, the closed loop of the linear model.
pub fn closed_loop(p: &Params, k: &Vec4) -> Mat {
    let (a, b) = linearise(p);
    let mut m = a;
    for i in 0..4 {
        for j in 0..4 {
            m[i][j] -= b[i] * k[j];
        }
    }
    m
}

/// Largest `|s_n| / |s_0|` over `n` steps of a linear map from each unit vector; below 1 and
/// shrinking means the map is stable.
pub fn growth(m: &Mat, steps: usize) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..4 {
        let mut v = [0.0; 4];
        v[i] = 1.0;
        for _ in 0..steps {
            v = mat_vec(m, &v);
        }
        worst = worst.max(dot(&v, &v).sqrt());
    }
    worst
}

/// Bang-bang LQR: push right when `-K s > 0`. `K` comes from [`lqr_gain`] with the plant's
/// nominal parameters (the controller does not know a scenario's perturbed physics).
#[derive(Clone, Copy, Debug)]
pub struct Lqr {
    /// The gain, `u = -K s`.
    pub k: Vec4,
}

impl Lqr {
    /// `Q = I`, `R = 1` on the nominal plant (solved once per process).
    pub fn nominal() -> Lqr {
        static K: OnceLock<Vec4> = OnceLock::new();
        Lqr {
            k: *K.get_or_init(|| lqr_gain(&Params::default(), [1.0; 4], 1.0)),
        }
    }
}

impl Policy for Lqr {
    fn scores(&mut self, obs: &[f32; 4]) -> [f32; 2] {
        let s = obs.map(f64::from);
        [0.0, -dot(&self.k, &s) as f32]
    }
}

/// The classic hand rule: push towards where the pole is falling, `theta + 0.5 theta_dot`.
#[derive(Clone, Copy, Debug, Default)]
pub struct AngleRule;

impl Policy for AngleRule {
    fn scores(&mut self, obs: &[f32; 4]) -> [f32; 2] {
        [0.0, obs[2] + 0.5 * obs[3]]
    }
}

/// Left or right with equal probability, from a seeded stream.
#[derive(Clone, Debug)]
pub struct Random(pub Pcg64Mcg);

impl Policy for Random {
    fn scores(&mut self, _obs: &[f32; 4]) -> [f32; 2] {
        [0.5, unit_f64(&mut self.0) as f32]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// scipy.linalg.solve_discrete_are (a Schur-method solver, independent of the iteration
    /// here) on the same A, B with Q = I, R = 1: `K = solve(R + B'PB, B'PA)`.
    const SCIPY_K: Vec4 = [
        -0.910_126_381_505_224_6,
        -2.132_488_024_878_001_4,
        -30.594_562_996_749_527,
        -7.841_505_511_170_651,
    ];

    #[test]
    fn gain_matches_scipy() {
        let k = lqr_gain(&Params::default(), [1.0; 4], 1.0);
        for (a, b) in k.iter().zip(SCIPY_K) {
            assert!((a - b).abs() < 1e-8 * b.abs(), "{k:?} vs {SCIPY_K:?}");
        }
    }

    #[test]
    fn riccati_solution_is_a_fixed_point_and_stabilises() {
        let p = Params::default();
        let (a, b) = linearise(&p);
        let mut pm = diag([1.0; 4]);
        for _ in 0..20_000 {
            pm = riccati_step(&a, &b, &pm, [1.0; 4], 1.0);
        }
        let again = riccati_step(&a, &b, &pm, [1.0; 4], 1.0);
        for i in 0..4 {
            for j in 0..4 {
                assert!((again[i][j] - pm[i][j]).abs() < 1e-9 * (1.0 + pm[i][j].abs()));
            }
        }
        let k = lqr_gain(&p, [1.0; 4], 1.0);
        let cl = closed_loop(&p, &k);
        assert!(growth(&cl, 1_000) < 1e-3);
        // The open loop is unstable: the pole falls.
        assert!(growth(&a, 200) > 10.0);
    }

    #[test]
    fn linearisation_matches_finite_differences_of_the_plant() {
        let p = Params::default();
        let (a, b) = linearise(&p);
        let h = 1e-6;
        for j in 0..4 {
            let mut plus = [0.0; 4];
            let mut minus = [0.0; 4];
            plus[j] = h;
            minus[j] = -h;
            let sp = firmware::cartpole::step_with_force(&p, &State::from_array(plus), 0.0);
            let sm = firmware::cartpole::step_with_force(&p, &State::from_array(minus), 0.0);
            for i in 0..4 {
                let fd = (sp.to_array()[i] - sm.to_array()[i]) / (2.0 * h);
                assert!(
                    (fd - a[i][j]).abs() < 1e-6,
                    "A[{i}][{j}] {fd} vs {}",
                    a[i][j]
                );
            }
        }
        let sp = firmware::cartpole::step_with_force(&p, &State::default(), 1.0);
        let sm = firmware::cartpole::step_with_force(&p, &State::default(), -1.0);
        for i in 0..4 {
            let fd = (sp.to_array()[i] - sm.to_array()[i]) / 2.0;
            assert!((fd - b[i]).abs() < 1e-12, "B[{i}] {fd} vs {}", b[i]);
        }
    }

    #[test]
    fn rules_push_towards_the_fall() {
        let lean_right = [0.0, 0.0, 0.05, 0.1];
        let lean_left = lean_right.map(|v: f32| -v);
        let mut lqr = Lqr::nominal();
        assert!(lqr.scores(&lean_right)[1] > 0.0);
        assert!(lqr.scores(&lean_left)[1] < 0.0);
        assert!(AngleRule.scores(&lean_right)[1] > 0.0);
        assert!(AngleRule.scores(&lean_left)[1] < 0.0);
        assert_eq!(
            AngleRule.scores(&[0.0, 0.0, 0.1, -0.3])[1],
            0.1 + 0.5 * -0.3
        );
    }

    use firmware::cartpole::State;
}
