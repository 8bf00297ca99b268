//! What reading a run directory's marker costs (`policy_export::outdir`): at its cap, at most
//! twice its size, whatever it lists. It is read as it streams, each entry judged and none
//! kept; parsed whole, a list of short names took 100 MB, 6 times the marker. Measured by
//! the counting allocator, in bytes.

#[path = "../../weights/tests/support/counting.rs"]
mod counting;

use counting::{alone, peak_of};
use policy_export::outdir::{MARKER, MAX_MARKER_BYTES, check_output_dir};

/// `{"tool": ..., LIST: [ITEM(0), ITEM(1), ...]}` of as many items as stay within the cap.
fn marker(list: &str, item: impl Fn(usize) -> String) -> String {
    let mut text = format!(r#"{{"tool":"policy-export","version":"0","kind":"train","{list}":["#);
    let cap = usize::try_from(MAX_MARKER_BYTES).unwrap() - 2;
    for i in 0.. {
        let next = item(i);
        if text.len() + next.len() + 1 > cap {
            break;
        }
        if i > 0 {
            text.push(',');
        }
        text += &next;
    }
    text + "]}"
}

#[test]
fn a_marker_at_its_cap_costs_at_most_twice_its_size_to_read() {
    let _alone = alone();
    let dir = std::env::temp_dir().join(format!("pe-marker-memory-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases = [
        // An earlier version's list of names, the shortest: refused, read whole first.
        (
            marker("files", |i| format!("\"{i}\"")),
            Some("lists files without their sizes and digests"),
        ),
        // Entries for files no longer there (a user may remove a run's files): the run's.
        (
            marker("entries", |i| {
                format!(r#"{{"path":"{i}","bytes":0,"fnv1a64":"cbf29ce484222325"}}"#)
            }),
            None,
        ),
    ];
    for (text, refusal) in cases {
        std::fs::write(dir.join(MARKER), &text).unwrap();
        let size = std::fs::metadata(dir.join(MARKER)).unwrap().len();
        assert!(size > MAX_MARKER_BYTES - 100 && size <= MAX_MARKER_BYTES);
        drop(text);
        let (checked, peak) =
            peak_of(|| check_output_dir(&dir, "train").map_err(|e| e.to_string()));
        match (checked, refusal) {
            (Ok(()), None) => {}
            (Err(e), Some(want)) if e.contains(want) => {}
            other => panic!("{other:?}"),
        }
        assert!(peak as u64 <= 2 * size, "{peak} bytes to read {size}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
