//! `scripts/regenerate.sh`, the one command that measures every results file again, runs
//! exactly the steps of `docs/results/manifest.toml`: `--list` (which runs nothing) shows each
//! with its command, the selection flags choose among them, and what it cannot run is refused
//! before any work.

use std::process::Command;

use e2e::{build_tool, repo, test_profile};
use host_sim::manifest::Manifest;

/// `scripts/regenerate.sh --list` (which runs nothing) shows every step of the manifest with
/// its command, the selection flags choose among them, and a step that needs a missing tool
/// or a selection that matches nothing is refused before any work.
#[test]
fn the_regeneration_script_runs_the_manifests_steps() {
    // Built here with the test run's features; the script is told not to build them its
    // own way (for the two tools alone, another copy of half the workspace).
    build_tool("host-sim");
    build_tool("policy-export");
    let script = |args: &[&str]| {
        let o = Command::new(repo().join("scripts/regenerate.sh"))
            .args(["--profile", &test_profile(), "--built"])
            .args(args)
            .env("PYTHON", "/nonexistent/python")
            .current_dir(repo())
            .output()
            .unwrap();
        let out = String::from_utf8(o.stdout).unwrap() + &String::from_utf8(o.stderr).unwrap();
        (o.status.code(), out)
    };
    let m = Manifest::load(&repo()).unwrap();
    let (code, all) = script(&["--list", "--skip", "sb3-*"]);
    assert_eq!(code, Some(0), "{all}");
    for s in &m.steps {
        let listed = all
            .lines()
            .any(|l| l.starts_with(&s.name) && l.ends_with(&s.run));
        let skipped = all.contains(&format!("left out: {} (--skip)", s.name));
        assert!(listed != skipped, "{}: {all}", s.name);
    }
    let (code, out) = script(&["--list", "--only", "eval-*", "--skip", "eval-hard*"]);
    assert_eq!(code, Some(0), "{out}");
    let steps: Vec<&str> = out.lines().filter(|l| l.starts_with("eval-")).collect();
    assert_eq!(steps.len(), 5, "{out}");
    assert!(out.contains("left out: eval-hard (--skip)\n"), "{out}");
    let (code, out) = script(&["--list", "--from", "tables"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("\n1 steps, about "), "{out}");
    // SB3 needs $PYTHON: missing here, so its steps are refused, naming the way out.
    let refusals: [(&[&str], &str); 4] = [
        (&["--only", "sb3-nominal"], "sb3-nominal needs sb3"),
        (&["--only", "nothing*"], "no step matches 'nothing*'"),
        (&["--from", "nothing"], "--from: no step named 'nothing'"),
        (&["--colour"], "unknown argument '--colour'"),
    ];
    for (args, want) in refusals {
        let (code, out) = script(args);
        assert_eq!(code, Some(2), "{args:?}: {out}");
        assert!(out.contains(want), "{args:?}: {out}");
        assert!(!out.contains("== [1/"), "{args:?} ran a step: {out}");
    }
}
