//! Which figures of a results file moved when it was measured again: row by row (an eval
//! row by its controller, scenario and horizon; a reproduction's by its study and label; a
//! processor-in-the-loop check likewise), each figure with a 95% interval compared against
//! the old interval, the rest for equality. What `scripts/regenerate.sh` prints per file.

use std::collections::{BTreeMap, BTreeSet};

use serde_json::{Map, Value as Json};

/// How one file's rows compare with its earlier version's.
#[derive(Debug, Default, PartialEq)]
pub struct Moved {
    /// Rows in the new file.
    pub rows: usize,
    /// Rows with a figure outside its earlier 95% interval: the row, and each such figure
    /// as `field old -> new (interval)`.
    pub moved: Vec<(String, Vec<String>)>,
    /// Rows that changed, all within their intervals (or figures without one).
    pub within: Vec<String>,
    /// The fields that changed in any row, in the order first seen.
    pub fields: Vec<String>,
    /// Rows that are new, and rows that are gone.
    pub new: Vec<String>,
    pub gone: Vec<String>,
}

/// Refuses a results file no tool writes: a row named twice (which of the two would a
/// comparison mean?), and in a row a subnormal number, episodes, failures or a horizon that
/// are not whole counts (episodes and horizon at least 1), more failures than episodes, a
/// success rate other than the share the counts give, steps beyond the horizon, a rate
/// outside [0, 1], a magnitude below 0, an interval neither a half-width of at least 0 nor
/// `[low, high]` with low <= high, a period not above 0.
pub fn check(doc: &Json) -> Result<(), String> {
    let mut names = BTreeSet::new();
    for (name, row) in &entries(doc) {
        let at = weights::quote(name);
        if !names.insert(name.as_str()) {
            return Err(format!("expected each row once, found {at} twice"));
        }
        check_row(row).map_err(|e| format!("row {at}: {e}"))?;
    }
    Ok(())
}

/// Figures that are sizes (a deviation, a share, a rate of events, steps): never below 0.
const MAGNITUDES: [&str; 11] = [
    "rms_",
    "mean_abs_",
    "heat",
    "reversals_per_s",
    "switches_per_s",
    "duty_tv_per_s",
    "mean_steps",
    "p5_steps",
    "min_steps",
    "fallback_share",
    "time_ns",
];

/// One row's figures, as [`check`] holds them.
fn check_row(row: &Json) -> Result<(), String> {
    numbers("", row)?;
    let count = |k: &str| match row.get(k) {
        None => Ok(None),
        Some(v) => v
            .as_u64()
            .map(Some)
            .ok_or_else(|| format!("expected `{k}` a whole count, found {}", shown(v))),
    };
    let (episodes, failures, horizon) = (count("episodes")?, count("failures")?, count("horizon")?);
    for (k, n) in [("episodes", episodes), ("horizon", horizon)] {
        if n == Some(0) {
            return Err(format!("expected `{k}` at least 1, found 0"));
        }
    }
    if let (Some(e), Some(f)) = (episodes, failures) {
        if f > e {
            return Err(format!("expected at most {e} failures, found {f}"));
        }
        let share = (e - f) as f64 / e as f64;
        if let Some(r) = row.get("success_rate").and_then(Json::as_f64)
            && (r - share).abs() > 1e-9
        {
            return Err(format!(
                "expected `success_rate` {} ({f} failures of {e}), found {}",
                fig(share),
                fig(r)
            ));
        }
    }
    let Some(fields) = row.as_object() else {
        return Ok(());
    };
    for (k, v) in fields {
        figure(k, v, horizon).map_err(|e| format!("expected {} {e}", weights::quote(k)))?;
    }
    Ok(())
}

