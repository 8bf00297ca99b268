//! The generic JSON reader's peak memory (`weights::json::value`: results files compared,
//! figures looked up) on texts made to amplify, each at the weight limit: a value costs
//! tens of bytes however short its text, and an object a whole map node, so the weight, not
//! the size, bounds the memory. Measured by the counting allocator, in bytes, never time.

#[path = "support/counting.rs"]
mod counting;

use counting::{alone, peak_of};
use weights::json::{ARRAY_WEIGHT, KEY_WEIGHT, MAX_WEIGHT, OBJECT_WEIGHT, value, weight};

/// Memory a value may take for each unit of its weight, beyond twice the text (which a
/// string value copies).
const PER_WEIGHT: usize = 64;

/// `{"rows": [ITEM, ...]}` with as many items, each weighing `per`, as leave it within
/// `limit`.
fn rows(item: &str, per: u64, limit: u64) -> String {
    let n = ((limit - OBJECT_WEIGHT - KEY_WEIGHT - ARRAY_WEIGHT) / per) as usize;
    format!("{{\"rows\": [{}]}}", vec![item; n].join(","))
}

#[test]
fn a_text_at_the_weight_limit_costs_its_weight_whatever_its_shape() {
    let _alone = alone();
    let long = format!("\"{}\"", "s".repeat(4096));
    let one_key = format!("{{\"{}\": 0}}", "k".repeat(200));
    let top = 2 * OBJECT_WEIGHT + KEY_WEIGHT + ARRAY_WEIGHT;
    let fields: Vec<String> = (0..(MAX_WEIGHT - top) / (KEY_WEIGHT + 1))
        .map(|i| format!("\"{i}\": 0"))
        .collect();
    let cases = [
        ("numbers", rows("0", 1, MAX_WEIGHT)),
        ("empty objects", rows("{}", OBJECT_WEIGHT, MAX_WEIGHT)),
        (
            "objects of one long key",
            rows(&one_key, OBJECT_WEIGHT + KEY_WEIGHT + 1, MAX_WEIGHT),
        ),
        (
            "nested arrays",
            rows("[[[[0]]]]", 4 * ARRAY_WEIGHT + 1, MAX_WEIGHT),
        ),
        ("long strings", rows(&long, 1, MAX_WEIGHT / 100)),
        (
            "one row of many fields",
            format!("{{\"rows\": [{{{}}}]}}", fields.join(",")),
        ),
    ];
    for (what, text) in cases {
        let w = weight(&text).unwrap() as usize;
        let (got, peak) = peak_of(|| value(&text).map(drop));
        eprintln!("{what}: {} bytes, weight {w}, peak {peak}", text.len());
        assert!(got.is_ok(), "{what}: {got:?}");
        assert!(
            peak <= 2 * text.len() + PER_WEIGHT * w,
            "{what}: peak {peak} bytes for a text of {} weighing {w}",
            text.len()
        );
        // Past the limit it is refused before any value is kept.
        let over = text.replacen('[', &format!("[{}", "0,".repeat(MAX_WEIGHT as usize)), 1);
        let (got, peak) = peak_of(|| value(&over).map(drop));
        assert!(
            got.unwrap_err()
                .contains("expected values weighing at most"),
            "{what}"
        );
        assert!(peak < 4096, "{what}: a refusal kept {peak} bytes");
    }
}
