//! Results tables in the documents, rendered from `eval --json` files, so that a figure
//! quoted in a table cannot drift from the measurement it comes from.
//!
//! A block is a marker line naming a results file and what to show, the table, and a
//! closing line:
//!
//! ```text
//! <!-- results: docs/results/eval-shipped.json horizon=500 success=policy,lqr compare=policy,lqr -->
//! | scenario | ... |
//! <!-- /results -->
//! ```
//!
//! [`OPTIONS_HELP`] lists the options. A figure in running text is tied to one row the same
//! way ([`values`]). [`update`] renders every block and value of a document from its file;
//! `host-sim tables` writes the documents with it or, with `--check`, compares them. Markers
//! inside fenced code are text, so a document can show the syntax. Each results file has a
//! page of its own, every row with where the file came from ([`pages`]).

use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::ops::Range;

use serde::Deserialize;
use weights::quote;

use crate::eval::group;

pub mod pages;
mod pil;
pub mod values;

/// How a marker line starts; the results file and the options follow.
pub const OPEN: &str = "<!-- results:";
/// The line that closes a block.
pub const CLOSE: &str = "<!-- /results -->";
pub use crate::manifest::RESULTS_DIR;

/// The options of a marker, as `host-sim tables --help` shows them.
pub const OPTIONS_HELP: &str = "\
A block is the lines between `<!-- results: docs/results/FILE.json OPTION... -->` and
`<!-- /results -->`; FILE.json is `host-sim eval --json` output. One row per scenario, the
first column its spec; the columns follow in this order:

  horizon=N      the rows of that horizon (needed when the file has several)
  scenarios=A,B  only these scenarios, in the file's order (default: all of them)
  success=C,D    one column per controller: success rate, its Wilson 95% interval and
                 the failed episodes, e.g. `100.0% [99.6, 100.0] (0)`
  brief          success rates alone, e.g. `100.0%`
  below=A,B      `below?`: `yes` where B's success interval lies wholly below A's
  compare=A,B    RMS theta (deg, 2 decimals), RMS x (m, 3 decimals) and command switches
                 per second (1 decimal), each as `A / B`
  pil=C          controller C's processor-in-the-loop check (`eval --pil --json`): periods,
                 answers that differ from the reference's, the target's time per period
                 (median, 99th percentile and worst, us), the worst as a share of the
                 period, and the periods over it";

/// What a marker asks for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Spec {
    /// The results file, relative to the repository's root.
    pub file: String,
    /// The horizon whose rows are shown.
    pub horizon: Option<u32>,
    /// The scenarios shown, if not all.
    pub scenarios: Option<Vec<String>>,
    /// A success column per controller.
    pub success: Vec<String>,
    /// Success rates without interval and failures.
    pub brief: bool,
    /// Whether the second's success interval lies below the first's.
    pub below: Option<[String; 2]>,
    /// RMS theta, RMS x and switches of the first against the second.
    pub compare: Option<[String; 2]>,
    /// A controller's processor-in-the-loop columns.
    pub pil: Option<String>,
}

/// A marked block: its marker's line (from 1), what it asks for, and the bytes of its table.
#[derive(Debug, PartialEq)]
pub struct Block {
    pub line: usize,
    pub spec: Spec,
    pub body: Range<usize>,
}

/// Why a document's blocks cannot be rendered: the line (from 1) and what is wrong there.
#[derive(Debug, PartialEq)]
pub struct Refusal {
    pub line: usize,
    pub message: String,
}

fn refuse(line: usize, message: impl Into<String>) -> Refusal {
    Refusal {
        line,
        message: message.into(),
    }
}

