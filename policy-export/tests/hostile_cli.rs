//! The command line against hostile use: huge counts, outputs that are not ours, inputs
//! that never end, runs that diverge. Every refusal exits 2 before any work, names what was
//! expected and what was found, quotes little of the input, and touches nothing.

use std::path::PathBuf;
use std::process::{Command, Output};

// The shared harness: its runner of refusals and its FIFOs.
#[allow(dead_code)]
#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

use hostile::{FORGED, entries, mkfifo, refused_escaped};

#[path = "hostile_cli/modes.rs"]
mod modes;
#[path = "hostile_cli/run_dir.rs"]
mod run_dir;

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_policy-export"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pe-hostile-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str]) -> Output {
    exe().args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit 2, within the refusals' processor time, with `want` in a short message.
fn refused(args: &[&str], want: &str) {
    let ran = hostile::run_counted(exe().args(args));
    let seen = format!(
        "{args:?}: exit {:?} after {:?} of processor time: {}",
        ran.code, ran.cpu, ran.stderr
    );
    assert_eq!(ran.code, Some(2), "{seen}");
    assert!(ran.stderr.contains(want), "{seen}");
    assert!(
        ran.stderr.len() < 1_000,
        "{args:?}: {} bytes of message",
        ran.stderr.len()
    );
    assert!(ran.late().is_none(), "{seen}");
}

#[test]
fn huge_counts_are_refused_before_any_allocation() {
    let max = "18446744073709551615";
    let seeds = format!("0..{max}");
    let long = "x".repeat(100_000);
    let cases: [(&[&str], &str); 20] = [
        (
            &["train", "--episodes", max],
            "episodes must be in [1, 1000000]",
        ),
        (
            &["train", "--seeds", &seeds],
            "expected at most 10000 seeds",
        ),
        (
            &["train", "--buffer-size", "10000000000"],
            "buffer_size must be in [1, 5000000]",
        ),
        (
            &["train", "--max-steps", "4294967295"],
            "max_steps must be in [1, 1000000]",
        ),
        (
            &["train", "--max-env-steps", max],
            "max_env_steps must be in [0, 1000000000]",
        ),
        (
            &["train", "--updates-per-train", "100000"],
            "updates_per_train must be in [1, 1000]",
        ),
        (&["train", "--train-unit", "hours"], "invalid value 'hours'"),
        (
            &["train", "--preset", "paper-fast"],
            "invalid value 'paper-fast'",
        ),
        (
            &["train", "--batch-size", "100000"],
            "batch_size must be in [1, 4096]",
        ),
        (
            &["train", "--final-eval-episodes", "0"],
            "final_eval_episodes must be in [1, 100000]",
        ),
        (
            &["train", "--adam-eps", "1e-50"],
            "adam_eps must be a normal f32 > 0",
        ),
        (
            &["train", "--lr", "1e39"],
            "lr must be > 0 and finite in f32",
        ),
        (
            &["reproduce", "--seeds", max],
            "--seeds must be in [2, 1000]",
        ),
        (
            &["reproduce", "--seeds", "1"],
            "--seeds must be in [2, 1000]",
        ),
        (
            &["reproduce", "--study", "bogus"],
            "--study: expected one of table1, table4",
        ),
        (
            &["reproduce", "--study", &long],
            "--study: expected one of table1, table4",
        ),
        (
            &["reproduce", "--study", "table1,table4,table1"],
            "--study: expected each study once, found table1 twice",
        ),
        (&["train", "--seeds", &long], "expected START..END"),
        (&["train", "--seeds", "+0..2"], "each in decimal digits"),
        (&["train", "--seeds", "0..+2"], "each in decimal digits"),
    ];
    for (args, want) in cases {
        refused(args, want);
    }
}

