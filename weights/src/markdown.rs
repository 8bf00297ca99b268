//! Text an input supplies (a results file's rows and provenance, a manifest's words) in
//! generated Markdown: the one way any of it enters a page, a table's cell or a code span.
//! What [`crate::quote`] is to messages and [`crate::source::comment_text`] to generated
//! source. The result is one line that opens no markup: a name with a line break, a `|` or
//! an escape sequence broke a results page's table, added headings and wrote raw control
//! characters into it.

/// Punctuation that opens Markdown's markup in running text: code, emphasis, a link, HTML
/// or an entity. Markdown drops the backslash put before any of them.
const MARKUP: &str = "`*_~[]<&";

/// `text` as Markdown text that reads as written: the punctuation that opens markup
/// (`` ` * _ ~ [ ] < & ``) and a table's `|` escaped with a backslash, which Markdown
/// drops, and every character [`crate::quote`] escapes (control, separator and format
/// characters) and the backslash written as Rust escapes them (`\n`, `\u{1b}`, `\\`), which
/// Markdown shows as they are.
pub fn text(text: &str) -> String {
    escaped(text, false)
}

/// `text` as a Markdown code span, its backticks included. Inside one Markdown escapes
/// nothing, so a backtick, which would close it, is written `\u{60}`; `|` is `\|`, which a
/// table's cell reads as `|` even in a code span; control, separator and format characters
/// and the backslash are written as [`text`] writes them.
pub fn code(text: &str) -> String {
    format!("`{}`", escaped(text, true))
}

fn escaped(text: &str, code: bool) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '|' => out.push_str("\\|"),
            '`' if code => out.push_str("\\u{60}"),
            c if !code && MARKUP.contains(c) => {
                out.push('\\');
                out.push(c);
            }
            // Quotes mean nothing to Markdown; Rust's escapes of them would only add noise.
            '\'' | '"' => out.push(c),
            c => out.extend(c.escape_debug()),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hostile_text_is_one_line_that_opens_no_markup() {
        let name = "a|b\n## injected](javascript:x) <script>";
        assert_eq!(
            text(name),
            "a\\|b\\n## injected\\](javascript:x) \\<script>"
        );
        assert_eq!(
            code("\u{1b}[2J`\n# injected | x"),
            "`\\u{1b}[2J\\u{60}\\n# injected \\| x`"
        );
        assert_eq!(text("cpu\u{7}\r\n| evil |"), "cpu\\u{7}\\r\\n\\| evil \\|");
        assert_eq!(
            text("*a* _b_ ~c~ `d` &#27; [e]"),
            "\\*a\\* \\_b\\_ \\~c\\~ \\`d\\` \\&#27; \\[e\\]"
        );
        assert_eq!(code("back\\slash"), "`back\\\\slash`");
        assert_eq!(text("rtl\u{202e}ls\u{2028}"), "rtl\\u{202e}ls\\u{2028}");
        for hostile in [name, "\u{1b}[2J`\n#", "\u{0}\t\u{7f}\u{85}"] {
            for out in [text(hostile), code(hostile)] {
                assert!(!out.chars().any(char::is_control), "{out:?}");
            }
        }
    }

    #[test]
    fn what_the_tools_write_reads_as_written() {
        for plain in [
            "host-sim eval --scenario noise+delay=2,encoder=2400/15000 --json",
            "scripts/pil_c.py",
            "AMD EPYC, family 25, model 1 (x2)",
            "2026-12-03T00:00:00Z",
            "caf\u{e9} 'quoted' \"twice\"",
        ] {
            assert_eq!(code(plain), format!("`{plain}`"));
        }
        assert_eq!(text("lqr-predict, 95% of it"), "lqr-predict, 95% of it");
    }
}
