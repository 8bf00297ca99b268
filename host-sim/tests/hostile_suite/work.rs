//! Work that grew faster than its input, held within the processor time a refusal may use
//! (the harness's measure, the child's own).

use std::process::Command;

use super::hostile::{self, Scratch};
use super::{exe, os};

/// Work that grew with the square of its input: `results moved` searched the old rows once
/// per new row (10 MB files of 150,000 rows took 104 s of processor time). Linear now, it
/// stays within a refusal's budget of processor time, the harness's measure.
#[test]
fn comparing_results_files_of_many_rows_is_not_quadratic() {
    let s = Scratch::new("hs-moved");
    let rows = |tag: &str| {
        let row =
            |i: usize| format!(r#"{{"controller":"c","scenario":"{tag}{i}","horizon":1,"x":{i}}}"#);
        let rows: Vec<String> = (0..150_000).map(row).collect();
        format!(r#"{{"rows":[{}]}}"#, rows.join(","))
    };
    let (old, new) = (s.join("old.json"), s.join("new.json"));
    std::fs::write(&old, rows("s")).unwrap();
    std::fs::write(&new, rows("t")).unwrap();
    let ran =
        hostile::run_counted(Command::new(exe()).args(os(&[&"results", &"moved", &old, &new])));
    assert_eq!(ran.code, Some(0), "{}", ran.stderr);
    assert!(ran.late().is_none(), "{:?}", ran.late());
    let out = String::from_utf8_lossy(&ran.stdout);
    assert!(out.contains("150000 rows, 0 moved beyond their 95% intervals, 0 changed within them, 150000 new, 150000 gone"), "{}", &out[..out.len().min(300)]);
}
