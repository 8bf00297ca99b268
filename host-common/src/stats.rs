//! The project's one convention for uncertainty, used by every table it prints:
//!
//! - a **mean** comes with the half-width of its two-sided 95% Student-t interval,
//!   `t(0.975, n - 1) * s / sqrt(n)` with `s` the sample standard deviation ([`Estimate`]);
//! - a **proportion** (success rates, seeds that converge) comes with Wilson's 95% score
//!   interval ([`wilson`]), which stays honest at 0% and 100%, where the normal
//!   approximation collapses to a point.
//!
//! The t quantile is computed (by inverting the t distribution's CDF through the regularised
//! incomplete beta function), not looked up, so every n gets its own.

use serde::Serialize;

/// A sample mean and the half-width of its 95% Student-t interval (NaN for fewer than two
/// values, where there is no interval).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Estimate {
    /// Sample mean.
    pub mean: f64,
    /// Half-width of the 95% interval.
    pub ci95: f64,
}

impl Estimate {
    /// Mean and 95% half-width of `values`; NaN mean for none.
    pub fn of(values: &[f64]) -> Estimate {
        Estimate::of_each(values.len(), |i| values[i])
    }

    /// [`Estimate::of`] the `n` values `value(0)` to `value(n - 1)`, bit for bit, each
    /// computed where it is summed (twice) rather than kept: a figure of ten million
    /// episodes holds no list of them.
    pub fn of_each(n: usize, value: impl Fn(usize) -> f64) -> Estimate {
        let values = || (0..n).map(&value);
        let mean = mean_of(n, values());
        let ci95 = if n < 2 {
            f64::NAN
        } else {
            t975(n - 1) * sd_about(n, mean, values()) / (n as f64).sqrt()
        };
        Estimate { mean, ci95 }
    }

    /// `"m ± h"` with `p` decimals, or just `"m"` when there is no interval.
    pub fn show(&self, p: usize) -> String {
        if self.ci95.is_finite() {
            format!("{:.p$} ± {:.p$}", self.mean, self.ci95)
        } else {
            format!("{:.p$}", self.mean)
        }
    }
}

/// Arithmetic mean; NaN for no values.
pub fn mean(v: &[f64]) -> f64 {
    mean_of(v.len(), v.iter().copied())
}

/// The mean of the `n` values `v` yields, summed in order; NaN for none.
fn mean_of(n: usize, v: impl Iterator<Item = f64>) -> f64 {
    if n == 0 {
        return f64::NAN;
    }
    v.sum::<f64>() / n as f64
}

/// Sample standard deviation (n - 1 in the denominator); NaN for fewer than two values.
pub fn sd(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return f64::NAN;
    }
    sd_about(v.len(), mean(v), v.iter().copied())
}

/// The sample standard deviation of the `n >= 2` values `v` yields, whose mean is `m`.
fn sd_about(n: usize, m: f64, v: impl Iterator<Item = f64>) -> f64 {
    (v.map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
}

/// The median (the mean of the two middle values for an even count); NaN for none.
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n == 0 {
        f64::NAN
    } else {
        (s[(n - 1) / 2] + s[n / 2]) / 2.0
    }
}

/// Student's t 0.975 quantile with `df >= 1` degrees of freedom: the `t` with
/// `P(T <= t) = 0.975`, found by bisection on the CDF to the last bits of an f64.
pub fn t975(df: usize) -> f64 {
    let d = df.max(1) as f64;
    // P(|T| > t) = I_{d / (d + t^2)}(d / 2, 1 / 2); find where it is 0.05.
    let tail = |t: f64| beta_inc(d / 2.0, 0.5, d / (d + t * t));
    let (mut lo, mut hi) = (0.0f64, 1.0e3);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid == lo || mid == hi {
            break;
        }
        if tail(mid) > 0.05 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The regularised incomplete beta function `I_x(a, b)`, by its continued fraction
/// (modified Lentz), using the symmetry `I_x(a, b) = 1 - I_{1-x}(b, a)` where it converges
/// faster.
fn beta_inc(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front =
        libm::lgamma(a + b) - libm::lgamma(a) - libm::lgamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * beta_fraction(a, b, x) / a
    } else {
        1.0 - ln_front.exp() * beta_fraction(b, a, 1.0 - x) / b
    }
}

