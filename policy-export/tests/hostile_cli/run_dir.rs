//! A run directory's optional summary: absent only when no such name exists. Whatever has the
//! name is read as an input is, and a directory, a FIFO or a link to a device is refused,
//! naming what it is: taken as absent, the module lost the run's provenance without a word.

use std::path::Path;

use super::{mkfifo, refused, scratch};

/// What a summary is made, and how.
type Kind<'a> = (&'a str, &'a dyn Fn(&Path));

#[test]
fn a_summary_that_is_not_a_regular_file_is_refused_not_taken_as_absent() {
    let dir = scratch("summary-kinds");
    let policy = concat!(env!("CARGO_MANIFEST_DIR"), "/../shipped/policy.safetensors");
    let out = dir.join("policy.rs");
    let kinds: [Kind; 3] = [
        ("a directory", &|p| std::fs::create_dir(p).unwrap()),
        ("a FIFO", &|p| mkfifo(p)),
        ("a device", &|p| {
            std::os::unix::fs::symlink("/dev/zero", p).unwrap()
        }),
    ];
    for (k, (kind, make)) in kinds.iter().enumerate() {
        let run = dir.join(format!("run-{k}"));
        std::fs::create_dir(&run).unwrap();
        std::fs::copy(policy, run.join("policy.safetensors")).unwrap();
        make(&run.join("summary.json"));
        // Named as the run directory, and as the policy file beside it.
        for src in [run.clone(), run.join("policy.safetensors")] {
            let export = [
                "export",
                src.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ];
            refused(
                &export,
                &format!("summary.json: expected a regular file, found {kind}"),
            );
            assert!(!out.exists(), "{kind}: nothing written");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
