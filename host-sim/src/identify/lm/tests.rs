use super::*;

/// A problem with a known answer: the exponential decay `a exp(-b t) + c` through points
/// made from `a = 2, b = 0.7, c = -0.3`, found from a start far off, in two blocks (the
/// first half of the points and the second) that both depend on all three parameters and
/// have none of their own.
#[test]
fn finds_a_known_minimum() {
    let t: Vec<f64> = (0..40).map(|i| f64::from(i) * 0.1).collect();
    let f = |x: &[f64], b: usize, out: &mut [f64]| {
        for (o, t) in out.iter_mut().zip(&t[b * 20..]) {
            *o = x[0] * (-x[1] * t).exp() + x[2] - (2.0 * (-0.7 * t).exp() - 0.3);
        }
    };
    let block = |rows: Range<usize>| Block {
        rows,
        shared: vec![0, 1, 2],
        own: 3..3,
    };
    let p = Problem {
        eval: &f,
        shared: 3,
        blocks: vec![block(0..20), block(20..40)],
        lower: vec![-10.0, 0.0, -10.0],
        upper: vec![10.0, 10.0, 10.0],
        scale: vec![1.0; 3],
    };
    let s = p.solve(&[0.5, 3.0, 1.0], 100);
    for (got, want) in s.x.iter().zip([2.0, 0.7, -0.3]) {
        assert!((got - want).abs() < 1e-6, "{:?}", s.x);
    }
    // Every evaluation counted: at least the first residuals and one Jacobian's 3 columns.
    assert!(s.evaluated >= 4 * 40, "{}", s.evaluated);
    assert_eq!(s.evaluated % 20, 0, "whole blocks only");
    // A bound holds the answer at the bound.
    let bounded = Problem {
        lower: vec![-10.0, 0.0, 0.0],
        ..p
    };
    assert_eq!(bounded.solve(&[0.5, 3.0, 1.0], 100).x[2], 0.0);
}

/// Sums over `t` of 1, t and t^2.
fn moments(t: &[f64]) -> [f64; 3] {
    [
        t.len() as f64,
        t.iter().sum(),
        t.iter().map(|t| t * t).sum(),
    ]
}

/// The least-squares intercept and slopes of lines `a + b_k t` through the blocks' points
/// `t[k]` at heights `y(k, t, i)`: with each slope at its best for a given intercept,
/// `b_k = (S_ty - a S1) / S2`, the intercept solves the reduced equation
/// `a sum_k (n - S1^2 / S2) = sum_k (S_y - S1 S_ty / S2)`.
fn by_hand(t: &[Vec<f64>], y: impl Fn(usize, f64, usize) -> f64) -> (f64, Vec<f64>) {
    let (mut num, mut den, mut sums) = (0.0, 0.0, Vec::new());
    for (k, t) in t.iter().enumerate() {
        let [n, s1, s2] = moments(t);
        let ys: Vec<f64> = t.iter().enumerate().map(|(i, &t)| y(k, t, i)).collect();
        let (sy, sty): (f64, f64) = (ys.iter().sum(), t.iter().zip(&ys).map(|(t, y)| t * y).sum());
        num += sy - s1 * sty / s2;
        den += n - s1 * s1 / s2;
        sums.push((sty, s1, s2));
    }
    let intercept = num / den;
    let slopes = sums
        .into_iter()
        .map(|(sty, s1, s2)| (sty - intercept * s1) / s2)
        .collect();
    (intercept, slopes)
}

/// Straight lines `a + b_k t` through two blocks of points, the intercept `a` shared, each
/// block's slope `b_k` its own: the least-squares answer found exactly, and the shared
/// intercept's inverse normal element against the one written out by hand. For a line
/// through the origin's points `t`, eliminating the slope from `J'J = [[n, S1], [S1, S2]]`
/// leaves `n - S1^2 / S2`; the blocks add, and the element is the inverse of the sum.
#[test]
fn own_parameters_are_eliminated_exactly() {
    let t = [
        vec![0.0, 0.5, 1.0, 1.5, 2.0],
        vec![-1.0, 0.3, 0.9, 2.2, 3.1, 4.0, 4.4],
    ];
    let (a, b) = (0.5, [2.0, -1.0]);
    let noise = [0.01, -0.02, 0.015, 0.0, -0.01, 0.02, 0.005];
    let f = |x: &[f64], k: usize, out: &mut [f64]| {
        for (i, (o, t)) in out.iter_mut().zip(&t[k]).enumerate() {
            *o = x[0] + x[1 + k] * t - (a + b[k] * t + noise[i]);
        }
    };
    let p = Problem {
        eval: &f,
        shared: 1,
        blocks: vec![
            Block {
                rows: 0..5,
                shared: vec![0],
                own: 1..2,
            },
            Block {
                rows: 5..12,
                shared: vec![0],
                own: 2..3,
            },
        ],
        lower: vec![-10.0; 3],
        upper: vec![10.0; 3],
        scale: vec![1.0; 3],
    };
    let s = p.solve(&[0.0, 0.0, 0.0], 100);
    let reduced: f64 = t
        .iter()
        .map(|t| {
            let [n, s1, s2] = moments(t);
            n - s1 * s1 / s2
        })
        .sum();
    let inv = s.normal.shared_inverse(&[0]).unwrap();
    assert!(
        (inv[0] * reduced - 1.0).abs() < 1e-6,
        "{inv:?} against {}",
        1.0 / reduced
    );
    // The normal equations' solution by hand.
    let (intercept, slopes) = by_hand(&t, |k, t, i| a + b[k] * t + noise[i]);
    assert!(
        (s.x[0] - intercept).abs() < 1e-6,
        "{:?} against {intercept}",
        s.x
    );
    for (k, slope) in slopes.into_iter().enumerate() {
        assert!(
            (s.x[1 + k] - slope).abs() < 1e-6,
            "{:?}: slope {k} {slope}",
            s.x
        );
    }
    // A block's own parameter its residuals do not depend on is not identifiable.
    let flat = |x: &[f64], _: usize, out: &mut [f64]| out.fill(x[0] - 1.0);
    let singular = Problem { eval: &flat, ..p };
    let s = singular.solve(&[0.0, 0.0, 0.0], 10);
    assert!(s.normal.shared_inverse(&[0]).is_none());
}
