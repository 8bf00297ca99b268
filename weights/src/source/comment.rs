//! Untrusted text in generated source: the one way any of it (a file's name, a checkpoint's
//! tensor prefix, a run's provenance) enters a comment of a Rust module or a C header.

use std::fmt::Write;

/// Longest text rendered into a comment, in characters; longer is cut and marked `...`.
pub const COMMENT_MAX: usize = 300;

/// `text` as the inside of a one-line comment, safe in a Rust `//` or `//!` comment and
/// inside a C `/* */` comment: printable ASCII stays, except that `\` becomes `\\` and the
/// sequences that could end or open a comment or splice a line (`*/`, `/*`, `//`, and the
/// trigraph `??/`) are broken with a `\`; every other character (line breaks, carriage
/// returns, NUL, U+2028 and U+2029, anything beyond ASCII) becomes `\u{HEX}`. The result is
/// one line of printable ASCII, at most about [`COMMENT_MAX`] characters and an ellipsis.
pub fn comment_text(text: &str) -> String {
    let mut out = String::new();
    let mut prev = '\0';
    for (i, c) in text.chars().enumerate() {
        if i == COMMENT_MAX {
            out.push_str("...");
            break;
        }
        match c {
            '\\' => out.push_str("\\\\"),
            // The second character of `*/`, `/*`, `//` or `??` follows a `\`.
            '/' | '*' | '?' if matches!((prev, c), ('*', '/') | ('/', '*' | '/') | ('?', '?')) => {
                out.push('\\');
                out.push(c);
            }
            ' '..='~' => out.push(c),
            _ => {
                let _ = write!(out, "\\u{{{:x}}}", u32::from(c));
            }
        }
        prev = c;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hostile_text_stays_one_printable_line_with_no_comment_delimiter() {
        let cases = [
            ("plain policy.safetensors", "plain policy.safetensors"),
            ("a\nfn evil() {}", "a\\u{a}fn evil() {}"),
            ("cr\r", "cr\\u{d}"),
            ("end */ int x;", "end *\\/ int x;"),
            ("open /* x", "open /\\* x"),
            ("nul\0", "nul\\u{0}"),
            ("ls\u{2028}ps\u{2029}", "ls\\u{2028}ps\\u{2029}"),
            ("back\\slash\\", "back\\\\slash\\\\"),
            ("line // comment", "line /\\/ comment"),
            ("tri??/", "tri?\\?/"),
            ("caf\u{e9}", "caf\\u{e9}"),
            ("tab\tdel\u{7f}", "tab\\u{9}del\\u{7f}"),
            ("***///", "***\\/\\/\\/"),
        ];
        for (raw, want) in cases {
            assert_eq!(comment_text(raw), want, "{raw:?}");
        }
    }

    #[test]
    fn long_text_is_cut() {
        let long = "x".repeat(100_000);
        let c = comment_text(&long);
        assert_eq!(c.len(), COMMENT_MAX + 3);
        assert!(c.ends_with("..."));
    }
}