/// One field of a row: `Err` completes "expected FIELD ...".
fn figure(k: &str, v: &Json, horizon: Option<u64>) -> Result<(), String> {
    let mean = v.get("mean").and_then(Json::as_f64).or(v.as_f64());
    let found = |x: &Json| format!("found {}", shown(x));
    if k.ends_with("_rate") && !mean.is_some_and(|r| (0.0..=1.0).contains(&r)) {
        return Err(format!("in [0, 1], {}", found(v)));
    }
    if MAGNITUDES.iter().any(|m| k.starts_with(m)) && mean.is_some_and(|x| x < 0.0) {
        return Err(format!("at least 0, {}", found(v)));
    }
    if k.ends_with("_steps")
        && let (Some(x), Some(h)) = (mean, horizon)
        && x > h as f64
    {
        return Err(format!("at most the horizon {h}, {}", found(v)));
    }
    if k == "period_s" && !mean.is_some_and(|x| x > 0.0) {
        return Err(format!("above 0, {}", found(v)));
    }
    let interval = match v.get("ci95") {
        Some(ci) if v.is_object() => Some(ci),
        _ => k.ends_with("_ci95").then_some(v),
    };
    // `null`: no interval (a figure of fewer than two episodes, whose NaN JSON writes so).
    match interval.map(|ci| (ci, ci.as_f64(), ci.as_array().map(Vec::as_slice))) {
        None | Some((Json::Null, _, _)) | Some((_, Some(0.0..), _)) => Ok(()),
        Some((_, _, Some([lo, hi]))) if lo.as_f64() <= hi.as_f64() && lo.is_number() => Ok(()),
        Some((ci, _, _)) => Err(format!(
            "an interval: a half-width of at least 0, or [low, high] with low <= high; {}",
            found(ci)
        )),
    }
}

/// Refuses a subnormal number anywhere in `v` (a slip, as everywhere a number comes in): in
/// f64, which the figures stay in (they never reach a board's f32).
fn numbers(path: &str, v: &Json) -> Result<(), String> {
    match v {
        Json::Number(n) => match n.as_f64() {
            Some(x) if x == 0.0 || x.is_normal() => Ok(()),
            _ => Err(format!(
                "expected {} zero or a normal number, found {}",
                weights::quote(path),
                shown(v)
            )),
        },
        Json::Array(a) => a.iter().try_for_each(|x| numbers(path, x)),
        Json::Object(o) => o.iter().try_for_each(|(k, x)| numbers(k, x)),
        _ => Ok(()),
    }
}

/// A value as the report shows it: a whole number as written, a real one shortest, as Rust
/// reads it back (`{:?}`: `1e-320`, `2.5`, where four decimals showed `9.9999e-321` and
/// `2.5000`); any other value quoted.
fn shown(v: &Json) -> String {
    match v {
        Json::Number(n) if n.is_f64() => n.as_f64().map_or_else(|| n.to_string(), fig),
        Json::Number(n) => n.to_string(),
        _ => weights::quote(&v.to_string()),
    }
}

/// A real number found or compared, shortest.
fn fig(x: f64) -> String {
    format!("{x:?}")
}

/// The comparison of `old` with `new`, two versions of one results file.
pub fn compare(old: &Json, new: &Json) -> Moved {
    let (old, new) = (entries(old), entries(new));
    let mut m = Moved {
        rows: new.len(),
        ..Moved::default()
    };
    // Rows and fields looked up by name, not searched for: a file of many rows (or a row of
    // many fields) is compared in n log n, where a search per row was n squared (10 MB
    // files of 150,000 rows took minutes). `check` has refused a name given twice.
    let was_named: BTreeMap<&str, &Json> = old.iter().map(|(k, row)| (k.as_str(), *row)).collect();
    let new_names: BTreeSet<&str> = new.iter().map(|(k, _)| k.as_str()).collect();
    let mut seen = BTreeSet::new();
    // Rows are matched by their whole names, and shown escaped and cut: a name from the file
    // cannot move the cursor or forge a line of the report.
    let shown = |k: &String| weights::excerpt(k);
    for (key, row) in &new {
        match was_named.get(key.as_str()) {
            None => m.new.push(shown(key)),
            Some(was) => {
                let (beyond, changed) = fields(was, row);
                for f in &changed {
                    if seen.insert(f.clone()) {
                        m.fields.push(f.clone());
                    }
                }
                if !beyond.is_empty() {
                    m.moved.push((shown(key), beyond));
                } else if !changed.is_empty() {
                    m.within.push(shown(key));
                }
            }
        }
    }
    m.gone = old
        .iter()
        .filter(|(k, _)| !new_names.contains(k.as_str()))
        .map(|(k, _)| shown(k))
        .collect();
    m
}

