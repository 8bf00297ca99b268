//! A policy exported into a crate of a board's own: the generated module compiles outside
//! this workspace, on the host (where rustc's own literal parsing is checked against the
//! weights, bit for bit) and for the default microcontroller target (the first in
//! rust-toolchain.toml), and on none of the listed targets does depending on `firmware` bring
//! any of the self-test application's runtime.

use std::path::{Path, PathBuf};
use std::process::Command;

use e2e::{default_target, mcu_targets, repo};
use firmware::network::{Mlp, shapes};
use firmware::rig::Rig;
use weights::Weights;
use weights::source::rust_module;

/// A rig whose every number is awkward to write: the constants must come back bit for bit.
fn awkward_rig() -> Rig {
    let mut rig = Rig::GYMNASIUM;
    let p = &mut rig.params;
    (p.masscart, p.masspole, p.length) = (0.6000000000000001, 0.08, 0.22);
    (p.force_mag, p.motor_damping, p.tau) = (5.0, 3.000_000_000_000_000_4, 0.01);
    (p.x_threshold, p.cart_friction, p.pole_friction) = (0.4, 1e-300, 5e-324);
    rig.encoders.cart_counts_per_m = 15_000;
    rig.encoders.pole_counts_per_rev = 2_400;
    (rig.dead_time, rig.end_stop_margin) = (2, 0.05);
    rig.tuning.accel_sd = [0.1, 1.0 / 3.0];
    rig
}

/// The rig's numbers as the dump program prints them: each f64's bits, then the integers.
fn rig_lines(rig: &Rig) -> Vec<String> {
    let p = &rig.params;
    let t = &rig.tuning;
    let mut f: Vec<String> = p
        .values()
        .into_iter()
        .chain([
            rig.end_stop_margin,
            t.force_sd,
            t.accel_sd[0],
            t.accel_sd[1],
        ])
        .map(|v| format!("{:016x}", v.to_bits()))
        .collect();
    let e = &rig.encoders;
    f.push(format!(
        "{} {} {}",
        e.cart_counts_per_m, e.pole_counts_per_rev, rig.dead_time
    ));
    f
}

/// Observations whose Q-values the scratch crate prints: a balanced state, leaning states,
/// the edges of the failure box and values with long mantissas.
const PROBES: [[f32; 4]; 4] = [
    [0.0, 0.0, 0.0, 0.0],
    [0.01, -0.02, 0.03, 0.04],
    [-2.4, -1.5, -0.2094395, -2.0],
    [1.0e-7, -3.3333333, 0.12345679, -0.9876543],
];

/// Weights whose decimal forms are awkward: subnormals, extremes, signed zeros, values that
/// need nine significant digits.
fn awkward() -> Weights {
    let special = [
        f32::MIN_POSITIVE,
        -1.0e-45,
        -0.0,
        0.1,
        16_777_217.0,
        2.718_281_7,
        -3.402_823_5e38,
        1.175_494_2e-38,
    ];
    let tensors = shapes(16, 2).map(|s| {
        (0..s.len())
            .map(|i| {
                special
                    .get(i)
                    .copied()
                    .unwrap_or(((i * 7919) % 1000) as f32 * -0.012_345_679 + 0.3)
            })
            .collect()
    });
    Weights::new(16, weights::BANG_BANG.to_vec(), tensors).unwrap()
}

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

/// A crate outside the workspace that depends on `firmware` by path and compiles the
/// exported module as `mod policy;`.
fn scratch_crate(name: &str, module: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let firmware = repo().join("firmware").canonicalize().unwrap();
    write(
        &dir.join("Cargo.toml"),
        &format!(
            "[package]\nname = \"user-board\"\nversion = \"0.1.0\"\nedition = \"2024\"\n\n\
             [lib]\ncrate-type = [\"staticlib\", \"rlib\"]\n\n\
             [dependencies]\nfirmware = {{ path = {:?} }}\n\n\
             # Its own workspace: nothing of the project's but `firmware`.\n[workspace]\n",
            firmware.display().to_string()
        ),
    );
    // The project's lock file pins the same versions; cargo drops what this crate does not use.
    std::fs::copy(repo().join("Cargo.lock"), dir.join("Cargo.lock")).unwrap();
    write(&dir.join("src/policy.rs"), module);
    write(
        &dir.join("src/lib.rs"),
        "#![cfg_attr(target_os = \"none\", no_std)]\n\
         pub mod policy;\n\n\
         /// What a board's C code would call: 1 pushes right.\n\
         #[unsafe(no_mangle)]\n\
         pub extern \"C\" fn user_action(obs: &[f32; 4]) -> u8 {\n    \
             policy::BOARD_POLICY.greedy(obs) as u8\n}\n\n\
         #[cfg(target_os = \"none\")]\n\
         #[panic_handler]\n\
         fn panic(_: &core::panic::PanicInfo<'_>) -> ! {\n    loop {}\n}\n",
    );
    write(
        &dir.join("src/bin/dump.rs"),
        "use user_board::policy::{BOARD_POLICY as P, RIG};\n\
         fn main() {\n    \
             for t in P.tensors() { for v in t { println!(\"{:08x}\", v.to_bits()); } }\n    \
             let (p, t) = (&RIG.params, &RIG.tuning);\n    \
             for v in [p.gravity, p.masscart, p.masspole, p.length, p.force_mag, p.motor_damping, \
                 p.tau, p.theta_threshold_radians, p.x_threshold, p.cart_friction, p.pole_friction, \
                 RIG.end_stop_margin, t.force_sd, t.accel_sd[0], t.accel_sd[1]] {\n        \
                 println!(\"{:016x}\", v.to_bits());\n    }\n    \
             let e = &RIG.encoders;\n    \
             println!(\"{} {} {}\", e.cart_counts_per_m, e.pole_counts_per_rev, RIG.dead_time);\n    \
             let obs: Vec<f32> = std::env::args().skip(1).map(|a| a.parse().unwrap()).collect();\n    \
             for o in obs.chunks(4) {\n        \
                 let q = P.forward(&[o[0], o[1], o[2], o[3]]);\n        \
                 println!(\"q {:08x} {:08x}\", q[0].to_bits(), q[1].to_bits());\n    }\n}\n",
    );
    dir
}

