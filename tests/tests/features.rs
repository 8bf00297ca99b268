//! What the scripts build after the test suite builds on the suite's artefacts: the Python
//! extension (`scripts/python.sh`, which the package's build compiles alone), a host tool
//! built with the workspace selected (`scripts/fuzz.sh`'s configuration seed) and the
//! end-to-end crate's tests (`scripts/test.sh` runs them as `-p e2e`) resolve every
//! package's features as `cargo test --workspace` did. A feature that only a development
//! dependency or another member (the Python extension's array crates) turns on would make
//! each of them compile a second copy of the trainer and the simulator (a minute of CI's);
//! `host-common/Cargo.toml` asks for those features too.

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

use e2e::repo;

/// Each package's features as `cargo tree` resolves them for `select` (package id -> the
/// features it is built with).
fn features(select: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["tree", "--locked", "--prefix", "none", "-f", "{p}|{f}"])
        .args(select)
        .current_dir(repo())
        .output()
        .expect("running cargo tree");
    assert!(
        out.status.success(),
        "cargo tree {select:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut found: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8(out.stdout).unwrap().lines() {
        let line = line.trim_end_matches(" (*)");
        if let Some((package, list)) = line.split_once('|') {
            let set = found.entry(package.to_owned()).or_default();
            set.extend(list.split(',').filter(|f| !f.is_empty()).map(str::to_owned));
        }
    }
    found
}

/// The packages whose features differ from the suite's, each with both lists.
fn differ(
    built: &BTreeMap<String, BTreeSet<String>>,
    suite: &BTreeMap<String, BTreeSet<String>>,
) -> Vec<String> {
    built
        .iter()
        .filter(|(p, f)| suite.get(*p) != Some(*f))
        .map(|(p, f)| format!("{p}: {f:?}, in the suite {:?}", suite.get(p)))
        .collect()
}

#[test]
fn the_scripts_builds_resolve_the_features_the_suite_built() {
    let suite = features(&["--workspace", "-e", "normal,dev,build"]);
    assert!(suite.keys().any(|p| p.starts_with("policy-export ")));
    let builds: [(&str, &[&str]); 3] = [
        (
            "the workspace's tools",
            &["--workspace", "-e", "normal,build"],
        ),
        (
            "the Python extension",
            &["-p", "cartpole-ddqn-py", "-e", "normal,build"],
        ),
        (
            "the end-to-end tests, run apart (scripts/test.sh)",
            &["-p", "e2e", "-e", "normal,dev,build"],
        ),
    ];
    for (what, select) in builds {
        let built = features(select);
        let apart = differ(&built, &suite);
        assert!(
            apart.is_empty(),
            "{what} resolved features the suite did not (a development dependency's or \
             another member's): {apart:#?}; ask for those features in host-common/Cargo.toml"
        );
    }
}