fn beta_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..500 {
        let m = f64::from(m);
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        for (num, last) in [
            (aa, false),
            (-(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)), true),
        ] {
            d = 1.0 + num * d;
            if d.abs() < TINY {
                d = TINY;
            }
            c = 1.0 + num / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let step = d * c;
            h *= step;
            if last && (step - 1.0).abs() < 1e-16 {
                return h;
            }
        }
    }
    h
}

/// Wilson's 95% score interval `[lower, upper]` for `k` successes in `n` trials.
pub fn wilson(k: usize, n: usize) -> [f64; 2] {
    if n == 0 {
        return [0.0, 1.0];
    }
    let (k, n, z) = (k as f64, n as f64, Z975);
    let p = k / n;
    let denom = 1.0 + z * z / n;
    let centre = (p + z * z / (2.0 * n)) / denom;
    let half = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt() / denom;
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

/// The standard normal's 0.975 quantile.
pub const Z975: f64 = 1.959_963_984_540_054;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_match_published_tables() {
        // Student t 0.975 (e.g. NIST/SEMATECH e-Handbook, table 1.4.2.7.2).
        for (df, want) in [
            (1, 12.706),
            (2, 4.303),
            (4, 2.776),
            (9, 2.262),
            (19, 2.093),
            (30, 2.042),
            (100, 1.984),
        ] {
            assert!((t975(df) - want).abs() < 5e-4, "df {df}: {}", t975(df));
        }
        // And tends to the normal quantile.
        assert!((t975(1_000_000) - Z975).abs() < 1e-5);
    }

    #[test]
    fn the_incomplete_beta_has_its_closed_forms() {
        // I_x(1, 1) = x; I_x(a, 1) = x^a; I_x(1, b) = 1 - (1 - x)^b.
        for x in [0.1, 0.5, 0.93] {
            assert!((beta_inc(1.0, 1.0, x) - x).abs() < 1e-14);
            assert!((beta_inc(3.0, 1.0, x) - x.powi(3)).abs() < 1e-14);
            assert!((beta_inc(1.0, 2.5, x) - (1.0 - (1.0 - x).powf(2.5))).abs() < 1e-14);
        }
    }

    #[test]
    fn estimates_use_student_t() {
        let e = Estimate::of(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(e.mean, 2.5);
        // s = sqrt(5/3), t(0.975, 3) = 3.182446.
        assert!((e.ci95 - 3.182_446_3 * (5.0f64 / 3.0).sqrt() / 2.0).abs() < 1e-6);
        assert!(Estimate::of(&[1.0]).ci95.is_nan());
        assert_eq!(Estimate::of(&[1.0]).show(1), "1.0");
        assert_eq!(median(&[3.0, 1.0, 2.0, 10.0]), 2.5);
    }

    #[test]
    fn wilson_matches_hand_computed_values() {
        // 1000 of 1000: upper 1, lower n / (n + z^2).
        let [lo, hi] = wilson(1000, 1000);
        assert!((lo - 1000.0 / (1000.0 + Z975 * Z975)).abs() < 1e-12 && hi == 1.0);
        // 50 of 100: centre 0.5, half-width z sqrt(0.0025 + z^2/40000) / (1 + z^2/100).
        let [lo, hi] = wilson(50, 100);
        let z = Z975;
        let half = z * (0.0025f64 + z * z / 40_000.0).sqrt() / (1.0 + z * z / 100.0);
        assert!((lo - (0.5 - half)).abs() < 1e-12 && (hi - (0.5 + half)).abs() < 1e-12);
    }
}
