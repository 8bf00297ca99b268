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

use firmware::link::Target;
use shipped::envelope::ENVELOPE;
use shipped::policy::{POLICY, RIG};
use shipped::policy_int::POLICY_INT;

/// Serves the link until the host closes it: every frame answered, the period timed on a
/// clock of `clock_hz` (`now`, with `since` its difference) from the frame's last byte to
/// the command. Whether the link ended cleanly.
fn serve(
    clock_hz: u32,
    mut read: impl FnMut() -> Option<u8>,
    mut write: impl FnMut(&[u8]) -> bool,
    now: impl Fn() -> u32,
    since: impl Fn(u32, u32) -> u32,
) -> bool {
    let mut target = Target::new(&POLICY, &POLICY_INT, RIG, ENVELOPE, clock_hz);
    while let Some(byte) = read() {
        let arrived = now();
        if let Some(answer) = target.receive(byte, || since(arrived, now()))
            && !write(answer)
        {
            return false;
        }
    }
    true
}

/// What the architecture's entry runs: the link, on the semihosting console. Whether it
/// ended cleanly.
#[cfg(target_os = "none")]
fn run<B: port::Clock>(board: &mut B) -> bool {
    let Some(mut port) = port::Port::open() else {
        return false;
    };
    board.start();
    let port = core::cell::RefCell::new(&mut port);
    serve(
        B::HZ,
        || port.borrow_mut().read(),
        |bytes| port.borrow_mut().write(bytes),
        || board.now(),
        B::since,
    )
}

#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    use std::io::{Read, Write};
    let start = std::time::Instant::now();
    let mut input = std::io::stdin().lock();
    let mut output = std::io::stdout().lock();
    let ok = serve(
        1_000_000_000,
        || {
            let mut b = [0u8];
            input.read_exact(&mut b).ok().map(|()| b[0])
        },
        |bytes| {
            output
                .write_all(bytes)
                .and_then(|()| output.flush())
                .is_ok()
        },
        || start.elapsed().as_nanos() as u32,
        |a, b| b.wrapping_sub(a),
    );
    if ok {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}
