//! One page per results file, `docs/results/NAME.md` beside `NAME.json`: what the file
//! measures (its step in the manifest), where it came from (its provenance: command, date,
//! revision, machine) and every row as a table. The documents link to these pages and quote
//! only the figures a sentence needs.

use host_common::provenance::Provenance;
use serde::Deserialize;
use serde_json::Value as Json;

use weights::markdown::{code, text};

use super::pil;
use super::values::{Format, show};
use crate::eval::group;
use crate::manifest::Step;

/// The page of `file` (`docs/results/NAME.json`).
pub fn path(file: &str) -> String {
    format!("{}.md", file.strip_suffix(".json").unwrap_or(file))
}

/// The page of the results file `file` whose text is `json`, made by `steps` of the
/// manifest.
pub fn page(file: &str, json: &str, steps: &[&Step]) -> Result<String, String> {
    let doc: Json = weights::json::value(json).map_err(|e| format!("{file} is not JSON: {e}"))?;
    let name = file.rsplit('/').next().unwrap_or(file);
    let mut s = format!("# {}\n\n", text(name.trim_end_matches(".json")));
    match steps {
        [] => {}
        [one] => s += &format!("{}.\n\n", capitalised(&one.about)),
        several => {
            for st in several {
                s += &format!("- {}.\n", capitalised(&st.about));
            }
            s += "\n";
        }
    }
    // The link's target is the name as it is: `tables` takes only names that need no
    // escaping there (`tables_cmd::results_files`).
    s += &format!(
        "Written by `host-sim tables` from [{}]({name}); do not edit. \
         `scripts/regenerate.sh` measures it again (`docs/results/manifest.toml`).\n\n",
        code(name)
    );
    s += &origin(&doc, steps).map_err(|e| format!("{file}: {e}"))?;
    let body = if doc.get("envelope").is_some() {
        envelope(&doc)
    } else {
        rows(&doc)
    };
    Ok(s + &body.map_err(|e| format!("{file}: {e}"))?)
}

/// Where the list of pages goes.
pub const INDEX: &str = "docs/results/README.md";

/// The list of pages, `docs/results/README.md`: per results file (its name, the JSON's text
/// and the steps that make it), its page, what it measures and when it was measured.
pub fn index(files: &[(String, String, Vec<&Step>)]) -> Result<String, String> {
    let mut s = String::from(
        "# Results\n\nEvery results file of the repository, with the page `host-sim tables` \
         writes for it: the command that made it, when and where, and every row. Written by \
         `host-sim tables`; do not edit. The commands are `docs/results/manifest.toml`'s; \
         `scripts/regenerate.sh` runs them (`docs/DEVELOPMENT.md`). The paper's reproduction \
         is [`docs/reproduction/tables.md`](../reproduction/tables.md) \
         (`docs/REPRODUCTION.md`).\n\n| page | what it measures | measured |\n| --- | --- | --- |\n",
    );
    for (name, json, steps) in files {
        let doc: Json =
            weights::json::value(json).map_err(|e| format!("{name} is not JSON: {e}"))?;
        let first = match doc.get("provenance") {
            Some(Json::Array(runs)) => runs.first(),
            other => other,
        };
        let when = first
            .and_then(|p| p.get("date")?.as_str())
            .map_or("before files recorded it".to_string(), |d| {
                text(&d.chars().take(10).collect::<String>())
            });
        let about = steps
            .first()
            .map_or(String::new(), |st| capitalised(&st.about));
        let page = path(name);
        let page = page.rsplit('/').next().unwrap_or(&page);
        s += &format!(
            "| [{}]({page}) | {about} | {when} |\n",
            text(page.trim_end_matches(".md"))
        );
    }
    Ok(s)
}

/// A manifest's words as a sentence's start, escaped ([`text`]).
fn capitalised(words: &str) -> String {
    let mut c = words.chars();
    let up: String = c
        .next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default();
    text(&up)
}