/// Every block of `text`, in order, or the first marker that is malformed.
pub fn blocks(text: &str) -> Result<Vec<Block>, Refusal> {
    let mut out = Vec::new();
    // The open block: its marker's line, what it asks for, where its table starts.
    let mut open: Option<(usize, Spec, usize)> = None;
    let mut fenced = false;
    let mut at = 0;
    for (i, raw) in text.split_inclusive('\n').enumerate() {
        let (n, start) = (i + 1, at);
        let line = raw.trim_end_matches(['\n', '\r']);
        at += raw.len();
        if open.is_none() && line.trim_start().starts_with("```") {
            fenced = !fenced;
        }
        if fenced {
            continue;
        }
        if line.starts_with("<!-- results") {
            if let Some((first, ..)) = open {
                return Err(refuse(
                    n,
                    format!("a marker inside the block of line {first}"),
                ));
            }
            let rest = line
                .strip_prefix(OPEN)
                .ok_or_else(|| refuse(n, format!("expected `{OPEN} FILE OPTION... -->`")))?;
            open = Some((n, parse_spec(rest).map_err(|m| refuse(n, m))?, at));
        } else if line.starts_with("<!-- /results") {
            if line != CLOSE {
                return Err(refuse(n, format!("expected `{CLOSE}` alone on its line")));
            }
            let (first, spec, body) = open
                .take()
                .ok_or_else(|| refuse(n, "a closing marker without an opening one"))?;
            out.push(Block {
                line: first,
                spec,
                body: body..start,
            });
        }
    }
    match open {
        Some((first, ..)) => Err(refuse(
            first,
            format!("no `{CLOSE}` line closes this block"),
        )),
        None => Ok(out),
    }
}

/// The file and options after [`OPEN`].
fn parse_spec(rest: &str) -> Result<Spec, String> {
    let inner = rest
        .trim_end()
        .strip_suffix("-->")
        .ok_or("the marker does not end with `-->` on its line")?;
    let mut words = inner.split_whitespace();
    let file = words.next().ok_or("the marker names no results file")?;
    parse_results_file(file)?;
    let mut spec = Spec {
        file: file.to_string(),
        ..Spec::default()
    };
    let mut seen: Vec<&str> = Vec::new();
    for word in words {
        let (key, value) = word.split_once('=').unwrap_or((word, ""));
        if seen.contains(&key) {
            return Err(format!("option {} given twice", quote(key)));
        }
        seen.push(key);
        match (key, word.contains('=')) {
            ("brief", false) => spec.brief = true,
            ("horizon", true) => {
                let h = value.parse().map_err(|_| {
                    format!(
                        "horizon= expects a number of periods, found {}",
                        quote(value)
                    )
                })?;
                spec.horizon = Some(h);
            }
            ("scenarios", true) => spec.scenarios = Some(list(key, value)?),
            ("success", true) => spec.success = list(key, value)?,
            ("below", true) => spec.below = Some(pair(key, value)?),
            ("compare", true) => spec.compare = Some(pair(key, value)?),
            ("pil", true) => spec.pil = Some(list(key, value)?.join(",")),
            _ => {
                return Err(format!(
                    "unknown option {} (known: horizon=N, scenarios=A,B, \
                     success=C,D, brief, below=A,B, compare=A,B, pil=C)",
                    quote(word)
                ));
            }
        }
    }
    let columns = [
        spec.below.is_some(),
        spec.compare.is_some(),
        spec.pil.is_some(),
    ];
    if spec.success.is_empty() && !columns.contains(&true) {
        return Err(
            "the marker asks for no column: give success=, below=, compare= or pil=".into(),
        );
    }
    if spec.brief && spec.success.is_empty() {
        return Err("brief shortens the success= columns, and there are none".into());
    }
    Ok(spec)
}

/// `file` if it names a file directly in [`RESULTS_DIR`], of letters, digits, `.`, `-` and
/// `_`: the name then reaches every message as it is, with nothing to escape.
fn parse_results_file(file: &str) -> Result<&str, String> {
    let name = file.strip_prefix(RESULTS_DIR).unwrap_or_default();
    let plain = |c: char| c.is_ascii_alphanumeric() || "._-".contains(c);
    if !name.ends_with(".json") || !name.chars().all(plain) || name.starts_with('.') {
        return Err(format!(
            "expected a file {RESULTS_DIR}NAME.json, found {}",
            quote(file)
        ));
    }
    Ok(file)
}

fn list(key: &str, value: &str) -> Result<Vec<String>, String> {
    let items: Vec<String> = value.split(',').map(str::to_string).collect();
    if items.iter().any(String::is_empty) {
        return Err(format!(
            "{key}= expects names separated by commas, found {}",
            quote(value)
        ));
    }
    Ok(items)
}

fn pair(key: &str, value: &str) -> Result<[String; 2], String> {
    <[String; 2]>::try_from(list(key, value)?)
        .map_err(|v| format!("{key}= expects two controllers, found {}", v.len()))
}

