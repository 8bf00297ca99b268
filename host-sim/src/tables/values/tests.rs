use super::*;
use crate::tables::update;

/// Four rows in `eval --json`'s shape (fields neither a table nor a value shows left out), with figures
/// whose roundings are worked out by hand below; the last has no `mean_abs_x_m`.
const JSON: &str = r#"{"seed": 0, "rows": [
  {"controller": "policy", "scenario": "nominal", "horizon": 500, "period_s": 0.02, "episodes": 1000,
   "success_ci95": [0.99, 1.0], "failures": 0, "success_rate": 1.0, "rms_theta_deg": {"mean": 0.2582, "ci95": 0.01},
   "rms_x_m": {"mean": 0.09184, "ci95": 0.002}, "mean_abs_x_m": {"mean": 0.0876, "ci95": 0.1},
   "switches_per_s": {"mean": 33.4226, "ci95": 0.1}, "mean_steps": 500.0},
  {"controller": "policy", "scenario": "push=1.1/50", "horizon": 10000, "period_s": 0.02, "episodes": 1000,
   "success_ci95": [0.98, 0.99], "failures": 10, "success_rate": 0.99, "rms_theta_deg": {"mean": 2.7129, "ci95": 0.1},
   "rms_x_m": {"mean": 1.0684, "ci95": 0.1}, "mean_abs_x_m": {"mean": 0.9, "ci95": 0.1},
   "switches_per_s": {"mean": 31.46, "ci95": 0.1}, "mean_steps": 9950.27},
  {"controller": "lqr", "scenario": "push=1.1/50", "horizon": 10000, "period_s": 0.02, "episodes": 1000,
   "success_ci95": [0.72, 0.77], "failures": 251, "success_rate": 0.749, "rms_theta_deg": {"mean": 3.1241, "ci95": 0.1},
   "rms_x_m": {"mean": 0.63166, "ci95": 0.1}, "mean_abs_x_m": {"mean": 0.5, "ci95": 0.1},
   "switches_per_s": {"mean": 36.06, "ci95": 0.1}, "mean_steps": 8000.0},
  {"controller": "lqr", "scenario": "push=1.1/50", "horizon": 500, "period_s": 0.02, "episodes": 12345,
   "success_ci95": [0.89, 0.91], "failures": 1234, "success_rate": 0.90004, "rms_theta_deg": {"mean": 3.0, "ci95": 0.1},
   "rms_x_m": {"mean": 0.6, "ci95": 0.1}, "switches_per_s": {"mean": 36.0, "ci95": 0.1},
   "mean_steps": 480.0}
]}"#;

const FILE: &str = "docs/results/x.json";

/// The figure the marker between `<!-- value: ` and ` -->` asks for from [`JSON`].
fn figure(inner: &str) -> Result<String, String> {
    let spec = parse_spec(&format!("{FILE} {inner}"))?;
    Rows::default().render(&spec, &mut |_| Ok(JSON.to_string()))
}

#[test]
fn every_field_in_its_default_format_and_in_others() {
    let nominal = "scenario=nominal";
    let lqr = "scenario=push=1.1/50 horizon=10000 controller=lqr";
    let cases = [
        (format!("{nominal} success_rate"), "100.0%"),
        (format!("{nominal} success_rate:%0"), "100%"),
        (format!("{lqr} success_rate"), "74.9%"),
        (format!("{lqr} success_rate:%2"), "74.90%"),
        (format!("{lqr} failures"), "251"),
        (format!("{lqr} successes"), "749"),
        (format!("{lqr} episodes"), "1,000"),
        (format!("{lqr} rms_x_m"), "0.632"),
        (format!("{lqr} rms_x_m:.2"), "0.63"),
        (format!("{lqr} rms_theta_deg"), "3.12"),
        (format!("{nominal} rms_theta_deg"), "0.26"),
        (format!("{nominal} rms_x_m"), "0.092"),
        (format!("{nominal} mean_abs_x_m"), "0.088"),
        (format!("{nominal} switches_per_s"), "33.4"),
        (format!("{nominal} switches_per_s:int"), "33"),
        (format!("{nominal} mean_steps"), "500.0"),
        ("horizon=500 controller=lqr episodes".into(), "12,345"),
        ("horizon=500 controller=lqr failures".into(), "1,234"),
        ("horizon=500 controller=lqr successes".into(), "11,111"),
        ("horizon=500 controller=lqr success_rate".into(), "90.0%"),
        (
            "controller=policy horizon=10000 mean_steps:int".into(),
            "9,950",
        ),
        (
            "controller=policy horizon=10000 mean_steps".into(),
            "9950.3",
        ),
        (
            "controller=policy horizon=10000 success_rate".into(),
            "99.0%",
        ),
    ];
    for (inner, want) in cases {
        assert_eq!(figure(&inner).as_deref(), Ok(want), "{inner}");
    }
}

