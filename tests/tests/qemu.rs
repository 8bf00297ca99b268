//! The self-test application on every microcontroller target rust-toolchain.toml lists, each
//! on the QEMU machine its runner in `.cargo/config.toml` names: its self-test must pass, its
//! Q-values (float and integer) must equal the host's bit for bit, its paced loops must
//! report their overruns under QEMU's instruction-counting clock, and two runs of the image
//! at once must print the same report byte for byte, overruns included, whatever the load.
//!
//! Needs `qemu-system-arm` and `qemu-system-riscv32` (Debian: `apt-get install qemu-system-arm
//! qemu-system-misc`) and the targets (`scripts/setup.sh`). `CARTPOLE_SKIP_QEMU=1` skips it,
//! loudly, on machines without QEMU; CI installs QEMU and runs it.

use std::path::Path;
use std::process::{Command, Output};

use e2e::{build_app, runners};

/// The self-test's probe lines as the host computes them: the same application, built for
/// the host, prints the same report.
fn expected_probe_lines() -> Vec<String> {
    let out = cargo(&["run", "-q", "--release", "-p", "selftest-app"]);
    assert!(out.status.success(), "the host self-test failed");
    probe_lines(&String::from_utf8_lossy(&out.stdout))
        .map(str::to_string)
        .collect()
}

fn probe_lines(stdout: &str) -> impl Iterator<Item = &str> {
    stdout
        .lines()
        .filter(|l| l.split(' ').next().is_some_and(|w| w.starts_with("probe")))
}

fn cargo(args: &[&str]) -> Output {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    Command::new(cargo)
        .args(args)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .output()
        .expect("running cargo")
}

/// `elf` run by `target`'s runner in `.cargo/config.toml`, as `cargo run` would.
fn run_image(target: &str, elf: &Path) -> Output {
    let (_, runner) = runners()
        .into_iter()
        .find(|(t, _)| t == target)
        .unwrap_or_else(|| panic!("{target}: no runner in .cargo/config.toml"));
    let mut words = runner.split_whitespace();
    let program = words.next().expect("an empty runner");
    Command::new(program)
        .args(words)
        .arg(elf)
        .output()
        .unwrap_or_else(|e| panic!("{target}: running {program}: {e}"))
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
/// The report's lines on `target`'s renderings of its own (the VFP dot product on
/// hard-float cores, the integer kernels on Arm), compared with the portable definitions;
/// where the target runs the definitions themselves, there is nothing to compare, and the
/// report says so.
fn own_kernel_lines(target: &str) -> [String; 3] {
    let (own_dot, own_int) = (target.ends_with("eabihf"), target.starts_with("thumb"));
    let kernel = |own: bool, what: &str, cases: &str, portable: &str| match own {
        true => format!("{what}: 0 of {cases} differ"),
        false => format!("{what}: the portable {portable} itself on this target"),
    };
    let forward = "random observations";
    [
        kernel(own_dot, "dot", "1000 random vector pairs", "order"),
        kernel(own_int, "int", &format!("300 {forward}"), "forward pass"),
        kernel(
            own_int,
            "int, nine levels",
            &format!("300 {forward}"),
            "forward pass",
        ),
    ]
}

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
    let elf = build_app("selftest-app", Some(target));
    // The image twice at once, beside the other targets' runs: virtual time counts
    // instructions and nothing else, so the load the runs put on the host (and any other)
    // must not change a byte of the report.
    let (out, again) = std::thread::scope(|s| {
        let again = s.spawn(|| run_image(target, &elf));
        (run_image(target, &elf), again.join().unwrap())
    });
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{target}: exit {:?}\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let again = String::from_utf8_lossy(&again.stdout);
    let differ: Vec<(&str, &str)> = stdout
        .lines()
        .zip(again.lines())
        .filter(|(a, b)| a != b)
        .collect();
    assert!(
        stdout == again,
        "{target}: two runs of one image differ, so the host's time reached the target's \
         clock (is `sleep=off` in its runner's -icount?): {differ:?}"
    );
    let probes: Vec<&str> = probe_lines(&stdout).collect();
    assert_eq!(
        probes,
        expected_probe_lines(),
        "{target} Q-values differ from the host's"
    );
    for line in own_kernel_lines(target) {
        assert!(stdout.contains(&line), "{target}: {stdout}");
    }
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
    assert!(
        stdout.contains("start-up: balancing after 200 periods, 141 of them balancing"),
        "{target}: {stdout}"
    );
    assert!(stdout.lines().any(|l| l == "PASS"), "{stdout}");
    Some(stdout.into_owned())
}

/// The paced loops' overruns `target` must report: a core with an FPU keeps the period with
/// either policy; on one without, the f32 forward pass (soft float) outlasts the period, so its
/// overruns must show, and the integer one must keep it.
fn check_periods(target: &str, out: &str) {
    let (f32_late, int8_late) = (overruns(out, "f32"), overruns(out, "int8"));
    match target {
        "thumbv7em-none-eabihf" | "thumbv8m.main-none-eabihf" => {
            assert_eq!((f32_late, int8_late), (0, 0), "{target}: {out}");
        }
        // Its f32 step is slower than the RISC-V core's: a late tick in every period.
        "thumbv6m-none-eabi" => {
            assert!(
                f32_late >= 50,
                "{target}: the f32 overruns went unseen: {out}"
            );
            assert_eq!(int8_late, 0, "{target}: {out}");
        }
        "riscv32imac-unknown-none-elf" => {
            assert!(
                f32_late >= 25,
                "{target}: the f32 overruns went unseen: {out}"
            );
            assert_eq!(int8_late, 0, "{target}: {out}");
            assert!(out.contains("instructions per forward pass: f32 "), "{out}");
        }
        other => panic!("{other}: no expected overruns here; add the target's"),
    }
}

/// One thread per target, so every failing target reports (its thread's panic message) and
/// the QEMU runs overlap.
#[test]
fn every_target_matches_the_host_and_keeps_its_period() {
    let targets = e2e::mcu_targets();
    let failed: Vec<&String> = std::thread::scope(|s| {
        let runs: Vec<_> = targets
            .iter()
            .map(|t| {
                let run = s.spawn(move || {
                    if let Some(out) = run_on(t) {
                        check_periods(t, &out);
                    }
                });
                (t, run)
            })
            .collect();
        runs.into_iter()
            .filter_map(|(t, run)| run.join().is_err().then_some(t))
            .collect()
    });
    assert!(failed.is_empty(), "failed on {failed:?}");
}