/// The rows of a results file by name, or, for a file without rows (an envelope), the file
/// as one entry; never its provenance.
fn entries(doc: &Json) -> Vec<(String, &Json)> {
    let mut out = Vec::new();
    let Some(top) = doc.as_object() else {
        return vec![("the file".into(), doc)];
    };
    for (list, prefix) in [("rows", ""), ("pil", "pil check: ")] {
        for row in top.get(list).and_then(Json::as_array).into_iter().flatten() {
            out.push((format!("{prefix}{}", name(row)), row));
        }
    }
    if !top.contains_key("rows") {
        out.push(("the file's figures".into(), doc));
    }
    out
}

/// `controller on scenario at horizon`, or `study: label`: each as the row gives it, `?`
/// where it gives none (a horizon of 2.5 is named `at 2.5`, not cut to `at 0`).
fn name(row: &Json) -> String {
    let s = |k: &str| row.get(k).and_then(Json::as_str).unwrap_or("?").to_string();
    if row.get("study").is_some() {
        return format!("{}: {}", s("study"), s("label"));
    }
    let h = row.get("horizon").map_or("?".into(), |h| match h {
        Json::Number(_) => shown(h),
        other => other.to_string(),
    });
    format!("{} on {} at {h}", s("controller"), s("scenario"))
}

/// The figures of `new` outside `old`'s intervals, and the fields that differ at all (new
/// and gone ones too).
fn fields(old: &Json, new: &Json) -> (Vec<String>, Vec<String>) {
    let (Some(o), Some(n)) = (old.as_object(), new.as_object()) else {
        let changed = (old != new).then(|| "the value".to_string());
        return (Vec::new(), changed.into_iter().collect());
    };
    let skip = |k: &str| ["provenance", "rows", "pil", "per_seed"].contains(&k);
    let mut beyond = Vec::new();
    let mut changed = Vec::new();
    for (key, nv) in n.iter().filter(|(k, _)| !skip(k)) {
        match o.get(key) {
            Some(ov) if ov == nv => {}
            Some(ov) => {
                changed.push(weights::excerpt(key));
                beyond.extend(outside(key, ov, nv, o));
            }
            None => changed.push(format!("{} (new)", weights::excerpt(key))),
        }
    }
    let gone = o.keys().filter(|k| !skip(k) && !n.contains_key(*k));
    changed.extend(gone.map(|k| format!("{} (gone)", weights::excerpt(k))));
    (beyond, changed)
}

/// `field old -> new (interval)` if `new` lies outside the old 95% interval of `key`: its
/// own `{mean, ci95}`, or a sibling `KEY_ci95` (`STEM_ci95` for `STEM_rate`; a half-width,
/// or `[low, high]`).
fn outside(key: &str, old: &Json, new: &Json, row: &Map<String, Json>) -> Option<String> {
    let num = |v: &Json, k: &str| v.get(k).and_then(Json::as_f64);
    let (field, key) = (key, weights::excerpt(key));
    if let (Some(a), Some(h), Some(b)) = (num(old, "mean"), num(old, "ci95"), num(new, "mean")) {
        return ((b - a).abs() > h)
            .then(|| format!("{key} {} -> {} (+-{})", fig(a), fig(b), fig(h)));
    }
    let (a, b) = (old.as_f64()?, new.as_f64()?);
    // `eval`'s success rate keeps its interval as `success_ci95`.
    let stem = field.strip_suffix("_rate").unwrap_or(field);
    let interval = row
        .get(&format!("{field}_ci95"))
        .or_else(|| row.get(&format!("{stem}_ci95")))?;
    match interval {
        Json::Array(lh) => {
            let (lo, hi) = (lh.first()?.as_f64()?, lh.get(1)?.as_f64()?);
            let shown = format!(
                "{key} {} -> {} ([{}, {}])",
                fig(a),
                fig(b),
                fig(lo),
                fig(hi)
            );
            (b < lo || b > hi).then_some(shown)
        }
        h => {
            let h = h.as_f64()?;
            ((b - a).abs() > h).then(|| format!("{key} {} -> {} (+-{})", fig(a), fig(b), fig(h)))
        }
    }
}

