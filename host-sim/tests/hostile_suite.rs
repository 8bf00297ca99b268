//! `host-sim` against a table of hostile command lines: every path argument of every
//! subcommand given every kind of bad file, every output every place it must not write, and
//! bad counts and specs; each refused by the rules of `docs/HOSTILE_INPUT.md`, checked by the
//! shared harness. And standard output closed before the first line: no panic, exit 0.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

use hostile::{Bad, Case, Format, Scratch, run_all, uniform_policy, with_stdout_closed};

#[path = "hostile_suite/worlds.rs"]
mod worlds;

#[path = "hostile_suite/work.rs"]
mod work;

#[path = "hostile_suite/outputs.rs"]
mod outputs;

#[path = "hostile_suite/text.rs"]
mod text;
use worlds::{bad_rigs, bad_rows, bad_specs};

fn exe() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_host-sim"))
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

fn os(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    args.iter().map(|a| a.as_ref().to_owned()).collect()
}

fn format(path: &str, cap: u64, malformed: &'static [&'static str]) -> Format {
    Format {
        valid: std::fs::read(repo(path)).unwrap(),
        cap,
        malformed,
        fine: &[],
    }
}

/// Logs of the desk rig's two experiments, as `simulate-logs` writes them.
fn logs(s: &Scratch) -> PathBuf {
    let out = s.join("good.log");
    let o = Command::new(exe())
        .args(os(&[
            &"simulate-logs",
            &"--world",
            &repo("rigs/desk.toml"),
            &"--rig",
            &repo("rigs/desk-measured.toml"),
            &"--out",
            &out,
        ]))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// The command line of a slot, given the bad path.
type Args = Box<dyn Fn(&Path) -> Vec<OsString>>;
type Slot = (&'static str, Format, Args);

/// Where a slot's command line takes the bad path.
const BAD_PATH: &str = "<bad>";

/// The command line `template` with the bad path in its place.
fn with_bad(template: Vec<OsString>) -> Args {
    Box::new(move |b| {
        let at = |a: &OsString| if a == BAD_PATH { b.into() } else { a.clone() };
        template.iter().map(at).collect()
    })
}

/// Every path argument of every subcommand: its file format and its command line.
fn slots(s: &Scratch, log: &Path) -> Vec<Slot> {
    let words = &["expected", "safetensors"];
    let policy = || format("shipped/policy.safetensors", 64 << 20, words);
    let rig = || format("rigs/desk.toml", 64 << 10, &["expected", "missing field"]);
    let envelope = || format("docs/results/envelope.json", 64 << 10, &["expected"]);
    let results = || format("docs/results/eval-int.json", 16 << 20, &["expected"]);
    let int = repo("docs/results/eval-int.json");
    let moved = |old: &dyn AsRef<std::ffi::OsStr>, new: &dyn AsRef<std::ffi::OsStr>| {
        with_bad(os(&[&"results", &"moved", old, new]))
    };
    let words = &["not a trajectory case", "expected", "no cases"];
    let replay = || format("tests/data/gym_traj_public.jsonl", 64 << 20, words);
    let log_format = Format {
        valid: std::fs::read(log).unwrap(),
        cap: 32 << 20,
        malformed: &["expected"],
        fine: &[],
    };
    let (desk, measured) = (repo("rigs/desk.toml"), repo("rigs/desk-measured.toml"));
    let (traj, out, render) = (
        repo("tests/data/gym_traj_public.jsonl"),
        s.join("out.toml"),
        s.join("render"),
    );
    let eval = |flag: &str| {
        // The envelope is read by the monitored controller alone.
        let controller = if flag == "--envelope" {
            "monitored"
        } else {
            "policy"
        };
        let nominal: Vec<OsString> =
            format!("eval --episodes 1 --scenario nominal --controller {controller}")
                .split(' ')
                .map(OsString::from)
                .collect();
        with_bad([nominal, os(&[&flag, &BAD_PATH])].concat())
    };
    let agree = |flag: &str| with_bad(os(&[&"agree", &"--states", &"1", &flag, &BAD_PATH]));
    let draw = |flag: &str| {
        let cmd = os(&[&"render", &"--horizon", &"5", &"--out", &render]);
        with_bad([cmd, os(&[&flag, &BAD_PATH])].concat())
    };
    let identify = |log: &dyn AsRef<std::ffi::OsStr>, rig: &dyn AsRef<std::ffi::OsStr>| {
        with_bad(os(&[&"identify", log, &"--rig", rig, &"--out", &out]))
    };
    let simulate = |world: &dyn AsRef<std::ffi::OsStr>, rig: &dyn AsRef<std::ffi::OsStr>| {
        let (w, r, o) = (&"--world", &"--rig", &"--out");
        with_bad(os(&[&"simulate-logs", w, world, r, rig, o, &out]))
    };
    vec![
        ("eval-policy", policy(), eval("--policy")),
        ("eval-rig", rig(), eval("--rig")),
        ("eval-world", rig(), eval("--world")),
        ("eval-envelope", envelope(), eval("--envelope")),
        ("agree-policy", policy(), agree("--policy")),
        ("agree-rig", rig(), agree("--rig")),
        ("render-policy", policy(), draw("--policy")),
        ("render-rig", rig(), draw("--rig")),
        ("replay", replay(), with_bad(os(&[&"replay", &BAD_PATH]))),
        // The good file first: nothing of it may be printed before the bad one is refused.
        (
            "replay-second",
            replay(),
            with_bad(os(&[&"replay", &traj, &BAD_PATH])),
        ),
        ("identify-log", log_format, identify(&BAD_PATH, &measured)),
        ("identify-rig", rig(), identify(&log, &BAD_PATH)),
        ("simulate-world", rig(), simulate(&BAD_PATH, &measured)),
        ("simulate-rig", rig(), simulate(&desk, &BAD_PATH)),
        ("moved-old", results(), moved(&BAD_PATH, &int)),
        ("moved-new", results(), moved(&int, &BAD_PATH)),
    ]
}

/// Every path argument of every subcommand, given every kind of bad file.
fn bad_inputs(s: &Scratch, log: &Path) -> Vec<Case> {
    let slots = slots(s, log);
    hostile::bad_input_cases(&s.0, slots.iter().map(|(t, f, a)| (*t, f, &**a as _)))
}

/// Every output, given places it must not write.
fn bad_outputs(s: &Scratch, log: &Path) -> Vec<Case> {
    let fifo = s.join("out-fifo");
    hostile::mkfifo(&fifo);
    let (dir, file) = (s.join("out-dir"), s.join("out-file"));
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(&file, b"keep").unwrap();
    let (world, rig) = (repo("rigs/desk.toml"), repo("rigs/desk-measured.toml"));
    let files: [(&str, PathBuf, &[&'static str]); 7] = [
        ("directory", dir.clone(), &["found a directory"]),
        ("device", "/dev/null".into(), &["found a device"]),
        ("fifo", fifo.clone(), &["found a FIFO"]),
        ("under-file", file.join("x"), &["found a regular file"]),
        ("proc", "/proc/cartpole/x".into(), &["refuses"]),
        ("input", rig.clone(), &["would overwrite the input"]),
        ("log", log.to_path_buf(), &["would overwrite the input"]),
    ];
    let mut cases = Vec::new();
    for (label, out, want) in files {
        let identify = os(&[&"identify", &log, &"--rig", &rig, &"--out", &out]);
        cases.push(Case::new(
            format!("identify --out {label}"),
            &identify,
            want,
        ));
        // envelope reads no file at all.
        if !matches!(label, "input" | "log") {
            let envelope = os(&[&"envelope", &"--out", &out]);
            cases.push(Case::new(
                format!("envelope --out {label}"),
                &envelope,
                want,
            ));
        }
        // simulate-logs reads no log.
        if label != "log" {
            let simulate = os(&[
                &"simulate-logs",
                &"--world",
                &world,
                &"--rig",
                &rig,
                &"--out",
                &out,
            ]);
            cases.push(Case::new(
                format!("simulate-logs --out {label}"),
                &simulate,
                want,
            ));
        }
    }
    cases.extend(bad_output_dirs(s, log, &dir, &file, fifo));
    cases
}

/// Every output directory, given places it must not write.
fn bad_output_dirs(s: &Scratch, log: &Path, dir: &Path, file: &Path, fifo: PathBuf) -> Vec<Case> {
    let rig = repo("rigs/desk-measured.toml");
    let mut cases = Vec::new();
    let dirs: [(&str, PathBuf, &[&'static str]); 5] = [
        ("file", file.to_path_buf(), &["found a regular file"]),
        ("device", "/dev/null".into(), &["found a device"]),
        ("fifo", fifo, &["found a FIFO"]),
        ("under-file", file.join("d"), &["found a regular file"]),
        ("proc", "/proc/cartpole/d".into(), &["refuses"]),
    ];
    for (label, out, want) in dirs {
        let render = os(&[&"render", &"--horizon", &"5", &"--out", &out]);
        cases.push(Case::new(format!("render --out {label}"), &render, want));
        let plots = os(&[
            &"identify",
            &log,
            &"--rig",
            &rig,
            &"--out",
            &s.join("id.toml"),
            &"--plots",
            &out,
        ]);
        cases.push(Case::new(format!("identify --plots {label}"), &plots, want));
    }
    cases.extend(outputs::apart(s, log, &rig));
    // A picture's name taken by a directory.
    std::fs::create_dir_all(dir.join("episode.gif")).unwrap();
    let render = os(&[&"render", &"--horizon", &"5", &"--out", &dir]);
    cases.push(Case::new(
        "render over a directory".into(),
        &render,
        &["found a directory"],
    ));
    cases
}

/// Counts and policies no command can take.
fn bad_values(s: &Scratch) -> Vec<Case> {
    let mut cases = Vec::new();
    let huge = s.join("huge.safetensors");
    uniform_policy(&huge, 1e30, "");
    for cmd in [
        &["eval", "--episodes", "1"][..],
        &["agree", "--states", "1"],
        &["render", "--horizon", "5"],
    ] {
        let mut args: Vec<OsString> = cmd.iter().map(OsString::from).collect();
        args.extend(os(&[&"--policy", &huge]));
        cases.push(Case::new(
            format!("{cmd:?} infinite outputs"),
            &args,
            &["expected finite Q-values"],
        ));
    }
    let numbers = [
        "-1",
        "abc",
        "",
        "1e999",
        "NaN",
        "99999999999999999999999",
        "0",
    ];
    let flags: [(&str, &[&str]); 11] = [
        ("--episodes", &["eval"]),
        ("--horizon", &["eval"]),
        ("--episodes", &["envelope"]),
        ("--horizon", &["envelope"]),
        ("--quantile", &["envelope"]),
        ("--margin", &["envelope"]),
        (
            "--min-success",
            &["eval", "--episodes", "1", "--scenario", "nominal"],
        ),
        ("--states", &["agree"]),
        ("--horizon", &["render", "--out", "r"]),
        ("--stride", &["render", "--out", "r"]),
        (
            "--jitter",
            &["simulate-logs", "--world", "w", "--rig", "r", "--out", "o"],
        ),
    ];
    for (flag, cmd) in flags {
        for v in numbers {
            let mut args: Vec<OsString> = cmd.iter().map(OsString::from).collect();
            args.extend([OsString::from(flag), OsString::from(v)]);
            let want = [
                "invalid value",
                "must be",
                "must lie",
                "expected",
                "No such file",
            ];
            cases.push(Case::new(format!("{cmd:?} {flag} {v:?}"), &args, &want));
        }
    }
    cases.extend(outputs::tiny_reals(s));
    cases
}

/// Results files of `tables` that are no files: a FIFO (which blocked) and a link to
/// `/dev/zero` (read until memory ran out).
fn bad_tables(s: &Scratch) -> Vec<Case> {
    let mut cases = Vec::new();
    for (kind, bad) in [("fifo", Bad::Fifo), ("zero", Bad::LinkToDevice)] {
        let root = s.join(&format!("tables-{kind}"));
        std::fs::create_dir_all(root.join("docs/results")).unwrap();
        std::fs::write(root.join("Cargo.toml"), b"").unwrap();
        let marker = "<!-- results: docs/results/r.json success=policy -->\n<!-- /results -->\n";
        std::fs::write(root.join("docs/A.md"), marker).unwrap();
        let format = Format {
            valid: Vec::new(),
            cap: 0,
            malformed: &[],
            fine: &[],
        };
        let made = bad.make(&root.join("docs/results"), "r", &format);
        std::fs::rename(made, root.join("docs/results/r.json")).unwrap();
        for check in [&["--check"][..], &[]] {
            let mut args = os(&[&"tables", &"--root", &root]);
            args.extend(check.iter().map(OsString::from));
            cases.push(Case::new(
                format!("tables {kind} {check:?}"),
                &args,
                &bad.expect(&format),
            ));
        }
    }
    // A results file whose page is the list of pages: refused after the drawing, exit 1.
    let root = s.join("tables-readme");
    std::fs::create_dir_all(root.join("docs/results")).unwrap();
    std::fs::write(root.join("Cargo.toml"), b"").unwrap();
    std::fs::copy(
        repo("docs/results/eval-shipped.json"),
        root.join("docs/results/README.json"),
    )
    .unwrap();
    for check in [&["--check"][..], &[]] {
        let mut args = os(&[&"tables", &"--root", &root]);
        args.extend(check.iter().map(OsString::from));
        cases.push(Case::new(
            format!("tables README.json {check:?}"),
            &args,
            &["the page of docs/results/README.json"],
        ));
    }
    cases
}

/// A trajectory whose decimal states contradict its exact ones: replay read the hex strings
/// and ignored the decimals, whatever they held.
fn bad_replays(s: &Scratch) -> Vec<Case> {
    let text = std::fs::read_to_string(repo("tests/data/gym_traj_public.jsonl")).unwrap();
    let mut case: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    case["states"][3] = serde_json::json!([0.0, 0.0, 0.0, 0.0]);
    let file = s.join("contradicts.jsonl");
    std::fs::write(&file, format!("\n{case}\n")).unwrap();
    vec![Case::new(
        "replay states against states_hex".into(),
        &os(&[&"replay", &file]),
        &[":2: states row 3 is [0.0, 0.0, 0.0, 0.0] but states_hex row 3 is ["],
    )]
}

#[test]
fn every_hostile_command_line_is_refused_by_the_rules() {
    let s = Scratch::new("hs-suite");
    let log = logs(&s);
    let mut cases = bad_inputs(&s, &log);
    cases.extend(bad_outputs(&s, &log));
    cases.extend(bad_values(&s));
    cases.extend(bad_specs());
    cases.extend(bad_tables(&s));
    cases.extend(bad_rigs(&s));
    cases.extend(bad_rows());
    cases.extend(bad_replays(&s));
    cases.extend(text::bad_text(&s));
    let n = run_all(&exe(), &s.0, &cases);
    assert!(n >= 200, "{n} cases");
}

#[test]
fn a_closed_standard_output_ends_the_command_quietly() {
    let s = Scratch::new("hs-pipe");
    let traj = repo("tests/data/gym_traj_public.jsonl");
    let commands: [Vec<OsString>; 4] = [
        os(&[
            &"eval",
            &"--episodes",
            &"3",
            &"--scenario",
            &"nominal",
            &"--json",
        ]),
        os(&[&"eval", &"--episodes", &"3", &"--scenario", &"nominal"]),
        os(&[&"replay", &traj]),
        os(&[&"parts"]),
    ];
    for args in commands {
        let (code, err) = with_stdout_closed(&exe(), &args, &s.0);
        assert_eq!(code, Some(0), "{args:?}: {err}");
        assert!(
            !err.contains("panicked") && !err.contains("Broken pipe"),
            "{args:?}: {err}"
        );
    }
    // Written work is finished all the same.
    let out = s.join("pics");
    let (code, err) = with_stdout_closed(
        &exe(),
        &os(&[&"render", &"--horizon", &"5", &"--out", &out]),
        &s.0,
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(out.join("episode.gif").is_file() && out.join("episode.png").is_file());
    // A full disk is not a reader that left: exit 1, said.
    let full = Command::new(exe())
        .args(["parts"])
        .stdout(std::fs::File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    assert_eq!(full.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&full.stderr).contains("writing standard output"));
}
