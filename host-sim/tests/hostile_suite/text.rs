//! The hostile suite's text flags: bytes that are not UTF-8 where a command takes text.

use std::ffi::OsString;

use super::hostile::{Case, Scratch};
use super::{os, repo};

/// Text flags given bytes that are not UTF-8: each is named with what it was given, a stray
/// byte as U+FFFD (clap's message named neither), even past a path that is not UTF-8, which
/// is taken.
pub fn bad_text(s: &Scratch) -> Vec<Case> {
    use std::os::unix::ffi::OsStrExt;
    let bytes = |b: &[u8]| std::ffi::OsStr::from_bytes(b).to_owned();
    let policy = s.0.join(std::ffi::OsStr::from_bytes(b"p\xff.safetensors"));
    std::fs::copy(repo("shipped/policy.safetensors"), &policy).unwrap();
    let cases: [(Vec<OsString>, &'static str); 7] = [
        (
            os(&[&"eval", &"--scenario", &bytes(b"noise\xff")]),
            "--scenario: expected UTF-8 text, found \"noise\u{fffd}\"",
        ),
        // Two flags so given: the first is named; a flag given again after it: named, not
        // "argument 3".
        (
            os(&[
                &"eval",
                &"--episodes",
                &bytes(b"1\xff"),
                &"--scenario",
                &bytes(b"noise\xff"),
            ]),
            "--episodes: expected UTF-8 text, found \"1\u{fffd}\"",
        ),
        (
            os(&[
                &"eval",
                &"--episodes",
                &bytes(b"1\xff"),
                &"--episodes",
                &"2",
            ]),
            "--episodes: expected UTF-8 text, found \"1\u{fffd}\"",
        ),
        (
            os(&[
                &"eval",
                &"--policy",
                &policy,
                &"--episodes",
                &bytes(b"1\xff"),
            ]),
            "--episodes: expected UTF-8 text, found \"1\u{fffd}\"",
        ),
        (
            os(&[&"startup", &bytes(b"--knock=1@2\xfe")]),
            "--knock: expected UTF-8 text, found \"1@2\u{fffd}\"",
        ),
        (
            os(&[&"results", &"moved", &"a", &"b", &"--name", &bytes(b"\xc3")]),
            "--name: expected UTF-8 text, found \"\u{fffd}\"",
        ),
        (
            os(&[&"eval", &"--controller", &bytes(b"lqr\xff")]),
            "invalid value 'lqr\u{fffd}' for '--controller",
        ),
    ];
    cases
        .into_iter()
        .map(|(args, want)| Case::new(format!("{args:?}"), &args, &[want]))
        .collect()
}
