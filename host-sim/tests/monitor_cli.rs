//! The runtime monitor from the command line: `host-sim envelope` regenerates the shipped
//! envelope byte for byte and measures a policy file's, `eval --controller monitored` holds
//! the fault the policy alone does not and fires nowhere else, and bad input exits 2 before
//! any work.

use std::path::PathBuf;
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap()
}

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(path)
}

/// The command recorded in the shipped module writes the shipped module again.
#[test]
fn the_shipped_envelope_regenerates_byte_for_byte() {
    let shipped = std::fs::read_to_string(repo("shipped/src/envelope.rs")).unwrap();
    let line = shipped
        .lines()
        .find_map(|l| l.strip_prefix("//! - measured: `host-sim "))
        .expect("the module records its command");
    let dir = std::env::temp_dir().join(format!("hs-envelope-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("envelope.rs");
    let mut args: Vec<&str> = line.trim_end_matches('`').split(' ').collect();
    args.extend(["--out", out.to_str().unwrap()]);
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), shipped);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn rows(args: &[&str]) -> Vec<serde_json::Value> {
    let o = run(&[&["eval", "--json", "--episodes", "40"][..], args].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    v["rows"].as_array().unwrap().clone()
}

#[test]
fn the_monitor_holds_a_frozen_encoder_and_fires_nowhere_else() {
    // Half a second of frozen encoder every ten: the policy alone falls in many episodes.
    let r = rows(&[
        "--scenario",
        "encoder+stuck=25/500",
        "--horizon",
        "3000",
        "--controller",
        "policy,monitored",
    ]);
    let (alone, watched) = (&r[0], &r[1]);
    assert!(alone["failures"].as_u64().unwrap() >= 5, "{alone}");
    assert_eq!(watched["failures"], 0, "{watched}");
    assert!(watched["fallback_share"].as_f64().unwrap() > 0.0);
    // Where nothing goes wrong, the monitored rows are the policy's, and the fallback never
    // decides a period.
    let r = rows(&[
        "--scenario",
        "noise+delay+push",
        "--controller",
        "policy,monitored",
    ]);
    let strip = |row: &serde_json::Value| {
        let mut row = row.clone();
        row.as_object_mut().unwrap().remove("controller");
        row
    };
    assert_eq!(strip(&r[0]), strip(&r[1]));
    assert_eq!(r[1]["fallback_share"], 0.0);
}

/// A policy file's envelope, measured and handed to `eval`, monitors that policy.
#[test]
fn a_policy_files_envelope_is_measured_and_monitors_it() {
    let policy = repo("shipped/policy.safetensors");
    let dir = std::env::temp_dir().join(format!("hs-envelope-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("envelope.json");
    let o = run(&[
        "envelope",
        "--policy",
        policy.to_str().unwrap(),
        "--scenario",
        "nominal,noise+push",
        "--episodes",
        "10",
        "--horizon",
        "2000",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::write(&file, &o.stdout).unwrap();
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (envelope, largest) = (&report["envelope"], &report["quantiles"][3]);
    let range = [2.4, 20.0, 0.42, 20.0];
    for c in 0..4 {
        // The largest reading times the margin, within the bins' range.
        let (e, l) = (envelope[c].as_f64().unwrap(), largest[c].as_f64().unwrap());
        let margin = e > l && e <= 1.1 * l + 1e-6;
        assert!(margin || e == range[c], "{report}");
    }
    let r = rows(&[
        "--policy",
        policy.to_str().unwrap(),
        "--envelope",
        file.to_str().unwrap(),
        "--scenario",
        "encoder+stuck=25/500",
        "--horizon",
        "3000",
        "--controller",
        "monitored",
    ]);
    assert_eq!(r[0]["failures"], 0, "{}", r[0]);
    another_policys_envelope_is_refused(&report, &file);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The report names the policy it measured as the shipped module does (the same policy
/// read from its file here), and `eval` refuses it for another policy, or a digest that is
/// none.
fn another_policys_envelope_is_refused(report: &serde_json::Value, file: &std::path::Path) {
    let shipped = std::fs::read_to_string(repo("shipped/src/envelope.rs")).unwrap();
    let digest = report["policy_digest"].as_str().unwrap();
    assert!(
        shipped.contains(&format!("POLICY_DIGEST: u64 = {digest};")),
        "{digest}"
    );
    let other = repo("weights/tests/fixtures/cleanrl.safetensors");
    let eval = |envelope: &std::path::Path| {
        run(&[
            "eval",
            "--policy",
            other.to_str().unwrap(),
            "--envelope",
            envelope.to_str().unwrap(),
            "--controller",
            "monitored",
            "--episodes",
            "1",
        ])
    };
    let o = eval(file);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!(
            "measured for the policy of digest {digest}, not this one"
        )),
        "{err}"
    );
    let mut edited = report.clone();
    edited["policy_digest"] = "0x12".into();
    let bad = file.with_file_name("edited.json");
    std::fs::write(&bad, serde_json::to_vec(&edited).unwrap()).unwrap();
    let o = eval(&bad);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("expected policy_digest as 0x and 16 hex digits, found \"0x12\""),
        "{err}"
    );
}

/// Envelope files no monitor can take, written in `dir`: not JSON, a negative limit, two
/// below f32's least normal, one the parser reads as 0.
fn bad_envelopes(dir: &std::path::Path) -> [String; 6] {
    [
        ("a.json", r#"{"envelope": [1, 2, "x", 3]}"#),
        ("b.json", r#"{"envelope": [1, -2, 3, 3]}"#),
        // Below f32's least subnormal: a zero once narrowed, so refused before.
        ("c.json", r#"{"envelope": [1, 1, 5e-324, 1]}"#),
        // Normal in f64, a subnormal once narrowed.
        ("d.json", r#"{"envelope": [1, 1e-39, 1, 1]}"#),
        // A zero to the parser, without a word.
        ("e.json", r#"{"envelope": [1, 1, 1e-400, 1]}"#),
        // Finite, an infinity once narrowed.
        ("f.json", r#"{"envelope": [1, 1, 1, 3.5e38]}"#),
    ]
    .map(|(name, text)| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_owned()
    })
}

#[test]
fn bad_input_exits_2_before_any_work() {
    let fixture = repo("weights/tests/fixtures/cleanrl.safetensors");
    let fixture = fixture.to_str().unwrap();
    let dir = std::env::temp_dir().join(format!("hs-envelope-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let files = bad_envelopes(&dir);
    let [not_json, negative, tiny, tinier, zero, huge] = files.each_ref().map(String::as_str);
    let monitored = ["eval", "--controller", "monitored"];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            [&monitored[..], &["--policy", fixture]].concat(),
            "--controller monitored needs the envelope measured for --policy",
        ),
        // Named as given: it said `monitored`.
        (
            vec![
                "eval",
                "--controller",
                "policy-int,monitored-int",
                "--policy",
                fixture,
            ],
            "--controller monitored-int needs the envelope measured for --policy",
        ),
        (
            [&monitored[..], &["--envelope", not_json]].concat(),
            "expected the JSON `host-sim envelope --json` prints",
        ),
        (
            [&monitored[..], &["--envelope", negative]].concat(),
            "limits.max_abs[1]: expected zero or more, found the limits [",
        ),
        (
            [&monitored[..], &["--envelope", tiny]].concat(),
            "expected each limit zero or a normal number, in float32 too (at least 1.1754944e-38), found 5e-324",
        ),
        (
            [&monitored[..], &["--envelope", tinier]].concat(),
            "in float32 too (at least 1.1754944e-38), found 1e-39",
        ),
        (
            [&monitored[..], &["--envelope", huge]].concat(),
            "expected each limit within float32's range (+-3.4028235e38), found 3.5e38",
        ),
        (
            [&monitored[..], &["--envelope", zero]].concat(),
            "line 1, column 21: 1e-400 reads as 0",
        ),
        (
            vec!["envelope", "--policy", fixture, "--out", "x.rs"],
            "--out writes the shipped crate's module",
        ),
        (
            vec!["envelope", "--quantile", "0"],
            "--quantile must be a normal number in (0, 1]",
        ),
        (
            vec!["envelope", "--margin", "NaN"],
            "--margin must be in [1, 10]",
        ),
        // Past the bound by less than an f32 can tell: refused, not rounded into it.
        (
            vec!["envelope", "--margin", "10.0000001"],
            "--margin must be in [1, 10], got 10.0000001",
        ),
        (
            vec!["envelope", "--episodes", "0"],
            "--episodes must be in [1, 100000]",
        ),
        (vec!["envelope", "--out", dir.to_str().unwrap()], "--out"),
    ];
    for (args, want) in cases {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want) && o.stdout.is_empty(), "{args:?}: {err}");
    }
    assert!(!std::path::Path::new("x.rs").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A report whose account of its measurement no `envelope` run could have written (a
/// quantile of 5, a margin of 0.5, more episodes balanced than ran) was taken for its limits
/// without a word; one written by hand, the limits alone, still is.
#[test]
fn a_report_that_contradicts_itself_is_refused() {
    let dir = std::env::temp_dir().join(format!("hs-envelope-odd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let limits = r#""envelope": [2, 3, 0.2, 5]"#;
    for (extra, want) in [
        (
            r#""quantile": 5"#,
            "expected a quantile in (0, 1], normal, found 5.0",
        ),
        (
            r#""margin": 0.5"#,
            "expected a margin in [1, 10], found 0.5",
        ),
        (
            r#""balanced": 1000, "episodes_run": 2"#,
            "expected at most the episodes run (2) balanced, found 1000",
        ),
        ("", ""),
    ] {
        let file = dir.join("e.json");
        let sep = if extra.is_empty() { "" } else { ", " };
        std::fs::write(&file, format!("{{{limits}{sep}{extra}}}")).unwrap();
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["eval", "--controller", "monitored", "--episodes", "1"])
            .args(["--horizon", "5", "--envelope"])
            .arg(&file)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        if want.is_empty() {
            assert!(o.status.success(), "{err}");
        } else {
            assert_eq!(o.status.code(), Some(2), "{err}");
            assert!(err.contains(want), "{err}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An envelope bounds the readings of the plant it was measured on: the shipped one
/// (Gymnasium's machine) ran the desk rig's monitor, and so did a file measured there.
#[test]
fn an_envelope_measured_on_another_machine_is_refused() {
    let desk = repo("rigs/desk.toml");
    let desk = desk.to_str().unwrap();
    let monitored = [
        "eval",
        "--controller",
        "monitored",
        "--episodes",
        "1",
        "--horizon",
        "5",
    ];
    let says = "the runtime monitor's envelope was measured on another machine";
    let o = run(&[&monitored[..], &["--rig", desk]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(says), "{err}");
    // The committed measurement of the shipped policy, on Gymnasium's machine.
    let file = repo("docs/results/envelope.json");
    let policy = repo("shipped/policy.safetensors");
    let with = [
        "--policy",
        policy.to_str().unwrap(),
        "--envelope",
        file.to_str().unwrap(),
    ];
    let o = run(&[&monitored[..], &with, &["--rig", desk]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(says), "{err}");
    let o = run(&[&monitored[..], &with].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