#[test]
fn text_that_is_not_utf8_is_refused_naming_its_flag_and_a_path_that_is_not_is_taken() {
    use std::ffi::{OsStr, OsString};
    use std::os::unix::ffi::OsStrExt;
    let dir = scratch("utf8");
    let out = dir.join(OsStr::from_bytes(b"o\xff.rs"));
    let policy = concat!(env!("CARGO_MANIFEST_DIR"), "/../shipped/policy.safetensors");
    let os = |a: &[&[u8]]| -> Vec<OsString> {
        a.iter().map(|b| OsStr::from_bytes(b).to_owned()).collect()
    };
    let export = |rest: &[&[u8]]| -> Vec<OsString> {
        let mut args = os(&[b"export", policy.as_bytes(), b"--out"]);
        args.push(out.clone().into());
        args.extend(os(rest));
        args
    };
    let cases: [(Vec<OsString>, &str); 8] = [
        (
            export(&[b"--name", b"P\xff"]),
            "--name: expected UTF-8 text, found \"P\u{fffd}\"",
        ),
        // Two flags so given, either first: the first is named. A flag given again after
        // the bytes: it was "argument 6", its value replaced by the second in the trace.
        (
            export(&[b"--prefix", b"a\xfe", b"--name", b"P\xff"]),
            "--prefix: expected UTF-8 text, found \"a\u{fffd}\"",
        ),
        (
            export(&[b"--name", b"P\xff", b"--prefix", b"a\xfe"]),
            "--name: expected UTF-8 text, found \"P\u{fffd}\"",
        ),
        (
            export(&[b"--name", b"P\xff", b"--name", b"Q"]),
            "--name: expected UTF-8 text, found \"P\u{fffd}\"",
        ),
        (
            export(&[b"--prefix=a\xfe"]),
            "--prefix: expected UTF-8 text, found \"a\u{fffd}\"",
        ),
        (
            os(&[b"train", b"--print-config", b"--domain", b"noise\xff"]),
            "--domain: expected UTF-8 text, found \"noise\u{fffd}\"",
        ),
        (
            os(&[b"train", b"--print-config", b"--levels=-1,\xc3"]),
            "--levels: expected UTF-8 text, found \"-1,\u{fffd}\"",
        ),
        (
            os(&[b"reproduce", b"--study", b"table1,\xff"]),
            "--study: expected UTF-8 text, found \"table1,\u{fffd}\"",
        ),
    ];
    for (args, want) in cases {
        let ran = hostile::run_counted(exe().args(&args));
        let seen = format!("{args:?}: exit {:?}: {}", ran.code, ran.stderr);
        assert_eq!(ran.code, Some(2), "{seen}");
        assert_eq!(ran.stderr.trim_end(), format!("error: {want}"), "{seen}");
        assert!(ran.late().is_none(), "{seen}");
    }
    assert_eq!(entries(&dir), Vec::<String>::new());
    let o = exe().args(export(&[b"--name", b"P"])).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        std::fs::read_to_string(&out)
            .unwrap()
            .contains("pub static P:")
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn outputs_that_are_not_the_tools_are_refused_before_the_work() {
    let dir = scratch("outs");
    let file = dir.join("notes.txt");
    std::fs::write(&file, b"mine").unwrap();
    let f = file.to_str().unwrap();
    refused(
        &["train", "--seeds", "0..3", "--out", f],
        "not replacing it: it is a regular file",
    );
    refused(
        &["reproduce", "--seeds", "2", "--out", f],
        "not replacing it: it is a regular file",
    );
    refused(&["train", "--out", "/dev/null"], "it is a device");
    // A directory of someone else's, even one with a file named as a run's.
    let foreign = dir.join("photos");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("cat.jpg"), b"meow").unwrap();
    std::fs::write(foreign.join("summary.json"), b"{}").unwrap();
    for args in [
        &["train", "--episodes", "1", "--out"][..],
        &["train", "--episodes", "1", "--seeds", "0..2", "--out"],
        &["reproduce", "--seeds", "2", "--study", "table4", "--out"],
    ] {
        let mut args = args.to_vec();
        args.push(foreign.to_str().unwrap());
        refused(&args, "holds no .cartpole-run marker");
    }
    assert_eq!(std::fs::read(&file).unwrap(), b"mine");
    assert_eq!(std::fs::read(foreign.join("cat.jpg")).unwrap(), b"meow");
    assert_eq!(std::fs::read(foreign.join("summary.json")).unwrap(), b"{}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_run_directory_is_replaced_whole_only_while_it_holds_only_the_runs_files() {
    let dir = scratch("whole");
    let out = dir.join("run");
    let o = out.to_str().unwrap();
    // What killed runs of processes that no longer exist leave behind: one marked as this
    // tool's staging (removed), one not (kept: nothing shows it is ours).
    let marker = r#"{"tool":"policy-export","version":"0","kind":"train","files":[]}"#;
    let stale = dir.join(".run.4000000000.partial");
    std::fs::create_dir(&stale).unwrap();
    std::fs::write(stale.join(".cartpole-run"), marker).unwrap();
    let unmarked = dir.join(".run.4000000001.partial");
    std::fs::create_dir(&unmarked).unwrap();
    std::fs::write(unmarked.join("summary.json"), b"{}").unwrap();
    let train = |seed: &str| {
        let o = run(&["train", "--episodes", "5", "--seed", seed, "--out", o]);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(out.join("policy.safetensors")).unwrap()
    };
    let first = train("1");
    // A file the user put in the run directory makes it theirs.
    std::fs::write(out.join("cartpole_policy.h"), b"an export of the first run").unwrap();
    refused(
        &["train", "--episodes", "5", "--out", o],
        "holds 1 entry policy-export did not write (\"cartpole_policy.h\")",
    );
    assert_eq!(
        std::fs::read(out.join("policy.safetensors")).unwrap(),
        first
    );
    std::fs::remove_file(out.join("cartpole_policy.h")).unwrap();
    let second = train("2");
    assert_ne!(first, second);
    // The second run replaced the whole directory.
    assert_eq!(
        entries(&out),
        [
            ".cartpole-run",
            "metrics.csv",
            "policy.rs",
            "policy.safetensors",
            "summary.json"
        ]
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["seed"], 2);
    assert_eq!(entries(&dir), [".run.4000000001.partial", "run"]);
    // Another tool's marker, or another kind's, is not this run's.
    std::fs::write(
        out.join(".cartpole-run"),
        marker.replace("train", "reproduce"),
    )
    .unwrap();
    refused(
        &["train", "--episodes", "5", "--out", o],
        "marks an output of \"policy-export\" \"reproduce\", not of policy-export train",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_marker_written_by_hand_has_no_file_it_lists_removed() {
    let dir = scratch("by-hand");
    let out = dir.join("run");
    let o = out.to_str().unwrap();
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("thesis.tex"), b"years of work").unwrap();
    // An earlier version's list of names, then a list with a size and a digest made up.
    let names = r#"{"tool":"policy-export","version":"0","kind":"train","files":["thesis.tex"]}"#;
    let made_up = r#"{"tool":"policy-export","version":"0","kind":"train","entries":[
        {"path":"thesis.tex","bytes":13,"fnv1a64":"0123456789abcdef"}]}"#;
    for (marker, want) in [
        (names, "lists files without their sizes and digests"),
        (
            made_up,
            "1 file no longer as policy-export wrote (its .cartpole-run lists",
        ),
    ] {
        std::fs::write(out.join(".cartpole-run"), marker).unwrap();
        refused(&["train", "--episodes", "5", "--out", o], want);
        assert_eq!(
            std::fs::read(out.join("thesis.tex")).unwrap(),
            b"years of work"
        );
    }
    // The same directory as a killed commit would have left it aside: the next run keeps
    // what the marker does not prove the run's.
    let aside = dir.join(".run.4000000000.old");
    std::fs::rename(&out, &aside).unwrap();
    let o = run(&["train", "--episodes", "5", "--out", o]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(aside.join("thesis.tex")).unwrap(),
        b"years of work"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_run_that_diverges_on_its_last_update_writes_nothing() {
    let dir = scratch("diverge");
    let out = dir.join("d");
    let o = run(&[
        "train",
        "--episodes",
        "1",
        "--max-steps",
        "1",
        "--batch-size",
        "1",
        "--learning-starts",
        "1",
        "--lr",
        "1e38",
        "--grad-clip",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("weights are unusable"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn endless_or_huge_inputs_are_refused_without_reading_them() {
    let dir = scratch("inputs");
    let fifo = dir.join("fifo");
    mkfifo(&fifo);
    let out = dir.join("p.rs");
    let o = out.to_str().unwrap();
    refused(
        &["export", "/dev/zero", "--out", o],
        "expected a regular file, found a device",
    );
    refused(
        &["export", fifo.to_str().unwrap(), "--out", o],
        "found a FIFO",
    );
    refused(&["train", "--config", "/dev/zero"], "found a device");
    refused(
        &["train", "--config", fifo.to_str().unwrap()],
        "found a FIFO",
    );
    let big = dir.join("big.toml");
    std::fs::write(&big, format!("gamma = [{}]\n", "1, ".repeat(1_000_000))).unwrap();
    refused(
        &["train", "--config", big.to_str().unwrap()],
        "expected at most 131072 bytes",
    );
    // A header that declares far more than any checkpoint needs.
    let header = dir.join("header.safetensors");
    let mut bytes = (2u64 << 30).to_le_bytes().to_vec();
    bytes.extend_from_slice(b"{}");
    std::fs::write(&header, bytes).unwrap();
    refused(
        &["export", header.to_str().unwrap(), "--out", o],
        "expected at most 1048576",
    );
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The command-line parser's own refusals (a value a flag's parser refuses, a value not among
/// a flag's choices, an unknown flag or subcommand) show the user's text escaped: clap quoted
/// it raw, so a line break in it printed a forged error line of its own.
#[test]
fn the_parser_s_refusals_show_the_text_they_quote_escaped() {
    let exe = std::path::Path::new(env!("CARGO_BIN_EXE_policy-export"));
    let unknown = format!("--se{FORGED}");
    let command = format!("tra{FORGED}");
    let cases: [(&[&str], &str); 5] = [
        (&["train", "--seeds", FORGED], "--seeds"),
        (&["train", "--threads", FORGED], "--threads"),
        (&["export", "--format", FORGED], "--format"),
        (&["train", &unknown], "--se"),
        (&[&command], "tra"),
    ];
    for (args, flag) in cases {
        refused_escaped(exe, args, flag);
    }
}
