use super::*;

/// Each manifest text is refused with its words among the message's.
fn refused<const N: usize>(cases: [(String, &str); N]) {
    for (text, want) in cases {
        let e = Manifest::parse(&text).unwrap_err();
        assert!(e.contains(want), "{want}: {e}");
    }
}

const TWO: &str = r#"
[[step]]
name = "eval-x"
about = "x"
run = "host-sim eval --scenario noise+delay=2 --json"
output = "docs/results/eval-x.json"
stdout = true
cost = 1.5

[[step]]
name = "tables"
about = "the documents"
run = "host-sim tables && echo done"
cost = 0
"#;

/// The list's mark for none as a name, an output a command reads as an option or in the
/// repository's own history, and a command printed turned around (U+202E).
#[test]
fn refuses_what_a_script_would_misread() {
    let cases = [
        (
            TWO.replace("name = \"tables\"", "name = \"-\""),
            "starting with a letter",
        ),
        (
            TWO.replace("eval-x.json\"", "-rf\""),
            "a part starting with `-`",
        ),
        (
            TWO.replace("docs/results/eval-x.json\"", ".git/config\""),
            "own `.git`",
        ),
        // One name in NFC and in NFD: two outputs on Linux, one on macOS.
        (
            TWO.replace("eval-x.json\"", "re\u{301}s.json\""),
            "a part of other characters than a-z",
        ),
        // One place where case is ignored (macOS, Windows): `.GIT` is the repository's.
        (
            TWO.replace("docs/results/eval-x.json\"", "DOCS/results/eval-x.json\""),
            "takes `runs/X`",
        ),
        (
            TWO.replace("docs/results/eval-x.json\"", ".GIT/config\""),
            "a part of other characters",
        ),
        (
            TWO.replace("eval-x.json\"", "$(id).json\""),
            "a shell reads",
        ),
        (TWO.replace("eval-x.json\"", "x.\""), "ending in `.`"),
        (
            TWO.replace("docs/results/eval-x.json\"", "docs/results/manifest.toml\""),
            "the manifest itself",
        ),
        (
            TWO.replace("echo done", "echo \u{202e}enod"),
            "no invisible format",
        ),
    ];
    refused(cases);
}

#[test]
fn reads_steps_their_words_and_results() {
    let m = Manifest::parse(TWO).unwrap();
    assert_eq!(m.steps.len(), 2);
    // Words are no number: only a cost written `1e-400` is refused.
    Manifest::parse(&TWO.replace("about = \"x\"", "about = \"below 1e-400\"")).unwrap();
    let words = m.steps[0].words().unwrap();
    assert_eq!(
        words,
        ["host-sim", "eval", "--scenario", "noise+delay=2", "--json"]
    );
    assert_eq!(m.steps[0].results(), Some("docs/results/eval-x.json"));
    assert_eq!(m.steps[1].words(), None, "`&&` is the shell's");
    assert_eq!(m.steps[1].results(), None);
    assert_eq!(m.producing("docs/results/eval-x.json")[0].name, "eval-x");
}

