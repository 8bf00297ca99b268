//! No output of the simulator lands in an output directory of `policy-export` (one holding
//! its run marker), at any depth, even through a directory not made yet: the next `train`
//! to that directory refused to replace it, the run stranded.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

#[test]
fn outputs_inside_a_run_directory_are_refused_before_any_work() {
    let dir = std::env::temp_dir().join(format!("hs-outside-runs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let run = dir.join("run");
    std::fs::create_dir_all(run.join("seed-1")).unwrap();
    std::fs::write(run.join(".cartpole-run"), b"{}").unwrap();
    let (world, rig) = (repo("rigs/desk.toml"), repo("rigs/desk-measured.toml"));
    let path = |p: &Path| p.to_str().unwrap().to_owned();
    let cases: [Vec<String>; 4] = [
        vec!["render".into(), "--out".into(), path(&run.join("pics"))],
        vec![
            "render".into(),
            "--out".into(),
            path(&run.join("seed-1/new/pics")),
        ],
        [
            "simulate-logs",
            "--world",
            &path(&world),
            "--rig",
            &path(&rig),
            "--out",
        ]
        .map(String::from)
        .into_iter()
        .chain([path(&run.join("x.log"))])
        .collect(),
        vec![
            "render".into(),
            "--out".into(),
            path(&dir.join("elsewhere/../run/p")),
        ],
    ];
    for args in &cases {
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("expected a path outside the output directories of policy-export"),
            "{args:?}: {err}"
        );
    }
    let mut left: Vec<_> = std::fs::read_dir(&run)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    left.sort();
    assert_eq!(left, [".cartpole-run", "seed-1"]);
    assert_eq!(std::fs::read_dir(run.join("seed-1")).unwrap().count(), 0);
    std::fs::remove_dir_all(&dir).unwrap();
}
