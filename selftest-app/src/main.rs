//! The Cortex-M application: a start-up self-test, then the balance controller at 50 Hz.
//!
//! On a microcontroller (`target_os = "none"`) it reports over semihosting (or defmt with
//! the `defmt` feature) and exits with the self-test's verdict, which is what QEMU runs:
//!
//! ```sh
//! cargo run --release -p firmware --target thumbv7em-none-eabihf   # Cortex-M4F, mps2-an386
//! cargo run --release -p firmware --target thumbv6m-none-eabi      # Cortex-M0, micro:bit
//! ```
//!
//! On the host the same self-test runs natively, so the two reports can be compared.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(unsafe_code)]

#[cfg(target_os = "none")]
mod mcu;

#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    use firmware::{ffi::cartpole_policy_forward, policy::POLICY, selftest};
    let ok = selftest::report(
        &POLICY,
        |o, q| cartpole_policy_forward(o, q),
        |l| println!("{l}"),
    );
    if ok {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}
