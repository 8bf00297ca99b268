//! Work that grew faster than its input, held within the processor time a refusal may use
//! (the harness's measure, the child's own), and memory held to a count.

use std::process::Command;

use super::hostile::{self, Scratch};
use super::{exe, os};

/// Work and memory that grew faster than the input: `results moved` searched the old rows
/// once per new row (10 MB files of 150,000 rows took 104 s of processor time), and a
/// value parsed costs tens of bytes however short its text (16 MB of `0,` took 1.7 GB).
/// Rows are looked up by name now, and a file of more values than a results file holds is
/// refused before any is kept: at the limit the comparison stays within a refusal's budget of
/// processor time, the harness's measure; one row more is refused.
#[test]
fn comparing_results_files_at_their_count_limit_is_linear_and_one_row_more_is_refused() {
    let s = Scratch::new("hs-moved");
    // Five values a row, and two for the file and its list.
    let at_limit = ((weights::json::MAX_VALUES - 2) / 5) as usize;
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
        ran.stderr
            .contains("expected at most 100000 values, found more"),
        "{}",
        ran.stderr
    );
}
