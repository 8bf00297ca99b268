//! The checkpoints users have, through `policy-export export` as a user runs it: SB3's
//! `model.zip`, `torch.save` zips and ONNX export the network their safetensors twin does,
//! and a hostile pickle or a foreign graph exits 2 naming what was refused, writing nothing.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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
