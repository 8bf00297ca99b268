//! A reply's scores: one per output of the policy, as many as it has, in a buffer of fixed
//! size.

use core::fmt;

use crate::network::MAX_OUTPUTS;

/// One to [`MAX_OUTPUTS`] scores, in a fixed buffer.
#[derive(Clone, Copy)]
pub struct Values<T> {
    v: [T; MAX_OUTPUTS],
    n: u8,
}

impl<T: Copy + Default> Values<T> {
    /// The scores of an `A`-output policy (`A` in `1..=MAX_OUTPUTS`, checked as it compiles).
    pub fn of<const A: usize>(q: [T; A]) -> Values<T> {
        const { assert!(A >= 1 && A <= MAX_OUTPUTS) };
        let mut v = [T::default(); MAX_OUTPUTS];
        v[..A].copy_from_slice(&q);
        Values { v, n: A as u8 }
    }

    /// `q`'s scores; `None` for none or more than [`MAX_OUTPUTS`].
    pub fn new(q: &[T]) -> Option<Values<T>> {
        let mut each = q.iter().copied();
        Values::from_fn(q.len(), || each.next())
    }

    /// `n` scores (`1..=MAX_OUTPUTS`, else `None`), each `next`'s, in order; `None` if
    /// `next` runs out.
    pub(super) fn from_fn(n: usize, mut next: impl FnMut() -> Option<T>) -> Option<Values<T>> {
        if !(1..=MAX_OUTPUTS).contains(&n) {
            return None;
        }
        let mut v = [T::default(); MAX_OUTPUTS];
        for x in v.get_mut(..n)? {
            *x = next()?;
        }
        Some(Values { v, n: n as u8 })
    }
}

impl<T> Values<T> {
    /// The scores, one per output.
    pub fn as_slice(&self) -> &[T] {
        self.v.get(..usize::from(self.n)).unwrap_or(&[])
    }
}

impl<T: PartialEq> PartialEq for Values<T> {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl<T: fmt::Debug> fmt::Debug for Values<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.as_slice()).finish()
    }
}
