//! What a policy's outputs ask of the motor: each output is a duty level, a signed fraction
//! of the motor's full push. The paper's network has two, full push left and right
//! ([`Levels::BANG_BANG`]); a gentler policy may have more (say `{-1, -0.5, -0.2, 0, 0.2,
//! 0.5, 1}`), so that it can hold the pole with a fraction of the effort. [`between`] finds
//! the duty between three levels at which their scores peak (what
//! [`Refined`](super::Refined) drives).

use crate::config::ConfigError;

/// A signed motor duty in thousandths of the full push (`+` towards +x): what the bridge's
/// PWM drives and what the plant's motor model takes. A thousandth is finer than any duty
/// step a policy chooses, and exact for the levels one writes (`0.2` is `200`).
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Duty(i16);

impl Duty {
    /// Thousandths in a full push.
    pub const FULL: i16 = 1000;
    /// The motor off.
    pub const OFF: Duty = Duty(0);
    /// Full push towards -x.
    pub const LEFT: Duty = Duty(-Duty::FULL);
    /// Full push towards +x.
    pub const RIGHT: Duty = Duty(Duty::FULL);

    /// `fraction` of the full push, to the nearest thousandth; refused: not finite, or
    /// beyond `[-1, 1]`.
    pub const fn from_fraction(fraction: f32) -> Result<Duty, ConfigError> {
        if !fraction.is_finite() {
            return Err(ConfigError::NotFinite("levels"));
        }
        if fraction < -1.0 || fraction > 1.0 {
            return Err(ConfigError::OutOfRange("levels"));
        }
        let t = fraction * Duty::FULL as f32;
        // Round half away from zero, in a `const fn` (no `f32::round` in core).
        let r = if t < 0.0 { t - 0.5 } else { t + 0.5 };
        Ok(Duty(r as i16))
    }

    /// The duty of `t` thousandths of the full push; `None` beyond `-1000..=1000`.
    pub const fn from_thousandths(t: i16) -> Option<Duty> {
        if t < -Duty::FULL || t > Duty::FULL {
            None
        } else {
            Some(Duty(t))
        }
    }

    /// Thousandths of the full push, `-1000..=1000`.
    pub const fn thousandths(self) -> i16 {
        self.0
    }

    /// The duty as a fraction of the full push, `-1..=1`: what the plant's motor model and
    /// the observer's and predictor's models take.
    pub fn fraction(self) -> f32 {
        f32::from(self.0) / f32::from(Duty::FULL)
    }

    /// Whether the duty pushes towards +x (`Some(true)`), -x, or not at all (`None`).
    pub const fn direction(self) -> Option<bool> {
        match self.0 {
            0 => None,
            d => Some(d > 0),
        }
    }

    /// The duty's size, `0..=1000` thousandths.
    pub const fn magnitude(self) -> u16 {
        self.0.unsigned_abs()
    }
}

/// The duty of each of a policy's `A` outputs, in increasing order: output `i` drives
/// `duty(i)`. Built once ([`Levels::new`] is a `const fn`, so a board's levels are checked as
/// it is compiled).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Levels<const A: usize>([Duty; A]);

impl Levels<2> {
    /// The paper's two actions: full push left (output 0), full push right (output 1).
    pub const BANG_BANG: Levels<2> = Levels([Duty::LEFT, Duty::RIGHT]);
}

/// Whether `fractions` are duty levels a policy may choose among: at least two, each
/// finite and within `[-1, 1]`, strictly increasing once rounded to thousandths. The one
/// check of [`Levels::new`], for a list whose length is known only at run time (a policy
/// file's).
pub const fn check_levels(fractions: &[f32]) -> Result<(), ConfigError> {
    if fractions.len() < 2 {
        return Err(ConfigError::TooFew("levels"));
    }
    let mut last = i16::MIN;
    let mut i = 0;
    while i < fractions.len() {
        let d = match Duty::from_fraction(fractions[i]) {
            Ok(d) => d.0,
            Err(e) => return Err(e),
        };
        if i > 0 && d <= last {
            return Err(ConfigError::NotIncreasing("levels"));
        }
        last = d;
        i += 1;
    }
    Ok(())
}

