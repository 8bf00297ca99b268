//! The microcontroller targets are listed once, in rust-toolchain.toml: every one needs a QEMU
//! runner in `.cargo/config.toml` and no runner may be left for a target not listed, and the
//! shell side (`scripts/targets.sh`) must read the same list as the tests.

use std::collections::BTreeSet;
use std::process::Command;

use e2e::{mcu_targets, repo, runners};

#[test]
fn every_listed_target_has_a_runner_and_every_runner_a_listed_target() {
    let listed: BTreeSet<String> = mcu_targets().into_iter().collect();
    let with_runner: BTreeSet<String> = runners().into_iter().map(|(t, _)| t).collect();
    let no_runner: Vec<&String> = listed.difference(&with_runner).collect();
    let not_listed: Vec<&String> = with_runner.difference(&listed).collect();
    assert!(
        no_runner.is_empty() && not_listed.is_empty(),
        "listed in rust-toolchain.toml without a runner in .cargo/config.toml: {no_runner:?}; \
         a runner in .cargo/config.toml for a target rust-toolchain.toml does not list: \
         {not_listed:?}"
    );
}

#[test]
fn the_runners_start_qemu() {
    for (target, runner) in runners() {
        assert!(runner.starts_with("qemu-system-"), "{target}: {runner}");
    }
}

#[test]
fn the_scripts_read_the_same_list() {
    let out = Command::new("bash")
        .args(["-c", ". scripts/targets.sh && mcu_targets"])
        .current_dir(repo())
        .output()
        .expect("running bash");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed: Vec<String> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(str::to_owned)
        .collect();
    assert_eq!(printed, mcu_targets());
}
