//! The processor-in-the-loop target: the board's controller (its sensor, observer,
//! predictor, limits and policy, in either format) run for a world simulated on a host, one
//! period per frame of the link (`docs/LINK.md`, `firmware::link::Target`), over QEMU's
//! semihosting console (`port`). `host-sim eval --pil qemu:TARGET` starts it in QEMU and drives it.
//!
//! ```sh
//! cargo build --release -p selftest-app --bin pil --target thumbv6m-none-eabi
//! ```
//!
//! Built for the host, it serves the same link on standard input and output, timing
//! periods in nanoseconds: the host's own run of the target code.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(unsafe_code)]

#[cfg(all(target_os = "none", target_arch = "arm"))]
mod on_arm;
#[cfg(all(target_os = "none", target_arch = "riscv32"))]
mod on_riscv;
#[cfg(target_os = "none")]
mod port;

mod pil_app;

#[cfg(target_os = "none")]
use pil_app::run;

/// What the application holds: the shipped policy, both formats, its rig and envelope.
fn target(clock_hz: u32) -> firmware::link::Target<'static, 64> {
    shipped::target(clock_hz)
}

#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    pil_app::main()
}