impl<const A: usize> Levels<A> {
    /// The levels `fractions` (each a fraction of the full push); refused as
    /// [`check_levels`] refuses.
    pub const fn new(fractions: [f32; A]) -> Result<Levels<A>, ConfigError> {
        if let Err(e) = check_levels(&fractions) {
            return Err(e);
        }
        let mut duty = [Duty::OFF; A];
        let mut i = 0;
        while i < A {
            duty[i] = match Duty::from_fraction(fractions[i]) {
                Ok(d) => d,
                Err(e) => return Err(e),
            };
            i += 1;
        }
        Ok(Levels(duty))
    }

    /// Each level as a fraction of the full push, in output order.
    pub fn fractions(&self) -> [f32; A] {
        self.0.map(Duty::fraction)
    }

    /// The duty of output `i`; `None` for an index beyond the outputs.
    #[inline]
    pub const fn duty(&self, i: usize) -> Option<Duty> {
        if i < A { Some(self.0[i]) } else { None }
    }

    /// Every level, in output order.
    pub const fn duties(&self) -> &[Duty; A] {
        &self.0
    }
}

/// Of the duties `duty(0), duty(1), ...` up to the first `None` (in increasing order, as a
/// policy's levels are), the index of the one nearest the force `force` when full duty
/// pushes with `full`: the highest whose midpoint with the level below lies under `force`
/// (`force > midpoint * full`), so the lower of two equally near, and, with the paper's
/// two levels, the sign of `force` exactly (`force > 0` pushes right). `None` without
/// levels; the lowest for a force that is not a number.
pub fn nearest(duty: impl Fn(usize) -> Option<Duty>, force: f32, full: f32) -> Option<usize> {
    let mut best = duty(0)?;
    let mut i = 1;
    while let Some(d) = duty(i) {
        // Anything but "above", a NaN force included, stops at the level reached.
        let mid = 0.5 * (best.fraction() + d.fraction()) * full;
        if force.partial_cmp(&mid) != Some(core::cmp::Ordering::Greater) {
            break;
        }
        best = d;
        i += 1;
    }
    Some(i - 1)
}

/// What the controller asked of the motor in one period.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// Drive at this duty: a level the policy chose (or a duty between its levels,
    /// [`Refined`](super::Refined)), or the monitor's fallback.
    Drive(Duty),
    /// Duty off, for want of a decision: a rejected reading, scores that are not numbers,
    /// a stopped monitor.
    Coast,
}

impl Command {
    /// The motor duty of the command, the fraction of full force the model-based observer
    /// and predictor apply ([`crate::cartpole::Plant::motor_force`]): `-1` to `1`, `0`
    /// coasting.
    pub fn level(self) -> f32 {
        match self {
            Command::Drive(d) => d.fraction(),
            Command::Coast => 0.0,
        }
    }
}

/// How far a chosen output's score stands above its lower and its higher neighbour's
/// ([`Scores::rises`](super::Scores::rises)): as floats, or exactly, as integer scores differ. A rise below zero
/// (an output that is no peak) has no integer form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rises {
    /// A float network's.
    Float(f32, f32),
    /// An integer network's, in its output units.
    Int(u32, u32),
}

impl Rises {
    /// Output `i`'s rises among the float scores `q`; `None` without both neighbours.
    pub fn of_floats(q: &[f32], i: usize) -> Option<Rises> {
        let (lo, mid, hi) = around(q, i)?;
        Some(Rises::Float(mid - lo, mid - hi))
    }

    /// Output `i`'s rises among the integer scores `q`, exact; `None` without both
    /// neighbours, or where a neighbour scores higher.
    pub fn of_ints(q: &[i32], i: usize) -> Option<Rises> {
        let (lo, mid, hi) = around(q, i)?;
        let rise = |n: i32| u32::try_from(i64::from(mid) - i64::from(n)).ok();
        Some(Rises::Int(rise(lo)?, rise(hi)?))
    }
}

/// Output `i` of `q` and its neighbours, lower first.
fn around<T: Copy>(q: &[T], i: usize) -> Option<(T, T, T)> {
    Some((*q.get(i.checked_sub(1)?)?, *q.get(i)?, *q.get(i + 1)?))
}