/// The scenarios of `rows` in the file's order, those `spec` asks for if it names them.
fn scenarios<'a>(rows: &[&'a Row], spec: &Spec, horizon: u32) -> Result<Vec<&'a str>, String> {
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.scenario.as_str()) {
            names.push(&r.scenario);
        }
    }
    if let Some(wanted) = &spec.scenarios {
        if let Some(w) = wanted.iter().find(|w| !names.contains(&w.as_str())) {
            return Err(format!(
                "{} has no {} at horizon {horizon}",
                spec.file,
                quote(w)
            ));
        }
        names.retain(|n| wanted.iter().any(|w| w == n));
    }
    if names.is_empty() {
        return Err(format!("{} has no rows at horizon {horizon}", spec.file));
    }
    Ok(names)
}

/// The part of `eval --json`'s output the tables show.
#[derive(Deserialize)]
struct Results {
    rows: Vec<Row>,
    /// `eval --pil`'s checks.
    #[serde(default)]
    pil: Vec<pil::Check>,
}

/// The fields of `eval::Row` the tables show.
#[derive(Deserialize)]
struct Row {
    controller: String,
    scenario: String,
    horizon: u32,
    /// The control period, s (results files older than the field have none).
    #[serde(default)]
    period_s: Option<f64>,
    success_rate: f64,
    success_ci95: [f64; 2],
    failures: usize,
    rms_theta_deg: Mean,
    rms_x_m: Mean,
    switches_per_s: Mean,
}

#[derive(Deserialize)]
struct Mean {
    mean: f64,
}

/// The Markdown table `spec` asks for from `json`, `eval --json`'s output.
pub fn render(spec: &Spec, json: &str) -> Result<String, String> {
    render_from(spec, &parse_results(spec, json)?)
}

/// `json` as `eval --json` output, or why not.
fn parse_results(spec: &Spec, json: &str) -> Result<Results, String> {
    weights::json::parse(json)
        .map_err(|e| format!("{} is not `eval --json` output: {e}", spec.file))
}

/// [`render`] from the parsed file.
fn render_from(spec: &Spec, results: &Results) -> Result<String, String> {
    let horizon = match spec.horizon {
        Some(h) => h,
        None => only_horizon(&results.rows)
            .ok_or_else(|| format!("{} has several horizons: give horizon=N", spec.file))?,
    };
    let rows: Vec<&Row> = results
        .rows
        .iter()
        .filter(|r| r.horizon == horizon)
        .collect();
    let names = scenarios(&rows, spec, horizon)?;
    let mut out = header(spec);
    for name in names {
        let find = |c: &str| {
            rows.iter()
                .find(|r| r.scenario == name && r.controller == c)
                .copied()
                .ok_or_else(|| {
                    format!(
                        "{} has no {} on {} at horizon {horizon}",
                        spec.file,
                        quote(c),
                        quote(name)
                    )
                })
        };
        let mut cells = vec![weights::markdown::code(name)];
        for c in &spec.success {
            cells.push(success(find(c)?, spec.brief));
        }
        if let Some([a, b]) = &spec.below {
            let below = find(b)?.success_ci95[1] < find(a)?.success_ci95[0];
            cells.push(if below { "yes" } else { "no" }.to_string());
        }
        if let Some([a, b]) = &spec.compare {
            let (a, b) = (find(a)?, find(b)?);
            let (ta, tb) = (a.rms_theta_deg.mean, b.rms_theta_deg.mean);
            cells.push(format!("{ta:.2} / {tb:.2}"));
            cells.push(format!("{:.3} / {:.3}", a.rms_x_m.mean, b.rms_x_m.mean));
            let (sa, sb) = (a.switches_per_s.mean, b.switches_per_s.mean);
            cells.push(format!("{sa:.1} / {sb:.1}"));
        }
        if let Some(c) = &spec.pil {
            let check = pil::find(&results.pil, c, name, horizon).ok_or_else(|| {
                format!(
                    "{} has no pil check of {} on {}",
                    spec.file,
                    quote(c),
                    quote(name)
                )
            })?;
            let period = find(c)?.period_s.ok_or_else(|| {
                format!(
                    "{} gives no period_s for {} on {}",
                    spec.file,
                    quote(c),
                    quote(name)
                )
            })?;
            cells.extend(pil::cells(check, period));
        }
        out += &format!("| {} |\n", cells.join(" | "));
    }
    Ok(out)
}

