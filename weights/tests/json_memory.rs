//! The JSON reader's peak memory (`weights::json::parse`, every results file, run summary,
//! envelope and marker the tools read back) on texts made to amplify, each at the count
//! limit: a value costs tens of bytes however short its text, and an object a whole map node,
//! so the count, not the size, bounds the memory. Measured by the counting allocator, in
//! bytes, never time.

#[path = "support/counting.rs"]
mod counting;

use counting::{alone, peak_of};
use serde_json::Value;
use weights::json::{MAX_VALUES, parse};

/// Memory beyond the text's own bytes (which a value may copy, as a string does) that a
/// parse at the limit may take.
const CONSTANT: usize = 40 << 20;

/// `{"rows": [ITEM, ...]}` with as many items as leave the file at `values` values, each item
/// `per` values.
fn rows(item: &str, per: u64, values: u64) -> String {
    let n = ((values - 2) / per) as usize;
    format!("{{\"rows\": [{}]}}", vec![item; n].join(","))
}

#[test]
fn a_file_at_the_count_limit_costs_its_text_and_a_constant_whatever_its_shape() {
    let _alone = alone();
    let long = format!("\"{}\"", "s".repeat(4096));
    let one_key = format!("{{\"{}\": 0}}", "k".repeat(200));
    let fields: Vec<String> = (0..MAX_VALUES - 3).map(|i| format!("\"{i}\": 0")).collect();
    let cases = [
        ("numbers", rows("0", 1, MAX_VALUES)),
        ("empty objects", rows("{}", 1, MAX_VALUES)),
        ("objects of one long key", rows(&one_key, 2, MAX_VALUES)),
        ("nested arrays", rows("[[[[0]]]]", 5, MAX_VALUES)),
        ("long strings", rows(&long, 1, MAX_VALUES / 10)),
        (
            "one row of many fields",
            format!("{{\"rows\": [{{{}}}]}}", fields.join(",")),
        ),
    ];
    for (what, text) in cases {
        let (got, peak) = peak_of(|| parse::<Value>(&text).map(drop));
        eprintln!("{what}: {} bytes, peak {peak}", text.len());
        assert!(got.is_ok(), "{what}: {got:?}");
        assert!(
            peak <= 2 * text.len() + CONSTANT,
            "{what}: peak {peak} bytes for a text of {}",
            text.len()
        );
        // One value more is refused before any is kept.
        let over = text.replacen("[", &format!("[{}", "0,".repeat(MAX_VALUES as usize)), 1);
        let (got, peak) = peak_of(|| parse::<Value>(&over).map(drop));
        assert!(got.unwrap_err().contains("expected at most"), "{what}");
        assert!(peak < 4096, "{what}: a refusal kept {peak} bytes");
    }
}