/// The parts [`between`] cuts a float network's fraction `t` into: an f32's precision.
const FLOAT_PARTS: i64 = 1 << 24;

/// The duty at the peak of the parabola through the points `(levels[k], score k)`, where
/// the middle score stands `rise` above its neighbours' (both at least zero for a chosen
/// level), to the nearest thousandth, and strictly between the midpoints the middle level
/// shares with its neighbours, so that rounding it to the nearest level gives the middle one
/// back (a peak on a midpoint, where a neighbour scores as the middle level, is moved a
/// thousandth inside).
///
/// The peak lies at `m1 + t (m2 - m1)`, `m1` and `m2` the midpoints of the lower and higher
/// pair of levels and `t = r1 h2 / (r1 h2 + r2 h1)` (`r1`, `r2` the rises, `h1`, `h2` the
/// gaps between the levels). Integer scores find it in integers alone, as a board without
/// floating point runs them, exactly. Rises that give no such `t` (negative, not numbers,
/// both zero, or large enough to overflow) leave the middle level.
pub fn between(levels: [Duty; 3], rise: Rises) -> Duty {
    let [lo, mid, hi] = levels.map(|d| i64::from(d.thousandths()));
    let (h1, h2) = (mid - lo, hi - mid);
    if h1 <= 0 || h2 <= 0 {
        return levels[1];
    }
    // t as a fraction below / sum.
    let (below, sum) = match rise {
        Rises::Float(r1, r2) => {
            let (below, above) = (r1 * h2 as f32, r2 * h1 as f32);
            let t = below / (below + above);
            if !(below.is_finite() && above.is_finite() && (0.0..=1.0).contains(&t)) {
                return levels[1];
            }
            ((t * FLOAT_PARTS as f32 + 0.5) as i64, FLOAT_PARTS)
        }
        Rises::Int(r1, r2) => {
            // Each below 2^32 times 2^11, so every product below stays under 2^57.
            let (below, above) = (i64::from(r1) * h2, i64::from(r2) * h1);
            if below + above == 0 {
                return levels[1];
            }
            (below, below + above)
        }
    };
    // The peak is ((lo + mid) sum + below (hi - lo)) / (2 sum): rounded half away from zero.
    let twice = (lo + mid) * sum + below * (hi - lo);
    let peak = short_quotient(twice.unsigned_abs() + sum as u64, 2 * sum as u64) as i64;
    let peak = peak * twice.signum();
    let inside = (
        (lo + mid).div_euclid(2) + 1,
        (mid + hi + 1).div_euclid(2) - 1,
    );
    // Not `clamp`, whose check of its bounds' order would leave a panic in the code.
    let peak = peak.max(inside.0).min(inside.1);
    // Between two levels, so within [-1000, 1000].
    Duty::from_thousandths(peak as i16).unwrap_or(levels[1])
}

/// The bits of [`between`]'s quotient, the peak's magnitude rounded: the levels lie in
/// [-1000, 1000] and `below <= sum`, so `|twice| <= 2000 sum` and it is at most 1000.
const QUOTIENT_BITS: u32 = 10;

