//! The model-free estimator: one alpha-beta filter per channel, in integers.
//!
//! Each channel predicts `p + v`, compares with the new count, and corrects the position by
//! `alpha` and the velocity by `beta` times the residual (a steady-state Kalman filter for a
//! constant-velocity model). Its single parameter, the discount `d` in `(0, 1)`, sets
//! `alpha = 1 - d^2` and `beta = (1 - d)^2` (the critically damped g-h filter): `d = 0`
//! trusts each count fully (velocity = plain backward difference), larger `d` smooths more
//! and lags more. It runs in integers: positions in counts and velocities in counts per
//! period, both with the fixed-point format's fraction bits ([`crate::fixed`]), gains as
//! Q15 fractions, so it costs the same on a core without an FPU, gives the same bits on
//! every target, and hands out the physical state in f32 ([`AlphaBeta::state`]), in the
//! integer network's Q3.12 ([`AlphaBeta::fixed_state`]) and its raw values
//! ([`AlphaBeta::raw`]).
//!
//! ```
//! use firmware::estimator::{AlphaBeta, Encoders};
//! let enc = Encoders { cart_counts_per_m: 10_000, pole_counts_per_rev: 4_096 };
//! let mut est = AlphaBeta::new(enc, 0.5, 0.02)?;
//! // The cart moves 1 cm (100 counts) per 20 ms period: 0.5 m/s.
//! let mut s = [0.0; 4];
//! for k in 0..40 {
//!     s = est.update(100 * k, 0);
//! }
//! assert!((s[0] - 0.39).abs() < 1e-3 && (s[1] - 0.5).abs() < 1e-3, "{s:?}");
//! # Ok::<(), firmware::ConfigError>(())
//! ```

use super::{Encoders, wrap};
use crate::config::{ConfigError, non_negative, positive};
use crate::fixed::FRACTION_BITS;

/// One channel's alpha-beta filter in fixed point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Channel {
    /// Position estimate, 1/4096 count.
    p: i64,
    /// Velocity estimate, 1/4096 count per period.
    v: i64,
    /// The count measured, unwrapped (the cart) or in the revolution about upright (the
    /// pole).
    count: i64,
}

/// The farthest the cart's unwrapped count goes, so that it stays inside `i64` in fixed
/// point: 2^47 counts, thousands of kilometres on any encoder.
const MAX_CART_COUNT: i64 = 1 << 47;

impl Channel {
    fn start(count: i64) -> Channel {
        Channel {
            p: count << FRACTION_BITS,
            v: 0,
            count,
        }
    }

    /// One period, the counter having `moved` since the last. `per_rev` is the pole's
    /// counts a revolution, whose count stays within the revolution about upright and
    /// whose position moves with it by whole turns (as the observer's does, so that the
    /// residual is never wrapped); `None` for the cart. The arithmetic wraps where wild
    /// counts would overflow it (and the controller rejects the estimate), never in a run
    /// it could balance.
    #[inline]
    fn update(&mut self, moved: i32, (alpha_q15, beta_q15): (i64, i64), per_rev: Option<u32>) {
        let count = self.count + i64::from(moved);
        self.count = match per_rev {
            Some(n) => wrap::count(count, n),
            None => count.clamp(-MAX_CART_COUNT, MAX_CART_COUNT),
        };
        if per_rev.is_some() && self.count != count {
            self.p = self.p.wrapping_add((self.count - count) << FRACTION_BITS);
        }
        let predicted = self.p.wrapping_add(self.v);
        let residual = (self.count << FRACTION_BITS).wrapping_sub(predicted);
        // Round to nearest: an arithmetic shift alone would bias every correction downwards.
        let half = 1 << 14;
        let correct = |gain: i64| gain.wrapping_mul(residual).wrapping_add(half) >> 15;
        self.p = predicted.wrapping_add(correct(alpha_q15));
        self.v = self.v.wrapping_add(correct(beta_q15));
    }
}

/// One channel's conversion from the filter's raw units to the network's Q3.12 input, in
/// integers: `round(raw * multiplier / 2^40)`, saturated to `i16`. `raw` is first clamped to
/// `+-limit`, beyond which the result saturates anyway, so the product stays far inside
/// `i64` (under 2^56).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct ToFixed {
    multiplier: i64,
    limit: i64,
}

impl ToFixed {
    const SHIFT: u32 = 40;

