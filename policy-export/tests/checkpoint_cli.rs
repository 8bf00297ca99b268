//! The checkpoints users have, through `policy-export export` as a user runs it: SB3's
//! `model.zip`, `torch.save` zips and ONNX export the network their safetensors twin does,
//! and a hostile pickle or a foreign graph exits 2 naming what was refused, writing nothing.
//! A checkpoint of more outputs exports with the duty levels `--levels` gives, and exits 2
//! naming `--levels` without them, with another count, against the levels its file records,
//! or with a list that is no list of levels.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

// Checkpoints made byte by byte in the layouts real tools write.
#[path = "../../weights/tests/support/build.rs"]
mod build;

use weights::Weights;
use weights::checkpoint::to_safetensors;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../weights/tests/fixtures")
        .join(name)
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pe-ckpt-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn export(src: &Path, out: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_policy-export"))
        .arg("export")
        .arg(src)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// The generated source without its provenance lines (which name the file).
fn body(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .filter(|l| !l.contains("source: "))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn every_format_exports_the_source_its_safetensors_twin_does() {
    let dir = scratch("formats");
    for (file, twin, extra) in [
        (
            "sb3_dqn.zip",
            "sb3_policy.safetensors",
            &["--prefix", "q_net.q_net."][..],
        ),
        ("sequential64.pth", "sequential64.safetensors", &[]),
        ("sequential64_matmul.onnx", "sequential64.safetensors", &[]),
        ("cleanrl.cleanrl_model", "cleanrl.safetensors", &[]),
    ] {
        for fmt in ["rust", "c"] {
            let (a, b) = (dir.join(format!("a.{fmt}")), dir.join(format!("b.{fmt}")));
            let mut args = extra.to_vec();
            args.extend(["--format", fmt]);
            for (src, out) in [(file, &a), (twin, &b)] {
                let o = export(&fixture(src), out, &args);
                assert!(
                    o.status.success(),
                    "{src}: {}",
                    String::from_utf8_lossy(&o.stderr)
                );
            }
            assert_eq!(body(&a), body(&b), "{file} as {fmt}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_hostile_pickle_and_a_foreign_graph_exit_2_and_write_nothing() {
    let dir = scratch("refused");
    for (file, says) in [
        ("evil.pth", "refused global \"posix.system\""),
        ("tanh.onnx", "(\"Tanh\") is not part of a 4-H-H-2 Q-network"),
    ] {
        let out = dir.join("policy.rs");
        let o = export(&fixture(file), &out, &[]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{file}: {e}");
        assert!(e.contains(says) && !e.contains("panicked"), "{file}: {e}");
        assert!(o.stdout.is_empty());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "{file}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// SB3's `model.zip` of a DQN of width 64 with five outputs (online and target net, no
/// levels recorded), and its online net's tensors.
fn sb3_five() -> (Vec<u8>, [Vec<f32>; 6]) {
    let mut p = build::Pickle::new();
    p.dict();
    let net = build::network_of(64, 5);
    let tensors: [Vec<f32>; 6] = std::array::from_fn(|k| net[k].0.clone());
    let mut storages = build::items_of(&mut p, "q_net.q_net.", "a", net);
    storages.extend(build::items_of(
        &mut p,
        "q_net_target.q_net.",
        "b",
        build::network_of(64, 5),
    ));
    let policy = build::torch_zip(&p.end(), &storages);
    (
        build::zip(&[("data", b"{}"), ("policy.pth", &policy)]),
        tensors,
    )
}

#[test]
fn a_five_output_sb3_model_exports_with_the_levels_given_or_exits_2_naming_them() {
    let (dir, out_dir) = (scratch("levels-in"), scratch("levels-out"));
    let (sb3, tensors) = sb3_five();
    let sb3_file = dir.join("model.zip");
    std::fs::write(&sb3_file, sb3).unwrap();
    // The same network in the trainer's file, which records its levels.
    let twin = dir.join("policy.safetensors");
    let w = Weights::new(64, vec![-1.0, -0.2, 0.0, 0.2, 1.0], tensors).unwrap();
    std::fs::write(&twin, to_safetensors(&w, &Default::default()).unwrap()).unwrap();

    let sb3_args = |levels: &'static str| ["--prefix", "q_net.q_net.", "--levels", levels];
    let (a, b) = (out_dir.join("a.rs"), out_dir.join("b.rs"));
    for (src, out, args) in [
        (&sb3_file, &a, &sb3_args("-1,-0.2,0,0.2,1")[..]),
        (&twin, &b, &[]),
    ] {
        let o = export(src, out, args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(body(&a), body(&b));
    assert!(body(&a).contains("Levels<5>"), "{}", body(&a));
    std::fs::remove_dir_all(&out_dir).unwrap();

    let out_dir = scratch("levels-refused");
    let out = out_dir.join("policy.rs");
    for (src, args, says) in [
        (
            &sb3_file,
            &["--prefix", "q_net.q_net."][..],
            "5 outputs and its file records no duty levels",
        ),
        (
            &sb3_file,
            &sb3_args("-1,1"),
            "--levels [-1, 1]: expected one level per output of the network, 5; found 2",
        ),
        (
            &sb3_file,
            &sb3_args("-1,-0.2,zero,0.2,1"),
            "--levels \"-1,-0.2,zero,0.2,1\": expected comma-separated numbers, found \"zero\"",
        ),
        (
            &twin,
            &["--levels", "-1,-0.5,0,0.5,1"],
            "the file records the duty levels [-1, -0.2, 0, 0.2, 1]; expected those or no --levels",
        ),
    ] {
        let o = export(src, &out, args);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(says) && e.contains("--levels"), "{args:?}: {e}");
        assert!(
            o.stdout.is_empty() && !e.contains("panicked"),
            "{args:?}: {e}"
        );
        assert_eq!(std::fs::read_dir(&out_dir).unwrap().count(), 0, "{args:?}");
    }
    std::fs::remove_dir_all(&out_dir).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}
