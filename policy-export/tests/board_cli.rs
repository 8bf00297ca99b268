//! `export` says on standard error, and still exports (exit 0), when the run that made a
//! policy never tried it as its boards run it, or when a board fell in the finalists' trial.

use std::path::{Path, PathBuf};
use std::process::Command;

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_policy-export"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pe-board-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Exports `src` to `out`; what it printed on standard error, once it succeeded.
#[track_caller]
fn export(src: &Path, out: &Path) -> String {
    let o = exe()
        .arg("export")
        .arg(src)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(out.is_file(), "{err}");
    err
}

/// A finalists' trial result of `mean` over 50 episodes of 10,000 periods.
fn trial(mean: f64) -> serde_json::Value {
    serde_json::json!({
        "episodes": 50, "max_steps": 10000, "mean": mean, "min": mean.min(10000.0), "cost": 0.01
    })
}

/// Sets the run's `board_trial` to the f32 and int8 trial means given.
fn set_board_trial(run: &Path, f32: f64, int8: f64) {
    let path = run.join("summary.json");
    // A summary edited by hand: without the run's marker, whose digest would refuse it, the
    // directory is one put together by hand, its summary read as it is.
    let _ = std::fs::remove_file(run.join(".cartpole-run"));
    let mut s: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    s["board_trial"] = serde_json::json!({ "episode": 20, "f32": trial(f32), "int8": trial(int8) });
    std::fs::write(&path, serde_json::to_vec_pretty(&s).unwrap()).unwrap();
}

#[test]
fn export_warns_when_the_run_has_no_board_figures_or_a_board_fell() {
    let dir = scratch("warn");
    let run = dir.join("run");
    let o = exe()
        .args(["train", "--episodes", "20", "--seed", "2", "--out"])
        .arg(&run)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = run.join("summary.json");
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    assert!(s["board_trial"].is_null(), "{}", s["board_trial"]);
    let out = dir.join("policy.rs");
    let shown = summary.display().to_string();

    // The paper preset has no finalists' trial: no board figures, for the run directory and
    // for the policy file inside it alike.
    for src in [run.clone(), run.join("policy.safetensors")] {
        let err = export(&src, &out);
        let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("warning")).collect();
        assert_eq!(lines.len(), 1, "{err}");
        assert!(
            lines[0].contains(&shown) && lines[0].contains("no board-level trial figures"),
            "{err}"
        );
    }

    // The int8 board within a point of the float board's, or longer: nothing to say. The
    // float board need not last the trial's length, whose pushes no snapshot outlasts.
    for (f32, int8) in [(10_000.0, 10_000.0), (9_000.0, 8_950.0), (2_000.0, 6_100.0)] {
        set_board_trial(&run, f32, int8);
        let err = export(&run, &out);
        assert!(!err.contains("warning"), "{f32} {int8}: {err}");
    }

    // The int8 board fell more than a point sooner: both figures, named.
    for (f32, int8) in [(10_000.0, 9_876.5), (1_755.0, 539.0)] {
        set_board_trial(&run, f32, int8);
        let err = export(&run.join("policy.safetensors"), &out);
        let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("warning")).collect();
        assert_eq!(lines.len(), 1, "{err}");
        let want = format!(
            "board_trial.int8.mean is {int8:.1} periods against board_trial.f32.mean {f32:.1}"
        );
        assert!(
            lines[0].contains(&shown) && lines[0].contains(&want),
            "{err}"
        );
    }

    // A policy file no summary describes (the shipped one's directory holds none).
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shipped/policy.safetensors");
    let err = export(&shipped, &out);
    assert!(!err.contains("warning"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
