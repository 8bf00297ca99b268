use super::*;

/// Four rows at horizon 500 and one at 10,000, in `eval --json`'s shape (the fields the
/// tables do not show left out), with values whose roundings are worked out by hand below.
const JSON: &str = r#"{"seed": 0, "rows": [
  {"controller": "policy", "scenario": "nominal", "horizon": 500, "success_rate": 1.0,
   "success_ci95": [0.996173, 1.0], "failures": 0, "rms_theta_deg": {"mean": 0.2582, "ci95": 0.1},
   "rms_x_m": {"mean": 0.09184, "ci95": 0.1}, "switches_per_s": {"mean": 33.4226, "ci95": 0.1}},
  {"controller": "lqr", "scenario": "nominal", "horizon": 500, "success_rate": 1.0,
   "success_ci95": [0.996173, 1.0], "failures": 0, "rms_theta_deg": {"mean": 0.3049, "ci95": 0.1},
   "rms_x_m": {"mean": 0.2016, "ci95": 0.1}, "switches_per_s": {"mean": 33.36, "ci95": 0.1}},
  {"controller": "policy", "scenario": "push=1.1/50", "horizon": 500, "success_rate": 0.5,
   "success_ci95": [0.4501, 0.5499], "failures": 500, "rms_theta_deg": {"mean": 1.234, "ci95": 0.1},
   "rms_x_m": {"mean": 0.5, "ci95": 0.1}, "switches_per_s": {"mean": 30.04, "ci95": 0.1}},
  {"controller": "lqr", "scenario": "push=1.1/50", "horizon": 500, "success_rate": 0.0,
   "success_ci95": [0.0, 0.0038], "failures": 1000, "rms_theta_deg": {"mean": 2.5, "ci95": 0.1},
   "rms_x_m": {"mean": 0.25, "ci95": 0.1}, "switches_per_s": {"mean": 12.0, "ci95": 0.1}},
  {"controller": "policy", "scenario": "delay", "horizon": 10000, "success_rate": 1.0,
   "success_ci95": [0.996173, 1.0], "failures": 0, "rms_theta_deg": {"mean": 0.2, "ci95": 0.1},
   "rms_x_m": {"mean": 0.1, "ci95": 0.1}, "switches_per_s": {"mean": 32.0, "ci95": 0.1}}
]}"#;

fn spec(options: &str) -> Spec {
    parse_spec(&format!(" docs/results/x.json {options} -->")).unwrap()
}

#[test]
fn renders_success_below_and_compare_columns() {
    let table = render(
        &spec("horizon=500 success=policy,lqr below=policy,lqr compare=policy,lqr"),
        JSON,
    )
    .unwrap();
    let want = "\
| scenario | policy success [95% CI] (failed) | lqr success [95% CI] (failed) | below? | RMS theta deg policy / lqr | RMS x m policy / lqr | switches/s policy / lqr |
| --- | ---: | ---: | :---: | ---: | ---: | ---: |
| `nominal` | 100.0% [99.6, 100.0] (0) | 100.0% [99.6, 100.0] (0) | no | 0.26 / 0.30 | 0.092 / 0.202 | 33.4 / 33.4 |
| `push=1.1/50` | 50.0% [45.0, 55.0] (500) | 0.0% [0.0, 0.4] (1,000) | yes | 1.23 / 2.50 | 0.500 / 0.250 | 30.0 / 12.0 |
";
    assert_eq!(table, want);
}