#[test]
fn a_value_must_be_one_rows_number() {
    let cases = [
        (
            "scenario=delay success_rate",
            "no row of docs/results/x.json matches \"scenario=delay\"",
        ),
        (
            "scenario=push=1.1/50 controller=lqr failures",
            "2 rows of docs/results/x.json match \"scenario=push=1.1/50 controller=lqr\"",
        ),
        (
            "failures",
            "4 rows of docs/results/x.json match no selector",
        ),
        (
            "horizon=500 controller=lqr mean_abs_x_m",
            "has no number `mean_abs_x_m`",
        ),
    ];
    for (inner, want) in cases {
        let err = figure(inner).unwrap_err();
        assert!(err.contains(want), "{inner}: {err}");
    }
    let mut rows = Rows::default();
    let spec = parse_spec(&format!("{FILE} episodes")).unwrap();
    let err = rows.render(&spec, &mut |_| Ok(r#"{"rows": 3}"#.into()));
    assert!(err.unwrap_err().contains("is not `eval --json` output"));
}

#[test]
fn the_marker_parser_refuses() {
    let cases = [
        ("", "names no results file"),
        ("x.json failures", "expected a file docs/results/NAME.json"),
        ("docs/results/x.json scenario=nominal", "names no field"),
        ("docs/results/x.json rms_y", "unknown field \"rms_y\""),
        ("docs/results/x.json failures episodes", "a second field"),
        (
            "docs/results/x.json colour=red failures",
            "unknown selector",
        ),
        (
            "docs/results/x.json horizon=ten failures",
            "horizon= expects",
        ),
        (
            "docs/results/x.json horizon=1 horizon=2 failures",
            "`horizon` given twice",
        ),
        (
            "docs/results/x.json controller=a controller=b failures",
            "\"controller\" empty or given twice",
        ),
        ("docs/results/x.json scenario= failures", "empty or given"),
        ("docs/results/x.json rms_x_m:.x", "unknown format \".x\""),
        (
            "docs/results/x.json success_rate:%10",
            "unknown format \"%10\"",
        ),
        ("docs/results/x.json failures:sci", "unknown format \"sci\""),
    ];
    for (inner, want) in cases {
        let err = parse_spec(inner).unwrap_err();
        assert!(err.contains(want), "{inner}: {err}");
    }
}

#[test]
fn the_value_finder_refuses_with_the_line() {
    let open = "<!-- value: docs/results/x.json failures -->";
    let cases = [
        (
            format!("a\nb {open}12 c\n"),
            2,
            "no `<!-- /value -->` follows",
        ),
        (
            format!("a {open}1{open}2{CLOSE}\n"),
            1,
            "no `<!-- /value -->`",
        ),
        (format!("a\n\nb {CLOSE}\n"), 3, "without an opening one"),
        (
            format!("a {open}1{CLOSE} {CLOSE}\n"),
            1,
            "without an opening",
        ),
        (
            "a <!-- value: docs/results/x.json failures\n-->1<!-- /value -->\n".into(),
            1,
            "does not end with `-->` on its line",
        ),
        (
            "x\ny <!-- value docs/results/x.json failures -->1<!-- /value -->\n".into(),
            2,
            "expected `<!-- value: FILE",
        ),
        (format!("a {open}\n1{CLOSE}\n"), 1, "no `<!-- /value -->`"),
        (
            "a <!-- value: docs/results/x.json scenario=a--b failures -->1<!-- /value -->\n".into(),
            1,
            "expected no `--` inside",
        ),
        (
            "a <!-- value: docs/results/x.json failures--->1<!-- /value -->\n".into(),
            1,
            "expected no `--` inside",
        ),
        (
            "a <!-- value: docs/results/x.json -->1<!-- /value -->\n".into(),
            1,
            "names no field",
        ),
    ];
    for lead in ["", "  ", "- ", "> ", "12. ", "  * ", "> 3) "] {
        let text = format!("a\n{lead}{open}1{CLOSE} b\n");
        let err = values(&text).unwrap_err();
        assert_eq!(err.line, 2, "{text}: {err:?}");
        assert!(err.message.contains("first on its line"), "{text}: {err:?}");
    }
    for lead in ["| ", "a ", "12 ", "-- ", "(", "x. "] {
        let text = format!("a\n{lead}{open}1{CLOSE} b\n");
        assert_eq!(values(&text).map(|v| v.len()), Ok(1), "{text}");
    }
    for (text, line, want) in cases {
        let err = values(&text).unwrap_err();
        assert_eq!(err.line, line, "{text}: {err:?}");
        assert!(err.message.contains(want), "{text}: {err:?}");
    }
}

#[test]
fn markers_in_code_are_text() {
    let text = "\
Write `<!-- value: FILE FIELD -->0.092<!-- /value -->` or ``a `<!-- /value -->` b``.
```text
<!-- value: shown -->1<!-- /value -->
```
An unclosed ` backtick <!-- value: docs/results/x.json failures -->0<!-- /value -->.
";
    let found = values(text).unwrap();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].line, 5);
    assert_eq!(&text[found[0].body.clone()], "0");
}

#[test]
fn update_rewrites_values_beside_tables_and_names_the_stale_ones() {
    let lqr = "<!-- value: docs/results/x.json horizon=10000 controller=lqr";
    let text = format!(
        "\
# Doc

The policy fails {lqr} failures -->250<!-- /value --> of {lqr} episodes -->1,000<!-- /value -->,
<!-- results: docs/results/x.json horizon=500 scenarios=nominal success=policy brief -->
| stale |
<!-- /results -->
RMS x {lqr} rms_x_m -->0.632<!-- /value --> m.
"
    );
    let (new, stale) = update(&text, |_| Ok(JSON.to_string())).unwrap();
    let table = "| scenario | policy success |\n| --- | ---: |\n| `nominal` | 100.0% |\n";
    let fixed = text
        .replace("-->250<", "-->251<")
        .replace("| stale |\n", table);
    assert_eq!(new, fixed);
    let lines: Vec<(usize, &str)> = stale.iter().map(|s| (s.line, s.what.as_str())).collect();
    assert_eq!(
        lines,
        [
            (
                3,
                "the value \"250\" differs from docs/results/x.json's `251` \
                 (failures, \"horizon=10000 controller=lqr\")"
            ),
            (4, "the table differs from docs/results/x.json"),
        ]
    );
    let (again, none) = update(&new, |_| Ok(JSON.to_string())).unwrap();
    assert_eq!((again, none), (new, vec![]));
    let inside = text.replace(
        "| stale |",
        &format!("| {lqr} failures -->1<!-- /value --> |"),
    );
    let err = update(&inside, |_| Ok(JSON.to_string())).unwrap_err();
    assert_eq!(err.line, 5);
    assert!(
        err.message.contains("inside the table of line 4"),
        "{err:?}"
    );
    let err = update(&text, |f| Err(format!("cannot read {f}"))).unwrap_err();
    assert_eq!(
        (err.line, err.message.as_str()),
        (4, "cannot read docs/results/x.json")
    );
}
