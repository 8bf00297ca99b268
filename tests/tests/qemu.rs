//! The self-test application on emulated Cortex-M4F (mps2-an386), Cortex-M33 (mps2-an505),
//! Cortex-M0 (micro:bit) and RV32IMAC (QEMU `virt`) cores:
//! its self-test must pass, its Q-values (float and integer) must equal the host's bit for bit,
//! and its paced loops must report their overruns under QEMU's instruction-counting clock.
//!
//! Needs `qemu-system-arm` and `qemu-system-riscv32` (Debian: `apt-get install qemu-system-arm
//! qemu-system-misc`) and the targets
//! targets (`scripts/setup.sh`). `CARTPOLE_SKIP_QEMU=1` skips it, loudly, on machines
//! without QEMU; CI installs QEMU and runs it.

use std::process::Command;

use firmware::policy::POLICY;
use firmware::policy_int::POLICY_INT;
use firmware::selftest::{INT_PROBES, PROBES, int_probe_line, probe_line};

fn expected_probe_lines() -> Vec<String> {
    let float = PROBES.iter().enumerate().map(|(i, obs)| {
        let mut s = String::new();
        probe_line(&mut s, i, obs, &POLICY.forward(obs)).unwrap();
        s
    });
    let int = INT_PROBES.iter().enumerate().map(|(i, obs)| {
        let mut s = String::new();
        int_probe_line(&mut s, i, obs, &POLICY_INT.forward(obs)).unwrap();
        s
    });
    float.chain(int).collect()
}

/// The overruns a `paced <format>:` line reports.
fn overruns(stdout: &str, format: &str) -> u32 {
    let prefix = format!("paced {format}: 50 periods, ");
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("no `{prefix}` line in\n{stdout}"));
    assert!(line.ends_with("balanced"), "{line}");
    line.split(' ').next().unwrap().parse().unwrap()
}

/// Runs the self-test on `target`; its output, once every common check passed.
fn run_on(target: &str) -> Option<String> {
    if std::env::var_os("CARTPOLE_SKIP_QEMU").is_some_and(|v| v == "1") {
        eprintln!("SKIPPED: CARTPOLE_SKIP_QEMU=1, firmware not run on {target}");
        return None;
    }
    let (qemu, package) = if target.starts_with("riscv32") {
        ("qemu-system-riscv32", "qemu-system-misc")
    } else {
        ("qemu-system-arm", "qemu-system-arm")
    };
    let found = Command::new(qemu).arg("--version").output();
    assert!(
        found.is_ok_and(|o| o.status.success()),
        "{qemu} not found: install it (apt-get install {package}) or set \
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
    let probes: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("probe ") || l.starts_with("probe-int "))
        .collect();
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
        stdout.contains("int: 0 of 300 random observations differ"),
        "{target}: {stdout}"
    );
    for format in ["f32", "int8"] {
        assert!(
            stdout.contains(&format!("{format} self-test: 5 of 5 episodes balanced")),
            "{stdout}"
        );
        assert!(
            stdout.contains(&format!(
                "{format} estimator episode: 500 steps through 4096-count encoders, balanced"
            )),
            "{target}: {stdout}"
        );
    }
    assert!(stdout.lines().any(|l| l == "PASS"), "{stdout}");
    Some(stdout.into_owned())
}

#[test]
fn cortex_m4f_matches_the_host_and_balances_in_real_time() {
    if let Some(out) = run_on("thumbv7em-none-eabihf") {
        // 8,905 and 8,753 instructions per forward pass against 312,500 per period.
        assert_eq!(
            (overruns(&out, "f32"), overruns(&out, "int8")),
            (0, 0),
            "{out}"
        );
    }
}

#[test]
fn cortex_m33_matches_the_host_and_balances_in_real_time() {
    if let Some(out) = run_on("thumbv8m.main-none-eabihf") {
        assert_eq!(
            (overruns(&out, "f32"), overruns(&out, "int8")),
            (0, 0),
            "{out}"
        );
    }
}

#[test]
fn risc_v_matches_the_host_and_the_integer_policy_keeps_its_period() {
    if let Some(out) = run_on("riscv32imac-unknown-none-elf") {
        // No FPU either: soft float about 417,000 instructions per forward pass, int8 33,000.
        assert!(
            overruns(&out, "f32") >= 25,
            "the f32 policy's overruns went unseen: {out}"
        );
        assert_eq!(overruns(&out, "int8"), 0, "{out}");
        assert!(out.contains("instructions per forward pass: f32 "), "{out}");
    }
}

#[test]
fn cortex_m0_matches_the_host_and_the_integer_policy_keeps_its_period() {
    if let Some(out) = run_on("thumbv6m-none-eabi") {
        // Soft float: about 865,000 instructions per forward pass, nearly three periods, so
        // most ticks arrive while a step runs. The integer forward pass takes about 22,000.
        let f32_late = overruns(&out, "f32");
        assert!(
            f32_late >= 50,
            "the f32 policy's overruns went unseen: {out}"
        );
        assert_eq!(overruns(&out, "int8"), 0, "{out}");
    }
}
