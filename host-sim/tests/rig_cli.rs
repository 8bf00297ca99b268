//! `--rig` at the simulator's doors: a rig file no machine has is refused by `eval`, `render`
//! and `agree` with exit status 2 and a message naming the field, before anything is written
//! or printed; and a policy run on another rig than the one it records is warned about, while
//! its own rig is not.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use shipped::policy::POLICY;
use weights::Weights;
use weights::checkpoint::to_safetensors;

#[path = "../../tests/support/spoilt_rigs.rs"]
mod spoilt;
use spoilt::bad_rigs;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hs-rig-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn eval_render_and_agree_refuse_a_rig_no_machine_has_naming_the_field() {
    let dir = scratch("bad");
    let pics = dir.join("pics");
    let out = pics.to_str().unwrap();
    for (rig, field) in bad_rigs(&dir) {
        let rig = rig.to_str().unwrap();
        let cases: [&[&str]; 4] = [
            &["eval", "--episodes", "2", "--horizon", "10", "--rig", rig],
            &[
                "eval",
                "--controller",
                "lqr",
                "--episodes",
                "2",
                "--rig",
                rig,
            ],
            &["render", "--horizon", "5", "--rig", rig, "--out", out],
            &["agree", "--states", "10", "--rig", rig],
        ];
        for args in cases {
            let o = run(args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
            assert!(err.contains(field) && err.len() < 1_000, "{args:?}: {err}");
            assert!(o.stdout.is_empty(), "{args:?} printed on stdout");
            assert!(!pics.exists(), "{args:?} wrote {out}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A run directory whose policy file records `rig_toml` as the rig it was trained for.
fn run_dir(dir: &Path, rig_toml: &str) -> PathBuf {
    let run = dir.join("run");
    std::fs::create_dir_all(&run).unwrap();
    let meta = BTreeMap::from([(
        twin::rigfile::METADATA_KEY.to_string(),
        rig_toml.to_string(),
    )]);
    let bytes = to_safetensors(
        &Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap(),
        &meta,
    )
    .unwrap();
    std::fs::write(run.join("policy.safetensors"), bytes).unwrap();
    run
}

/// `eval` of two nominal episodes of 20 periods, with `extra` after.
fn short_eval<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let head = [
        "eval",
        "--scenario",
        "nominal",
        "--episodes",
        "2",
        "--horizon",
        "20",
    ];
    [&head[..], extra].concat()
}

#[test]
fn eval_warns_when_rig_is_not_the_rig_the_policy_records_and_only_then() {
    let dir = scratch("warn");
    let desk = repo().join("rigs/desk.toml");
    let policy = run_dir(&dir, &std::fs::read_to_string(&desk).unwrap());
    let eval = |rig: Option<&Path>| {
        let mut args = short_eval(&["--policy", policy.to_str().unwrap()]);
        args.extend(["--controller", "policy"]);
        if let Some(rig) = rig {
            args.extend(["--rig", rig.to_str().unwrap()]);
        }
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{args:?}: {err}");
        assert!(!o.stdout.is_empty(), "{args:?}: no table");
        err
    };
    let other = eval(Some(&repo().join("rigs/gymnasium.toml")));
    assert!(
        other.contains("warning: the policy was trained for another rig than --rig gives"),
        "{other}"
    );
    for rig in [Some(desk.as_path()), None] {
        let err = eval(rig);
        assert!(!err.contains("warning"), "--rig {rig:?}: {err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_world_of_another_period_than_its_board_is_refused_naming_both() {
    let desk = repo().join("rigs/desk.toml");
    let fast = repo().join("rigs/desk-100hz-identified.toml");
    let (desk, fast) = (desk.to_str().unwrap(), fast.to_str().unwrap());
    let fast_world = repo().join("rigs/desk-100hz.toml");
    let slow_board = "its world's, 0.02 s; found 0.01 s";
    let eval_fast: &[&str] = &[
        "eval",
        "--controller",
        "lqr",
        "--episodes",
        "1",
        "--rig",
        fast,
    ];
    let startup_fast: &[&str] = &["startup", "--episodes", "1", "--rig", fast];
    let cases = [
        (
            [eval_fast, &["--world", desk]].concat(),
            "--rig",
            slow_board,
        ),
        (
            [startup_fast, &["--world", desk]].concat(),
            "--rig",
            slow_board,
        ),
        // Without --rig and --policy, the board is Gymnasium's machine, at 50 Hz.
        (
            vec![
                "eval",
                "--episodes",
                "1",
                "--world",
                fast_world.to_str().unwrap(),
            ],
            "Gymnasium's machine",
            "its world's, 0.01 s; found 0.02 s",
        ),
    ];
    for (args, board, periods) in cases {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        let named = err.contains("--world") && err.contains(board);
        assert!(named && err.contains(periods), "{args:?}: {err}");
        assert!(o.stdout.is_empty(), "{args:?} printed on stdout");
    }
}

/// A spec is judged on the machine its episodes run on, which a policy's recorded rig
/// gives: `delay=1` is the desk's own dead time, and a short pole with the most pivot
/// friction integrates in the desk's Runge-Kutta steps where Gymnasium's Euler step of a
/// period does not.
#[test]
fn eval_and_render_judge_a_spec_on_the_rig_the_policy_records() {
    let dir = scratch("judged");
    let desk = repo().join("rigs/desk.toml");
    let gym = repo().join("rigs/gymnasium.toml");
    let policy = run_dir(&dir, &std::fs::read_to_string(&desk).unwrap());
    let pics = dir.join("pics");
    let (policy, gym, out) = (
        policy.to_str().unwrap(),
        gym.to_str().unwrap(),
        pics.to_str().unwrap(),
    );
    let short = "length=0.15+friction=0/0.1";
    let head = [
        "eval",
        "--controller",
        "lqr",
        "--episodes",
        "2",
        "--horizon",
        "20",
    ];
    let eval = |spec: &'static str| [&head[..], &["--policy", policy, "--scenario", spec]].concat();
    let refusals = [
        (
            eval("delay=1"),
            "scenario \"delay=1\": delay changes nothing on this machine, whose own dead time \
             is 1 period",
        ),
        // --rig gives the machine, and no row runs the policy: it would change nothing.
        (
            [&head[..], &["--rig", gym, "--scenario", short]].concat(),
            "the pivot's friction damps a velocity",
        ),
    ];
    for (args, want) in refusals {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want) && o.stdout.is_empty(), "{args:?}: {err}");
    }
    let render = ["render", "--controller", "lqr", "--horizon", "5"];
    let render = [
        &render[..],
        &["--policy", policy, "--scenario", short, "--out", out],
    ]
    .concat();
    for args in [eval(short), eval("delay=2"), render] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{args:?}: {err}");
        assert!(!o.stdout.is_empty(), "{args:?}: nothing printed");
    }
    assert!(pics.join("episode.png").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The desk rig with `from` replaced by `to`, written to `dir` as `name`.
fn desk_with(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let desk = std::fs::read_to_string(repo().join("rigs/desk.toml")).unwrap();
    assert!(desk.contains(from), "{from}");
    let path = dir.join(name);
    std::fs::write(&path, desk.replacen(from, to, 1)).unwrap();
    path
}

/// `args`, refused with exit status 2 and a message holding `want`, before any output.
fn refused(args: &[&str], want: &str) {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(want), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?} printed on stdout");
}

/// A `--world` whose episodes run as on the board's own machine changes nothing: judged on
/// the machines built, so a copy of the board's rig, or one that differs only where the board
/// models its own (the end-stop margin), is refused; a world of other physics is taken.
#[test]
fn a_world_that_builds_the_boards_own_is_refused() {
    let dir = scratch("own-world");
    let copy = desk_with(&dir, "copy.toml", "", "");
    let margin = desk_with(&dir, "margin.toml", "margin_m = 0.05", "margin_m = 0.08");
    let heavier = desk_with(
        &dir,
        "heavier.toml",
        "pole_mass_kg = 0.08",
        "pole_mass_kg = 0.09",
    );
    let (desk, gym) = (
        repo().join("rigs/desk.toml"),
        repo().join("rigs/gymnasium.toml"),
    );
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let (desk, gym) = (path(&desk), path(&gym));
    let eval = [
        "eval",
        "--controller",
        "lqr",
        "--episodes",
        "1",
        "--horizon",
        "5",
    ];
    let own = "expected another machine than the board's, or --world left out; found the \
               same physics, encoders, dead time and integration";
    for world in [path(&copy), path(&margin)] {
        let on_desk = [&eval[..], &["--rig", &desk, "--world", &world]].concat();
        refused(&on_desk, &format!("and --rig {desk}: {own}"));
        let startup = [
            "startup",
            "--episodes",
            "1",
            "--rig",
            &desk,
            "--world",
            &world,
        ];
        refused(&startup, own);
    }
    refused(
        &[&eval[..], &["--world", &gym]].concat(),
        &format!("--world {gym} and Gymnasium's machine: {own}"),
    );
    for args in [
        [&eval[..], &["--rig", &desk, "--world", &path(&heavier)]].concat(),
        [&eval[..], &["--rig", &gym, "--world", &desk]].concat(),
        [&eval[..], &["--world", &desk]].concat(),
    ] {
        let o = run(&args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--policy` and `--levels` where no row runs the network or rounds to its levels change
/// nothing, as `--envelope` without a monitored row: the file is read for the rig it
/// records alone, which --rig replaces, or which a file that records none does not give.
#[test]
fn a_policy_that_no_row_reads_is_refused() {
    let dir = scratch("unread");
    let desk = repo().join("rigs/desk.toml");
    let on_desk = run_dir(&dir, &std::fs::read_to_string(&desk).unwrap());
    let bare = dir.join("bare.safetensors");
    let weights = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    std::fs::write(&bare, to_safetensors(&weights, &BTreeMap::new()).unwrap()).unwrap();
    let (desk, on_desk, bare) = (
        desk.to_str().unwrap(),
        on_desk.to_str().unwrap(),
        bare.to_str().unwrap(),
    );
    let read_by = "is read by the controllers that run its network or round to its \
                   levels (policy, policy-int, policy-refined, policy-int-refined, monitored, \
                   monitored-int, lqr-levels, lqr-levels-predict) alone";
    refused(
        &short_eval(&["--policy", bare, "--controller", "lqr,rule"]),
        &format!(
            "--policy {bare} {read_by}, and for the rig it records, which is Gymnasium's \
             machine (or none), the machine without it; expected one of them, or --policy left \
             out, found lqr, rule"
        ),
    );
    refused(
        &short_eval(&["--policy", on_desk, "--rig", desk, "--controller", "lqr"]),
        &format!("found lqr and --rig {desk}"),
    );
    refused(
        &short_eval(&["--policy", on_desk, "--levels=-1,1", "--controller", "lqr"]),
        &format!("--levels {read_by}; expected one of them, found lqr"),
    );
    let render = [
        "render",
        "--horizon",
        "5",
        "--controller",
        "lqr",
        "--policy",
        bare,
    ];
    let out = dir.join("pics");
    refused(
        &[&render[..], &["--out", out.to_str().unwrap()]].concat(),
        read_by,
    );
    assert!(!out.exists());
    // The rig it records is the machine, as --rig would give it; a row of the network reads it.
    let json = |args: &[&str]| -> serde_json::Value {
        let o = run(&[args, &["--json"]].concat());
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let by_policy = json(&short_eval(&["--policy", on_desk, "--controller", "lqr"]));
    let by_rig = json(&short_eval(&["--rig", desk, "--controller", "lqr"]));
    assert_eq!(by_policy["rows"], by_rig["rows"]);
    json(&short_eval(&["--policy", bare, "--controller", "policy"]));
    std::fs::remove_dir_all(&dir).unwrap();
}