/// Where the file came from: its provenance (one run, or one per run for a file several
/// runs merge into), or, for a file measured before files recorded it, the manifest's
/// commands.
fn origin(doc: &Json, steps: &[&Step]) -> Result<String, String> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Runs {
        One(Provenance),
        Several(Vec<Provenance>),
    }
    let runs = match doc.get("provenance") {
        None => None,
        Some(p) => Some(
            match Runs::deserialize(p).map_err(|e| format!("a malformed provenance: {e}"))? {
                Runs::One(p) => vec![p],
                Runs::Several(ps) => ps,
            },
        ),
    };
    let Some(runs) = runs else {
        let mut s = String::from(
            "The file records no provenance: it was measured before results files did. The \
             manifest makes it with:\n\n",
        );
        for st in steps {
            s += &format!("- {}\n", code(&st.run));
        }
        return Ok(s + "\n");
    };
    Ok(runs.iter().map(|p| p.markdown() + "\n").collect())
}

/// A field of a row: a number, or a `{mean, ci95}`'s mean.
fn num(row: &Json, key: &str) -> Option<f64> {
    let v = row.get(key)?;
    v.as_f64().or_else(|| v.get("mean")?.as_f64())
}

/// An estimate's mean alone, as `format` writes it.
fn mean(row: &Json, key: &str, format: Format) -> String {
    num(row, key).map_or("-".into(), |m| show(m, format))
}

/// `mean ± ci95` of an estimate, with `d` decimals.
fn estimate(row: &Json, key: &str, d: usize) -> String {
    match (
        num(row, key),
        row.get(key).and_then(|v| v.get("ci95")?.as_f64()),
    ) {
        (Some(m), Some(h)) => format!("{m:.d$} ± {h:.d$}"),
        (Some(m), None) => format!("{m:.d$}"),
        _ => "-".into(),
    }
}

/// The rows of `eval --json` (and its `--pil` checks), one table per horizon.
fn rows(doc: &Json) -> Result<String, String> {
    let rows = doc
        .get("rows")
        .and_then(Json::as_array)
        .ok_or("expected `eval --json` output (a `rows` array) or an envelope")?;
    let mut horizons: Vec<u64> = Vec::new();
    for r in rows {
        let h = r
            .get("horizon")
            .and_then(Json::as_u64)
            .ok_or("a row without a horizon")?;
        if !horizons.contains(&h) {
            horizons.push(h);
        }
    }
    let fallback = rows
        .iter()
        .any(|r| num(r, "fallback_share").is_some_and(|f| f > 0.0));
    let motor = rows.iter().any(|r| r.get("mean_abs_duty").is_some());
    let mut s = String::new();
    for h in horizons {
        s += &format!("## Horizon {} periods\n\n", group(h as usize));
        s += "| scenario | controller | episodes | success [95% CI] | failed | mean steps | RMS theta deg | RMS x m | mean abs x m | switches/s | faults |";
        if motor {
            s += " reversals/s | mean abs duty | duty variation /s | heat |";
        }
        s += if fallback { " fallback |\n" } else { "\n" };
        s += "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |";
        if motor {
            s += " ---: | ---: | ---: | ---: |";
        }
        s += if fallback { " ---: |\n" } else { "\n" };
        for r in rows
            .iter()
            .filter(|r| r.get("horizon").and_then(Json::as_u64) == Some(h))
        {
            s += &row_line(r, motor, fallback)?;
        }
        s += "\n";
    }
    if let Some(checks) = doc.get("pil") {
        s += &pil_checks(checks, rows)?;
    }
    Ok(s)
}