#[test]
fn refuses_what_the_script_could_not_run() {
    let cases = [
        (
            TWO.replace("\"tables\"", "\"eval-x\""),
            "a second step of that name",
        ),
        (
            TWO.replace("\"tables\"", "\"T\\u001b\""),
            "step \"T\\u{1b}\": expected a name of a-z",
        ),
        (
            TWO.replace("cost = 0\n", "cost = -1\n"),
            "a cost of 0 or more",
        ),
        (
            TWO.replace("cost = 0\n", "cost = 0\nneeds = [\"gpu\"]\n"),
            "needs \"gpu\"",
        ),
        (
            TWO.replace(
                "stdout = true\ncost = 1.5",
                "cost = 1.5\nstdout = true\nrebuilt = 1",
            ),
            "unknown field",
        ),
        (
            TWO.replace("output = \"docs/results/eval-x.json\"\n", ""),
            "names no output",
        ),
        (
            TWO.replace("run = \"host-sim tables", "run = \"\\thost-sim tables"),
            "no control character",
        ),
        (
            TWO.replace("about = \"x\"", "about = \"x\\u001b[2J\\u0007y\""),
            "no control character",
        ),
        (
            TWO.replace("eval-x.json\"", "eval-x\\u001b.json\""),
            "no control character",
        ),
        (
            TWO.replace("cost = 0\n", "cost = 5e-324\n"),
            "zero or a normal number, found 5e-324",
        ),
        // Read as 0 by the parser, as if written so.
        (
            TWO.replace("cost = 0\n", "cost = 1e-400\n"),
            "1e-400 reads as 0",
        ),
        (
            TWO.replace("cost = 0\n", "cost = 0\nneeds = [\"qemu\", \"qemu\"]\n"),
            "needs \"qemu\" twice (items 0 and 1)",
        ),
        (
            TWO.replace(
                "cost = 0\n",
                "cost = 0\noutput = \"docs/results/eval-x.json\"\n",
            ),
            "printed by one step and written by another",
        ),
        (
            TWO.replace("cost = 0\n", "cost = -0.0\n"),
            "a cost of 0 or more CPU minutes, zero or a normal number, found -0.0",
        ),
        // A file in the other's directory: the next run of that step refuses to replace it.
        (
            TWO.replace(
                "cost = 0\n",
                "cost = 0\noutput = \"docs/results/eval-x.json/extra.txt\"\n",
            ),
            "step \"tables\": output \"docs/results/eval-x.json/extra.txt\" lies inside step \
             \"eval-x\"'s output \"docs/results/eval-x.json\"",
        ),
    ];
    refused(cases);
}

/// Every field `results steps` prints is one tab-separated field that `regenerate.sh`'s
/// `IFS=$'\t' read` gives back: an empty one vanished there (the step's about ran as its
/// command), `-` is its none, a separator is a line break to an editor.
#[test]
fn refuses_a_field_the_steps_list_cannot_carry() {
    let out = "output = \"docs/results/eval-x.json\"";
    let cases = [
        (
            TWO.replace(out, "output = \"\""),
            "\"eval-x\": output: expected",
        ),
        (
            TWO.replace(out, "output = \"-\""),
            "output: expected a path",
        ),
        (
            TWO.replace(out, "output = \"/etc/passwd\""),
            "(an absolute path)",
        ),
        (TWO.replace(out, "output = \"../../x\""), "(a `..` part)"),
        (
            TWO.replace(out, "output = \"docs/./x\""),
            "(a `.` or empty part)",
        ),
        (
            TWO.replace(out, "output = \"docs/\""),
            "(a name ending in `/`)",
        ),
        (
            TWO.replace("cost = 0\n", "cost = 0\nprepare = \"\"\n"),
            "\"tables\": prepare: expected a command, found \"\"; leave",
        ),
        (
            TWO.replace("cost = 0\n", "cost = 0\nprepare = \"-\"\n"),
            "prepare: expected a command, found \"-\", the steps' list's mark",
        ),
        (
            TWO.replace("about = \"x\"", "about = \" \""),
            "about: expected words, found \" \"",
        ),
        (
            TWO.replace("about = \"x\"", "about = \"x\u{2028}y\""),
            "about: expected no control character (a tab, a line break, an escape), no line or paragraph separator (U+2028, U+2029) and no invisible format character (U+202E), found \"\\u{2028}\"",
        ),
        (
            TWO.replace("about = \"x\"", "about = \"x\u{2029}y\""),
            "found \"\\u{2029}\"",
        ),
        (
            TWO.replace("about = \"x\"", "about = \"x\u{85}y\""),
            "found \"\\u{85}\"",
        ),
        (
            TWO.replace("&& echo done", "&& echo \u{2028}"),
            "run: expected no control",
        ),
        (
            TWO.replace(out, "output = \"o\u{2028}\""),
            "output: expected no control",
        ),
        (
            TWO.replace(out, "output = \"runs/x\"")
                .replace("stdout = true\n", "")
                .replace("cost = 0\n", "cost = 0\noutput = \"runs/x\"\n"),
            "step \"eval-x\": output \"runs/x\" is step \"tables\"'s too; expected one step per output",
        ),
    ];
    refused(cases);
    // A results file takes its rows from several steps, each under its labels.
    let shared = TWO.replace("stdout = true\n", "").replace(
        "cost = 0\n",
        "cost = 0\noutput = \"docs/results/eval-x.json\"\n",
    );
    let m = Manifest::parse(&shared).unwrap();
    assert_eq!(m.producing("docs/results/eval-x.json").len(), 2);
}
