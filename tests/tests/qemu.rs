//! The self-test application on emulated Cortex-M4F (mps2-an386) and Cortex-M0 (micro:bit) cores:
//! its self-test must pass and its Q-values must equal the host's bit for bit.
//!
//! Needs `qemu-system-arm` (Debian: `apt-get install qemu-system-arm`) and the two thumb
//! targets (`scripts/setup.sh`). `CARTPOLE_SKIP_QEMU=1` skips it, loudly, on machines
//! without QEMU; CI installs QEMU and runs it.

use std::process::Command;

use firmware::policy::POLICY;
use firmware::selftest::{PROBES, probe_line};

fn expected_probe_lines() -> Vec<String> {
    PROBES
        .iter()
        .enumerate()
        .map(|(i, obs)| {
            let mut s = String::new();
            probe_line(&mut s, i, obs, &POLICY.forward(obs)).unwrap();
            s
        })
        .collect()
}

fn run_on(target: &str) {
    if std::env::var_os("CARTPOLE_SKIP_QEMU").is_some_and(|v| v == "1") {
        eprintln!("SKIPPED: CARTPOLE_SKIP_QEMU=1, firmware not run on {target}");
        return;
    }
    let qemu = Command::new("qemu-system-arm").arg("--version").output();
    assert!(
        qemu.is_ok_and(|o| o.status.success()),
        "qemu-system-arm not found: install it (apt-get install qemu-system-arm) or set \
         CARTPOLE_SKIP_QEMU=1"
    );
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "run",
            "-q",
            "--release",
            "-p",
            "selftest-app",
            "--target",
            target,
        ])
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .output()
        .expect("running cargo");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{target}: exit {:?}\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let probes: Vec<&str> = stdout.lines().filter(|l| l.starts_with("probe ")).collect();
    assert_eq!(
        probes,
        expected_probe_lines(),
        "{target} Q-values differ from the host's"
    );
    assert!(
        stdout.contains("dot: 0 of 1000 random vector pairs differ"),
        "{target}: {stdout}"
    );
    assert!(
        stdout.contains("self-test: 5 of 5 episodes balanced"),
        "{stdout}"
    );
    assert!(
        stdout.contains("estimator episode: 500 steps through 4096-count encoders, balanced"),
        "{target}: {stdout}"
    );
    assert!(stdout.lines().any(|l| l == "PASS"), "{stdout}");
}

#[test]
fn cortex_m4f_matches_the_host_and_balances() {
    run_on("thumbv7em-none-eabihf");
}

#[test]
fn cortex_m0_matches_the_host_and_balances() {
    run_on("thumbv6m-none-eabi");
}
