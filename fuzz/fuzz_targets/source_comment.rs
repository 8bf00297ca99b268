//! Untrusted text into generated source: any text rendered by `comment_text` is one line of
//! printable ASCII with no comment delimiter, and as a name and a provenance line of an
//! export, either refused or confined to comments: the code is that of a plain export.
#![no_main]

use firmware::network::shapes;
use firmware::rig::Rig;
use libfuzzer_sys::fuzz_target;
use weights::Weights;
use weights::source::{
    COMMENT_MAX, c_header, check_c_name, check_rust_name, comment_text, rust_module,
};

/// `text` without the provenance lines, which start with `prefix`.
fn code(text: &str, prefix: &str) -> Vec<String> {
    text.lines()
        .filter(|l| !l.starts_with(prefix))
        .map(String::from)
        .collect()
}

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let c = comment_text(&text);
    assert!(c.bytes().all(|b| (b' '..=b'~').contains(&b)), "{c:?}");
    for seq in ["*/", "/*", "//", "??"] {
        assert!(!c.contains(seq), "{seq} in {c:?}");
    }
    // Each character at most `\u{10ffff}`.
    assert!(c.len() <= 10 * COMMENT_MAX + 3);
    let name = text.lines().next().unwrap_or("");
    let w = Weights::new(16, weights::BANG_BANG.to_vec(), shapes(16, 2).map(|s| vec![0.5; s.len()])).unwrap();
    let (hostile, plain) = (vec![text.to_string()], vec!["plain".to_string()]);
    if check_rust_name(name).is_ok() {
        let a = rust_module(&w, name, &hostile, &Rig::GYMNASIUM).unwrap();
        let b = rust_module(&w, name, &plain, &Rig::GYMNASIUM).unwrap();
        assert_eq!(code(&a, "//! - "), code(&b, "//! - "));
    }
    if check_c_name(name).is_ok() {
        assert!(name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_'));
        let a = c_header(&w, name, &hostile, &Rig::GYMNASIUM).unwrap();
        let b = c_header(&w, name, &plain, &Rig::GYMNASIUM).unwrap();
        assert_eq!(code(&a, " * - "), code(&b, " * - "));
    }
});
