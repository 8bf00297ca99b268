//! The pole's hanging count: the middle of its swing, once two windows agree on it.

/// Windows of the pole's counts, each reduced to the middle of its lowest and highest.
#[derive(Clone, Copy, Debug)]
pub(super) struct Zeroing {
    window: u16,
    seen: u16,
    first: i32,
    /// The window's lowest and highest count, less `first` (so a counter that wraps between
    /// them does not split the swing).
    lo: i64,
    hi: i64,
    previous: Option<i32>,
}

impl Zeroing {
    /// Windows of `window` periods.
    pub(super) const fn new(window: u16) -> Zeroing {
        Zeroing {
            window,
            seen: 0,
            first: 0,
            lo: 0,
            hi: 0,
            previous: None,
        }
    }

    /// One period's pole count; the hanging count once the middles of two windows in a row
    /// lie within a count of each other.
    pub(super) fn count(&mut self, pole: i32) -> Option<i32> {
        if self.seen == 0 {
            self.first = pole;
            (self.lo, self.hi) = (0, 0);
        }
        let d = i64::from(pole.wrapping_sub(self.first));
        self.lo = self.lo.min(d);
        self.hi = self.hi.max(d);
        self.seen = self.seen.saturating_add(1);
        if self.seen < self.window {
            return None;
        }
        self.seen = 0;
        // A count `c` is an angle in [c, c + 1): the swing's middle lies at (lo + hi + 1) / 2,
        // and its count is the one below. A window's span is at most twice the counts one i32
        // can move, so the middle fits.
        let middle = self
            .first
            .wrapping_add((self.lo + self.hi + 1).div_euclid(2) as i32);
        let agreed = self
            .previous
            .is_some_and(|p| middle.wrapping_sub(p).unsigned_abs() <= 1);
        self.previous = Some(middle);
        agreed.then_some(middle)
    }
}
