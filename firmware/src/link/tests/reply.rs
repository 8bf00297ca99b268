//! A reply's scores: one to `MAX_OUTPUTS` of them, their count in the body.

extern crate std;
use std::vec::Vec;

use super::{cobs_encoded, received};
use crate::controller::{Command, Duty, FaultFlags};
use crate::link::*;
use crate::network::MAX_OUTPUTS;

fn reply(command: Command, scores: Scores) -> Packet {
    Packet {
        seq: 0x0102,
        message: Message::Reply(Reply {
            command,
            scores,
            faults: FaultFlags(0x0301),
            ticks: 5,
        }),
    }
}

fn payload(p: &Packet) -> Vec<u8> {
    let mut out = [0u8; MAX_PAYLOAD];
    let n = p.encode(&mut out);
    out[..n].to_vec()
}

/// What the reader makes of `payload` with its CRC, framed.
fn read(payload: &[u8]) -> Vec<Result<Packet, Reason>> {
    let mut raw = payload.to_vec();
    raw.extend_from_slice(&crc::crc32(payload).to_le_bytes());
    let mut bytes = cobs_encoded(&raw);
    bytes.push(0);
    received(&bytes)
}

/// The payload's header and fixed fields as docs/LINK.md gives them: version 3, kind
/// `0x83`, sequence `0x0102`, duty, faults `0x0301`, ticks 5, scores' type and count.
fn head(duty: [u8; 2], kind: u8, count: u8) -> Vec<u8> {
    [
        &[3, 0x83, 0x02, 0x01][..],
        &duty,
        &[0x01, 0x03, 5, 0, 0, 0, kind, count],
    ]
    .concat()
}

#[test]
fn replies_of_one_two_and_the_most_scores_read_back_in_both_arithmetics() {
    assert_eq!(MAX_OUTPUTS, 9);
    let f: Vec<f32> = (0..9).map(|i| -1.5 + i as f32 * 0.375).collect();
    let n: Vec<i32> = (0..9)
        .map(|i: i32| i32::MIN.wrapping_add(i.wrapping_mul(0x1234_5678)))
        .collect();
    for count in [1, 2, 9] {
        for scores in [
            Scores::F32(Values::new(&f[..count]).unwrap()),
            Scores::I32(Values::new(&n[..count]).unwrap()),
        ] {
            for command in [Command::Drive(Duty::LEFT), Command::Coast] {
                let p = reply(command, scores);
                let bytes = payload(&p);
                assert_eq!(bytes.len(), 4 + 10 + 4 * count);
                assert_eq!(read(&bytes), [Ok(p)], "{count} scores");
            }
        }
    }
}

#[test]
fn a_reply_has_the_bytes_the_protocol_document_gives() {
    let two = reply(
        Command::Drive(Duty::RIGHT),
        Scores::F32(Values::of([1.0, -2.0])),
    );
    let want = [
        head([0xE8, 0x03], 0, 2),
        std::vec![0, 0, 0x80, 0x3F, 0, 0, 0, 0xC0],
    ]
    .concat();
    assert_eq!(payload(&two), want);
    assert_eq!(read(&want), [Ok(two)]);
    let one = reply(Command::Coast, Scores::I32(Values::of([-1])));
    let want = [head([0x00, 0x80], 1, 1), std::vec![0xFF; 4]].concat();
    assert_eq!(payload(&one), want);
    // A duty of 0.2 (200 thousandths): a level between the full pushes.
    let fifth = Command::Drive(Duty::from_fraction(0.2).unwrap());
    let want = [head([0xC8, 0x00], 1, 1), std::vec![0xFF; 4]].concat();
    assert_eq!(
        read(&want),
        [Ok(reply(fifth, Scores::I32(Values::of([-1]))))]
    );
}

#[test]
fn a_reply_whose_count_or_fields_are_out_of_range_or_disagree_with_its_length_is_refused() {
    let scores = |n: usize| std::vec![0x11u8; 4 * n];
    let refused = [Err(Reason::Length)];
    let right = [0xE8, 0x03];
    // Count 0, with no scores and with one.
    assert_eq!(read(&head(right, 0, 0)), refused);
    assert_eq!(read(&[head(right, 0, 0), scores(1)].concat()), refused);
    // One more than the most: with the most scores; with as many, the frame is longer
    // than the longest.
    let over = MAX_OUTPUTS as u8 + 1;
    assert_eq!(read(&[head(right, 1, over), scores(9)].concat()), refused);
    assert_eq!(
        read(&[head(right, 1, over), scores(10)].concat()),
        [Err(Reason::Oversized)]
    );
    // A count the length disagrees with, either way.
    assert_eq!(read(&[head(right, 0, 2), scores(3)].concat()), refused);
    assert_eq!(read(&[head(right, 0, 3), scores(2)].concat()), refused);
    // A good reply cut short, in its scores and in its fixed fields.
    let good = [head(right, 0, 2), scores(2)].concat();
    assert!(read(&good)[0].is_ok());
    assert_eq!(read(&good[..good.len() - 1]), refused);
    assert_eq!(read(&good[..4 + 9]), refused);
    // A duty beyond the full push, a scores' type the protocol has not.
    assert_eq!(
        read(&[head([0xE9, 0x03], 0, 2), scores(2)].concat()),
        refused
    );
    assert_eq!(read(&[head(right, 2, 2), scores(2)].concat()), refused);
}
