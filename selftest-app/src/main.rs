//! The Cortex-M application: a start-up self-test, then the balance controller at the
//! shipped rig's control period.
//!
//! On a microcontroller (`target_os = "none"`) it reports over semihosting (or defmt with
//! the `defmt` feature) and exits with the self-test's verdict, which is what QEMU runs:
//!
//! ```sh
//! cargo run --release -p selftest-app --target thumbv7em-none-eabihf   # Cortex-M4F, mps2-an386
//! cargo run --release -p selftest-app --target thumbv6m-none-eabi      # Cortex-M0, micro:bit
//! ```
//!
//! On the host the same self-test runs natively, so the two reports can be compared.
//!
//! This crate owns what a board's own application would: the runtime (`cortex-m-rt`), the
//! critical-section implementation, the memory maps (the default target's `memory.x` at the
//! repository root, the other machines' in `memory/`; `build.rs` says how each is linked) and
//! the panic handler. The `firmware` library it runs has none of them.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(unsafe_code)]

#[cfg(target_os = "none")]
mod app;
#[cfg(all(target_os = "none", target_arch = "arm"))]
mod arm_selftest;
#[cfg(all(target_os = "none", target_arch = "arm"))]
mod on_arm;
#[cfg(all(target_os = "none", target_arch = "riscv32"))]
mod on_riscv;
#[cfg(target_os = "none")]
mod period;
#[cfg(all(target_os = "none", target_arch = "riscv32"))]
mod riscv_selftest;
mod selftest;

/// What the architecture's entry runs: the self-test and the paced loop; whether all passed.
#[cfg(target_os = "none")]
fn run(board: &mut impl app::Board) -> bool {
    app::run(board)
}

#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    use selftest::{selftest_forward, selftest_forward_int};
    use selftest::{selftest_forward_levels, selftest_forward_levels_int};
    use shipped::{policy::POLICY, policy_int::POLICY_INT};
    let ok = selftest::report(
        &POLICY,
        &POLICY_INT,
        |o, q| selftest_forward(Some(o), Some(q)),
        |o, q| selftest_forward_int(Some(o), Some(q)),
        |l| println!("{l}"),
    );
    selftest::levels_probes(
        |o, q| selftest_forward_levels(Some(o), Some(q)),
        |o, q| selftest_forward_levels_int(Some(o), Some(q)),
        |l| println!("{l}"),
    );
    selftest::refine_probe(
        |a, o| selftest::selftest_refine_int(Some(a), Some(o)),
        |l| println!("{l}"),
    );
    if ok {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}
