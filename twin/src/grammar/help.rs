//! The parts' table as people read it: the syntax list, a flag's help, the Markdown table.

use super::{Fallback, Field, PARTS, PartSpec, Stretch};

/// Every part's syntax, comma-separated: what an error lists and the help shows.
pub fn syntax_list() -> String {
    let all: Vec<&str> = PARTS.iter().map(|p| p.syntax).collect();
    all.join(", ")
}

/// The help of a `--scenario` flag: of a list of scenarios, one row each, which the sets
/// may name, or (`rows` false) of one.
pub fn scenario_help(rows: bool) -> String {
    let one = format!("`nominal`, or parts joined by `+` from {}", syntax_list());
    if !rows {
        return format!("One scenario: {one}");
    }
    format!(
        "Scenarios, one row each: {one}; `all` is the robustness set, `hard` the set beyond \
         it, `hard-candidates` what that set is chosen from (on Gymnasium's machine alone), `faults` \
         one row per fault"
    )
}

/// The table of parts in Markdown, as `docs/SCENARIOS.md` shows it (`host-sim parts` prints
/// it; a test keeps the document's copy equal to it).
pub fn markdown_table() -> String {
    let mut out = String::from("| part | values | what it does |\n| --- | --- | --- |\n");
    for p in PARTS {
        let values: Vec<String> = p.fields.iter().map(describe).collect();
        out.push_str(&format!(
            "| `{}` | {}{}{} | {} |\n",
            p.syntax,
            values.join("; "),
            idle(p),
            stretch(p),
            p.doc
        ));
    }
    out
}

/// A field's bounds and what it is when left out, as the table shows them.
fn describe(f: &Field) -> String {
    let left_out = match f.fallback {
        Fallback::Required => String::new(),
        Fallback::Value(v) => format!(", default {v}"),
        Fallback::FiveTimesFirst => ", default 5 times the first".into(),
        Fallback::Absent => ", optional".into(),
    };
    format!("{} {} to {}{left_out}", f.name, f.lo, f.hi)
}

/// The values a part is refused at, as the table shows them.
fn idle(p: &PartSpec) -> String {
    let Some((fields, at)) = p.idle_fields() else {
        return String::new();
    };
    let names: Vec<&str> = fields.iter().map(|f| f.name).collect();
    format!(
        "; not {} {at} (it would change nothing)",
        names.join(" and ")
    )
}

/// How long a part's stretch may be ([`super::Stretch`]), as the table shows it.
fn stretch(p: &PartSpec) -> String {
    match p.stretch {
        None => String::new(),
        Some(Stretch { always: None, .. }) => "; K at most EVERY".into(),
        Some(Stretch {
            always: Some(instead),
            ..
        }) => format!("; K below EVERY (in every period, it is `{instead}`)"),
    }
}
