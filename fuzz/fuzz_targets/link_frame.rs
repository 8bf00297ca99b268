//! Bytes as a target's serial port would receive them, through the link's frame reader and
//! the target that runs the controller on them (its session, its controller in either
//! format, its observer, filter and predictor built from what Start says): no panic on
//! anything, every answer one the encoder can send, and every packet the reader accepts
//! one the encoder gives the same bytes for, so nothing is accepted that a host did not
//! send.
#![no_main]

use firmware::link::{FrameReader, MAX_FRAME, Packet, Target, frame};
use shipped::envelope::ENVELOPE;
use shipped::policy::{POLICY, RIG};
use shipped::policy_int::POLICY_INT;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut reader = FrameReader::default();
    let mut target = Target::new(&POLICY, &POLICY_INT, RIG, ENVELOPE, 1);
    for &byte in data {
        let Some(got) = reader.push(byte) else {
            continue;
        };
        if let Ok(packet) = got {
            assert_eq!(round_trip(&packet), wire(&packet));
        }
        let answer = target.handle(got, || 0);
        assert_eq!(round_trip(&answer), wire(&answer));
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
