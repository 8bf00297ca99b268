use super::*;
use crate::cartpole::{State, advance};

/// scipy.linalg.solve_discrete_are (a Schur-method solver, independent of the iteration
/// here) on the same A, B with Q = I, R = 1: `K = solve(R + B'PB, B'PA)`.
const SCIPY_K: Vec4 = [
    -0.910_126_381_505_224_6,
    -2.132_488_024_878_001_4,
    -30.594_562_996_749_527,
    -7.841_505_511_170_651,
];

/// The filter's gain from scipy 1.17's `solve_discrete_are(A.T, C.T, Q, R)` (the dual
/// equation), then `L = P C' (C P C' + R)^-1`, for `Q = 25 B B' + diag(0, (2 tau)^2, 0,
/// (4 tau)^2)` and `R` the quantisation variances of 20,480 counts per metre and 4,096 per
/// revolution.
pub(crate) const SCIPY_L: [[f64; 2]; 4] = [
    [0.999_887_734_712_334_8, -5.265_692_462_437_351e-5],
    [49.982_312_594_476_94, -0.008_559_685_986_956_654],
    [-0.051_970_301_502_234_29, 0.959_519_034_329_048_1],
    [-7.360_876_922_851_586, 44.266_047_266_843_92],
];

/// `m v`.
fn mat_vec(m: &Mat, v: &Vec4) -> Vec4 {
    m.map(|row| row.iter().zip(v).map(|(a, b)| a * b).sum())
}

fn closed_loop(p: &Params, k: &Vec4) -> Mat {
    let (a, b) = linearise(p);
    let mut m = a;
    for i in 0..4 {
        for j in 0..4 {
            m[i][j] -= b[i] * k[j];
        }
    }
    m
}

/// Largest `|s_n| / |s_0|` over `n` steps of a linear map from each unit vector.
fn growth(m: &Mat, steps: usize) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..4 {
        let mut v = [0.0; 4];
        v[i] = 1.0;
        for _ in 0..steps {
            v = mat_vec(m, &v);
        }
        worst = worst.max(libm::sqrt(dot(&v, &v)));
    }
    worst
}

#[test]
fn lqr_gain_matches_scipy() {
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
    assert!(growth(&closed_loop(&p, &k), 1_000) < 1e-3);
    // The open loop is unstable: the pole falls.
    assert!(growth(&a, 200) > 10.0);
}

/// The linearisation of `p` against central differences of the plant's own step, at
/// upright and at rest, duty off.
fn check_against_finite_differences(p: &Params) {
    let (a, b) = linearise(p);
    let step =
        |s: [f64; 4], external: f64| advance(p, &State::from_array(s), 0.0, external).to_array();
    let h = 1e-6;
    for j in 0..4 {
        let (mut plus, mut minus) = ([0.0; 4], [0.0; 4]);
        plus[j] = h;
        minus[j] = -h;
        let (sp, sm) = (step(plus, 0.0), step(minus, 0.0));
        for i in 0..4 {
            let fd = (sp[i] - sm[i]) / (2.0 * h);
            assert!(
                (fd - a[i][j]).abs() < 1e-6,
                "{p:?}: A[{i}][{j}] {fd} vs {}",
                a[i][j]
            );
        }
    }
    let (sp, sm) = (step([0.0; 4], 1.0), step([0.0; 4], -1.0));
    for i in 0..4 {
        let fd = (sp[i] - sm[i]) / 2.0;
        assert!((fd - b[i]).abs() < 1e-12, "{p:?}: B[{i}] {fd} vs {}", b[i]);
    }
}

#[test]
fn linearisation_matches_finite_differences_of_the_plant() {
    check_against_finite_differences(&Params::default());
    // A desk rig's motor and pivot, at 100 Hz.
    check_against_finite_differences(&Params {
        masscart: 0.6,
        masspole: 0.08,
        length: 0.22,
        force_mag: 5.0,
        motor_damping: 3.0,
        pole_friction: 0.002,
        tau: 0.01,
        ..Params::default()
    });
}

#[test]
fn kalman_gain_matches_scipy_and_its_observer_is_stable() {
    let p = Params::default();
    let (a, b) = linearise(&p);
    let t = p.tau;
    let mut q = diag([0.0, (2.0 * t) * (2.0 * t), 0.0, (4.0 * t) * (4.0 * t)]);
    for i in 0..4 {
        for j in 0..4 {
            q[i][j] += 25.0 * b[i] * b[j];
        }
    }
    let count = |per: f64| (1.0 / per) * (1.0 / per) / 12.0;
    let r = [
        count(20_480.0),
        count(4_096.0 / (2.0 * core::f64::consts::PI)),
    ];
    let l = kalman_gain(&a, &q, r);
    for (row, want) in l.iter().zip(SCIPY_L) {
        for (g, w) in row.iter().zip(want) {
            assert!((g - w).abs() < 1e-9 * w.abs(), "{l:?} vs {SCIPY_L:?}");
        }
    }
    // The estimation error evolves as e' = (I - L C) A e: it must decay.
    let mut err = a;
    for i in 0..4 {
        for j in 0..4 {
            err[i][j] -= l[i][0] * a[0][j] + l[i][1] * a[2][j];
        }
    }
    assert!(growth(&err, 500) < 1e-6, "{}", growth(&err, 500));
}
