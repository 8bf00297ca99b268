//! `docs/results/manifest.toml`: how every generated file and every results file is made, one
//! step per file in the order they depend on each other. `scripts/regenerate.sh` runs the
//! steps; `host-sim tables` titles each results file's page from its step; the end-to-end
//! tests re-run a sample of each file's rows from its step's command. The file's header
//! describes the fields.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use serde::Deserialize;

/// Where the manifest lives, from the repository's root.
pub const PATH: &str = "docs/results/manifest.toml";
/// Where every results file lives: the steps' outputs there, and every file a document's
/// marker names.
pub const RESULTS_DIR: &str = "docs/results/";

/// The tools a step may need beyond cargo, as `scripts/regenerate.sh` checks them.
pub const NEEDS: [&str; 3] = ["qemu", "arm-gcc", "sb3"];

/// Largest manifest read.
const MAX_BYTES: u64 = 1 << 20;

/// Every step, in order.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    #[serde(rename = "step")]
    pub steps: Vec<Step>,
}

/// One step: a command and what it writes.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Step {
    /// What `--only`, `--from` and `--skip` match.
    pub name: String,
    /// What the step makes.
    pub about: String,
    /// The command, run by bash from the repository's root.
    pub run: String,
    /// The file or directory it writes.
    #[serde(default)]
    pub output: Option<String>,
    /// Whether the command prints the output rather than writing it.
    #[serde(default)]
    pub stdout: bool,
    /// A command run first, building what `run` needs.
    #[serde(default)]
    pub prepare: Option<String>,
    /// Tools beyond cargo, of [`NEEDS`].
    #[serde(default)]
    pub needs: Vec<String>,
    /// Whether the tools must be built again after it.
    #[serde(default)]
    pub rebuild: bool,
    /// Estimated CPU minutes.
    pub cost: f64,
}

impl Step {
    /// The command's words, if it is one plain command line: no shell syntax, each word
    /// one argument (how the tests run a step's command without a shell).
    pub fn words(&self) -> Option<Vec<&str>> {
        let plain = |c: char| c.is_ascii_alphanumeric() || "-_=+/.,:".contains(c);
        let words: Vec<&str> = self.run.split(' ').filter(|w| !w.is_empty()).collect();
        words.iter().all(|w| w.chars().all(plain)).then_some(words)
    }

    /// Whether it writes a results file: one under `docs/results/` or a reproduction.
    pub fn results(&self) -> Option<&str> {
        let out = self.output.as_deref()?;
        let json = out.starts_with(RESULTS_DIR) && out.ends_with(".json");
        (json || out == "docs/reproduction").then_some(out)
    }
}

impl Manifest {
    /// The manifest of the repository at `root`.
    pub fn load(root: &Path) -> anyhow::Result<Manifest> {
        let path = root.join(PATH);
        let bytes = weights::files::read_capped(&path, MAX_BYTES)?;
        let text =
            String::from_utf8(bytes).map_err(|_| anyhow::anyhow!("{PATH}: expected UTF-8 text"))?;
        Manifest::parse(&text).map_err(|e| anyhow::anyhow!("{PATH}: {e}"))
    }

    /// The manifest in `text`, checked: names unique and plain, every field a line that
    /// `results steps` prints as one tab-separated field, an output in the repository and
    /// written by one step (a results file's rows by several), known tools, a cost.
    pub fn parse(text: &str) -> Result<Manifest, String> {
        // The parser reads a cost of `1e-400` as 0, which it refuses written so.
        if let Some(why) = weights::hidden_zero_in_numbers(text) {
            return Err(why);
        }
        let m: Manifest =
            toml::from_str(text).map_err(|e| weights::located(text, e.span(), e.message()))?;
        // Each output's writers and whether one prints it, gathered once: a check per step
        // over all steps was quadratic in the manifest's length.
        let mut outputs: HashMap<&str, (Vec<&str>, bool)> = HashMap::new();
        for t in &m.steps {
            if let Some(o) = &t.output {
                let e = outputs.entry(o.as_str()).or_default();
                e.0.push(&t.name);
                e.1 |= t.stdout;
            }
        }
        let mut names = HashSet::new();
        for s in &m.steps {
            let at = format!("step {}", weights::quote(&s.name));
            let named = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || "-.".contains(c);
            if s.name.is_empty() || !s.name.chars().all(named) {
                return Err(format!("{at}: expected a name of a-z, 0-9, `-` and `.`"));
            }
            if !names.insert(s.name.as_str()) {
                return Err(format!("{at}: a second step of that name"));
            }
            check_fields(s).map_err(|e| format!("{at}: {e}"))?;
            if let Some((writers, printed)) = s.output.as_deref().and_then(|o| outputs.get(o))
                && let Some(other) = writers.iter().find(|w| **w != s.name)
            {
                if *printed {
                    return Err(format!(
                        "{at}: its output is printed by one step and written by another"
                    ));
                }
                // Two steps merge their rows into one results file (each under its labels);
                // any other output the second would overwrite.
                if !s.results().is_some_and(|r| r.ends_with(".json")) {
                    return Err(format!(
                        "{at}: output {} is step {}'s too; expected one step per output \
                         (several merge their rows into one results file, docs/results/*.json, \
                         alone)",
                        weights::quote(s.output.as_deref().unwrap_or_default()),
                        weights::quote(other)
                    ));
                }
            }
            check_needs_and_cost(s).map_err(|e| format!("{at}: {e}"))?;
        }
        Ok(m)
    }

