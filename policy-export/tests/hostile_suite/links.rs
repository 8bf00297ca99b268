//! Output directories named through symbolic links.

use std::ffi::OsString;

use crate::hostile::{Case, Scratch};

/// A directory output named by a link and a trailing slash, which the system follows: refused
/// before a run long enough to show the work (it trained to the end, then was refused).
pub fn linked_with_a_slash(s: &Scratch) -> Vec<Case> {
    let empty = s.join("empty-run");
    std::fs::create_dir(&empty).unwrap();
    let (link, dangling) = (s.join("run-link"), s.join("dangling-link"));
    std::os::unix::fs::symlink(&empty, &link).unwrap();
    std::os::unix::fs::symlink(s.join("nowhere"), &dangling).unwrap();
    let mut cases = Vec::new();
    for (label, out) in [("link/", &link), ("dangling//", &dangling)] {
        let mut named = out.as_os_str().to_owned();
        named.push(&label[label.find('/').unwrap()..]);
        for cmd in [
            &["train", "--episodes", "3000", "--max-steps", "200"][..],
            &["reproduce", "--seeds", "2", "--study", "table1"],
        ] {
            let mut args: Vec<OsString> = cmd.iter().map(OsString::from).collect();
            args.extend([OsString::from("--out"), named.clone()]);
            cases.push(Case::new(
                format!("{cmd:?} --out {label}"),
                &args,
                &["it is a symbolic link"],
            ));
        }
    }
    cases
}
