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
            // `-` alone is the steps' list's mark for none, and a leading `-` an option's.
            let leads = s.name.starts_with(|c: char| c.is_ascii_alphanumeric());
            if !leads || !s.name.chars().all(named) {
                return Err(format!(
                    "{at}: expected a name of a-z, 0-9, `-` and `.`, starting with a letter or \
                     a digit"
                ));
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
        // After each step's own checks, which name a malformed output (`runs/x/`) as such.
        nested(&m.steps)?;
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
    c.is_control() || c == '\u{2028}' || c == '\u{2029}' || invisible(c)
}

/// Whether `c` is a format character a terminal shows as nothing while it reorders or hides
/// what follows (U+202E turned a printed command around): Unicode's bidirectional controls,
/// zero-width characters and the byte-order mark.
fn invisible(c: char) -> bool {
    matches!(c, '\u{200B}'..='\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2060}'..='\u{2069}' | '\u{FEFF}')
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
                "{key}: expected no control character (a tab, a line break, an escape), no \
                 line or paragraph separator (U+2028, U+2029) and no invisible format \
                 character (U+202E), found {}",
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
/// empty part, a directory's name ending in `/`, a part a command would read as an option
/// (`-rf`), the repository's `.git`, the manifest, or a part not [`plain`].
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
    } else if parts().any(|p| p.starts_with('-')) {
        Some("a part starting with `-`, which a command reads as an option")
    } else if parts().any(|p| p == ".git") {
        Some("the repository's own `.git`")
    } else if parts().any(|p| !p.chars().all(plain) || p.ends_with('.') || p.len() > 255) {
        Some(
            "a part of other characters than a-z, 0-9, `.`, `_` and `-`, ending in `.` or past \
             255 bytes: a file system that ignores case or normalises Unicode takes `runs/X` \
             or `re\u{301}s` for `runs/x` or `r\u{e9}s`, and a shell reads `$` or `*`",
        )
    } else if o == PATH {
        Some("the manifest itself")
    } else {
        None
    }
}

/// Whether `c` may be part of an output's name: one place on every file system, as its
/// name says, and nothing a shell reads.
fn plain(c: char) -> bool {
    c.is_ascii_lowercase() || c.is_ascii_digit() || "._-".contains(c)
}

/// Refuses an output inside another step's (a file in `train`'s run directory): the step
/// that writes it adds a file the run did not write, and the next `train` refuses to
/// replace the run. Compared by components, sorted, so that whatever lies inside an output
/// follows it at once and neighbours alone are compared.
fn nested(steps: &[Step]) -> Result<(), String> {
    let mut places: Vec<(Vec<&str>, &Step)> = steps
        .iter()
        .filter_map(|s| Some((s.output.as_deref()?.split('/').collect(), s)))
        .collect();
    places.sort_by(|a, b| a.0.cmp(&b.0));
    for w in places.windows(2) {
        let ((outer, a), (inner, b)) = (&w[0], &w[1]);
        if inner.len() > outer.len() && inner.starts_with(outer) {
            return Err(format!(
                "step {}: output {} lies inside step {}'s output {}; expected a place of its own",
                weights::quote(&b.name),
                weights::quote(&inner.join("/")),
                weights::quote(&a.name),
                weights::quote(&outer.join("/"))
            ));
        }
    }
    Ok(())
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
    // `-0.0` passed `>= 0` and was shown as the step's cost.
    if !(s.cost.is_finite() && s.cost.is_sign_positive() && weights::plain(s.cost)) {
        return Err(format!(
            "expected a cost of 0 or more CPU minutes, zero or a normal number, found {:?}",
            s.cost
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
