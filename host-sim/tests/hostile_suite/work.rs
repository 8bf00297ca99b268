//! Work that grew faster than its input, held within the processor time a refusal may use
//! (the harness's measure, the child's own), and memory held to a count.

use std::process::Command;

use super::hostile::{self, Scratch};
use super::{exe, os};

/// Work and memory that grew faster than the input: `results moved` searched the old rows
/// once per new row (10 MB files of 150,000 rows took 104 s of processor time), and a
/// value parsed costs tens of bytes however short its text (16 MB of `0,` took 1.7 GB).
/// Rows are looked up by name now, and a file whose values weigh more than `eval`'s largest
/// output is refused before any is kept: at the limit the comparison stays within a refusal's
/// budget of processor time, the harness's measure; one row more is refused.
#[test]
fn comparing_results_files_at_their_weight_limit_is_linear_and_one_row_more_is_refused() {
    let s = Scratch::new("hs-moved");
    // A row is an object of four keys and values; the file an object with a key and a list.
    use weights::json::{ARRAY_WEIGHT, KEY_WEIGHT, MAX_WEIGHT, OBJECT_WEIGHT};
    let row_weight = OBJECT_WEIGHT + 4 * (KEY_WEIGHT + 1);
    let at_limit = ((MAX_WEIGHT - OBJECT_WEIGHT - KEY_WEIGHT - ARRAY_WEIGHT) / row_weight) as usize;
    let rows = |tag: &str, n: usize| {
        let row =
            |i: usize| format!(r#"{{"controller":"c","scenario":"{tag}{i}","horizon":1,"x":{i}}}"#);
        let rows: Vec<String> = (0..n).map(row).collect();
        format!(r#"{{"rows":[{}]}}"#, rows.join(","))
    };
    let (old, new, over) = (s.join("old.json"), s.join("new.json"), s.join("over.json"));
    std::fs::write(&old, rows("s", at_limit)).unwrap();
    std::fs::write(&new, rows("t", at_limit)).unwrap();
    std::fs::write(&over, rows("t", at_limit + 1)).unwrap();
    let moved = |new: &std::path::Path| {
        hostile::run_counted(Command::new(exe()).args(os(&[&"results", &"moved", &old, &new])))
    };
    let ran = moved(&new);
    assert_eq!(ran.code, Some(0), "{}", ran.stderr);
    assert!(ran.late().is_none(), "{:?}", ran.late());
    let out = String::from_utf8_lossy(&ran.stdout);
    let want = format!(
        "{n} rows, 0 moved beyond their 95% intervals, 0 changed within them, {n} new, {n} gone",
        n = at_limit
    );
    assert!(out.contains(&want), "{}", &out[..out.len().min(300)]);
    let ran = moved(&over);
    assert_eq!(ran.code, Some(2), "{}", ran.stderr);
    assert!(
        ran.stderr.contains("expected values weighing at most"),
        "{}",
        ran.stderr
    );
}
