//! A case's lists read with their bounds: a list longer than a case can be is refused at the
//! first row past it, and `states_hex`'s strings become numbers as they are read, so a case
//! costs its rows' numbers (32 bytes a state), never a string per value (a 64 MiB line of
//! one-character strings took 886 MB).

use std::fmt;
use std::marker::PhantomData;

use serde::de::{Deserialize, Deserializer, Error, SeqAccess, Visitor};

use super::MAX_ACTIONS;

/// At most [`MAX_ACTIONS`] actions.
pub fn actions<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
    at_most(d, MAX_ACTIONS, "actions")
}

/// At most one terminated flag an action.
pub fn flags<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<bool>, D::Error> {
    at_most(d, MAX_ACTIONS, "terminated flags")
}

/// At most one state an action, and the first.
pub fn states<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<[f64; 4]>, D::Error> {
    at_most(d, MAX_ACTIONS + 1, "states")
}

/// As [`states`], each value a `float.hex()` string read into its exact number.
pub fn hex_states<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<[f64; 4]>, D::Error> {
    let rows: Vec<[Hex; 4]> = at_most(d, MAX_ACTIONS + 1, "states_hex rows")?;
    Ok(rows.into_iter().map(|r| r.map(|h| h.0)).collect())
}

fn at_most<'de, D: Deserializer<'de>, T: Deserialize<'de>>(
    d: D,
    most: usize,
    what: &'static str,
) -> Result<Vec<T>, D::Error> {
    d.deserialize_seq(Bounded {
        most,
        what,
        item: PhantomData,
    })
}

struct Bounded<T> {
    most: usize,
    what: &'static str,
    item: PhantomData<T>,
}

impl<'de, T: Deserialize<'de>> Visitor<'de> for Bounded<T> {
    type Value = Vec<T>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a list of at most {} {}", self.most, self.what)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<T>, A::Error> {
        let mut out = Vec::new();
        while let Some(x) = seq.next_element()? {
            if out.len() == self.most {
                return Err(A::Error::custom(format!(
                    "expected at most {} {}, found more",
                    self.most, self.what
                )));
            }
            out.push(x);
        }
        Ok(out)
    }
}

/// One `float.hex()` value, read without keeping its string.
struct Hex(f64);

impl<'de> Deserialize<'de> for Hex {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Hex, D::Error> {
        d.deserialize_str(HexVisitor)
    }
}

struct HexVisitor;

impl Visitor<'_> for HexVisitor {
    type Value = Hex;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a float.hex() string")
    }

    fn visit_str<E: Error>(self, s: &str) -> Result<Hex, E> {
        super::parse_hex_f64(s).map(Hex).map_err(E::custom)
    }
}
