//! `host-sim startup`: the shipped desk policy from power-on on the true desk rig, both
//! arithmetics, a knock that drops the pole recovered, the same figures for the same seed,
//! and bad input refused with exit 2 (a number that reads as zero, in `eval`'s scenarios too).

use std::path::PathBuf;
use std::process::{Command, Output};

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(path)
}

fn startup(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("startup")
        .args(args)
        .output()
        .unwrap()
}

fn desk(args: &[&str]) -> serde_json::Value {
    let (rig, world) = (repo("rigs/desk-identified.toml"), repo("rigs/desk.toml"));
    let mut all = vec!["--json", "--rig", rig.to_str().unwrap()];
    all.extend(["--world", world.to_str().unwrap()]);
    all.extend(args);
    let o = startup(&all);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn lifted_poles_are_caught_in_both_arithmetics_with_the_zero_within_a_count() {
    let v = desk(&["--start", "lifted", "--episodes", "40"]);
    assert_eq!(v["start"], "lifted");
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for (row, arithmetic) in rows.iter().zip(["f32", "int8"]) {
        assert_eq!(row["arithmetic"], arithmetic);
        assert_eq!(
            (row["episodes"].as_u64(), row["success"].as_f64()),
            (Some(40), Some(1.0))
        );
        assert_eq!(row["catches"], 40, "{row}");
        assert!(row["zero_error_counts"].as_i64().unwrap() <= 1, "{row}");
        // The lift comes at 5 to 7 s: the catch follows it within a few periods.
        let t: Vec<f64> = serde_json::from_value(row["time_to_balance_s"].clone()).unwrap();
        assert!(t[0] > 5.0 && t[3] < 9.5, "{t:?}");
        assert_eq!(row["into_margin"], 0, "{row}");
    }
}

/// A 40 N push held for a period, 20 s after power-on, once the pole is up: it drops the
/// pole in most episodes, the motor stops, and the swing-up brings it back within 10 s of
/// the push without a reset (the zero taken once).
#[test]
fn a_knock_that_drops_the_pole_is_recovered_by_the_swing_up() {
    let v = desk(&["--knock", "40@20", "--episodes", "24", "--hold", "20"]);
    assert_eq!(v["knock"], serde_json::json!([40.0, 20.0]));
    for row in v["rows"].as_array().unwrap() {
        assert_eq!(row["episodes"], 24, "{row}");
        // Up at the knock in every episode (swung up within 10 s), then back after it.
        assert!(row["catches"].as_u64().unwrap() >= 24 + 12, "{row}");
        assert!(row["falls"].as_u64().unwrap() >= 12, "{row}");
        assert!(row["success"].as_f64().unwrap() >= 0.9, "{row}");
        assert!(row["zero_error_counts"].as_i64().unwrap() <= 1, "{row}");
        let t: Vec<f64> = serde_json::from_value(row["time_to_balance_s"].clone()).unwrap();
        assert!(t[3] <= 10.0, "{t:?}");
    }
}

#[test]
fn the_same_seed_gives_the_same_figures_and_another_seed_other_ones() {
    let run = |seed: &str| desk(&["--episodes", "12", "--seed", seed]);
    let (a, b, c) = (run("3"), run("3"), run("4"));
    assert_eq!(a, b);
    assert_ne!(a["rows"], c["rows"]);
}

#[test]
fn an_episode_is_drawn_beside_the_json_and_an_episode_past_the_run_is_refused() {
    let dir = std::env::temp_dir().join(format!("startup-render-{}", std::process::id()));
    let v = desk(&[
        "--episodes",
        "2",
        // Every period of the drawn episode is a frame: a short hold keeps it a few hundred.
        "--hold",
        "2",
        "--render",
        dir.to_str().unwrap(),
        "--episode",
        "1",
        "--stride",
        "5",
    ]);
    assert_eq!(v["rows"][0]["episodes"], 2);
    let gif = std::fs::read(dir.join("episode.gif")).unwrap();
    let png = std::fs::read(dir.join("episode.png")).unwrap();
    assert!(gif.starts_with(b"GIF89a") && png.starts_with(b"\x89PNG\r\n\x1a\n"));
    std::fs::remove_dir_all(&dir).unwrap();
    let o = startup(&["--episodes", "2", "--render", "x", "--episode", "2"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--episode must be below --episodes (2), found 2"),
        "{err}"
    );
    assert!(!std::path::Path::new("x").exists());
}

/// The drawn episode is held to `render`'s bounds before any episode runs: an hour to
/// balance and an hour held were 360,000 frames at 50 Hz (minutes of drawing, a GIF of
/// gigabytes), where `render` stops at 10,000.
#[test]
fn a_drawing_past_renders_bounds_is_refused_before_any_episode() {
    let refused = |args: &[&str], want: &str| {
        let mut all = vec!["--episodes", "1000000", "--render", "never"];
        all.extend(args);
        let o = startup(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(o.stdout.is_empty() && !std::path::Path::new("never").exists());
    };
    let from = "the episode --render draws (--within + --hold, after any --knock)";
    refused(
        &["--within", "3600", "--hold", "3600"],
        &format!("{from} must be in [1, 100000] periods to draw, got 360000"),
    );
    refused(
        &["--within", "100", "--hold", "302"],
        &format!(
            "{from} / --stride must make at most 10000 frames of the animation, got 10050 \
             (20100 / 2)"
        ),
    );
    refused(&["--stride", "0"], "--stride must be in [1, 1000], got 0");
    let o = startup(&["--stride", "3"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--render"));
}

#[test]
fn bad_input_exits_2_naming_what_was_expected() {
    let refused = |args: &[&str], expected: &str| {
        let o = startup(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(o.stdout.is_empty());
    };
    refused(
        &["--episodes", "0"],
        "--episodes must be 1 to 1000000, found 0",
    );
    refused(
        &["--hold=-1"],
        "--hold must be seconds in [0.001, 3600], found -1.0",
    );
    refused(
        &["--zero-error", "-12"],
        "--zero-error must be degrees in [-10, 10], zero or normal, found -12.0",
    );
    refused(
        &["--zero-error", "nan"],
        "--zero-error must be degrees in [-10, 10], zero or normal, found NaN",
    );
    refused(
        &["--cart-start=-0.1"],
        "--cart-start must be metres in [0, 10], zero or normal, found -0.1",
    );
    // Inside the range, but subnormal: the message said only the range, which holds it.
    refused(
        &["--cart-start", "1e-45"],
        "--cart-start must be metres in [0, 10], zero or normal, found 1e-45",
    );
    // The desk's track: 0.4 m either side; its pole encoder: 2,400 counts a turn.
    refused(
        &["--cart-start", "10"],
        "--cart-start must be at most the world's track half-length, 0.4 m, found 10.0",
    );
    refused(
        &["--zero-error", "0.05"],
        "--zero-error 0.05 degrees rounds to no count of the pole's encoder (2400 counts a turn",
    );
    let knock = "--knock expects NEWTONS@SECONDS, newtons in (0, 1000] and seconds in (0, 3600]";
    for bad in [
        "40",
        "x@3",
        "--knock=-5@3",
        "40@0",
        "40@nan",
        "1e9@3",
        "40@5@6",
        "5e-324@1",
        "1@1e-40",
    ] {
        let arg = if bad.starts_with("--") {
            bad.to_owned()
        } else {
            format!("--knock={bad}")
        };
        refused(&[&arg], knock);
    }
    refused(
        &["--start", "lifted", "--knock", "40@20"],
        "--knock needs a swing-up to bring the pole back",
    );
    let dir = std::env::temp_dir().join(format!("startup-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("rig.toml");
    let desk = std::fs::read_to_string(repo("rigs/desk.toml")).unwrap();
    std::fs::write(
        &bad,
        format!("{desk}\n[startup]\nrelease_angle_deg = 20.0\n"),
    )
    .unwrap();
    refused(
        &["--rig", bad.to_str().unwrap()],
        "startup.release_angle: expected at most params.theta_threshold_radians",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A number below f64's range reads as zero, which every check of a part passes.
#[test]
fn a_number_that_reads_as_zero_is_refused_in_a_scenario_and_a_flag() {
    for args in [
        &[
            "eval",
            "--scenario",
            "friction=1e-400/0.1",
            "--controller",
            "lqr",
        ][..],
        &["startup", "--zero-error", "1e-400"],
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("1e-400 reads as 0"), "{args:?}: {err}");
        // The flag named, its value given apart from it.
        let flag = args[1];
        assert!(
            err.starts_with(&format!("error: {flag} \"")),
            "{args:?}: {err}"
        );
    }
}

/// A drawing's directory ending in `/.` was refused by the system after the episodes (exit
/// 1); one ending in `/..` made a directory and drew in its parent. Both are refused first,
/// nothing made, in `render` and `startup --render` alike.
#[test]
fn a_drawing_directory_ending_in_a_dot_is_refused_first() {
    let dir = std::env::temp_dir().join(format!("hs-dot-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir(&dir).unwrap();
    for end in [".", ".."] {
        let out = dir.join("new").join(end);
        let out = out.to_str().unwrap();
        for (flag, o) in [
            ("--render", startup(&["--episodes", "2", "--render", out])),
            (
                "--out",
                Command::new(env!("CARGO_BIN_EXE_host-sim"))
                    .args(["render", "--horizon", "5", "--out", out])
                    .output()
                    .unwrap(),
            ),
        ] {
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{flag} {out}: {err}");
            let want = format!("{flag} {out}: expected a directory named by its own name");
            assert!(err.contains(&want), "{err}");
            assert!(o.stdout.is_empty(), "{flag} {out}");
            assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "{flag} {out}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Episodes too short to take the zero report no zero error (`null`, `-`): it was i64's
/// largest, 9223372036854775807 counts, as if measured.
#[test]
fn a_zero_never_taken_is_reported_as_none() {
    let o = startup(&["--episodes", "1", "--within", "1", "--hold", "1", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for row in v["rows"].as_array().unwrap() {
        assert!(row["zero_error_counts"].is_null(), "{row}");
        assert!(row["centre_error_counts"].is_null(), "{row}");
    }
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    let table = startup(&["--episodes", "1", "--within", "1", "--hold", "1"]);
    assert!(table.status.success());
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(!text.contains("9223372036854775807"), "{text}");
    // The zero and centre columns, the eighth and ninth of the row.
    let row = text.lines().find(|l| l.trim_start().starts_with("f32"));
    let cells: Vec<&str> = row.unwrap().split_whitespace().collect();
    assert_eq!(cells[7..9], ["-", "-"], "{row:?}");
}

/// A time that rounds to no period judged episodes at no time and reported 0%.
#[test]
fn a_time_that_rounds_to_no_period_is_refused() {
    for (flag, other) in [("--within", "--hold"), ("--hold", "--within")] {
        let o = startup(&[flag, "0.001", other, "1"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        let want = format!("{flag} 0.001 s rounds to no period of 0.02 s; expected at least half");
        assert!(err.contains(&want), "{err}");
        assert!(o.stdout.is_empty());
    }
}
