//! A part's values as its effect reads them.

use super::{Fallback, PartSpec};

/// A part's values as its effect reads them: one per field, `None` where left out.
pub struct Values<'a> {
    spec: &'static PartSpec,
    given: &'a [Option<f64>],
}

impl<'a> Values<'a> {
    /// `given`, one per field of `spec`.
    pub fn new(spec: &'static PartSpec, given: &'a [Option<f64>]) -> Values<'a> {
        Values { spec, given }
    }

    /// Field `i`'s value, its fallback filled in where it was left out.
    pub fn get(&self, i: usize) -> Option<f64> {
        self.given[i].or(match self.spec.fields[i].fallback {
            Fallback::Value(v) => Some(v),
            Fallback::FiveTimesFirst => self.given[0].map(|v| 5.0 * v),
            Fallback::Required | Fallback::Absent => None,
        })
    }

    /// The first field's value, 1 where it has none.
    pub fn first(&self) -> f64 {
        self.get(0).unwrap_or(1.0)
    }

    /// Field `i` as a whole number, 1 where it has none.
    pub fn whole(&self, i: usize) -> u32 {
        self.get(i).map_or(1, |v| v as u32)
    }
}