/// The comparison as lines: a summary, then each row that moved with its figures.
pub fn report(file: &str, m: &Moved) -> String {
    let mut s = format!(
        "{file}: {} rows, {} moved beyond their 95% intervals, {} changed within them, {} new, {} gone\n",
        m.rows,
        m.moved.len(),
        m.within.len(),
        m.new.len(),
        m.gone.len()
    );
    if !m.fields.is_empty() {
        s += &format!("  fields that changed: {}\n", m.fields.join(", "));
    }
    for (row, figures) in &m.moved {
        s += &format!("  moved: {row}: {}\n", figures.join("; "));
    }
    for row in &m.new {
        s += &format!("  new: {row}\n");
    }
    for row in &m.gone {
        s += &format!("  gone: {row}\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn row(rate: f64, ci: [f64; 2], theta: f64, failures: u64) -> Json {
        json!({"controller": "policy", "scenario": "noise", "horizon": 500, "success_rate": rate,
               "success_ci95": ci, "failures": failures, "mean_steps": 480.0, "mean_steps_ci95": 5.0,
               "rms_theta_deg": {"mean": theta, "ci95": 0.01}})
    }

    fn one_row(extra: Json) -> Json {
        let mut row = row(0.9, [0.88, 0.92], 0.5, 100);
        let fields = extra.as_object().unwrap().clone();
        row.as_object_mut().unwrap().extend(fields);
        json!({ "rows": [row] })
    }

    #[test]
    fn a_figure_moves_only_beyond_its_old_interval() {
        let old = json!({"seed": 0, "rows": [row(0.9, [0.88, 0.92], 0.50, 100)],
                         "provenance": {"date": "then"}});
        let same = json!({"seed": 0, "rows": [row(0.9, [0.88, 0.92], 0.50, 100)],
                          "provenance": {"date": "now"}});
        assert_eq!(
            compare(&old, &same),
            Moved {
                rows: 1,
                ..Moved::default()
            }
        );
        // 0.91 lies in [0.88, 0.92] and 0.505 within 0.01 of 0.50: changed, not moved.
        let near = json!({"rows": [row(0.91, [0.89, 0.93], 0.505, 90)], "seed": 0});
        let m = compare(&old, &near);
        assert_eq!((m.moved.len(), m.within.len()), (0, 1));
        // 0.95 is above 0.92, and 0.52 is 0.02 from 0.50.
        let mut far = json!({"rows": [row(0.95, [0.93, 0.97], 0.52, 50)], "seed": 0});
        far["rows"][0]["fallback_share"] = json!(0.0);
        let m = compare(&old, &far);
        assert_eq!(m.moved.len(), 1);
        let (name, figures) = &m.moved[0];
        assert_eq!(name, "policy on noise at 500");
        assert_eq!(
            figures,
            &[
                "rms_theta_deg 0.5 -> 0.52 (+-0.01)",
                "success_rate 0.9 -> 0.95 ([0.88, 0.92])"
            ]
        );
        let text = report("docs/results/x.json", &m);
        let want = "docs/results/x.json: 1 rows, 1 moved beyond their 95% intervals, 0 changed \
                    within them, 0 new, 0 gone\n  fields that changed: failures, \
                    fallback_share (new), rms_theta_deg, success_ci95, success_rate\n  moved: \
                    policy on noise at 500: ";
        assert!(text.starts_with(want), "{text}");
    }

    #[test]
    fn rows_are_matched_by_name_and_other_figures_by_equality() {
        let old = json!({"rows": [{"study": "t4", "label": "DQN", "final_mean100": {"mean": 68.5, "ci95": 21.6}},
                                  {"study": "t4", "label": "DDQN", "params": 4610}]});
        let new = json!({"rows": [{"study": "t4", "label": "DQN", "final_mean100": {"mean": 91.0, "ci95": 20.0}},
                                  {"study": "t5", "label": "lr", "params": 4610}]});
        let m = compare(&old, &new);
        assert_eq!(m.moved[0].0, "t4: DQN");
        assert_eq!(
            (m.new.clone(), m.gone.clone()),
            (vec!["t5: lr".to_string()], vec!["t4: DDQN".to_string()])
        );
        let env = |e: f64| json!({"envelope": [2.4, e], "periods": 10, "provenance": {}});
        assert_eq!(compare(&env(1.0), &env(1.0)).within.len(), 0);
        assert_eq!(compare(&env(1.0), &env(1.5)).within, ["the file's figures"]);
    }

    #[test]
    fn files_no_tool_writes_are_refused_and_names_are_escaped() {
        assert_eq!(check(&one_row(json!({"episodes": 1000}))), Ok(()));
        // Figures that may be negative, and both shapes of an interval.
        let fine = json!({"overestimation": {"mean": -0.5, "ci95": 0.2}, "mean_steps_ci95": null,
                          "success_ci95": [0.0, 0.0], "worst": {"start": [-0.01, 0.02]},
                          "rms_x_m": {"mean": 1e-39, "ci95": null}});
        assert_eq!(check(&one_row(fine)), Ok(()));
        for (extra, why) in [
            (
                json!({"episodes": -5}),
                "expected `episodes` a whole count, found -5",
            ),
            (
                json!({"episodes": 10}),
                "expected at most 10 failures, found 100",
            ),
            (json!({"success_rate": 1e308}), "in [0, 1], found 1e308"),
            (
                json!({"episodes": 0, "failures": 0}),
                "`episodes` at least 1",
            ),
            (json!({"horizon": 0}), "`horizon` at least 1, found 0"),
            (
                json!({"episodes": 1000, "success_rate": 1.0}),
                "expected `success_rate` 0.9 (100 failures of 1000), found 1.0",
            ),
            (
                json!({"mean_steps": 501.0}),
                "at most the horizon 500, found 501",
            ),
            (
                json!({"rms_theta_deg": {"mean": -3.0, "ci95": 0.1}}),
                "\"rms_theta_deg\" at least 0",
            ),
            (
                json!({"rms_x_m": {"mean": 0.1, "ci95": -1.0}}),
                "\"rms_x_m\" an interval",
            ),
            (
                json!({"success_ci95": [0.92, 0.88]}),
                "found \"[0.92,0.88]\"",
            ),
            (json!({"success_ci95": [0.1, 0.2, 0.3]}), "an interval"),
            (json!({"period_s": -0.02}), "\"period_s\" above 0"),
        ] {
            let e = check(&one_row(extra)).unwrap_err();
            assert!(e.contains(why), "{e}");
        }
        let twice = json!({"rows": [row(0.9, [0.8, 1.0], 0.5, 1), row(0.9, [0.8, 1.0], 0.5, 1)]});
        let e = check(&twice).unwrap_err();
        assert!(e.contains("\"policy on noise at 500\" twice"), "{e}");
        // Names alike for their first 200 characters are still two rows.
        let long = |end: &str| {
            let mut r = row(0.9, [0.8, 1.0], 0.5, 1);
            r["scenario"] = json!(format!("{}{end}", "noise+".repeat(40)));
            r
        };
        assert_eq!(check(&json!({"rows": [long("a"), long("b")]})), Ok(()));
        let mut forged = row(0.9, [0.8, 1.0], 0.5, 1);
        forged["scenario"] = json!("\u{1b}[2J\nerror: fake");
        let m = compare(&json!({"rows": []}), &json!({"rows": [forged]}));
        let text = report("x", &m);
        assert!(
            text.contains("new: policy on \\u{1b}[2J\\nerror: fake at 500"),
            "{text}"
        );
    }

    #[test]
    fn refused_figures_are_shown_shortest_and_rows_by_the_horizon_given() {
        for (extra, why) in [
            // Shortest, as read: four decimals showed 9.9999e-321, 2.5000 and 0.0000.
            (
                json!({"rms_x_m": {"mean": 1e-320, "ci95": null}}),
                "expected \"mean\" zero or a normal number, found 1e-320",
            ),
            (
                json!({"episodes": 2.5}),
                "expected `episodes` a whole count, found 2.5",
            ),
            (
                json!({"success_rate": 0.00001, "episodes": 1000}),
                "expected `success_rate` 0.9 (100 failures of 1000), found 1e-5",
            ),
            (
                json!({"heat": {"mean": 5e-324, "ci95": 0.0}}),
                "expected \"mean\" zero or a normal number, found 5e-324",
            ),
        ] {
            let e = check(&one_row(extra)).unwrap_err();
            assert!(e.contains(why), "{e}");
        }
        // A row is named by the horizon it gives, not one cut to a whole count.
        let e = check(&one_row(json!({"horizon": 2.5}))).unwrap_err();
        let want = "row \"policy on noise at 2.5\": expected `horizon` a whole count, found 2.5";
        assert_eq!(e, want);
    }
}