    /// For `q12_per_raw` output units per raw unit, capped at 2^20 (a period under a
    /// microsecond); computed once, at construction.
    fn new(q12_per_raw: f64) -> ToFixed {
        let k = q12_per_raw.clamp(1e-12, f64::from(1u32 << 20));
        ToFixed {
            multiplier: libm::round(k * (1u64 << Self::SHIFT) as f64) as i64,
            limit: libm::ceil(32_768.0 / k) as i64 + 1,
        }
    }

    #[inline]
    fn apply(self, raw: i64) -> i16 {
        let r = raw.clamp(-self.limit, self.limit);
        let half = 1i64 << (Self::SHIFT - 1);
        ((r * self.multiplier + half) >> Self::SHIFT).clamp(-32_768, 32_767) as i16
    }
}

/// The alpha-beta filter of [the module](self): two encoders in, `[x, x_dot, theta, theta_dot]`
/// out, once per period. Fixed-size, allocation-free, panic-free for any counts.
#[derive(Clone, Debug, PartialEq)]
pub struct AlphaBeta {
    enc: Encoders,
    period_s: f32,
    alpha_q15: i64,
    beta_q15: i64,
    cart: Channel,
    pole: Channel,
    /// The counts last read `(cart, pole)`, as the counter gave them.
    last: (i32, i32),
    started: bool,
    fixed: [ToFixed; 4],
    /// Added to the pole's position, 1/4096 count ([`AlphaBeta::trim`]).
    trim: i64,
}

impl AlphaBeta {
    /// An estimator for `enc` sampled every `period_s` seconds, with filter discount
    /// `discount` in `[0, 0.99]` (0.5 is a good start at 50 Hz). Refused, naming the
    /// field: encoders of zero counts, a discount outside its range or NaN, a period not
    /// above zero.
    pub fn new(enc: Encoders, discount: f32, period_s: f32) -> Result<AlphaBeta, ConfigError> {
        let enc = enc.check()?;
        let d = f64::from(discount);
        let d = non_negative(d, "discount")? as f32;
        if d > 0.99 {
            return Err(ConfigError::TooLarge("discount"));
        }
        let period_s = positive(f64::from(period_s), "period_s")? as f32;
        let q15 = |v: f32| (v * 32_768.0 + 0.5) as i64;
        // The raw state and the Q3.12 output carry the same fraction bits, so a raw unit is
        // worth SI units per count (per period) of output units.
        let [cart, pole] = enc.per_count();
        let per_s = 1.0 / f64::from(period_s);
        Ok(AlphaBeta {
            enc,
            period_s,
            alpha_q15: q15(1.0 - d * d),
            beta_q15: q15((1.0 - d) * (1.0 - d)),
            cart: Channel::default(),
            pole: Channel::default(),
            last: (0, 0),
            started: false,
            trim: 0,
            fixed: [
                ToFixed::new(cart),
                ToFixed::new(cart * per_s),
                ToFixed::new(pole),
                ToFixed::new(pole * per_s),
            ],
        })
    }

    /// Takes one period's counts (cart, pole) and returns the estimated state in SI units.
    /// The first call only initialises the positions (velocities start at zero). The counts
    /// are taken as differences from the last ones, in wrapping arithmetic, so a counter
    /// that wraps through `i32::MAX` moves the estimate by the counts it moved; the pole's
    /// angle stays in (-pi, pi].
    pub fn update(&mut self, cart_counts: i32, pole_counts: i32) -> [f32; 4] {
        let per_rev = self.enc.pole_counts_per_rev;
        if self.started {
            let gains = (self.alpha_q15, self.beta_q15);
            self.cart
                .update(cart_counts.wrapping_sub(self.last.0), gains, None);
            let pole = pole_counts.wrapping_sub(self.last.1);
            self.pole.update(pole, gains, Some(per_rev));
        } else {
            self.cart = Channel::start(i64::from(cart_counts));
            self.pole = Channel::start(wrap::count(i64::from(pole_counts), per_rev));
            self.started = true;
        }
        self.last = (cart_counts, pole_counts);
        self.state()
    }

    /// The pole's position handed out: within the revolution about upright, (-pi, pi].
    fn angle(&self) -> i64 {
        let rev = i64::from(self.enc.pole_counts_per_rev) << FRACTION_BITS;
        wrap::fixed(self.pole.p.wrapping_add(self.trim), rev)
    }

