//! `host-sim simulate-logs` then `host-sim identify`, as docs/RIGS.md runs them: the logs a
//! board measured as `rigs/desk-measured.toml` would stream from the true desk rig
//! (`rigs/desk.toml`), identified back to the truth; and bad requests refused with exit 2
//! and nothing written.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(path)
}

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("simulate-logs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn logs_of_the_true_rig_identify_back_to_it() {
    let dir = scratch("ok");
    let (log, out) = (dir.join("desk.log"), dir.join("rig.toml"));
    let (world, measured) = (repo("rigs/desk.toml"), repo("rigs/desk-measured.toml"));
    let o = host_sim(&[
        "simulate-logs",
        "--world",
        s(&world),
        "--rig",
        s(&measured),
        "--out",
        s(&log),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = host_sim(&["identify", s(&log), "--rig", s(&measured), "--out", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (found, truth) = (
        twin::rigfile::load(&out).unwrap(),
        twin::rigfile::load(&world).unwrap(),
    );
    let (q, p) = (&found.rig.params, &truth.rig.params);
    assert!((q.force_mag / p.force_mag - 1.0).abs() < 0.05, "{q:?}");
    assert!(
        (q.motor_damping / p.motor_damping - 1.0).abs() < 0.05,
        "{q:?}"
    );
    assert!((q.length / p.length - 1.0).abs() < 0.02, "{q:?}");
    assert_eq!(found.rig.dead_time, truth.rig.dead_time);
    // The intervals travel with the rig, for training to randomise at least that wide.
    let u = found.uncertainty;
    for v in [u.stall_force, u.damping, u.pole_com] {
        assert!(v > 0.0 && v < 0.05, "{u:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_board_of_another_period_or_a_wild_jitter_is_refused_and_nothing_written() {
    let dir = scratch("bad");
    let log = dir.join("desk.log");
    let world = repo("rigs/desk.toml");
    for (rig, jitter, want) in [
        (
            "rigs/desk-100hz-measured.toml",
            "0.5",
            "control period to be its world's, 0.02 s; found 0.01 s",
        ),
        (
            "rigs/desk-measured.toml",
            "NaN",
            "--jitter: expected counts in [0, 100]",
        ),
        (
            "rigs/desk-measured.toml",
            "1e9",
            "--jitter: expected counts in [0, 100]",
        ),
    ] {
        let o = host_sim(&[
            "simulate-logs",
            "--world",
            s(&world),
            "--rig",
            s(&repo(rig)),
            "--jitter",
            jitter,
            "--out",
            s(&log),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{rig} {jitter}: {err}");
        assert!(err.contains(want), "{want:?} in {err}");
        assert!(!log.exists(), "{rig} {jitter} wrote the log");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The cart experiment's seed is the board's 32 bits: one past them is refused with the range
/// (std said "number too large to fit in target type", no range), and nothing written.
#[test]
fn a_seed_past_the_boards_32_bits_is_refused_naming_the_range() {
    let dir = scratch("seed");
    let out = dir.join("x.log");
    let (world, measured) = (repo("rigs/desk.toml"), repo("rigs/desk-measured.toml"));
    for seed in ["18446744073709551615", "4294967296", "-1"] {
        let args = ["simulate-logs", "--world", s(&world), "--rig", s(&measured)];
        let o = host_sim(&[&args[..], &["--out", s(&out), "--seed", seed]].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains(&format!(
                "for '--seed <SEED>': expected a whole number in [0, 4294967295] (the board's \
                 sequence takes a 32-bit seed), found \"{seed}\""
            )),
            "{err}"
        );
        assert!(!out.exists());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
