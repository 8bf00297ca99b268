//! Bytes as a target's serial port would receive them, through the link's frame reader and
//! the target's session: no panic on anything, and every packet the reader accepts is one
//! the encoder gives the same bytes for, so nothing is accepted that a host did not send.
#![no_main]

use firmware::link::{FrameReader, MAX_FRAME, Session, frame};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut reader = FrameReader::default();
    let mut session = Session::default();
    for &byte in data {
        let Some(got) = reader.push(byte) else {
            continue;
        };
        if let Ok(packet) = got {
            let mut wire = [0u8; MAX_FRAME];
            let n = frame::encode(&packet, &mut wire);
            let mut again = FrameReader::default();
            let read: Vec<_> = wire[..n].iter().filter_map(|&b| again.push(b)).collect();
            assert_eq!(read, [Ok(packet)]);
        }
        session.accept(got);
    }
});
