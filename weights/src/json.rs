//! JSON the tools read back (results files, run summaries, envelopes, markers), parsed in two
//! passes so that its memory is bounded before any is taken: the values are counted first,
//! allocating nothing, and a text of more than [`MAX_VALUES`] is refused; only then is it
//! parsed. A parsed value costs tens of bytes whatever its text's length (`0,` is two bytes
//! and a 32-byte value), so a count, not the file's size, is what bounds the memory.

use std::cell::Cell;
use std::fmt;

use serde::de::{DeserializeOwned, DeserializeSeed, Error, IgnoredAny, MapAccess, SeqAccess};
use serde::de::{Deserializer, Visitor};

/// Most values (numbers, strings, arrays, objects, each counted once) a JSON file the tools
/// read may hold: 15 times the largest results file here (an `eval` of 2,000 rows).
pub const MAX_VALUES: u64 = 100_000;

/// `text` parsed as a `T`, or why not: not JSON, more than [`MAX_VALUES`] values, or not
/// a `T`. The message is serde's, cut and escaped.
pub fn parse<T: DeserializeOwned>(text: &str) -> Result<T, String> {
    let mut de = serde_json::Deserializer::from_str(text);
    let seen = Cell::new(0);
    Counter(&seen)
        .deserialize(&mut de)
        .and_then(|()| de.end())
        .map_err(|e| crate::excerpt(&e.to_string()))?;
    serde_json::from_str(text).map_err(|e| crate::excerpt(&e.to_string()))
}

/// Counts the values of one JSON value into its cell, refusing past [`MAX_VALUES`].
struct Counter<'a>(&'a Cell<u64>);

impl Counter<'_> {
    fn one<E: Error>(&self) -> Result<(), E> {
        self.0.set(self.0.get() + 1);
        if self.0.get() > MAX_VALUES {
            return Err(E::custom(format!(
                "expected at most {MAX_VALUES} values, found more"
            )));
        }
        Ok(())
    }
}

impl<'de> DeserializeSeed<'de> for Counter<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Counter<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E: Error>(self, _: bool) -> Result<(), E> {
        self.one()
    }

    fn visit_i64<E: Error>(self, _: i64) -> Result<(), E> {
        self.one()
    }

    fn visit_u64<E: Error>(self, _: u64) -> Result<(), E> {
        self.one()
    }

    fn visit_f64<E: Error>(self, _: f64) -> Result<(), E> {
        self.one()
    }

    fn visit_str<E: Error>(self, _: &str) -> Result<(), E> {
        self.one()
    }

    fn visit_unit<E: Error>(self) -> Result<(), E> {
        self.one()
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        self.one()?;
        while seq.next_element_seed(Counter(self.0))?.is_some() {}
        Ok(())
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        self.one()?;
        while map.next_key::<IgnoredAny>()?.is_some() {
            map.next_value_seed(Counter(self.0))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    #[test]
    fn values_are_counted_as_parsed_and_one_past_the_limit_is_refused() {
        let at = |n: u64| format!("[{}]", vec!["0"; n as usize - 1].join(","));
        let v: Value = parse(&at(MAX_VALUES)).unwrap();
        assert_eq!(v.as_array().unwrap().len() as u64, MAX_VALUES - 1);
        let e = parse::<Value>(&at(MAX_VALUES + 1)).unwrap_err();
        assert!(e.contains("expected at most 100000 values"), "{e}");
        // Keys are not values; every other kind is.
        let n: Value = parse(r#"{"a": [true, null, "s", -1, 2.5, {}]}"#).unwrap();
        assert_eq!(n["a"][3], -1);
        let e = parse::<Value>("[1] x").unwrap_err();
        assert!(e.contains("trailing characters"), "{e}");
        let e = parse::<Vec<u8>>("[1, 300]").unwrap_err();
        assert!(e.contains("u8"), "{e}");
    }
}