    /// The steps that write `output`, in order.
    pub fn producing(&self, output: &str) -> Vec<&Step> {
        self.steps
            .iter()
            .filter(|s| s.output.as_deref() == Some(output))
            .collect()
    }
}

/// The fields `results steps` prints, by their keys.
fn fields(s: &Step) -> [(&'static str, Option<&str>); 4] {
    [
        ("run", Some(s.run.as_str())),
        ("prepare", s.prepare.as_deref()),
        ("about", Some(s.about.as_str())),
        ("output", s.output.as_deref()),
    ]
}

/// Whether `c` ends a line somewhere: a control character (a tab, a line break, an escape,
/// U+0085) or Unicode's line and paragraph separators, which editors and terminals break at.
fn breaks(c: char) -> bool {
    c.is_control() || c == '\u{2028}' || c == '\u{2029}'
}

/// Refuses a field `results steps` could not print as one field of its line, which
/// `scripts/regenerate.sh` reads with `IFS=$'\t' read`: a break in it would cut the line, an
/// empty field would vanish (runs of tabs are one separator to `read`, so the fields after it
/// shift, and the step's prose ran as its command), and `-` is the line's mark for none. An
/// output is a place in the repository that a step writes: a file or a directory's name.
fn check_fields(s: &Step) -> Result<(), String> {
    for (key, value) in fields(s) {
        let Some(v) = value else { continue };
        if let Some(c) = v.chars().find(|&c| breaks(c)) {
            return Err(format!(
                "{key}: expected no control character (a tab, a line break, an escape) and no \
                 line or paragraph separator (U+2028, U+2029), found {}",
                weights::quote(&c.to_string())
            ));
        }
        let optional = matches!(key, "prepare" | "output");
        let none = if optional {
            "; leave the key out for none"
        } else {
            ""
        };
        if v.trim().is_empty() {
            return Err(format!(
                "{key}: expected {}, found {}{none}",
                what(key),
                weights::quote(v)
            ));
        }
        if v == "-" && optional {
            return Err(format!(
                "{key}: expected {}, found \"-\", the steps' list's mark for none{none}",
                what(key)
            ));
        }
    }
    if let Some(o) = s.output.as_deref()
        && let Some(why) = misplaced(o)
    {
        return Err(format!(
            "output: expected the file or directory written, a path in the repository from its \
             root, of plain parts; found {} ({why})",
            weights::quote(o)
        ));
    }
    if s.stdout && s.output.is_none() {
        return Err("stdout = true names no output".into());
    }
    Ok(())
}

/// What a text field holds, as messages name it.
fn what(key: &str) -> &'static str {
    match key {
        "output" => "a path from the repository's root",
        "about" => "words",
        _ => "a command",
    }
}

/// Why an output is not a place in the repository a step writes: absolute, through `..`
/// (outside, where `regenerate.sh` would rename a printed output onto it), through `.` or an
/// empty part, or a directory's name ending in `/`.
fn misplaced(o: &str) -> Option<&'static str> {
    let parts = || o.split('/');
    if o.starts_with('/') {
        Some("an absolute path")
    } else if o.ends_with('/') {
        Some("a name ending in `/`")
    } else if parts().any(|p| p == "..") {
        Some("a `..` part")
    } else if parts().any(|p| p.is_empty() || p == ".") {
        Some("a `.` or empty part")
    } else {
        None
    }
}

/// Refuses a tool beyond [`NEEDS`], one named twice, or a cost that is not a number of
/// minutes.
fn check_needs_and_cost(s: &Step) -> Result<(), String> {
    if let Some(n) = s.needs.iter().find(|n| !NEEDS.contains(&n.as_str())) {
        return Err(format!(
            "needs {}, expected one of {}",
            weights::quote(n),
            NEEDS.join(", ")
        ));
    }
    if let Some((k, n)) = s
        .needs
        .iter()
        .enumerate()
        .find(|(k, n)| s.needs[..*k].contains(n))
    {
        return Err(format!(
            "needs {} twice (items {} and {k})",
            weights::quote(n),
            s.needs[..k].iter().position(|m| m == n).unwrap_or(0)
        ));
    }
    if !(s.cost.is_finite() && s.cost >= 0.0 && weights::plain(s.cost)) {
        return Err(format!(
            "expected a cost of 0 or more CPU minutes, zero or a normal number, found {:?}",
            s.cost
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
        ];
        for (text, want) in cases {
            let e = Manifest::parse(&text).unwrap_err();
            assert!(e.contains(want), "{want}: {e}");
        }
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
                "about: expected no control character (a tab, a line break, an escape) and no line or paragraph separator (U+2028, U+2029), found \"\\u{2028}\"",
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
        for (text, want) in cases {
            let e = Manifest::parse(&text).unwrap_err();
            assert!(e.contains(want), "{want}: {e}");
        }
        // A results file takes its rows from several steps, each under its labels.
        let shared = TWO.replace("stdout = true\n", "").replace(
            "cost = 0\n",
            "cost = 0\noutput = \"docs/results/eval-x.json\"\n",
        );
        let m = Manifest::parse(&shared).unwrap();
        assert_eq!(m.producing("docs/results/eval-x.json").len(), 2);
    }
}
