//! The pole's angle about upright, kept to one revolution: (-pi, pi], in radians, in counts
//! and in the alpha-beta filter's fixed point. Each leaves a value already in range as it is,
//! bit for bit.

use core::f32::consts::{PI, TAU};

/// `t` moved by whole turns into (-pi, pi]; NaN stays NaN.
pub(crate) fn angle(t: f32) -> f32 {
    if t > -PI && t <= PI {
        return t;
    }
    // `fmodf` is exact, and so is a difference of two floats within a factor of two, so
    // the result is `t` less a whole number of turns, rounded once at most.
    let r = libm::fmodf(t, TAU);
    if r > PI {
        r - TAU
    } else if r <= -PI {
        r + TAU
    } else {
        r
    }
}

/// The count `c` moved by whole revolutions of `per_rev` counts into the revolution whose
/// counts' midpoints lie in (-pi, pi]: `[-floor(n/2), ceil(n/2) - 1]`.
pub(crate) fn count(c: i64, per_rev: u32) -> i64 {
    // At least one: a zero resolution, refused at construction, cannot divide by zero here.
    let n = i64::from(per_rev.max(1));
    let lo = -(n / 2);
    lo + (c - lo).rem_euclid(n)
}

/// A fixed-point angle `p` (a revolution is `rev` units, `rev` even) moved by whole
/// revolutions into `(-rev/2, rev/2]`, wrapping rather than overflowing.
pub(crate) fn fixed(p: i64, rev: i64) -> i64 {
    let half = rev / 2;
    half.wrapping_sub(half.wrapping_sub(p).rem_euclid(rev.max(1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_in_range_are_untouched_and_others_move_by_whole_turns() {
        let above_minus_pi = f32::from_bits((-PI).to_bits() - 1);
        for t in [
            0.0f32,
            -0.0,
            1e-30,
            3.0,
            PI,
            above_minus_pi,
            f32::MIN_POSITIVE,
        ] {
            assert_eq!(angle(t).to_bits(), t.to_bits());
        }
        assert_eq!(angle(-PI), PI);
        assert_eq!(angle(TAU), 0.0);
        // Whole turns off exactly, in f64 (where these differences are exact).
        for (t, turns) in [
            (TAU + 0.25, 1.0),
            (3.0 * TAU - 0.5, 3.0),
            (-PI - 0.125, -1.0),
        ] {
            let want = f64::from(t) - turns * f64::from(TAU);
            assert_eq!(f64::from(angle(t)), want, "{t}");
        }
        for t in [4.0f32, -4.0, 100.0, -1e6, 1e30, f32::MAX, -f32::MAX] {
            let w = angle(t);
            assert!(w > -PI && w <= PI, "{t} -> {w}");
            // An f64 reference: the same angle, up to the f32 spacing of `t`.
            let turns = (f64::from(t) - f64::from(w)) / f64::from(TAU);
            let tol = f64::from(t).abs() * 1e-7 / f64::from(TAU) + 1e-6;
            assert!((turns - turns.round()).abs() <= tol, "{t} -> {w}: {turns}");
        }
        assert!(angle(f32::NAN).is_nan() && angle(f32::INFINITY).is_nan());
    }

    #[test]
    fn counts_fall_in_the_revolution_about_upright() {
        // 4 counts: midpoints at -3/4 pi, -1/4 pi, 1/4 pi, 3/4 pi are counts -2..=1.
        let got: [i64; 8] = core::array::from_fn(|k| count(k as i64 - 4, 4));
        assert_eq!(got, [0, 1, -2, -1, 0, 1, -2, -1]);
        // 5 counts: -2..=2.
        assert_eq!([count(3, 5), count(-3, 5), count(2, 5)], [-2, 2, 2]);
        assert_eq!(count(i64::from(i32::MAX) + 5, 4_096), 4);
        assert_eq!(count(7, 0), 0);
    }

    #[test]
    fn fixed_point_angles_fall_in_the_half_open_revolution() {
        let rev = 4 << 12;
        assert_eq!(
            [fixed(rev / 2, rev), fixed(-rev / 2, rev)],
            [rev / 2, rev / 2]
        );
        assert_eq!(
            [fixed(rev, rev), fixed(-rev - 1, rev), fixed(5, rev)],
            [0, -1, 5]
        );
        assert_eq!(fixed(i64::MIN, rev), 0);
        assert!(fixed(i64::MAX, rev).abs() <= rev / 2);
    }
}