/// The horizon of every row, if there is one.
fn only_horizon(rows: &[Row]) -> Option<u32> {
    let first = rows.first()?.horizon;
    rows.iter().all(|r| r.horizon == first).then_some(first)
}

/// The header line and the alignment line.
fn header(spec: &Spec) -> String {
    let mut names = vec!["scenario".to_string()];
    let mut align = vec!["---"];
    // The marker's names, escaped as every text from a file is.
    let text = weights::markdown::text;
    for c in spec.success.iter().map(|c| text(c)) {
        names.push(if spec.brief {
            format!("{c} success")
        } else {
            format!("{c} success [95% CI] (failed)")
        });
        align.push("---:");
    }
    if spec.below.is_some() {
        names.push("below?".to_string());
        align.push(":---:");
    }
    if let Some([a, b]) = &spec.compare {
        for quantity in ["RMS theta deg", "RMS x m", "switches/s"] {
            names.push(format!("{quantity} {} / {}", text(a), text(b)));
            align.push("---:");
        }
    }
    if let Some(c) = &spec.pil {
        for name in pil::COLUMNS {
            names.push(format!("{} {name}", text(c)));
            align.push("---:");
        }
    }
    format!("| {} |\n| {} |\n", names.join(" | "), align.join(" | "))
}

/// `100.0% [99.6, 100.0] (0)`, or `100.0%` when brief.
fn success(r: &Row, brief: bool) -> String {
    let rate = format!("{:.1}%", 100.0 * r.success_rate);
    if brief {
        return rate;
    }
    let [lo, hi] = r.success_ci95;
    let failed = group(r.failures);
    format!("{rate} [{:.1}, {:.1}] ({failed})", 100.0 * lo, 100.0 * hi)
}

/// A table or value that differs from what its file gives: its marker's line and why.
#[derive(Debug, PartialEq)]
pub struct Stale {
    pub line: usize,
    pub what: String,
}

/// `text` with every block's table and every value rendered from its results file (`load`
/// reads one, given its path from the root), and the tables and values that changed, in
/// order; or the first refusal.
pub fn update(
    text: &str,
    mut load: impl FnMut(&str) -> Result<String, String>,
) -> Result<(String, Vec<Stale>), Refusal> {
    let found = blocks(text)?;
    let marked = values::values(text)?;
    // Each edit: the bytes replaced, their new text, and the stale entry if they differ.
    let mut edits: Vec<(Range<usize>, String, Stale)> = Vec::new();
    // Each file read and parsed once, however many blocks name it: a document of a thousand
    // blocks on one file parsed it a thousand times.
    let mut parsed: HashMap<&str, Results> = HashMap::new();
    for b in &found {
        let results = match parsed.entry(&b.spec.file) {
            Entry::Occupied(e) => e.into_mut(),
            Entry::Vacant(e) => {
                let json = load(&b.spec.file).map_err(|m| refuse(b.line, m))?;
                e.insert(parse_results(&b.spec, &json).map_err(|m| refuse(b.line, m))?)
            }
        };
        let table = render_from(&b.spec, results).map_err(|m| refuse(b.line, m))?;
        let what = format!("the table differs from {}", b.spec.file);
        edits.push((b.body.clone(), table, Stale { line: b.line, what }));
    }
    let mut rows = values::Rows::default();
    for v in marked {
        if let Some(b) = found.iter().find(|b| b.body.contains(&v.body.start)) {
            let m = format!(
                "a value inside the table of line {}, which is rewritten",
                b.line
            );
            return Err(refuse(v.line, m));
        }
        let figure = rows
            .render(&v.spec, &mut load)
            .map_err(|m| refuse(v.line, m))?;
        let what = format!(
            "the value {} differs from {}'s `{figure}` ({}, {})",
            quote(&text[v.body.clone()]),
            v.spec.file,
            v.spec.field,
            values::selectors(&v.spec)
        );
        edits.push((v.body, figure, Stale { line: v.line, what }));
    }
    edits.sort_by_key(|(r, ..)| r.start);
    let mut out = String::with_capacity(text.len());
    let mut stale = Vec::new();
    let mut at = 0;
    for (range, new, s) in edits {
        if text[range.clone()] != new {
            stale.push(s);
        }
        out += &text[at..range.start];
        out += &new;
        at = range.end;
    }
    out += &text[at..];
    Ok((out, stale))
}

#[cfg(test)]
mod tests;