/// `n / d` where the quotient is below `2^QUOTIENT_BITS` and `d << QUOTIENT_BITS` fits:
/// ten shift-and-subtract steps, where a Cortex-M0 (no divide instruction) would run a
/// general 64-bit division, the most of the refinement's instructions.
fn short_quotient(n: u64, d: u64) -> u64 {
    let mut step = d << (QUOTIENT_BITS - 1);
    let (mut q, mut r) = (0, n);
    for _ in 0..QUOTIENT_BITS {
        q <<= 1;
        if r >= step {
            r -= step;
            q |= 1;
        }
        step >>= 1;
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_checked_and_rounded_to_thousandths() {
        let seven = Levels::new([-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0]).unwrap();
        let t: [i16; 7] = seven.duties().map(Duty::thousandths);
        assert_eq!(t, [-1000, -500, -200, 0, 200, 500, 1000]);
        assert_eq!(seven.duty(7), None);
        assert_eq!(Levels::new([0.5]), Err(ConfigError::TooFew("levels")));
        assert_eq!(
            Levels::new([0.5, 0.2]),
            Err(ConfigError::NotIncreasing("levels"))
        );
        // Two levels a rounding apart are one level.
        assert_eq!(
            Levels::new([0.2, 0.2004]),
            Err(ConfigError::NotIncreasing("levels"))
        );
        assert_eq!(
            Levels::new([-1.5, 1.0]),
            Err(ConfigError::OutOfRange("levels"))
        );
        assert_eq!(
            Levels::new([f32::NAN, 1.0]),
            Err(ConfigError::NotFinite("levels"))
        );
        assert_eq!(Levels::new([-1.0, 1.0]), Ok(Levels::BANG_BANG));
    }

    #[test]
    fn the_nearest_level_of_a_linear_command() {
        let five = Levels::new([-1.0, -0.3, 0.0, 0.3, 1.0]).unwrap();
        let at = |u: f32| nearest(|i| five.duty(i), u, 1.0).unwrap();
        // Midpoints -0.65, -0.15, 0.15, 0.65; 0.15 is exactly half of 0.3 in f32, so on that
        // midpoint the lower level is driven.
        let got = [-2.0, -0.7, -0.16, 0.1, 0.15, 0.2, 0.64, 0.7, f32::INFINITY];
        assert_eq!(got.map(at), [0, 0, 1, 2, 2, 3, 3, 4, 4]);
        assert_eq!(at(f32::NAN), 0);
        // In newtons of a 10 N motor: -6.6 N is -0.66 of full duty.
        assert_eq!(nearest(|i| five.duty(i), -6.6, 10.0), Some(0));
        assert_eq!(nearest(|_| None, 1.0, 1.0), None);
    }

    #[test]
    fn with_the_papers_two_levels_the_nearest_is_the_sign_of_the_force() {
        let two = |i| Levels::BANG_BANG.duty(i);
        let tiny = f32::from_bits(1);
        for (force, want) in [
            (tiny, 1),
            (-tiny, 0),
            (0.0, 0),
            (-0.0, 0),
            (f32::NAN, 0),
            (-f32::INFINITY, 0),
            (1e30, 1),
        ] {
            assert_eq!(nearest(two, force, 10.0), Some(want), "{force}");
        }
    }

    proptest::proptest! {
        /// The division [`between`] runs is the general one wherever its quotient has the
        /// bits it allows: a divisor as large as the integer rises give, and as small as 2.
        #[test]
        fn the_short_quotient_is_the_quotient(
            d in proptest::prop_oneof![2u64..1000, 2u64..(1 << 45)],
            q in 0u64..(1 << QUOTIENT_BITS),
            r in 0u64..u64::MAX,
        ) {
            let n = q * d + r % d;
            proptest::prop_assert_eq!(short_quotient(n, d), n / d);
        }
    }

    /// The divisors [`between`] gives: the float path's one, and the integer path's largest
    /// (rises of `u32::MAX` across gaps of 2000), at the largest quotient the bits hold.
    #[test]
    fn the_short_quotient_at_the_divisors_between_gives() {
        let top = (1 << QUOTIENT_BITS) - 1;
        for d in [2 * FLOAT_PARTS as u64, 2 * 2000 * u64::from(u32::MAX)] {
            for n in [0, d - 1, d, top * d, top * d + d - 1] {
                assert_eq!(short_quotient(n, d), n / d, "{n} / {d}");
            }
        }
    }

    #[test]
    fn a_duty_is_its_thousandths() {
        assert_eq!(Duty::from_fraction(0.2).unwrap().thousandths(), 200);
        assert_eq!(Duty::from_fraction(-0.0005).unwrap().thousandths(), -1);
        assert_eq!(Duty::from_fraction(1.0).unwrap(), Duty::RIGHT);
        assert_eq!(Duty::LEFT.fraction(), -1.0);
        assert_eq!(
            (Duty::LEFT.direction(), Duty::OFF.direction()),
            (Some(false), None)
        );
        assert_eq!(Duty::LEFT.magnitude(), 1000);
    }
}
