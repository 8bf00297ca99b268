//! The pole's hanging count, from a pole at rest or swinging.
//!
//! A pole at rest gives it directly: the count it rests on, once two windows in a row have
//! seen it stay within a count. A swinging pole gives it by its turning points: a pendulum
//! swings symmetrically about hanging, and as friction and the motor's drag take its
//! amplitude down, three turning points in a row `e1, e2, e3` (a side, the other, the first
//! again) put the middle at `(e1 + 2 e2 + e3) / 4`, the decay over the two half swings
//! cancelling. It is taken once two such middles in a row agree within a count.

/// Counts back from a turning point before it counts as one: a count's flicker is not a
/// turn.
const TURN: i64 = 2;

/// The watch on the pole's counts.
#[derive(Clone, Copy, Debug)]
pub(super) struct Zeroing {
    window: u16,
    /// The count of the first period (counts are taken from it, so that a counter that wraps
    /// does not split the swing), once there was one.
    first: i32,
    started: bool,
    /// This window's periods, lowest and highest.
    seen: u16,
    lo: i64,
    hi: i64,
    rest: Option<i64>,
    /// The way the pole moves (`0` before it has moved [`TURN`] counts), the furthest count
    /// that way, and the last three turning points, oldest first.
    way: i8,
    furthest: i64,
    turns: [i64; 3],
    turned: u8,
    swing: Option<i64>,
}

impl Zeroing {
    /// Windows of `window` periods for a pole at rest.
    pub(super) const fn new(window: u16) -> Zeroing {
        Zeroing {
            window,
            first: 0,
            started: false,
            seen: 0,
            lo: 0,
            hi: 0,
            rest: None,
            way: 0,
            furthest: 0,
            turns: [0; 3],
            turned: 0,
            swing: None,
        }
    }

    /// One period's pole count; the hanging count once a pole at rest or swinging has shown
    /// it.
    pub(super) fn count(&mut self, pole: i32) -> Option<i32> {
        if !self.started {
            self.first = pole;
            self.started = true;
        }
        let p = i64::from(pole.wrapping_sub(self.first));
        let found = self.at_rest(p).or(self.swinging(p))?;
        // Within an i32's counts of the first: the turning points and the window are.
        Some(self.first.wrapping_add(found as i32))
    }

    /// A window's middle, once two in a row have stayed within a count and agree.
    fn at_rest(&mut self, p: i64) -> Option<i64> {
        if self.seen == 0 {
            (self.lo, self.hi) = (p, p);
        }
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
        self.seen = self.seen.saturating_add(1);
        if self.seen < self.window {
            return None;
        }
        self.seen = 0;
        // A count `c` is an angle in [c, c + 1): the middle lies at (lo + hi + 1) / 2, and
        // its count is the one below.
        let middle = (self.hi - self.lo <= 1).then(|| (self.lo + self.hi + 1).div_euclid(2));
        agree(&mut self.rest, middle)
    }

    /// The middle of the last three turning points, once two in a row agree.
    fn swinging(&mut self, p: i64) -> Option<i64> {
        let back = (p - self.furthest) * i64::from(self.way);
        if self.way == 0 {
            if (p - self.furthest).abs() >= TURN {
                self.way = if p > self.furthest { 1 } else { -1 };
                self.furthest = p;
            }
            return None;
        }
        if back > 0 {
            self.furthest = p;
            return None;
        }
        if back > -TURN {
            return None;
        }
        self.turns = [self.turns[1], self.turns[2], self.furthest];
        self.turned = self.turned.saturating_add(1);
        self.way = -self.way;
        self.furthest = p;
        if self.turned < 3 {
            return None;
        }
        let [e1, e2, e3] = self.turns;
        // Each count is the floor of its angle: half a count low on average, so the middle
        // is rounded rather than floored.
        let middle = (e1 + 2 * e2 + e3 + 2).div_euclid(4);
        agree(&mut self.swing, Some(middle))
    }
}

/// `middle`, if the one before it (kept in `previous`) lies within a count of it.
fn agree(previous: &mut Option<i64>, middle: Option<i64>) -> Option<i64> {
    let agreed = match (*previous, middle) {
        (Some(a), Some(b)) => (a - b).abs() <= 1,
        _ => false,
    };
    *previous = middle;
    middle.filter(|_| agreed)
}