    /// The current estimate `[x (m), x_dot (m/s), theta (rad), theta_dot (rad/s)]`.
    pub fn state(&self) -> [f32; 4] {
        let unit = crate::fixed::ONE;
        let m_per_unit = 1.0 / (unit * self.enc.cart_counts_per_m as f32);
        let rad_per_unit = core::f32::consts::TAU / (unit * self.enc.pole_counts_per_rev as f32);
        [
            self.cart.p as f32 * m_per_unit,
            self.cart.v as f32 * m_per_unit / self.period_s,
            self.angle() as f32 * rad_per_unit,
            self.pole.v as f32 * rad_per_unit / self.period_s,
        ]
    }

    /// The current estimate in the integer network's input format, Q3.12
    /// ([`crate::fixed`]), rounded to nearest and saturated to `i16` (+-8 units). Integer
    /// arithmetic only, so an FPU-less core runs it without a float library call.
    pub fn fixed_state(&self) -> [i16; 4] {
        let [x, x_dot, theta, theta_dot] = self.fixed;
        [
            x.apply(self.cart.p),
            x_dot.apply(self.cart.v),
            theta.apply(self.angle()),
            theta_dot.apply(self.pole.v),
        ]
    }

    /// The filter's fixed-point state `[cart p, cart v, pole p, pole v]`: positions in 1/4096
    /// count (the pole's within the revolution about upright), velocities in 1/4096 count per
    /// period.
    pub fn raw(&self) -> [i64; 4] {
        [self.cart.p, self.cart.v, self.angle(), self.pole.v]
    }

    /// Forgets the history: the next update starts afresh.
    pub fn reset(&mut self) {
        self.started = false;
    }

    /// The encoders' resolutions.
    pub fn encoders(&self) -> Encoders {
        self.enc
    }

