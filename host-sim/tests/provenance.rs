//! A results file says where it came from: `eval --json` and `envelope --json` record the
//! command line after the program's name (so that it runs again), the date, the revision
//! `git` reports for the checkout the tool was built from (never the directory it runs in,
//! whose configuration would run), the CPUs and the CPU's model.

use std::path::Path;
use std::process::Command;

use serde_json::Value as Json;

fn run(args: &[&str]) -> Json {
    run_in(&Path::new(env!("CARGO_MANIFEST_DIR")).join(".."), args, &[])
}

fn run_in(dir: &Path, args: &[&str], envs: &[(&str, &Path)]) -> Json {
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .envs(envs.iter().copied())
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// `git rev-parse --short HEAD` at the root, or `unknown` where git cannot say.
fn revision() -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let o = Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .current_dir(root)
        .output();
    match o {
        Ok(o) if o.status.success() => String::from_utf8(o.stdout).unwrap().trim().to_string(),
        _ => "unknown".into(),
    }
}

#[test]
fn eval_and_envelope_record_their_command_revision_and_machine() {
    let eval = [
        "eval",
        "--json",
        "--scenario",
        "nominal",
        "--episodes",
        "3",
        "--horizon",
        "20",
    ];
    let envelope = [
        "envelope",
        "--json",
        "--scenario",
        "nominal",
        "--episodes",
        "2",
        "--horizon",
        "30",
    ];
    for args in [&eval[..], &envelope[..]] {
        let doc = run(args);
        let p = &doc["provenance"];
        assert_eq!(p["tool"], "host-sim", "{p}");
        assert_eq!(p["argv"], serde_json::json!(args), "{p}");
        assert_eq!(p["revision"], revision().as_str(), "{p}");
        assert!(p["dirty"].is_boolean(), "{p}");
        let nproc = std::thread::available_parallelism().unwrap().get();
        assert_eq!(p["nproc"], nproc, "{p}");
        assert!(!p["cpu"].as_str().unwrap().is_empty(), "{p}");
        // YYYY-MM-DDTHH:MM:SSZ, in this century.
        let date = p["date"].as_str().unwrap();
        assert!(
            date.len() == 20 && date.starts_with("20") && date.ends_with('Z'),
            "{p}"
        );
    }
}

/// Run inside a checkout that is not the tool's, the tool records its own revision and
/// leaves that checkout alone: its `core.fsmonitor` command does not run, its index is not
/// rewritten.
#[test]
fn a_checkout_the_tool_runs_in_is_neither_asked_nor_touched() {
    let dir = std::env::temp_dir().join(format!("hs-git-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let ran = dir.join("FSMONITOR_RAN");
    let git = |args: &[&str]| {
        let o = Command::new("git")
            .args([
                "-c",
                "user.name=t",
                "-c",
                "user.email=t@t",
                "-c",
                "commit.gpgsign=false",
            ])
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    git(&["init", "-q"]);
    std::fs::write(dir.join("a"), "a").unwrap();
    git(&["add", "a"]);
    git(&["commit", "-q", "-m", "a"]);
    let monitor = format!("touch {}; false", ran.display());
    git(&["config", "core.fsmonitor", &monitor]);
    // A file changed since the index was written: a status would refresh the index.
    std::fs::write(dir.join("a"), "b").unwrap();
    let index = std::fs::read(dir.join(".git/index")).unwrap();
    let args = ["eval", "--json", "--episodes", "1", "--horizon", "5"];
    // Stood in, or named by the caller's GIT_DIR, which would send git there.
    let git_dir = dir.join(".git");
    for envs in [&[][..], &[("GIT_DIR", git_dir.as_path())]] {
        let doc = run_in(&dir, &args, envs);
        assert_eq!(doc["provenance"]["revision"], revision().as_str());
        assert!(!ran.exists(), "the checkout's core.fsmonitor ran");
        assert_eq!(std::fs::read(dir.join(".git/index")).unwrap(), index);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
