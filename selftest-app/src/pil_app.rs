//! What both processor-in-the-loop applications run (`pil` with the shipped policy,
//! `pil-desk` with the nine-level desk policy): the link served by the target their root
//! builds (`crate::target`), over QEMU's semihosting console (`port`), or, built for the
//! host, on standard input and output.

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
    let mut target = crate::target(clock_hz);
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
pub(crate) fn run<B: crate::port::Clock>(board: &mut B) -> bool {
    let Some(mut port) = crate::port::Port::open() else {
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

/// What the application built for the host runs: the link on standard input and output,
/// timed in nanoseconds.
#[cfg(not(target_os = "none"))]
pub(crate) fn main() -> std::process::ExitCode {
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
