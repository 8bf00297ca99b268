//! Figures in the documents' prose, written from one row of an `eval --json` file, so that a
//! number a sentence quotes cannot drift from the measurement it comes from.
//!
//! A value is a marker naming a results file, a row and a field, the figure, and a closing
//! marker, all on one line and not first on it; both markers are HTML comments, so only the
//! figure shows:
//!
//! ```text
//! RMS x <!-- value: docs/results/eval-shipped.json scenario=nominal horizon=500 controller=policy rms_x_m -->0.092<!-- /value --> m
//! ```
//!
//! [`HELP`] lists the fields and formats. [`values`] finds the markers of a document and
//! [`Rows::render`] gives each its figure; `super::update` puts them in. Markers inside fenced
//! code or an inline code span are text, so a document can show the syntax.

use std::collections::HashMap;
use std::ops::Range;

use serde_json::Value as Json;
use weights::quote;

use super::{Refusal, parse_results_file, refuse};
use crate::eval::group;

/// How an opening marker starts; the results file, the selectors and the field follow.
pub const OPEN: &str = "<!-- value:";
/// The marker that closes a value.
pub const CLOSE: &str = "<!-- /value -->";

/// The syntax, as `host-sim tables --help` shows it.
pub const HELP: &str = "\
A value is a figure in running text between `<!-- value: docs/results/FILE.json SELECTOR...
FIELD[:FORMAT] -->` and `<!-- /value -->`, both on one line and after some word of it
(Markdown shows a line that starts with one as raw HTML). The selectors
`scenario=SPEC`, `horizon=N` and `controller=C` must leave exactly one row of the file.
FIELD and its default format:

  success_rate                  %1 (`99.0%`)
  failures, successes, episodes int (`1,000`; successes are episodes less failures)
  rms_theta_deg                 .2 (the mean over episodes, as every field below)
  rms_x_m, mean_abs_x_m         .3
  switches_per_s, mean_steps    .1
  reversals_per_s               .1 (pushes of a tenth of full duty or more that reverse)
  mean_abs_duty                 %1 (the motor's mean |duty|)
  duty_tv_per_s                 .2 (the duty's total variation per second, in full pushes)
  heat                          %2 (mean squared current as a share of a full stall's)
  fallback_share                %2 (the share of periods a monitor's fallback decided)

FORMAT is `%N` (a percentage with N decimals), `.N` (N decimals) or `int` (rounded, with
thousands separators). With --check, exit 1 listing every value that differs from its row.";

/// How a figure is written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Format {
    /// Times 100, with this many decimals and a percent sign.
    Percent(usize),
    /// With this many decimals.
    Fixed(usize),
    /// Rounded to a whole number, with thousands separators.
    Int,
}

/// Every field a value can show, with its default format.
const FIELDS: [(&str, Format); 14] = [
    ("success_rate", Format::Percent(1)),
    ("failures", Format::Int),
    ("successes", Format::Int),
    ("episodes", Format::Int),
    ("rms_theta_deg", Format::Fixed(2)),
    ("rms_x_m", Format::Fixed(3)),
    ("mean_abs_x_m", Format::Fixed(3)),
    ("switches_per_s", Format::Fixed(1)),
    ("mean_steps", Format::Fixed(1)),
    ("reversals_per_s", Format::Fixed(1)),
    ("mean_abs_duty", Format::Percent(1)),
    ("duty_tv_per_s", Format::Fixed(2)),
    ("heat", Format::Percent(2)),
    ("fallback_share", Format::Percent(2)),
];

/// What an opening marker asks for.
#[derive(Clone, Debug, PartialEq)]
pub struct Spec {
    /// The results file, relative to the repository's root.
    pub file: String,
    pub scenario: Option<String>,
    pub horizon: Option<u64>,
    pub controller: Option<String>,
    /// One of [`FIELDS`].
    pub field: &'static str,
    pub format: Format,
}

/// A marked value: its line (from 1), what it asks for, and the bytes of its figure.
#[derive(Debug, PartialEq)]
pub struct Marked {
    pub line: usize,
    pub spec: Spec,
    pub body: Range<usize>,
}

/// Every value of `text`, in order, or the first marker that is malformed.
pub fn values(text: &str) -> Result<Vec<Marked>, Refusal> {
    let mut out = Vec::new();
    let mut fenced = false;
    let mut at = 0;
    for (i, raw) in text.split_inclusive('\n').enumerate() {
        let line = raw.trim_end_matches(['\n', '\r']);
        let start = at;
        at += raw.len();
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        }
        if !fenced {
            in_line(line, i + 1, start, &mut out)?;
        }
    }
    Ok(out)
}

/// The values of one line (its number `n`, at byte `start` of the text) onto `out`.
fn in_line(line: &str, n: usize, start: usize, out: &mut Vec<Marked>) -> Result<(), Refusal> {
    let code = code_spans(line);
    let mut from = 0;
    while let Some(i) = next_marker(line, from, &code) {
        let rest = &line[i..];
        if rest.starts_with("<!-- /value") {
            return Err(refuse(n, "a closing value marker without an opening one"));
        }
        if opens_block(&line[..i]) {
            return Err(refuse(
                n,
                "a value marker first on its line, which Markdown shows as raw HTML: \
                 expected a word before it",
            ));
        }
        let after = rest
            .strip_prefix(OPEN)
            .ok_or_else(|| refuse(n, format!("expected `{OPEN} FILE SELECTOR... FIELD -->`")))?;
        let end = after
            .find("-->")
            .ok_or_else(|| refuse(n, "the value marker does not end with `-->` on its line"))?;
        let inner = &after[..end];
        if inner.contains("--") || inner.ends_with('-') {
            // GitHub's Markdown ends or refuses such a comment, and would show the marker.
            return Err(refuse(n, "expected no `--` inside a value marker"));
        }
        let spec = parse_spec(inner).map_err(|m| refuse(n, m))?;
        let body = i + OPEN.len() + end + "-->".len();
        let close = line[body..]
            .find("<!--")
            .filter(|&c| line[body + c..].starts_with(CLOSE))
            .ok_or_else(|| refuse(n, format!("no `{CLOSE}` follows this value on its line")))?;
        out.push(Marked {
            line: n,
            spec,
            body: start + body..start + body + close,
        });
        from = body + close + CLOSE.len();
    }
    Ok(())
}

/// Whether a marker after `lead` would start its line's Markdown block, after nothing but
/// indentation, quote and list markers: CommonMark then reads the whole line as an HTML block,
/// not as the paragraph's text.
fn opens_block(lead: &str) -> bool {
    lead.split_whitespace().all(|w| {
        let ordered = w
            .strip_suffix(['.', ')'])
            .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()));
        matches!(w, ">" | "-" | "*" | "+") || ordered
    })
}

/// Where the next `<!-- value` or `<!-- /value` at or after `from` starts, outside `code`.
fn next_marker(line: &str, mut from: usize, code: &[Range<usize>]) -> Option<usize> {
    while let Some(i) = line[from..].find("<!--").map(|i| from + i) {
        let word = line[i + 4..].trim_start();
        let marker = word.starts_with("value") || word.starts_with("/value");
        if marker && !code.iter().any(|c| c.contains(&i)) {
            return Some(i);
        }
        from = i + 4;
    }
    None
}

/// The inline code spans of a line: a run of backticks up to the next run as long.
fn code_spans(line: &str) -> Vec<Range<usize>> {
    let b = line.as_bytes();
    let run = |i: usize| b[i..].iter().take_while(|&&c| c == b'`').count();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] != b'`' {
            i += 1;
            continue;
        }
        let n = run(i);
        let mut j = i + n;
        let mut close = None;
        while j < b.len() {
            let m = run(j);
            if m == n {
                close = Some(j + m);
                break;
            }
            j += m.max(1);
        }
        match close {
            Some(end) => {
                spans.push(i..end);
                i = end;
            }
            // A run nothing closes is literal backticks.
            None => i += n,
        }
    }
    spans
}

/// The file, selectors and field between [`OPEN`] and `-->`.
fn parse_spec(inner: &str) -> Result<Spec, String> {
    let mut words = inner.split_whitespace();
    let file = words
        .next()
        .ok_or("the value marker names no results file")?;
    let file = parse_results_file(file)?.to_string();
    let (mut scenario, mut horizon, mut controller) = (None, None, None);
    let mut field: Option<(&'static str, Format)> = None;
    for word in words {
        let Some((key, value)) = word.split_once('=') else {
            if field.is_some() {
                return Err(format!("a second field {}: a value shows one", quote(word)));
            }
            field = Some(parse_field(word)?);
            continue;
        };
        let slot = match key {
            "scenario" => &mut scenario,
            "controller" => &mut controller,
            "horizon" => {
                let h = value.parse().map_err(|_| {
                    format!(
                        "horizon= expects a number of periods, found {}",
                        quote(value)
                    )
                })?;
                if horizon.replace(h).is_some() {
                    return Err("selector `horizon` given twice".into());
                }
                continue;
            }
            _ => {
                return Err(format!(
                    "unknown selector {} (known: scenario=SPEC, horizon=N, controller=C)",
                    quote(word)
                ));
            }
        };
        if value.is_empty() || slot.replace(value.to_string()).is_some() {
            return Err(format!("selector {} empty or given twice", quote(key)));
        }
    }
    let (field, format) = field.ok_or("the value marker names no field")?;
    Ok(Spec {
        file,
        scenario,
        horizon,
        controller,
        field,
        format,
    })
}

/// `FIELD` or `FIELD:FORMAT`.
fn parse_field(word: &str) -> Result<(&'static str, Format), String> {
    let (name, format) = match word.split_once(':') {
        Some((name, format)) => (name, Some(format)),
        None => (word, None),
    };
    let &(field, default) = FIELDS.iter().find(|(f, _)| *f == name).ok_or_else(|| {
        let known: Vec<&str> = FIELDS.iter().map(|(f, _)| *f).collect();
        format!(
            "unknown field {} (known: {})",
            quote(name),
            known.join(", ")
        )
    })?;
    let format = match format {
        None => default,
        Some("int") => Format::Int,
        Some(f) => {
            let decimals = |d: &str| d.parse().ok().filter(|&d: &usize| d <= 9);
            match (f.strip_prefix('%'), f.strip_prefix('.')) {
                (Some(d), _) => decimals(d).map(Format::Percent),
                (_, Some(d)) => decimals(d).map(Format::Fixed),
                _ => None,
            }
            .ok_or_else(|| format!("unknown format {} (known: %N, .N, int; N 0 to 9)", quote(f)))?
        }
    };
    Ok((field, format))
}

/// `x` as `format` writes it.
pub fn show(x: f64, format: Format) -> String {
    match format {
        Format::Percent(d) => format!("{:.d$}%", 100.0 * x),
        Format::Fixed(d) => format!("{x:.d$}"),
        Format::Int => {
            let whole = group(x.round().abs() as usize);
            if x.round() < 0.0 {
                format!("-{whole}")
            } else {
                whole
            }
        }
    }
}

/// The rows of each results file asked for, each file read and parsed once.
#[derive(Default)]
pub struct Rows {
    files: HashMap<String, Vec<Json>>,
}

impl Rows {
    /// The figure `spec` asks for; `load` reads a file, given its path from the root.
    pub fn render(
        &mut self,
        spec: &Spec,
        load: &mut impl FnMut(&str) -> Result<String, String>,
    ) -> Result<String, String> {
        if !self.files.contains_key(&spec.file) {
            let text = load(&spec.file)?;
            let rows = parse_rows(&text)
                .ok_or_else(|| format!("{} is not `eval --json` output", spec.file))?;
            self.files.insert(spec.file.clone(), rows);
        }
        let row = select(&self.files[&spec.file], spec)?;
        let x = field(row, spec.field)
            .ok_or_else(|| format!("the row of {} has no number `{}`", spec.file, spec.field))?;
        Ok(show(x, spec.format))
    }
}

fn parse_rows(text: &str) -> Option<Vec<Json>> {
    let mut json: Json = weights::json::value(text).ok()?;
    match json.get_mut("rows")?.take() {
        Json::Array(rows) => Some(rows),
        _ => None,
    }
}

/// The one row `spec`'s selectors leave.
fn select<'a>(rows: &'a [Json], spec: &Spec) -> Result<&'a Json, String> {
    let text = |r: &Json, key: &str, want: &Option<String>| {
        want.as_ref()
            .is_none_or(|w| r.get(key).and_then(Json::as_str) == Some(w))
    };
    let found: Vec<&Json> = rows
        .iter()
        .filter(|r| {
            text(r, "scenario", &spec.scenario)
                && text(r, "controller", &spec.controller)
                && spec
                    .horizon
                    .is_none_or(|h| r.get("horizon").and_then(Json::as_u64) == Some(h))
        })
        .collect();
    match found[..] {
        [row] => Ok(row),
        [] => Err(format!(
            "no row of {} matches {}",
            spec.file,
            selectors(spec)
        )),
        _ => Err(format!(
            "{} rows of {} match {}: a value needs exactly one (add scenario=, horizon= or \
             controller=)",
            found.len(),
            spec.file,
            selectors(spec)
        )),
    }
}

/// The selectors as the marker gives them, for a message.
pub fn selectors(spec: &Spec) -> String {
    let mut out = Vec::new();
    if let Some(s) = &spec.scenario {
        out.push(format!("scenario={s}"));
    }
    if let Some(h) = spec.horizon {
        out.push(format!("horizon={h}"));
    }
    if let Some(c) = &spec.controller {
        out.push(format!("controller={c}"));
    }
    if out.is_empty() {
        return "no selector".into();
    }
    quote(&out.join(" "))
}

/// A field of a row: a number, a `{mean, ci95}`'s mean, or successes, derived.
fn field(row: &Json, name: &str) -> Option<f64> {
    if name == "successes" {
        return Some(field(row, "episodes")? - field(row, "failures")?);
    }
    let x = row.get(name)?;
    x.as_f64().or_else(|| x.get("mean")?.as_f64())
}

#[cfg(test)]
mod tests;
