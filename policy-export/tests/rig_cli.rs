//! A rig file no machine has, at each of the trainer's doors that take `--rig`: `train` and
//! `export` (Rust, C, and int8, whose calibration runs on the rig) refuse it with exit status
//! 2 and a message naming the field, before writing anything, and print nothing on stdout.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

#[path = "../../tests/support/spoilt_rigs.rs"]
mod spoilt;
use spoilt::bad_rigs;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pe-rig-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `args` with `--rig rig` and `--out out`: exit 2, `field` named, nothing on stdout, `out`
/// not written.
#[track_caller]
fn refused(args: &[&str], rig: &Path, out: &Path, field: &str) {
    let o: Output = Command::new(env!("CARGO_BIN_EXE_policy-export"))
        .args(args)
        .arg("--rig")
        .arg(rig)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    let seen = format!("{args:?} --rig {}: {err}", rig.display());
    assert_eq!(o.status.code(), Some(2), "{seen}");
    assert!(err.contains(field) && err.len() < 1_000, "{seen}");
    assert!(o.stdout.is_empty(), "{seen}");
    assert!(!out.exists(), "{seen}: {} was written", out.display());
}

#[test]
fn train_and_export_refuse_a_rig_no_machine_has_naming_the_field() {
    let dir = scratch("bad");
    let shipped = repo().join("shipped/policy.safetensors");
    let src = shipped.to_str().unwrap();
    for (rig, field) in bad_rigs(&dir) {
        refused(&["train", "--episodes", "1"], &rig, &dir.join("run"), field);
        for format in [
            &["export", src][..],
            &["export", src, "--format", "c"],
            &["export", src, "--quant", "int8", "--format", "c"],
        ] {
            refused(format, &rig, &dir.join("policy.out"), field);
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A rig file's name need not be text: `train --rig` takes any path, as `--config`, `--out`
/// and `export --rig` do, and the configuration holds the file's text, whatever its name.
#[test]
fn train_takes_a_rig_whose_path_is_not_utf8_and_keeps_its_text() {
    use std::os::unix::ffi::OsStrExt;
    let dir = scratch("utf8");
    let desk = repo().join("rigs/desk.toml");
    let odd = dir.join(std::ffi::OsStr::from_bytes(b"rig\xff\xfe.toml"));
    std::fs::copy(&desk, &odd).unwrap();
    let config = |rig: &Path| {
        let o = Command::new(env!("CARGO_BIN_EXE_policy-export"))
            .args(["train", "--preset", "deploy", "--print-config", "--rig"])
            .arg(rig)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "--rig {}: {err}", rig.display());
        String::from_utf8(o.stdout).unwrap()
    };
    let printed = config(&odd);
    assert_eq!(printed, config(&desk));
    let cfg: toml::Table = toml::from_str(&printed).unwrap();
    assert_eq!(
        cfg["rig"].as_str(),
        Some(std::fs::read_to_string(&desk).unwrap().as_str())
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
