//! A run directory's summary, which export copies into code: absent only when no such name
//! exists (whatever has the name is read as an input is, and a directory, a FIFO or a link
//! to a device is refused, naming what it is: taken as absent, the module lost the run's
//! provenance without a word), and its figures checked before they are copied.

use std::path::Path;

use std::process::Command;

use super::{mkfifo, refused, run, scratch, stderr};

/// What a summary is made, and how.
type Kind<'a> = (&'a str, &'a dyn Fn(&Path));

#[test]
fn a_summary_that_is_not_a_regular_file_is_refused_not_taken_as_absent() {
    let dir = scratch("summary-kinds");
    let policy = concat!(env!("CARGO_MANIFEST_DIR"), "/../shipped/policy.safetensors");
    let out = dir.join("policy.rs");
    let kinds: [Kind; 3] = [
        ("a directory", &|p| std::fs::create_dir(p).unwrap()),
        ("a FIFO", &|p| mkfifo(p)),
        ("a device", &|p| {
            std::os::unix::fs::symlink("/dev/zero", p).unwrap()
        }),
    ];
    for (k, (kind, make)) in kinds.iter().enumerate() {
        let run = dir.join(format!("run-{k}"));
        std::fs::create_dir(&run).unwrap();
        std::fs::copy(policy, run.join("policy.safetensors")).unwrap();
        make(&run.join("summary.json"));
        // Named as the run directory, and as the policy file beside it.
        for src in [run.clone(), run.join("policy.safetensors")] {
            let export = [
                "export",
                src.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ];
            refused(
                &export,
                &format!("summary.json: expected a regular file, found {kind}"),
            );
            assert!(!out.exists(), "{kind}: nothing written");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A trained run, its marker taken away (its digests would refuse every edit by hand), its
/// summary as written, and the export of it.
struct Edited {
    dir: std::path::PathBuf,
    run_dir: std::path::PathBuf,
    out: std::path::PathBuf,
    good: serde_json::Value,
}

impl Edited {
    fn new(name: &str) -> Edited {
        let dir = scratch(name);
        let (run_dir, out) = (dir.join("run"), dir.join("policy.rs"));
        let o = run(&[
            "train",
            "--episodes",
            "5",
            "--out",
            run_dir.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::remove_file(run_dir.join(".cartpole-run")).unwrap();
        let good = serde_json::from_slice(&std::fs::read(run_dir.join("summary.json")).unwrap());
        Edited {
            dir,
            run_dir,
            out,
            good: good.unwrap(),
        }
    }

    fn export(&self) -> [&str; 4] {
        let out = self.out.to_str().unwrap();
        ["export", self.run_dir.to_str().unwrap(), "--out", out]
    }

    /// Writes `summary` as the run's and checks that export refuses it with `says`.
    fn refused(&self, summary: &serde_json::Value, says: &str) {
        let path = self.run_dir.join("summary.json");
        std::fs::write(&path, serde_json::to_vec(summary).unwrap()).unwrap();
        refused(&self.export(), says);
        assert!(!self.out.exists());
    }
}

#[test]
fn a_run_summarys_figures_are_checked_before_export_copies_them_into_code() {
    let e = Edited::new("figures");
    let over = (e.good["final_eval"]["max_steps"].as_u64().unwrap() + 100) as f64;
    for (key, value, says) in [
        (
            "min",
            over.into(),
            "final_eval.min: expected a return from 1.0 to",
        ),
        ("episodes", 0.into(), "final_eval.episodes: expected 1 to"),
        (
            "mean",
            (-5.0).into(),
            "final_eval.min: expected a return from 1.0 to -5.0",
        ),
        ("max_steps", 0.into(), "final_eval.max_steps: expected 1 to"),
        (
            "mean",
            1e308.into(),
            "final_eval.mean: expected a return from",
        ),
        (
            "mean",
            5e-324.into(),
            "final_eval.mean: expected a normal number, found 5e-324",
        ),
        (
            "min",
            0.5.into(),
            "final_eval.min: expected a whole number of steps, found 0.5",
        ),
        // No episode takes no step; `-0.0` went into the module as the minimum.
        (
            "min",
            0.0.into(),
            "final_eval.min: expected a return from 1.0",
        ),
        ("min", (-0.0).into(), "found -0.0"),
    ] {
        let mut bad = e.good.clone();
        bad["final_eval"][key] = value;
        e.refused(&bad, "summary.json: not a run summary");
        e.refused(&bad, says);
    }
    // Read as 0, it went into the module as the measured minimum.
    let text = serde_json::to_string(&e.good).unwrap();
    let min = format!("\"min\":{}", e.good["final_eval"]["min"]);
    let hidden = text.replacen(&min, "\"min\":1e-400", 1);
    std::fs::write(e.run_dir.join("summary.json"), hidden).unwrap();
    refused(&e.export(), "1e-400 reads as 0");
    let mut bad = e.good.clone();
    bad["episodes_run"] = 0.into();
    e.refused(
        &bad,
        "episodes_run: expected 1 to 5 (at most the configured episodes), found 0",
    );
    // The run's own figures pass, shown shortest.
    let path = e.run_dir.join("summary.json");
    std::fs::write(&path, serde_json::to_vec(&e.good).unwrap()).unwrap();
    let o = run(&e.export());
    assert!(o.status.success(), "{}", stderr(&o));
    let module = std::fs::read_to_string(&e.out).unwrap();
    let mean = e.good["final_eval"]["mean"].as_f64().unwrap();
    assert!(
        module.contains(&format!("greedy evaluation: mean {mean:?}, min ")),
        "{module}"
    );
    std::fs::remove_dir_all(&e.dir).unwrap();
}

/// Another run's seed or configuration beside this policy file, or one past the trainer's
/// limits, is no summary of it; a run of an older version, whose files lack the keys added
/// since, is its own run's.
#[test]
fn a_summary_of_another_run_is_refused_and_an_older_runs_taken() {
    let e = Edited::new("other-run");
    let mut bad = e.good.clone();
    bad["seed"] = 12345.into();
    e.refused(
        &bad,
        "seed: the policy file records seed \"0\", the summary 12345",
    );
    let mut bad = e.good.clone();
    bad["config"]["algo"] = "dqn".into();
    e.refused(
        &bad,
        "config.algo: the policy file records \"ddqn\", the summary \"dqn\"",
    );
    let mut bad = e.good.clone();
    bad["config"]["episodes"] = 2_000_000_000_000u64.into();
    e.refused(&bad, "not a run summary: config: episodes");
    // An older version wrote neither `levels` nor `patience`, and recorded the kernel.
    let policy = e.run_dir.join("policy.safetensors");
    let import = weights::checkpoint::load(&policy, None).unwrap();
    let mut meta = import.metadata.clone();
    let mut config: serde_json::Value = serde_json::from_str(&meta["config"]).unwrap();
    let mut older = e.good.clone();
    for key in ["levels", "patience"] {
        config.as_object_mut().unwrap().remove(key);
        older["config"].as_object_mut().unwrap().remove(key);
    }
    config["kernel"] = e.good["config"]["kernel"].clone();
    meta.insert("config".into(), config.to_string());
    let file = weights::checkpoint::to_safetensors(&import.weights, &meta).unwrap();
    std::fs::write(&policy, file).unwrap();
    std::fs::write(e.run_dir.join("summary.json"), older.to_string()).unwrap();
    let o = run(&e.export());
    assert!(o.status.success(), "{}", stderr(&o));
    // A value no configuration takes is no match for the summary's, not a key to skip.
    std::fs::remove_file(&e.out).unwrap();
    config["algo"] = "DQN".into();
    meta.insert("config".into(), config.to_string());
    let file = weights::checkpoint::to_safetensors(&import.weights, &meta).unwrap();
    std::fs::write(&policy, file).unwrap();
    refused(
        &e.export(),
        "config.algo: the policy file records \"DQN\", the summary \"ddqn\"",
    );
    std::fs::remove_dir_all(&e.dir).unwrap();
}

/// A run of two five-step episodes, with `extra` flags, written to `out`.
fn tiny_run(out: &Path, extra: &[&str]) {
    let base = ["train", "--episodes", "2", "--max-steps", "5", "--out"];
    let o = run(&[&base[..], &[out.to_str().unwrap()], extra].concat());
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Export writes nothing into a run's directory (its marker, which proves the rest, was
/// overwritten, and then any junk in its place read as no marker), and a marker that is
/// none this tool wrote is refused, not taken as absent.
#[test]
fn export_keeps_out_of_a_run_and_reads_its_marker_as_an_input() {
    let dir = scratch("marked");
    let run_dir = dir.join("run");
    tiny_run(&run_dir, &[]);
    let marker = run_dir.join(".cartpole-run");
    let written = std::fs::read(&marker).unwrap();
    let src = run_dir.to_str().unwrap();
    std::fs::create_dir_all(run_dir.join("sub/deeper")).unwrap();
    for name in [
        ".cartpole-run",
        "metrics.csv",
        "notes.rs",
        "sub/deeper/x.rs",
        "new/x.rs",
    ] {
        let out = run_dir.join(name);
        refused(
            &["export", src, "--out", out.to_str().unwrap()],
            "expected a path outside the output directories of policy-export",
        );
    }
    assert_eq!(std::fs::read(&marker).unwrap(), written);
    assert!(!run_dir.join("notes.rs").exists() && !run_dir.join("new").exists());
    std::fs::remove_dir_all(run_dir.join("sub")).unwrap();
    // Beside the run, named through it, is outside it.
    let beside = run_dir.join("../beside.rs");
    let o = run(&["export", src, "--out", beside.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.join("policy.rs");
    let export = ["export", src, "--out", out.to_str().unwrap()];
    std::fs::write(&marker, b"junk").unwrap();
    refused(
        &export,
        ".cartpole-run: expected the marker its run wrote, or none: its .cartpole-run is not a \
         marker this tool wrote",
    );
    assert!(!out.exists());
    std::fs::remove_file(&marker).unwrap();
    let o = run(&export);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A seed's directory of a `--seeds` run named as `.` from inside it, or through a link,
/// is the run's: its summary, edited since, is refused as by its plain name (it went into
/// the module as fact).
#[test]
fn a_seeds_directory_is_its_run_s_however_it_is_named() {
    let dir = scratch("seed-named");
    let run_dir = dir.join("run");
    tiny_run(&run_dir, &["--seeds", "0..2"]);
    let seed = run_dir.join("seed-1");
    let summary = seed.join("summary.json");
    let text = std::fs::read_to_string(&summary).unwrap();
    std::fs::write(&summary, format!("{text} ")).unwrap();
    let link = dir.join("link");
    std::os::unix::fs::symlink(&seed, &link).unwrap();
    let out = dir.join("p.rs");
    for (src, cwd) in [
        (seed.as_path(), &dir),
        (Path::new("."), &seed),
        (&link, &dir),
    ] {
        let ran = super::hostile::run_counted(
            super::exe()
                .args([
                    "export",
                    src.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                ])
                .current_dir(cwd),
        );
        assert_eq!(ran.code, Some(2), "{src:?}: {}", ran.stderr);
        assert!(
            ran.stderr.contains("expected the file its run wrote"),
            "{}",
            ran.stderr
        );
    }
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `policy-export` as a user permissions hold: `nobody` through `setpriv` where the tests run
/// as root (as CI does), which no permission stops; itself otherwise.
fn unprivileged() -> Command {
    use std::os::unix::fs::MetadataExt;
    let exe = env!("CARGO_BIN_EXE_policy-export");
    if std::fs::metadata("/proc/self").unwrap().uid() != 0 {
        return Command::new(exe);
    }
    let mut c = Command::new("setpriv");
    c.args([
        "--reuid=65534",
        "--regid=65534",
        "--clear-groups",
        "--",
        exe,
    ]);
    c
}

/// An earlier run made read-only is refused before the work: its files could not be removed
/// once the new run was in place, which was found after a whole training (exit 1, the
/// earlier run kept aside under a hidden name).
#[test]
fn a_read_only_earlier_run_is_refused_before_the_work() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("read-only-run");
    let mode = |p: &Path, m: u32| std::fs::set_permissions(p, PermissionsExt::from_mode(m));
    mode(&dir, 0o777).unwrap();
    let run_dir = dir.join("run");
    let train = [
        "train",
        "--episodes",
        "3",
        "--max-steps",
        "10",
        "--out",
        run_dir.to_str().unwrap(),
    ];
    let made = unprivileged().args(train).output().unwrap();
    assert!(made.status.success(), "{}", stderr(&made));
    mode(&run_dir, 0o555).unwrap();
    let ran = super::hostile::run_counted(unprivileged().args(train));
    assert_eq!(ran.code, Some(2), "{}", ran.stderr);
    assert!(
        ran.stderr
            .contains("cannot be written in (Permission denied")
            && ran
                .stderr
                .contains("make it writable, or choose another --out"),
        "{}",
        ran.stderr
    );
    assert!(ran.late().is_none(), "{:?}", ran.cpu);
    mode(&run_dir, 0o755).unwrap();
    assert_eq!(super::entries(&dir), ["run"]);
    std::fs::remove_dir_all(&dir).unwrap();
}
