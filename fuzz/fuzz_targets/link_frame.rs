//! Bytes as a target's serial port would receive them, through the link's frame reader and
//! the targets that run the controller on them, the shipped policy's and the nine-level desk
//! policy's (each its session, its controller in either format, its observer, filter and
//! predictor built from what Start says): no panic on anything, every answer one the
//! encoder can send, and every packet the reader accepts one the encoder gives the same
//! bytes for, so nothing is accepted that a host did not send.
#![no_main]

use firmware::link::{FrameReader, MAX_FRAME, Packet, frame};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut reader = FrameReader::default();
    let mut target = shipped::target(1);
    let mut desk = shipped::desk_target(1);
    for &byte in data {
        let Some(got) = reader.push(byte) else {
            continue;
        };
        if let Ok(packet) = got {
            assert_eq!(round_trip(&packet), wire(&packet));
        }
        for answer in [target.handle(got, || 0), desk.handle(got, || 0)] {
            assert_eq!(round_trip(&answer), wire(&answer));
        }
    }
});

fn wire(p: &Packet) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = frame::encode(p, &mut out);
    out[..n].to_vec()
}

/// The bytes of `p` read back and written again (compared as bytes: a score may be NaN).
fn round_trip(p: &Packet) -> Vec<u8> {
    let mut reader = FrameReader::default();
    let read: Vec<_> = wire(p).iter().filter_map(|&b| reader.push(b)).collect();
    match read[..] {
        [Ok(again)] => wire(&again),
        _ => panic!("{p:?} read back as {read:?}"),
    }
}
