//! A duty between the levels: a Q-network scores a few duty levels, but the value of a
//! duty varies smoothly between them. [`Refined`] fits the parabola through the chosen
//! level's score and its two neighbours' and drives the duty at its peak, so a policy
//! trained on nine levels can hold the pole with the finer duty a linear controller would
//! give, without being trained again.
//!
//! The peak always lies between the midpoints the chosen level shares with its neighbours
//! (the chosen score is the largest of the three), so the refined duty is one that rounding
//! to the nearest level would give back as the chosen level: it refines the choice, never
//! overturns it.

use super::levels::Duty;
use super::policy::{Policy, Scores};
use super::reading::Reading;

/// `P`, its chosen level moved to the peak of the parabola through the scores of that level
/// and its two neighbours ([`between`]). An end level (full push, or the lowest or highest
/// of the levels) drives itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refined<P>(pub P);

impl<O: Reading, P: Policy<O>> Policy<O> for Refined<P> {
    type Scores = P::Scores;
    #[inline]
    fn scores(&mut self, obs: &O) -> P::Scores {
        self.0.scores(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.0.duty(i)
    }
    fn drive(&self, q: &P::Scores, i: usize) -> Option<Duty> {
        let level = self.0.drive(q, i)?;
        let lower = i.checked_sub(1).and_then(|k| self.0.duty(k));
        match (lower, self.0.duty(i + 1), q.rises(i)) {
            (Some(lo), Some(hi), Some(rise)) => Some(between([lo, level, hi], rise)),
            _ => Some(level),
        }
    }
}

/// How far a chosen output's score stands above its lower and its higher neighbour's
/// ([`Scores::rises`]): as floats, or exactly, as integer scores differ. A rise below zero
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

/// The scale of [`between`]'s fraction `t`: sixteen bits, a peak within a hundredth of a
/// thousandth of full duty.
const ONE: u64 = 1 << 16;

/// The duty at the peak of the parabola through the points `(levels[k], score k)`, where
/// the middle score stands `rise` above its neighbours' (both at least zero for a chosen
/// level), to the nearest thousandth.
///
/// The peak lies at `m1 + t (m2 - m1)`, `m1` and `m2` the midpoints of the lower and higher
/// pair of levels and `t = r1 h2 / (r1 h2 + r2 h1)` (`r1`, `r2` the rises, `h1`, `h2` the
/// gaps between the levels): the lower midpoint where the lower level scores as the middle
/// one, the higher where the higher does. Integer scores find it in integers alone, as a
/// board without floating point runs them. Rises that give no such `t` (negative, not
/// numbers, both zero, or large enough to overflow) leave the middle level.
pub fn between(levels: [Duty; 3], rise: Rises) -> Duty {
    let [lo, mid, hi] = levels.map(|d| i64::from(d.thousandths()));
    let (h1, h2) = (mid - lo, hi - mid);
    if h1 <= 0 || h2 <= 0 {
        return levels[1];
    }
    let t = match rise {
        Rises::Float(r1, r2) => {
            let (below, above) = (r1 * h2 as f32, r2 * h1 as f32);
            let t = below / (below + above);
            if !(below >= 0.0 && above >= 0.0 && (0.0..=1.0).contains(&t)) {
                return levels[1];
            }
            (t * ONE as f32 + 0.5) as u64
        }
        Rises::Int(r1, r2) => {
            // Each below 2^32 times 2^11, so the sum and its 2^16-fold fit 64 bits.
            let (below, above) = (u64::from(r1) * h2 as u64, u64::from(r2) * h1 as u64);
            let sum = below + above;
            if sum == 0 {
                return levels[1];
            }
            (below * ONE + sum / 2) / sum
        }
    };
    // 2 ONE times the peak: ONE (lo + mid) + t (hi - lo), half away from zero.
    let twice = (lo + mid) * ONE as i64 + t.min(ONE) as i64 * (hi - lo);
    let half = (twice.unsigned_abs() + ONE) / (2 * ONE);
    let peak = if twice < 0 {
        -(half as i64)
    } else {
        half as i64
    };
    i16::try_from(peak)
        .ok()
        .and_then(Duty::from_thousandths)
        .unwrap_or(levels[1])
}

#[cfg(test)]
mod tests;