/// One row of a results page: its figures, the motor's and the fallback's if the page has
/// them.
fn row_line(r: &Json, motor: bool, fallback: bool) -> Result<String, String> {
    let given = |r: &Json, k: &str| r.get(k).and_then(Json::as_str).map(str::to_string);
    let (Some(scenario), Some(controller)) = (given(r, "scenario"), given(r, "controller")) else {
        return Err("a row without a scenario or controller".into());
    };
    let count = |k: &str| num(r, k).map_or("-".into(), |x| show(x, Format::Int));
    let ci = r.get("success_ci95").and_then(Json::as_array);
    let bound = |i: usize| ci.and_then(|c| c.get(i)?.as_f64()).unwrap_or(f64::NAN);
    let success = num(r, "success_rate").ok_or("a row without a success_rate")?;
    let mut cells = vec![
        code(&scenario),
        text(&controller),
        count("episodes"),
        format!(
            "{:.1}% [{:.1}, {:.1}]",
            100.0 * success,
            100.0 * bound(0),
            100.0 * bound(1)
        ),
        count("failures"),
        num(r, "mean_steps").map_or("-".into(), |m| format!("{m:.1}")),
        estimate(r, "rms_theta_deg", 3),
        estimate(r, "rms_x_m", 3),
        estimate(r, "mean_abs_x_m", 3),
        estimate(r, "switches_per_s", 1),
        count("faults"),
    ];
    if motor {
        cells.push(estimate(r, "reversals_per_s", 1));
        cells.push(mean(r, "mean_abs_duty", Format::Percent(1)));
        cells.push(estimate(r, "duty_tv_per_s", 2));
        cells.push(mean(r, "heat", Format::Percent(2)));
    }
    if fallback {
        let f = num(r, "fallback_share").unwrap_or(0.0);
        cells.push(show(f, Format::Percent(2)));
    }
    Ok(format!("| {} |\n", cells.join(" | ")))
}

/// The processor-in-the-loop checks beside the rows.
fn pil_checks(checks: &Json, rows: &[Json]) -> Result<String, String> {
    let checks: Vec<pil::Check> = serde_json::from_value(checks.clone())
        .map_err(|e| format!("expected `eval --pil --json`'s checks: {e}"))?;
    let mut s = String::from("## On the target\n\n| scenario | controller | horizon |");
    for c in pil::COLUMNS {
        s += &format!(" {c} |");
    }
    s += "\n| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for c in &checks {
        let (controller, scenario, horizon) = c.key();
        let period = rows
            .iter()
            .find(|r| {
                r.get("controller").and_then(Json::as_str) == Some(controller)
                    && r.get("scenario").and_then(Json::as_str) == Some(scenario)
            })
            .and_then(|r| num(r, "period_s"))
            .ok_or_else(|| {
                let (c, s) = (weights::quote(controller), weights::quote(scenario));
                format!("no row with the period of {c} on {s}")
            })?;
        let cells = pil::cells(c, period).join(" | ");
        let (scenario, controller) = (code(scenario), text(controller));
        s += &format!("| {scenario} | {controller} | {horizon} | {cells} |\n");
    }
    Ok(s + "\n")
}