#[test]
fn brief_scenarios_and_the_only_horizon() {
    let brief = render(
        &spec("horizon=500 scenarios=push=1.1/50 success=lqr,policy brief"),
        JSON,
    );
    let want = "\
| scenario | lqr success | policy success |
| --- | ---: | ---: |
| `push=1.1/50` | 0.0% | 50.0% |
";
    assert_eq!(brief.unwrap(), want);
    // Without horizon= a file of several horizons is refused; one horizon needs none.
    let err = render(&spec("success=policy"), JSON).unwrap_err();
    assert!(err.contains("give horizon=N"), "{err}");
    let one = JSON.replace("\"horizon\": 500", "\"horizon\": 10000");
    let all = render(&spec("success=policy brief"), &one).unwrap();
    assert_eq!(all.lines().count(), 2 + 3, "{all}");
    assert!(all.ends_with("| `delay` | 100.0% |\n"), "{all}");
    // A scenario named with a line break, a `|` and a backtick stays one cell of one line,
    // and so does a controller named so by the marker.
    let named = one
        .replace("\"delay\"", "\"a|b\\n# c`\"")
        .replace("\"policy\"", "\"p|q\"");
    let all = render(&spec("success=p|q brief"), &named).unwrap();
    assert!(all.starts_with("| scenario | p\\|q success |\n"), "{all}");
    assert!(
        all.ends_with("| `a\\|b\\n# c\\u{60}` | 100.0% |\n"),
        "{all}"
    );
}

