//! The command line as a user meets it: bad input is refused up front with exit status 2
//! and a message naming the problem; a run directory exports to Rust and C bit for bit.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_policy-export"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pe-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `o` is a refusal of bad input: exit status 2, and a message that says `needle`.
#[track_caller]
fn assert_refused(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(
        o.status.code(),
        Some(2),
        "expected a refusal saying {needle:?}: {e}"
    );
    assert!(e.contains(needle), "expected {needle:?} in: {e}");
}

#[test]
fn invalid_hyperparameters_exit_2_before_any_work() {
    let dir = scratch("bad");
    let cases: &[(&[&str], &str)] = &[
        (&["--lr", "0"], "lr must be > 0"),
        (&["--lr", "-0.1"], "lr must be > 0"),
        (
            &["--batch-size", "4096"],
            "batch_size (4096) must not exceed buffer_size (2000)",
        ),
        (&["--width", "0"], "width must be one of"),
        (&["--gamma", "1.01"], "gamma must be in [0, 1]"),
        (
            &["--episodes", "0"],
            "episodes must be in [1, 1000000], got 0",
        ),
    ];
    for (args, want) in cases {
        let out_dir = dir.join("run");
        let o = exe()
            .arg("train")
            .args(*args)
            .arg("--out")
            .arg(&out_dir)
            .output()
            .unwrap();
        assert_refused(&o, want);
        assert!(
            !out_dir.exists(),
            "{args:?} must fail before writing anything"
        );
    }
    let toml = dir.join("typo.toml");
    std::fs::write(&toml, "gamma = 0.99\nlearning_rate = 0.001\n").unwrap();
    let o = exe()
        .args(["train", "--config"])
        .arg(&toml)
        .output()
        .unwrap();
    assert_refused(&o, "unknown key \"learning_rate\"");
    // A value of the file's, judged with the flags: said once, "invalid configuration".
    std::fs::write(&toml, "gamma = 1.5\n").unwrap();
    let o = exe()
        .args(["train", "--config"])
        .arg(&toml)
        .output()
        .unwrap();
    let want = format!(
        "error: invalid configuration: --config {} with the flags: gamma must be",
        toml.display()
    );
    assert!(stderr(&o).starts_with(&want), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches("invalid configuration").count(), 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_fast_preset_keeps_its_budget_and_reports_both_returns() {
    let dir = scratch("fast");
    let run = dir.join("run");
    let o = exe()
        .args([
            "train",
            "--preset",
            "fast",
            "--max-env-steps",
            "3000",
            "--out",
        ])
        .arg(&run)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("no gradient step"), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["config"]["reward"], "morvan");
    assert_eq!(s["config"]["max_env_steps"], 3000);
    // No snapshot balances within 3,000 steps, so the budget ends the run.
    let steps = s["env_steps"].as_u64().unwrap();
    assert_eq!(steps, 3000);
    let evals = s["periodic_evals"].as_array().unwrap();
    assert_eq!(
        s["selection_episodes"].as_u64().unwrap(),
        100 * evals.len() as u64
    );
    let taken = s["policy_episode"].as_u64().unwrap();
    assert!(evals.iter().any(|e| e["episode"] == taken));
    let csv = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    let at = |episode: u64| -> u64 {
        let row = csv.lines().nth(episode as usize).unwrap();
        row.split(',').nth(8).unwrap().parse().unwrap()
    };
    assert_eq!(s["policy_env_steps"].as_u64().unwrap(), at(taken));
    // The task's return counts steps; Morvan's reward is at most 0.7 a step, so the
    // learning return is smaller.
    let (ret, learning) = (
        s["final_mean100"].as_f64().unwrap(),
        s["final_learning_mean100"].as_f64().unwrap(),
    );
    assert!(learning < 0.7 * ret + 1e-9, "{learning} vs {ret}");
    let last = csv.lines().last().unwrap();
    assert_eq!(
        last.split(',').nth(8).unwrap().parse::<u64>().unwrap(),
        steps
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A run too short to reach `learning_starts` trains nothing, and says so.
#[test]
fn a_run_that_took_no_gradient_step_says_its_policy_is_untrained() {
    let dir = scratch("untrained");
    let run = dir.join("run");
    let o = exe()
        .args(["train", "--episodes", "2", "--max-steps", "5", "--out"])
        .arg(&run)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["grad_steps"], 0);
    assert!(
        stderr(&o).contains(&format!(
            "warning: seed 0: the run took no gradient step in its {} env steps \
             (learning_starts 32",
            s["env_steps"]
        )),
        "{}",
        stderr(&o)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_run_directory_exports_to_rust_and_c_bit_for_bit() {
    let dir = scratch("run");
    let run = dir.join("run");
    let o = exe()
        .args(["train", "--episodes", "20", "--seed", "2", "--out"])
        .arg(&run)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    for f in [
        "metrics.csv",
        "summary.json",
        "policy.safetensors",
        "policy.rs",
    ] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    let csv = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    assert!(csv.starts_with(
        "episode,return,learning_return,length,epsilon,mean_loss,mean_max_q,mean_discounted_return,env_steps,wall_s\n"
    ));
    assert_eq!(csv.lines().count(), 21);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("summary.json")).unwrap()).unwrap();
    for key in [
        "solved_episode_195",
        "solved_episode_475",
        "final_mean100",
        "best_mean100",
    ] {
        assert!(summary.get(key).is_some(), "summary lacks {key}");
    }
    assert_eq!(summary["config"]["gamma"], 0.98);
    assert_eq!(summary["seed"], 2);
    assert_eq!(summary["parameters"], 4610);

    // Exporting the run directory reproduces the run's own policy.rs exactly.
    let rs = dir.join("exported.rs");
    let o = export(&[run.to_str().unwrap(), "--out", rs.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&rs).unwrap(),
        std::fs::read(run.join("policy.rs")).unwrap()
    );

    let h = dir.join("policy.h");
    let st = run.join("policy.safetensors");
    let o = exe()
        .arg("export")
        .arg(&st)
        .args(["--format", "c", "--name", "balance", "--out"])
        .arg(&h)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let header = std::fs::read_to_string(&h).unwrap();
    assert!(
        header.contains("static const struct cartpole_mlp64 balance = {")
            && header.contains(
                "source: policy.safetensors (layers \"fc1\", \"fc2\", \"fc3\" under no prefix"
            ),
        "{header}"
    );
    // The rig the run recorded (Gymnasium's, as trained here) goes beside the weights.
    assert!(
        header.contains("static const struct cartpole_rig balance_rig = {")
            && header.contains("    2.4, /* x_threshold */\n")
            && header.contains("cartpole_controller_init_mlp64(&ctl, &balance, &balance_rig)"),
        "{header}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Another policy copied over a run's: the run's summary, seed and figures describe the
/// policy the run wrote, which its marker's digest tells from this one.
#[test]
fn a_policy_copied_over_a_runs_is_not_exported_as_the_runs() {
    let dir = scratch("copied");
    let (run, rs) = (dir.join("run"), dir.join("exported.rs"));
    let o = exe()
        .args(["train", "--episodes", "3", "--out"])
        .arg(&run)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::copy(
        fixture("cleanrl.safetensors"),
        run.join("policy.safetensors"),
    )
    .unwrap();
    let o = export(&[run.to_str().unwrap(), "--out", rs.to_str().unwrap()]);
    assert_refused(&o, "policy.safetensors: expected the file its run wrote");
    assert!(!rs.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../weights/tests/fixtures")
        .join(name)
}

fn export(args: &[&str]) -> Output {
    exe().arg("export").args(args).output().unwrap()
}

#[test]
fn pytorch_checkpoints_export_and_ambiguous_ones_list_their_networks() {
    let dir = scratch("torch");
    let out = dir.join("p.rs");
    let o = export(&[
        fixture("cleanrl.safetensors").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.contains("pub static POLICY: ::firmware::network::Mlp<16, 2>"),
        "{text}"
    );
    assert!(
        text.contains("layers \"0\", \"2\", \"4\" under prefix \"network.\""),
        "{text}"
    );

    let sb3 = fixture("sb3_policy.safetensors");
    let o = export(&[sb3.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_refused(&o, "under the prefixes q_net.q_net., q_net_target.q_net.");
    let o = export(&[
        sb3.to_str().unwrap(),
        "--prefix",
        "q_net.q_net.",
        "--name",
        "SB3_ONLINE",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("pub static SB3_ONLINE:") && text.contains("6 other tensors ignored"));

    let o = export(&[
        fixture("cleanrl_default.safetensors").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_refused(&o, "hidden widths 120 and 84 differ");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_names_and_outputs_exit_2_and_touch_nothing() {
    let dir = scratch("outs");
    let input = dir.join("w.safetensors");
    std::fs::copy(fixture("sequential.safetensors"), &input).unwrap();
    let before = std::fs::read(&input).unwrap();
    let inp = input.to_str().unwrap();
    let out = dir.join("p.rs");
    for (args, want) in [
        (vec![inp, "--out", inp], "would overwrite the input"),
        (vec![inp, "--out", "/dev/null"], "found a device"),
        (
            vec![inp, "--out", dir.to_str().unwrap()],
            "found a directory",
        ),
        (
            vec![inp, "--name", "lower", "--out", out.to_str().unwrap()],
            "--name: expected a Rust static's name",
        ),
        (
            vec![
                inp,
                "--format",
                "c",
                "--name",
                "int",
                "--out",
                out.to_str().unwrap(),
            ],
            "--name: expected a C identifier",
        ),
        (
            vec![inp, "--prefix", "nope.", "--out", out.to_str().unwrap()],
            "no tensors under prefix \"nope.\"",
        ),
    ] {
        let o = export(&args);
        assert_refused(&o, want);
    }
    assert_eq!(std::fs::read(&input).unwrap(), before);
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        1,
        "no temporary left behind"
    );
    // A run's summary is read for the provenance: an input, which the module replaced.
    let run = dir.join("run");
    std::fs::create_dir(&run).unwrap();
    std::fs::copy(&input, run.join("policy.safetensors")).unwrap();
    let summary = run.join("summary.json");
    std::fs::write(&summary, b"{}").unwrap();
    let kept = std::fs::read(&summary).unwrap();
    let o = export(&[run.to_str().unwrap(), "--out", summary.to_str().unwrap()]);
    assert_refused(&o, "would overwrite the input");
    assert_eq!(std::fs::read(&summary).unwrap(), kept);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exporting_a_broken_policy_names_the_tensor() {
    let dir = scratch("broken");
    let path = dir.join("short.safetensors");
    // A width-16 policy missing its output bias.
    let shapes = firmware::network::shapes(16, 2);
    let data: Vec<Vec<u8>> = shapes.iter().map(|s| vec![0u8; 4 * s.len()]).collect();
    let views: Vec<_> = firmware::network::TENSOR_NAMES[..5]
        .iter()
        .zip(&shapes)
        .zip(&data)
        .map(|((n, s), d)| {
            (
                *n,
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, s.dims().to_vec(), d)
                    .unwrap(),
            )
        })
        .collect();
    std::fs::write(&path, safetensors::serialize(views, None).unwrap()).unwrap();
    let out = dir.join("x.rs");
    let o = exe()
        .arg("export")
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_refused(&o, "layer \"fc3\" lacks its bias");
    assert!(!Path::new(&out).exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_shipped_policy_exports_to_the_committed_integer_module() {
    let dir = scratch("int");
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = dir.join("policy_int.rs");
    let o = export(&[
        repo.join("shipped/policy.safetensors").to_str().unwrap(),
        "--quant",
        "int8",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("5512 bytes"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        std::fs::read_to_string(repo.join("shipped/src/policy_int.rs")).unwrap(),
        "shipped/src/policy_int.rs is not what `export --quant int8` writes (docs/GUIDE.md, \
         \"Export\", says how to regenerate it)"
    );
    // A C header, per channel this time, for the board --rig describes.
    let c = dir.join("policy_int.h");
    let o = export(&[
        repo.join("shipped/policy.safetensors").to_str().unwrap(),
        "--quant",
        "int8",
        "--granularity",
        "per-channel",
        "--format",
        "c",
        "--rig",
        repo.join("rigs/desk.toml").to_str().unwrap(),
        "--out",
        c.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let header = std::fs::read_to_string(&c).unwrap();
    assert!(header.contains("static const struct cartpole_qmlp64 cartpole_policy_int = {"));
    assert!(header.contains("int8 weights (per-channel)"));
    assert!(
        header.contains("static const struct cartpole_rig cartpole_policy_int_rig = {")
            && header.contains("    15000, /* cart_counts_per_m */\n")
            && header.contains("    1, /* dead_time */\n"),
        "{header}"
    );
    // --granularity means nothing without --quant: refused before any work, nothing written.
    let never = dir.join("never.rs");
    let o = export(&[
        repo.join("shipped/policy.safetensors").to_str().unwrap(),
        "--granularity",
        "per-channel",
        "--out",
        never.to_str().unwrap(),
    ]);
    assert_refused(&o, "--quant");
    assert!(!never.exists());
}