/// `host-sim envelope --json`'s measurement.
fn envelope(doc: &Json) -> Result<String, String> {
    #[derive(Deserialize)]
    struct Report {
        scenarios: Vec<String>,
        episodes: u64,
        horizon: u64,
        balanced: u64,
        episodes_run: u64,
        periods: u64,
        quantile: f64,
        margin: f64,
        quantiles: [[f64; 4]; 4],
        envelope: [f64; 4],
    }
    let r = Report::deserialize(doc).map_err(|e| format!("expected an envelope's JSON: {e}"))?;
    let mut s = format!(
        "{} readings of {} balanced episodes of {} ({} episodes of {} periods in each of {} \
         scenarios: {}).\n\n| | x m | x_dot m/s | theta rad | theta_dot rad/s |\n\
         | --- | ---: | ---: | ---: | ---: |\n",
        group(r.periods as usize),
        group(r.balanced as usize),
        group(r.episodes_run as usize),
        group(r.episodes as usize),
        group(r.horizon as usize),
        r.scenarios.len(),
        r.scenarios
            .iter()
            .map(|n| code(n))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let names = [
        "0.99 quantile",
        "0.999 quantile",
        "0.9999 quantile",
        "largest",
    ];
    for (name, q) in names.iter().zip(r.quantiles) {
        s += &format!(
            "| {name} | {:.4} | {:.4} | {:.4} | {:.4} |\n",
            q[0], q[1], q[2], q[3]
        );
    }
    let e = r.envelope;
    s += &format!(
        "| **envelope** ({} quantile x {}) | {:.4} | {:.4} | {:.4} | {:.4} |\n\n",
        r.quantile, r.margin, e[0], e[1], e[2], e[3]
    );
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_page_says_where_its_file_came_from_and_shows_every_row() {
        let json = r#"{"seed": 0, "rows": [
          {"controller": "policy", "scenario": "noise", "horizon": 500, "episodes": 1000,
           "success_rate": 0.75, "success_ci95": [0.7224, 0.7758], "failures": 250,
           "mean_steps": 431.25, "rms_theta_deg": {"mean": 0.5, "ci95": 0.0123},
           "rms_x_m": {"mean": 0.1, "ci95": 0.002}, "mean_abs_x_m": {"mean": 0.08, "ci95": 0.001},
           "switches_per_s": {"mean": 30.04, "ci95": 0.2}, "faults": 12345, "fallback_share": 0.0}],
          "provenance": {"tool": "host-sim", "argv": ["eval", "--json"], "date": "2026-12-03T00:00:00Z",
           "revision": "abc1234", "dirty": false, "nproc": 2, "cpu": "AMD EPYC"}}"#;
        let step: Step = toml::from_str(
            "name = \"eval-x\"\nabout = \"the noise row\"\nrun = \"host-sim eval --json\"\ncost = 1",
        )
        .unwrap();
        let page = page("docs/results/eval-x.json", json, &[&step]).unwrap();
        let want = "# eval-x\n\nThe noise row.\n\nWritten by `host-sim tables` from \
                    [`eval-x.json`](eval-x.json); do not edit. `scripts/regenerate.sh` \
                    measures it again (`docs/results/manifest.toml`).\n\n\
                    - command: `host-sim eval --json`\n\
                    - run: 2026-12-03T00:00:00Z, revision abc1234\n\
                    - machine: 2 CPUs, AMD EPYC\n\n\
                    ## Horizon 500 periods\n\n";
        assert!(page.starts_with(want), "{page}");
        let row = "| `noise` | policy | 1,000 | 75.0% [72.2, 77.6] | 250 | 431.2 | 0.500 ± 0.012 | \
                   0.100 ± 0.002 | 0.080 ± 0.001 | 30.0 ± 0.2 | 12,345 |\n\n";
        assert!(page.ends_with(row), "{page}");
        let old = json
            .split("],\n          \"provenance\"")
            .next()
            .unwrap()
            .to_string()
            + "]}";
        let page = super::page("docs/results/eval-x.json", &old, &[&step]).unwrap();
        assert!(
            page.contains(
                "The file records no provenance: it was measured before results \
                           files did. The manifest makes it with:\n\n- `host-sim eval --json`\n"
            ),
            "{page}"
        );
    }

    #[test]
    fn a_row_with_the_motors_figures_shows_them() {
        let json = r#"{"rows": [{"controller": "lqr-linear", "scenario": "encoder",
           "horizon": 10000, "episodes": 10, "success_rate": 1.0, "success_ci95": [0.7, 1.0],
           "failures": 0, "mean_steps": 10000.0, "switches_per_s": {"mean": 49.2, "ci95": 0.04},
           "reversals_per_s": {"mean": 2.21, "ci95": 0.05}, "mean_abs_duty": {"mean": 0.0391},
           "duty_tv_per_s": {"mean": 1.234, "ci95": 0.01}, "heat": {"mean": 0.00321},
           "faults": 0}]}"#;
        let step: Step =
            toml::from_str("name = \"m\"\nabout = \"m\"\nrun = \"host-sim eval\"\ncost = 1")
                .unwrap();
        let page = page("docs/results/m.json", json, &[&step]).unwrap();
        assert!(
            page.contains(
                "| switches/s | faults | reversals/s | mean abs duty | duty variation /s | heat |\n"
            ),
            "{page}"
        );
        assert!(
            page.contains("| 49.2 ± 0.0 | 0 | 2.2 ± 0.1 | 3.9% | 1.23 ± 0.01 | 0.32% |\n"),
            "{page}"
        );
    }
}