fn cargo(dir: &Path, args: &[&str]) -> std::process::Output {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    // `--offline` right after the subcommand: anything after `--` goes to the program.
    let out = Command::new(cargo)
        .arg(args[0])
        .arg("--offline")
        .args(&args[1..])
        .current_dir(dir)
        // Not the workspace's target directory: this is another workspace.
        .env("CARGO_TARGET_DIR", dir.join("target"))
        .env_remove("RUSTFLAGS")
        .output()
        .expect("running cargo");
    assert!(
        out.status.success(),
        "cargo {args:?} in {}:\n{}",
        dir.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn an_exported_policy_builds_in_a_board_crate_bit_for_bit() {
    let w = awkward();
    let rig = awkward_rig();
    let module = rust_module(
        &w,
        "BOARD_POLICY",
        &["source: the project's e2e test".into()],
        &rig,
    )
    .unwrap();
    let dir = scratch_crate("user-board-build", &module);

    // On the host: the compiled constants, as rustc parsed the literals, are the weights.
    let args: Vec<String> = PROBES.iter().flatten().map(|v| format!("{v:e}")).collect();
    let mut run = vec!["run", "-q", "--release", "--bin", "dump", "--"];
    run.extend(args.iter().map(String::as_str));
    let out = String::from_utf8(cargo(&dir, &run).stdout).unwrap();
    let mut lines = out.lines();
    let want: Vec<String> = w
        .tensors()
        .iter()
        .flatten()
        .map(|v| format!("{:08x}", v.to_bits()))
        .collect();
    let got: Vec<&str> = lines.by_ref().take(want.len()).collect();
    assert_eq!(got, want, "the compiled constants differ from the weights");
    let rig_want = rig_lines(&rig);
    let rig_got: Vec<&str> = lines.by_ref().take(rig_want.len()).collect();
    assert_eq!(
        rig_got, rig_want,
        "the compiled rig differs from the rig exported"
    );
    let net: Box<Mlp<16>> = w.to_mlp().unwrap();
    for (obs, line) in PROBES.iter().zip(lines) {
        let q = net.forward(obs);
        assert_eq!(
            line,
            format!("q {:08x} {:08x}", q[0].to_bits(), q[1].to_bits())
        );
    }

    // For the default target, as a static library: all of firmware's code path is compiled.
    let target = default_target();
    if std::env::var_os("CARTPOLE_SKIP_THUMB").is_some_and(|v| v == "1") {
        eprintln!("SKIPPED: CARTPOLE_SKIP_THUMB=1, no {target} build");
        return;
    }
    cargo(
        &dir,
        &["build", "-q", "--release", "--lib", "--target", &target],
    );
    let lib = dir.join(format!("target/{target}/release/libuser_board.a"));
    assert!(lib.metadata().unwrap().len() > 18_000, "{}", lib.display());
}

#[test]
fn depending_on_firmware_brings_no_runtime_linker_script_or_critical_section() {
    let dir = scratch_crate(
        "user-board-tree",
        &rust_module(&awkward(), "BOARD_POLICY", &[], &Rig::GYMNASIUM).unwrap(),
    );
    for target in mcu_targets() {
        let out = cargo(
            &dir,
            &[
                "tree",
                "--target",
                &target,
                "-e",
                "normal,build",
                "--prefix",
                "none",
            ],
        );
        let tree = String::from_utf8(out.stdout).unwrap();
        assert!(tree.contains("firmware v"), "{tree}");
        for app_only in [
            "cortex-m-rt",
            "cortex-m ",
            "critical-section",
            "cortex-m-semihosting",
            "riscv-rt",
            "riscv ",
            "riscv-semihosting",
            "defmt",
            // Random starts are the host tools' and the self-test's (`firmware`'s `rand`
            // feature); a board draws nothing.
            "rand ",
            "rand_core ",
            "rand_pcg ",
        ] {
            assert!(
                !tree.contains(app_only),
                "{target}: a board crate inherits {app_only}:\n{tree}"
            );
        }
    }
}