    /// From the next reading on, reads the pole `rad` further from upright than its counts
    /// say, to 1/4096 count: a zero finer than a count. A reset keeps it.
    pub fn trim(&mut self, rad: f32) {
        let per_rev = crate::fixed::ONE * self.enc.pole_counts_per_rev as f32;
        let units = rad / core::f32::consts::TAU * per_rev;
        // Within a revolution, so that any finite trim is exact in i64; NaN trims nothing.
        self.trim = if units.abs() <= per_rev {
            libm::roundf(units) as i64
        } else {
            0
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ENC: Encoders = Encoders {
        cart_counts_per_m: 10_000,
        pole_counts_per_rev: 4_096,
    };

    #[test]
    fn the_filter_has_its_documented_gains() {
        let e = AlphaBeta::new(ENC, 0.5, 0.02).unwrap();
        // alpha = 1 - 0.25 = 0.75, beta = 0.25, in Q15.
        assert_eq!((e.alpha_q15, e.beta_q15), (24_576, 8_192));
        // Discount 0: the velocity is the plain backward difference.
        let mut raw = AlphaBeta::new(ENC, 0.0, 0.02).unwrap();
        raw.update(0, 0);
        let s = raw.update(37, -5);
        let u = 1 << FRACTION_BITS;
        assert_eq!(raw.raw(), [37 * u, 37 * u, -5 * u, -5 * u]);
        assert!((s[1] - 37.0 / 10_000.0 / 0.02).abs() < 1e-6);
    }

    #[test]
    fn a_trim_moves_the_angle_by_its_nearest_4096th_of_a_count_and_outlives_a_reset() {
        let u = 1 << FRACTION_BITS;
        let mut e = AlphaBeta::new(ENC, 0.5, 0.02).unwrap();
        // 0.01 rad of 4,096 counts a turn is 6.5190 counts: 26,702 units.
        e.trim(0.01);
        e.update(0, 10);
        assert_eq!(e.raw()[2], 10 * u + 26_702);
        e.reset();
        e.update(0, -10);
        assert_eq!(e.raw()[2], -10 * u + 26_702);
        e.trim(f32::NAN);
        assert_eq!(e.raw()[2], -10 * u);
    }

    #[test]
    fn a_constant_velocity_is_tracked_without_error() {
        // 3 counts per period on the pole: 3 * 2 pi / 4096 / 0.02 rad/s.
        let mut e = AlphaBeta::new(ENC, 0.6, 0.02).unwrap();
        let mut s = [0.0; 4];
        for k in 0..200 {
            s = e.update(0, 3 * k);
        }
        let w = 3.0 * core::f32::consts::TAU / 4096.0 / 0.02;
        assert!((s[3] - w).abs() < 1e-4 * w, "{s:?} vs {w}");
        assert!((s[2] - 199.0 * 3.0 * core::f32::consts::TAU / 4096.0).abs() < 1e-5);
    }

    #[test]
    fn a_step_settles_and_smoothing_trades_noise_for_lag() {
        // After a jump of 1000 counts the estimate converges; the filter is stable.
        for d in [0.0, 0.3, 0.6, 0.9] {
            let mut e = AlphaBeta::new(ENC, d, 0.02).unwrap();
            e.update(0, 0);
            let mut last = [0.0; 4];
            for _ in 0..400 {
                last = e.update(1000, 0);
            }
            assert!(
                (last[0] - 0.1).abs() < 1e-6 && last[1].abs() < 1e-4,
                "{d}: {last:?}"
            );
        }
        // A position that alternates by one count: the smoother filter reports less speed.
        let jitter = |d: f32| {
            let mut e = AlphaBeta::new(ENC, d, 0.02).unwrap();
            (0..200)
                .map(|k| e.update(k % 2, 0)[1].abs())
                .fold(0.0f32, f32::max)
        };
        assert!(
            jitter(0.8) < 0.3 * jitter(0.0),
            "{} {}",
            jitter(0.8),
            jitter(0.0)
        );
    }

    #[test]
    fn any_counts_are_safe() {
        let mut e = AlphaBeta::new(ENC, 0.5, 0.02).unwrap();
        for (c, p) in [
            (i32::MAX, i32::MIN),
            (i32::MIN, i32::MAX),
            (0, 0),
            (i32::MAX, i32::MAX),
        ] {
            let s = e.update(c, p);
            assert!(s.iter().all(|v| v.is_finite()), "{s:?}");
        }
        let zero = Encoders {
            cart_counts_per_m: 0,
            ..ENC
        };
        for (made, why) in [
            (
                AlphaBeta::new(zero, 0.5, 0.02),
                ConfigError::NotPositive("encoders.cart_counts_per_m"),
            ),
            (
                AlphaBeta::new(ENC, f32::NAN, 0.02),
                ConfigError::NotFinite("discount"),
            ),
            (
                AlphaBeta::new(ENC, 0.991, 0.02),
                ConfigError::TooLarge("discount"),
            ),
            (
                AlphaBeta::new(ENC, -0.1, 0.02),
                ConfigError::Negative("discount"),
            ),
            (
                AlphaBeta::new(ENC, 0.5, 0.0),
                ConfigError::NotPositive("period_s"),
            ),
        ] {
            assert_eq!(made, Err(why));
        }
        assert!(AlphaBeta::new(ENC, 0.99, 1e-6).is_ok());
    }

    #[test]
    fn the_fixed_state_is_the_float_state_correctly_rounded_in_q12() {
        for (enc, d) in [
            (ENC, 0.5),
            (
                Encoders {
                    cart_counts_per_m: 37,
                    pole_counts_per_rev: 16,
                },
                0.0,
            ),
            (
                Encoders {
                    cart_counts_per_m: 1 << 26,
                    pole_counts_per_rev: 1 << 24,
                },
                0.9,
            ),
        ] {
            let mut e = AlphaBeta::new(enc, d, 0.02).unwrap();
            let cart = 1.0 / f64::from(enc.cart_counts_per_m);
            let pole = core::f64::consts::TAU / f64::from(enc.pole_counts_per_rev);
            let k = [cart, cart / 0.02f32 as f64, pole, pole / 0.02f32 as f64];
            let mut c = (0i32, 0i32);
            for step in 0..300i32 {
                // A wandering, sometimes jumping pair of counts, out to the i32 range.
                c.0 = c.0.wrapping_add(step.wrapping_mul(7919) % 5003 - 2400);
                c.1 = c.1.wrapping_add(step.wrapping_mul(104_729) % 977 - 480);
                if step % 97 == 0 {
                    c.0 = c.0.wrapping_mul(-3);
                }
                e.update(c.0, c.1);
                let fixed = e.fixed_state();
                for ((raw, k), got) in e.raw().iter().zip(k).zip(fixed) {
                    let exact = *raw as f64 * k;
                    let want = exact.clamp(-32_768.0, 32_767.0);
                    assert!(
                        (f64::from(got) - want).abs() <= 0.5 + 1e-6 * want.abs().max(1.0),
                        "{enc:?} step {step}: raw {raw} -> {got}, exact {exact}"
                    );
                }
            }
        }
    }
}
