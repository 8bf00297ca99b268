//! `host-sim eval --policy` with checkpoints as PyTorch users save them (the fixtures of the
//! `weights` crate, written by real PyTorch and Stable-Baselines3 code).

use std::path::PathBuf;
use std::process::{Command, Output};

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
