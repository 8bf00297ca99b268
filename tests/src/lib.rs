//! End-to-end tests live in `tests/`. This library holds what several of them read from the
//! repository: the microcontroller targets, listed once in rust-toolchain.toml (rustup reads
//! them there), and the QEMU runners `.cargo/config.toml` gives them.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn toml_file(name: &str) -> toml::Table {
    let path = repo().join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.parse()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// rust-toolchain.toml's `targets`, in the file's order.
pub fn mcu_targets() -> Vec<String> {
    let file = toml_file("rust-toolchain.toml");
    let list = file
        .get("toolchain")
        .and_then(|t| t.get("targets"))
        .and_then(toml::Value::as_array)
        .expect("rust-toolchain.toml has no toolchain.targets list");
    let targets: Vec<String> = list
        .iter()
        .map(|t| t.as_str().expect("a target is a string").to_owned())
        .collect();
    assert!(!targets.is_empty(), "rust-toolchain.toml lists no targets");
    targets
}

/// The default target: the first listed, the one the root `memory.x` maps.
pub fn default_target() -> String {
    mcu_targets().swap_remove(0)
}

/// Each target `.cargo/config.toml` gives a `runner`, with that runner. An unquoted triple
/// with a dot in it (`[target.thumbv8m.main-none-eabihf]`) is a nested table in TOML, and
/// cargo reads it as the dotted name, so the walk joins the keys the same way.
pub fn runners() -> Vec<(String, String)> {
    fn walk(prefix: &str, table: &toml::Table, found: &mut Vec<(String, String)>) {
        for (key, value) in table {
            let Some(inner) = value.as_table() else {
                continue;
            };
            let name = format!("{prefix}{key}");
            match inner.get("runner").and_then(toml::Value::as_str) {
                Some(runner) => found.push((name, runner.to_owned())),
                None => walk(&format!("{name}."), inner, found),
            }
        }
    }
    let file = toml_file(".cargo/config.toml");
    let mut found = Vec::new();
    if let Some(targets) = file.get("target").and_then(toml::Value::as_table) {
        walk("", targets, &mut found);
    }
    found
}

/// Builds `selftest-app`'s binary `bin` in release for `target` (the host without one); the
/// executable's path, as cargo names it.
pub fn build_app(bin: &str, target: Option<&str>) -> PathBuf {
    build("selftest-app", bin, "release", target)
}

/// Builds a host tool (`host-sim`, `policy-export`) with the profile the tests were built
/// with, so that it reuses their artefacts; the executable's path. The whole workspace's
/// tests are selected beside it (fresh, after `cargo test --workspace`): alone, `-p
/// host-sim` would resolve its dependencies' features without the test run's development
/// dependencies and build a second copy of half the workspace for it.
pub fn build_tool(package: &str) -> PathBuf {
    build_with(package, &test_profile(), None, &["--workspace", "--tests"])
}

/// The cargo profile of this test binary: the name of the directory above its `deps/`
/// (`debug` is the `dev` profile's).
pub fn test_profile() -> String {
    let exe = std::env::current_exe().expect("the test binary's path");
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .and_then(Path::file_name)
        .and_then(|n| n.to_str())
        .expect("a test binary lies in PROFILE/deps/");
    match dir {
        "debug" => "dev".into(),
        other => other.into(),
    }
}

/// Builds binary `bin` of `package` with `profile` for `target` (the host without one); the
/// executable's path, as cargo names it.
pub fn build(package: &str, bin: &str, profile: &str, target: Option<&str>) -> PathBuf {
    build_with(bin, profile, target, &["-p", package])
}

/// [`build`], the packages selected by `select`.
fn build_with(bin: &str, profile: &str, target: Option<&str>, select: &[&str]) -> PathBuf {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut c = Command::new(cargo);
    c.args(["build", "-q", "--profile", profile])
        .args(select)
        .args(["--bin", bin])
        .arg("--message-format=json")
        .current_dir(repo());
    if let Some(t) = target {
        c.args(["--target", t]);
    }
    let out = c.output().expect("running cargo");
    assert!(
        out.status.success(),
        "{bin} for {target:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .expect("cargo's messages are UTF-8")
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        // The binary itself, not its unit tests' harness (`--tests` builds both).
        .filter(|m| m["target"]["name"] == bin && m["profile"]["test"] == false)
        .find_map(|m| m["executable"].as_str().map(PathBuf::from))
        .unwrap_or_else(|| panic!("{bin} for {target:?}: cargo named no executable"))
}
