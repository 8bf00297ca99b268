//! `host-sim soak`: a long episode's readings stay within the encoders' resolution of the
//! truth and do not drift, coast exactly where readings were dropped, a fall exits 1, and
//! bad input exits 2 before any work.

use std::process::{Command, Output};

fn soak(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("soak")
        .args(args)
        .output()
        .unwrap()
}

fn json(args: &[&str]) -> (Option<i32>, serde_json::Value) {
    let mut all = args.to_vec();
    all.push("--json");
    let o = soak(&all);
    let err = String::from_utf8_lossy(&o.stderr);
    let v = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{args:?}: {e} {err}"));
    (o.status.code(), v)
}

fn errors(v: &serde_json::Value, key: &str) -> Vec<f64> {
    v[key]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_f64().unwrap())
        .collect()
}

#[test]
fn readings_stay_within_a_count_of_the_truth_and_do_not_drift() {
    let (code, v) = json(&["--hours", "2", "--scenario", "encoder"]);
    assert_eq!(code, Some(0));
    assert_eq!(v["periods_run"], 360_000);
    assert_eq!(v["balanced"], true);
    assert_eq!(v["coasting_periods"], 0, "no fault injected, none found");
    // Gymnasium's rig: 20,480 counts a metre, 4,096 a revolution.
    let (cart, pole) = (1.0 / 20_480.0, std::f64::consts::TAU / 4096.0);
    let whole = errors(&v, "max_error");
    assert!(whole[0] < cart && whole[2] < pole, "{whole:?}");
    let (first, last) = (
        errors(&v, "max_error_first_hour"),
        errors(&v, "max_error_last_hour"),
    );
    assert!(
        last[0] <= first[0] * 1.05 && last[2] <= first[2] * 1.05,
        "{first:?} {last:?}"
    );
}

#[test]
fn dropped_readings_are_the_coasting_periods_and_a_fall_exits_1() {
    let (code, v) = json(&["--hours", "1", "--scenario", "encoder+drop=10"]);
    assert_eq!((code, &v["coasting_periods"]), (Some(0), &18_000.into()));
    // The motor dead for half a second every five: the pole falls.
    let (code, v) = json(&["--hours", "1", "--scenario", "weak=0/25/250"]);
    assert_eq!((code, &v["balanced"]), (Some(1), &false.into()));
    assert!(v["periods_run"].as_u64().unwrap() < 180_000);
}

#[test]
fn bad_input_exits_2_naming_what_was_expected() {
    for (args, expected) in [
        (&["--hours", "0"][..], "--hours"),
        (&["--hours", "1e9"], "--hours"),
        (&["--hours", "nan"], "--hours"),
        (
            &["--hours", "1e-10"],
            "--hours 1e-10 is less than one period of 0.02 s; expected at least 5.5",
        ),
        (&["--scenario", "bogus"], "unknown part"),
        (&["--controller", "nobody"], "controller"),
    ] {
        let o = soak(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(o.stdout.is_empty(), "{args:?}");
    }
}
