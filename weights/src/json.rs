//! JSON the tools read back. Into a type ([`parse`]: run summaries, envelopes,
//! `eval`'s rows for the tables) the memory is the type's, which ignores what it does not
//! name. Into a generic value ([`value`]: results files compared, figures looked up) every
//! value is kept, and costs tens of bytes however short its text (`0,` is two bytes and a
//! 32-byte value; an object of one key, a whole map node): so the text is read twice, its
//! values weighed first, keeping no value (only the keys of the objects being weighed, to
//! refuse one given twice), and one heavier than [`MAX_WEIGHT`] is refused before any is
//! kept.

use std::cell::Cell;
use std::collections::BTreeSet;
use std::fmt;

use serde::de::{DeserializeOwned, DeserializeSeed, Error, MapAccess, SeqAccess};
use serde::de::{Deserializer, Visitor};
use serde_json::Value;

/// What an object weighs against a number or a string: a map node's memory.
pub const OBJECT_WEIGHT: u64 = 16;
/// What an array weighs: the four values a list first makes room for.
pub const ARRAY_WEIGHT: u64 = 4;
/// What an object's key weighs beside its value: its string and its slot in the map.
pub const KEY_WEIGHT: u64 = 2;

/// The heaviest JSON text [`value`] reads: `eval --json` at its most rows (10,000, a row of
/// figures weighing a few hundred), with room to spare.
pub const MAX_WEIGHT: u64 = 5_000_000;

/// `text` parsed as a `T`, or why not (serde's message, cut and escaped).
pub fn parse<T: DeserializeOwned>(text: &str) -> Result<T, String> {
    serde_json::from_str(unmarked(text)).map_err(|e| crate::excerpt(&e.to_string()))
}

/// `text` without a leading byte-order mark, which some editors on Windows write and which
/// the TOML reader takes: refused here, a file would read in one format and not the other.
fn unmarked(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// `bytes` as UTF-8 text parsed as a `T` ([`parse`]), or why not.
pub fn parse_bytes<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, String> {
    std::str::from_utf8(bytes)
        .map_err(|e| e.to_string())
        .and_then(parse)
}

/// `text` parsed whole, once [`weight`] has found it within [`MAX_WEIGHT`].
pub fn value(text: &str) -> Result<Value, String> {
    weight(text)?;
    parse(text)
}

/// What `text`'s values weigh ([`OBJECT_WEIGHT`] an object, [`KEY_WEIGHT`] each of its keys,
/// [`ARRAY_WEIGHT`] an array, 1 any other value), read
/// without keeping any (only the keys of the objects being weighed: an object's, and its
/// enclosing objects', while its values are); refused past [`MAX_WEIGHT`], with a
/// key given twice in one object, or if it is not JSON.
pub fn weight(text: &str) -> Result<u64, String> {
    let mut de = serde_json::Deserializer::from_str(unmarked(text));
    let seen = Cell::new(0);
    Counter(&seen)
        .deserialize(&mut de)
        .and_then(|()| de.end())
        .map_err(|e| crate::excerpt(&e.to_string()))?;
    Ok(seen.get())
}

/// Weighs one JSON value into its cell, refusing past [`MAX_WEIGHT`].
struct Counter<'a>(&'a Cell<u64>);

impl Counter<'_> {
    fn add<E: Error>(&self, weight: u64) -> Result<(), E> {
        self.0.set(self.0.get() + weight);
        if self.0.get() > MAX_WEIGHT {
            return Err(E::custom(format!(
                "expected values weighing at most {MAX_WEIGHT} (an object {OBJECT_WEIGHT}, a key \
                 {KEY_WEIGHT}, an array {ARRAY_WEIGHT}, any other value 1), found more"
            )));
        }
        Ok(())
    }

    fn one<E: Error>(&self) -> Result<(), E> {
        self.add(1)
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
        self.add(ARRAY_WEIGHT)?;
        while seq.next_element_seed(Counter(self.0))?.is_some() {}
        Ok(())
    }

    // A key given twice is refused here, where the typed readers' serde refuses a field
    // twice: kept whole, the last would win without a word.
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        self.add(OBJECT_WEIGHT)?;
        let mut keys = BTreeSet::new();
        while let Some(key) = map.next_key::<String>()? {
            self.add(KEY_WEIGHT)?;
            map.next_value_seed(Counter(self.0))?;
            if let Some(again) = keys.replace(key) {
                let again = crate::quote(&again);
                return Err(A::Error::custom(format!(
                    "expected each key of an object once, found {again} twice"
                )));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_weighed_as_parsed_and_past_the_limit_refused() {
        let numbers = |n: u64| format!("[{}]", vec!["0"; n as usize].join(","));
        let most = MAX_WEIGHT - ARRAY_WEIGHT;
        assert_eq!(weight(&numbers(most)), Ok(MAX_WEIGHT));
        let v = value(&numbers(most)).unwrap();
        assert_eq!(v.as_array().unwrap().len() as u64, most);
        let e = value(&numbers(most + 1)).unwrap_err();
        assert!(
            e.contains("expected values weighing at most 5000000"),
            "{e}"
        );
        // An object 16, a key 2, an array 4, every other value 1.
        let n = r#"{"a": [true, null, "s", -1, 2.5, {}]}"#;
        assert_eq!(
            weight(n),
            Ok(2 * OBJECT_WEIGHT + KEY_WEIGHT + ARRAY_WEIGHT + 5)
        );
        assert_eq!(value(n).unwrap()["a"][3], -1);
        let e = value(r#"{"a": 1, "b": {"a": 2}, "a": 3}"#).unwrap_err();
        assert!(
            e.contains("expected each key of an object once, found \"a\" twice"),
            "{e}"
        );
        assert!(value(r#"{"a": 1, "b": {"a": 2}}"#).is_ok());
        let e = value("[1] x").unwrap_err();
        assert!(e.contains("trailing characters"), "{e}");
        // A byte-order mark first, as the TOML reader takes it; not elsewhere.
        assert_eq!(value("\u{feff}{\"a\": 1}").unwrap()["a"], 1);
        assert_eq!(parse::<Vec<u8>>("\u{feff}[7]"), Ok(vec![7]));
        assert!(value("[\u{feff}1]").is_err());
        let e = parse::<Vec<u8>>("[1, 300]").unwrap_err();
        assert!(e.contains("u8"), "{e}");
    }
}
