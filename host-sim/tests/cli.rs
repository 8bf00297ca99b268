//! `host-sim eval --policy` with checkpoints as PyTorch users save them (the fixtures of the
//! `weights` crate, written by real PyTorch and Stable-Baselines3 code).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

// The shared harness: its runner of refusals and its FIFOs.
#[allow(dead_code)]
#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

use hostile::{FORGED, mkfifo, refused_escaped};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../weights/tests/fixtures")
        .join(name)
}

fn eval(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args([
            "eval",
            "--scenario",
            "nominal",
            "--episodes",
            "20",
            "--controller",
            "policy",
        ])
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn eval_runs_pytorch_checkpoints_and_names_the_networks_of_an_ambiguous_one() {
    let cleanrl = fixture("cleanrl.safetensors");
    let o = eval(&["--json", "--policy", cleanrl.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["rows"][0]["episodes"], 20);

    let sb3 = fixture("sb3_policy.safetensors");
    let o = eval(&["--policy", sb3.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("under the prefixes q_net.q_net., q_net_target.q_net."),
        "{err}"
    );
    assert!(o.stdout.is_empty());

    let o = eval(&[
        "--policy",
        sb3.to_str().unwrap(),
        "--prefix",
        "q_net_target.q_net.",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let o = eval(&[
        "--policy",
        fixture("cleanrl_default.safetensors").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("hidden widths 120 and 84 differ"));
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap()
}

/// Exit 2, within the refusals' processor time, with `want` in a short message and nothing
/// on stdout.
fn refused(args: &[&str], want: &str) {
    let ran = hostile::run_counted(Command::new(env!("CARGO_BIN_EXE_host-sim")).args(args));
    let seen = format!(
        "{args:?}: exit {:?} after {:?} of processor time, {} bytes on stdout: {}",
        ran.code,
        ran.cpu,
        ran.stdout.len(),
        ran.stderr
    );
    assert_eq!(ran.code, Some(2), "{seen}");
    assert!(
        ran.stderr.contains(want) && ran.stderr.len() < 1_000,
        "{seen}"
    );
    assert!(ran.stdout.is_empty() && ran.late().is_none(), "{seen}");
}

#[test]
fn hostile_counts_scenarios_and_inputs_are_refused_up_front() {
    let max = "18446744073709551615";
    let noise = "noise+".repeat(10_000);
    let cases: [(&[&str], &str); 8] = [
        (
            &["eval", "--episodes", max],
            "--episodes must be in [1, 10000000]",
        ),
        (
            &["eval", "--horizon", "4294967295"],
            "--horizon must be in [1, 1000000]",
        ),
        (
            &["render", "--horizon", "4294967295"],
            "--horizon must be in [1, 100000]",
        ),
        (
            &["render", "--horizon", "100000", "--stride", "9"],
            "at most 10000 frames of the animation, got 11112 (100000 / 9)",
        ),
        // Each factor is finite; their product would not be, and 1e300 is refused on its own.
        (
            &["eval", "--scenario", "length=1e300+length=1e300"],
            "length factor must be zero or a normal number in [0.001, 1000], found \"1e300\"",
        ),
        (
            &["eval", "--scenario", "length=999+length=999"],
            "length comes to 9.98",
        ),
        (
            &["eval", "--scenario", &noise],
            "expected at most 1000 bytes",
        ),
        (
            &["eval", "--policy", "/dev/zero"],
            "expected a regular file, found a device",
        ),
    ];
    for (args, want) in cases {
        refused(args, want);
    }
    let dir = std::env::temp_dir().join(format!("hs-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    fifos_and_bad_states_are_refused(&dir);
    render_writes_only_into_a_directory_of_its_own(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A negative number given to a flag is its value, judged by the flag (clap took it for a
/// flag: "unexpected argument '-1' found", naming neither the flag nor what it takes); an
/// empty item of a list is named as found (clap said "none was supplied").
#[test]
fn a_negative_number_or_an_empty_item_is_refused_by_its_flag() {
    let cases: [(&[&str], &str); 9] = [
        (
            &["eval", "--seed", "-1"],
            "invalid value '-1' for '--seed <SEED>': expected a whole number of 0 or more, \
             found a negative one",
        ),
        (
            &["soak", "--hours", "-1"],
            "--hours must be a normal number of simulated hours in (0, 240], found -1.0",
        ),
        (
            &["startup", "--cart-start", "-0.1"],
            "--cart-start must be metres in [0, 10], zero or normal, found -0.1",
        ),
        (
            &["startup", "--knock", "-5@1"],
            "--knock expects NEWTONS@SECONDS, newtons in (0, 1000]",
        ),
        (
            &["eval", "--horizon", "-1"],
            "for '--horizon <HORIZON>': -1 is not in 0..=4294967295",
        ),
        (
            &["eval", "--controller", "lqr,"],
            "'--controller <CONTROLLER>' takes a list separated by ',', and found an empty item \
             in \"lqr,\"",
        ),
        // A value that is no number is still a flag: a missing value is named as before.
        (
            &["eval", "--seed", "--json"],
            "a value is required for '--seed <SEED>' but none was supplied",
        ),
        // Any spelling a float takes, which clap took for short flags ('-1', '-.').
        (
            &["startup", "--cart-start", "-1e-5"],
            "--cart-start must be metres in [0, 10], zero or normal, found -1e-5",
        ),
        (
            &["soak", "--hours", "-.5"],
            "--hours must be a normal number of simulated hours in (0, 240], found -0.5",
        ),
    ];
    for (args, want) in cases {
        refused(args, want);
    }
}

/// A FIFO as a policy or a trajectory, and a trajectory with a bad hexadecimal state (named
/// by its file and line).
fn fifos_and_bad_states_are_refused(dir: &Path) {
    let fifo = dir.join("fifo");
    mkfifo(&fifo);
    let fifo = fifo.to_str().unwrap();
    refused(&["eval", "--policy", fifo], "found a FIFO");
    refused(&["replay", fifo], "found a FIFO");
    let good = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/gym_traj_public.jsonl"
    ))
    .unwrap();
    let mut lines: Vec<String> = good.lines().take(3).map(String::from).collect();
    lines[2] = lines[2].replacen("0x1.", "0xZ.", 1);
    let bad = dir.join("bad.jsonl");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    refused(&["replay", bad.to_str().unwrap()], "bad.jsonl:3: ");
    refused(&["replay", bad.to_str().unwrap()], "0xZ.");
}

/// render's outputs: never onto a file that is not a directory, never over a FIFO; where all
/// is well, a real GIF and PNG, and nothing else, land in the directory.
fn render_writes_only_into_a_directory_of_its_own(dir: &Path) {
    let file = dir.join("notes.txt");
    std::fs::write(&file, b"mine").unwrap();
    refused(
        &["render", "--out", file.to_str().unwrap()],
        "expected a directory (or a new path)",
    );
    let pics = dir.join("pics");
    std::fs::create_dir(&pics).unwrap();
    mkfifo(&pics.join("episode.gif"));
    refused(&["render", "--out", pics.to_str().unwrap()], "found a FIFO");
    assert_eq!(std::fs::read(&file).unwrap(), b"mine");
    let fine = dir.join("fine");
    let o = run(&["render", "--out", fine.to_str().unwrap(), "--horizon", "20"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        std::fs::read(fine.join("episode.gif"))
            .unwrap()
            .starts_with(b"GIF89a")
    );
    assert!(
        std::fs::read(fine.join("episode.png"))
            .unwrap()
            .starts_with(b"\x89PNG")
    );
    assert_eq!(std::fs::read_dir(&fine).unwrap().count(), 2);
}

#[test]
fn the_integer_policy_is_evaluated_and_compared_with_the_float_one() {
    // The shipped policy and the shipped file quantised on the fly: the same integers.
    let shipped = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shipped/policy.safetensors");
    let a = eval(&["--json", "--controller", "policy-int"]);
    let b = eval(&[
        "--json",
        "--controller",
        "policy-int",
        "--policy",
        shipped.to_str().unwrap(),
    ]);
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let (a, b): (serde_json::Value, serde_json::Value) = (
        serde_json::from_slice(&a.stdout).unwrap(),
        serde_json::from_slice(&b.stdout).unwrap(),
    );
    // `eval` above asks for `policy`; `--controller` adds `policy-int`.
    assert_eq!(a["rows"][1]["controller"], "policy-int");
    assert_eq!(a["rows"], b["rows"]);

    let agree = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .arg("agree")
            .args(args)
            .output()
            .unwrap()
    };
    let o = agree(&["--states", "13000", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let states = r["states"].as_u64().unwrap();
    assert_eq!(states, 13_000);
    let binned: u64 = r["by_margin"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["states"].as_u64().unwrap())
        .sum();
    let disagree: u64 = r["by_margin"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["disagree"].as_u64().unwrap())
        .sum();
    assert_eq!(binned, states);
    assert_eq!(disagree, states - r["agree"].as_u64().unwrap());
    // The shipped policy's agreement over a million states is in docs/QUANTISATION.md;
    // this run has far fewer states, so the bound leaves room for sampling.
    assert!(r["agree"].as_u64().unwrap() * 100 > states * 85, "{r}");
    let o = agree(&["--states", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--states must be in [1, 100000000], got 0")
    );
}

#[test]
fn a_path_that_is_not_utf8_is_recorded_in_the_provenance_not_panicked_on() {
    use std::os::unix::ffi::OsStrExt;
    let dir = std::env::temp_dir().join(format!("hs-nonutf8-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let policy = dir.join(std::ffi::OsStr::from_bytes(b"p\xff.safetensors"));
    std::fs::copy(fixture("cleanrl.safetensors"), &policy).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args([
            "eval",
            "--scenario",
            "nominal",
            "--episodes",
            "2",
            "--horizon",
            "20",
        ])
        .args(["--controller", "policy", "--json", "--policy"])
        .arg(&policy)
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json = String::from_utf8(o.stdout).unwrap();
    assert!(json.contains("p\u{fffd}.safetensors"), "{json}");
}

#[test]
fn a_thread_count_from_the_environment_is_checked_and_help_into_a_full_disk_fails() {
    let exe = env!("CARGO_BIN_EXE_host-sim");
    let lqr = [
        "eval",
        "--episodes",
        "2",
        "--horizon",
        "5",
        "--controller",
        "lqr",
    ];
    for (var, threads, code) in [
        ("RAYON_NUM_THREADS", "100000", 2),
        ("RAYON_NUM_THREADS", "x", 2),
        ("RAYON_NUM_THREADS", "+2", 2),
        ("RAYON_RS_NUM_CPUS", "100000", 2),
        ("RAYON_NUM_THREADS", "2", 0),
    ] {
        let o = Command::new(exe)
            .args(lqr)
            .env(var, threads)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{threads}: {err}");
        assert!(
            code == 0 || err.contains(&format!("{var}: expected")),
            "{err}"
        );
    }
    // A long value is cut as every input quoted in a message is, the cut marked.
    let long = "7".repeat(1000);
    let o = Command::new(exe)
        .args(lqr)
        .env("RAYON_NUM_THREADS", &long)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let cut = format!("found {}", weights::quote(&long));
    assert!(cut.ends_with("\"...") && err.contains(&cut), "{err}");
    for args in [&["eval", "--help"][..], &["--version"]] {
        let full = std::fs::File::create("/dev/full").unwrap();
        let o = Command::new(exe).args(args).stdout(full).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("writing standard output"), "{err}");
    }
}

#[test]
fn the_names_of_outputs_and_pil_places_are_printed_escaped() {
    let dir = std::env::temp_dir().join(format!("hs-names-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("r\u{1b}[2J\nerror: fake");
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["render", "--controller", "lqr", "--horizon", "5", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        text.contains("r\\u{1b}[2J\\nerror: fake/episode.gif"),
        "{text}"
    );
    assert!(!text.lines().any(|l| l.starts_with("error")), "{text}");
    let o = eval(&["--pil", "exec:nowhere\u{1b}[31m"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("no program at nowhere\\u{1b}[31m"), "{err}");
}

#[test]
fn min_success_judges_every_row_the_network_drives_and_an_envelope_needs_the_monitor() {
    let exe = env!("CARGO_BIN_EXE_host-sim");
    let run = |args: &[&str]| Command::new(exe).arg("eval").args(args).output().unwrap();
    // Pushes no controller survives: the integer network's rows fail too.
    let o = run(&[
        "--controller",
        "policy-int",
        "--scenario",
        "push=50/5",
        "--episodes",
        "3",
        "--min-success",
        "1",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("policy-int below --min-success on push=50/5"),
        "{err}"
    );
    // With no row of the network's, the gate checked nothing and passed.
    for controllers in ["lqr", "lqr,rule"] {
        let o = run(&[
            "--controller",
            controllers,
            "--scenario",
            "push=3",
            "--episodes",
            "1",
            "--min-success",
            "0.9",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains(&format!(
                "--min-success judges the rows the network drives; expected a controller \
                 among policy, policy-int, policy-refined, policy-int-refined, monitored, \
                 monitored-int, found {}",
                controllers.replace(',', ", ")
            )),
            "{err}"
        );
    }
    let envelope = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/results/envelope.json");
    let o = run(&["--controller", "lqr", "--envelope", envelope]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--envelope is read by --controller monitored"),
        "{err}"
    );
}

/// `agree`, `envelope` and `startup` run no monitored controller: they take no --envelope
/// and offer none in their help (the file was read by nothing, their output as without it).
#[test]
fn an_envelope_where_no_monitored_controller_runs_is_refused() {
    let envelope = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/results/envelope.json");
    for command in ["agree", "envelope", "startup"] {
        refused(
            &[command, "--envelope", envelope],
            "unexpected argument '--envelope' found",
        );
        let help = String::from_utf8(run(&[command, "--help"]).stdout).unwrap();
        assert!(
            help.contains("--policy <") && !help.contains("--envelope <"),
            "{help}"
        );
    }
}

/// The command-line parser's own refusals (a value a flag's parser refuses, a value not among
/// a flag's choices, an unknown flag or subcommand) show the user's text escaped: clap quoted
/// it raw, so a line break in it printed a forged error line of its own.
#[test]
fn the_parser_s_refusals_show_the_text_they_quote_escaped() {
    let exe = Path::new(env!("CARGO_BIN_EXE_host-sim"));
    let unknown = format!("--epi{FORGED}");
    let command = format!("ev{FORGED}");
    let cases: [(&[&str], &str); 5] = [
        (&["eval", "--episodes", FORGED], "--episodes"),
        (&["eval", "--controller", FORGED], "--controller"),
        (&["eval", "--horizon", FORGED], "--horizon"),
        (&["eval", &unknown], "--epi"),
        (&[&command], "ev"),
    ];
    for (args, flag) in cases {
        refused_escaped(exe, args, flag);
    }
}