#[test]
fn renders_nothing_it_cannot_find() {
    let cases = [
        (
            "horizon=500 success=rule",
            "no \"rule\" on \"nominal\" at horizon 500",
        ),
        (
            "horizon=500 scenarios=delay success=policy",
            "no \"delay\" at horizon 500",
        ),
        ("horizon=20 success=policy", "no rows at horizon 20"),
        (
            "horizon=500 compare=policy,rule",
            "no \"rule\" on \"nominal\"",
        ),
    ];
    for (options, want) in cases {
        let err = render(&spec(options), JSON).unwrap_err();
        assert!(err.contains(want), "{options}: {err}");
    }
    let err = render(&spec("success=policy"), r#"{"rows": [{"scenario": 1}]}"#).unwrap_err();
    assert!(err.contains("is not `eval --json` output"), "{err}");
}

#[test]
fn the_marker_parser_refuses() {
    let cases = [
        (
            "docs/results/x.json success=policy",
            "does not end with `-->`",
        ),
        ("-->", "names no results file"),
        (
            "x.json success=policy -->",
            "expected a file docs/results/NAME.json",
        ),
        ("docs/results/../x.json success=a -->", "expected a file"),
        ("docs/results/x.txt success=a -->", "expected a file"),
        ("docs/results/x.json horizon=500 -->", "asks for no column"),
        (
            "docs/results/x.json brief compare=a,b -->",
            "brief shortens",
        ),
        (
            "docs/results/x.json success=a success=b -->",
            "\"success\" given twice",
        ),
        (
            "docs/results/x.json success=a horizon=ten -->",
            "horizon= expects a number",
        ),
        (
            "docs/results/x.json success=a,,b -->",
            "names separated by commas",
        ),
        (
            "docs/results/x.json compare=a,b,c -->",
            "two controllers, found 3",
        ),
        (
            "docs/results/x.json below=a -->",
            "two controllers, found 1",
        ),
        (
            "docs/results/x.json success=a colour=red -->",
            "unknown option \"colour=red\"",
        ),
        (
            "docs/results/x.json success=a brief=yes -->",
            "unknown option \"brief=yes\"",
        ),
    ];
    for (rest, want) in cases {
        let err = parse_spec(&format!(" {rest}")).unwrap_err();
        assert!(err.contains(want), "{rest}: {err}");
    }
    // A results file's name is plain, so it reaches every message as it is.
    let e = parse_spec(" docs/results/\u{1b}[2Jx.json success=a -->").unwrap_err();
    assert!(
        e.contains("expected a file docs/results/NAME.json") && !e.contains('\u{1b}'),
        "{e}"
    );
    // A marker's words reach a message quoted: escaped, and cut however long.
    let long = "Z".repeat(20_000);
    for word in [
        "\u{1b}[5mopt=1",
        "\u{1b}]0;t\u{7}",
        &long,
        &format!("success={long}"),
    ] {
        let err = parse_spec(&format!(" docs/results/x.json success=a {word} -->")).unwrap_err();
        assert!(
            !err.contains(['\u{1b}', '\u{7}']) && err.len() < 600,
            "{err}"
        );
    }
}

#[test]
fn the_block_finder_refuses_with_the_line() {
    let open = "<!-- results: docs/results/x.json success=policy -->";
    let cases = [
        (
            format!("a\n{open}\n| t |\n"),
            2,
            "no `<!-- /results -->` line",
        ),
        (format!("a\n\n{CLOSE}\n"), 3, "without an opening one"),
        (
            format!("{open}\n{open}\n{CLOSE}\n"),
            2,
            "inside the block of line 1",
        ),
        (
            format!("{open}\n<!-- /results-->\n"),
            2,
            "alone on its line",
        ),
        (
            "x\n<!-- results docs/results/x.json -->\n".to_string(),
            2,
            "expected `<!-- results:",
        ),
    ];
    for (text, line, want) in cases {
        let err = blocks(&text).unwrap_err();
        assert_eq!(err.line, line, "{text}: {err:?}");
        assert!(err.message.contains(want), "{text}: {err:?}");
    }
}

#[test]
fn update_rewrites_the_tables_alone_and_names_the_stale_ones() {
    let text = "\
# Doc

```text
<!-- results: docs/results/shown-in-code.json -->
```
<!-- results: docs/results/x.json horizon=500 scenarios=nominal success=policy brief -->
| an old table |
<!-- /results -->
Between.
<!-- results: docs/results/x.json horizon=10000 success=policy brief -->
| scenario | policy success |
| --- | ---: |
| `delay` | 100.0% |
<!-- /results -->
After.
";
    let mut asked = Vec::new();
    let (new, stale) = update(text, |f| {
        asked.push(f.to_string());
        Ok(JSON.to_string())
    })
    .unwrap();
    // Read once for both blocks that name it.
    assert_eq!(asked, ["docs/results/x.json"]);
    let fresh = "| scenario | policy success |\n| --- | ---: |\n| `nominal` | 100.0% |\n";
    assert_eq!(new, text.replace("| an old table |\n", fresh));
    let want = Stale {
        line: 6,
        what: "the table differs from docs/results/x.json".into(),
    };
    assert_eq!(stale, [want]);
    let (again, none) = update(&new, |_| Ok(JSON.to_string())).unwrap();
    assert_eq!((again, none), (new, vec![]));
    let err = update(text, |f| Err(format!("cannot read {f}"))).unwrap_err();
    assert_eq!(err, refuse(6, "cannot read docs/results/x.json"));
}

/// Two rows' processor-in-the-loop checks, as `eval --pil --json` ends.
const PIL: &str = r#"], "pil": [
  {"target": "qemu:t", "controller": "policy", "scenario": "nominal", "horizon": 500,
   "periods": 500000, "mismatches": 0, "first": null,
   "time_ns": [623400, 629100, 634951], "overruns": 0},
  {"target": "qemu:t", "controller": "policy", "scenario": "push=1.1/50", "horizon": 500,
   "periods": 1234, "mismatches": 1001, "first": null,
   "time_ns": [44254400, 44772200, 45300700], "overruns": 1234}
]}"#;

#[test]
fn renders_the_processor_in_the_loop_columns() {
    let without_period = JSON.replacen("\n]}", PIL, 1);
    let json = without_period.replace("\"horizon\": 500,", "\"horizon\": 500, \"period_s\": 0.02,");
    let table = render(&spec("horizon=500 success=policy brief pil=policy"), &json).unwrap();
    let want = "\
| scenario | policy success | policy periods | policy mismatches | policy time us median / p99 / worst | policy worst of period | policy overruns |
| --- | ---: | ---: | ---: | ---: | ---: | ---: |
| `nominal` | 100.0% | 500,000 | 0 | 623 / 629 / 635 | 3.2% | 0 |
| `push=1.1/50` | 50.0% | 1,234 | 1,001 | 44254 / 44772 / 45301 | 226.5% | 1,234 |
";
    assert_eq!(table, want);
    let lqr = render(&spec("horizon=500 pil=lqr"), &json).unwrap_err();
    assert!(
        lqr.contains("no pil check of \"lqr\" on \"nominal\""),
        "{lqr}"
    );
    let old = render(&spec("horizon=500 pil=policy"), &without_period).unwrap_err();
    assert!(old.contains("gives no period_s"), "{old}");
}
