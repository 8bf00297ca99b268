//! The processor-in-the-loop target of the nine-level desk policy (`shipped::desk`, its
//! integer version `shipped::desk_int` and the desk rig): the `pil` application with a
//! policy of duty levels in place of the shipped one, for `host-sim eval --pil
//! qemu:TARGET --pil-policy desk`.
//!
//! ```sh
//! cargo build --release -p selftest-app --bin pil-desk --target thumbv7em-none-eabihf
//! ```
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

/// What the application holds: the desk policy, both formats, its nine levels and its rig.
fn target(clock_hz: u32) -> firmware::link::Target<'static, 64, 9> {
    shipped::desk_target(clock_hz)
}

#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    pil_app::main()
}
