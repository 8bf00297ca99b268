extern crate std;
use std::vec::Vec;

use rand_core::Rng;
use rand_pcg::Pcg64Mcg;

use super::*;
use crate::controller::{Command, Duty, FaultFlags};
use crate::network::MAX_OUTPUTS;

mod reply;

/// The bit-at-a-time definition the nibble table must agree with.
fn crc32_bitwise(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 == 1 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn crc32_gives_the_catalogue_check_value_and_the_bitwise_definition() {
    assert_eq!(crc::crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc::crc32(b""), 0);
    let mut rng = Pcg64Mcg::new(7);
    for len in 0..200 {
        let data: Vec<u8> = (0..len).map(|_| rng.next_u32() as u8).collect();
        assert_eq!(crc::crc32(&data), crc32_bitwise(&data), "length {len}");
    }
}

pub(super) fn cobs_encoded(input: &[u8]) -> Vec<u8> {
    let mut out = std::vec![0u8; cobs::max_encoded_len(input.len())];
    let n = cobs::encode(input, &mut out).unwrap();
    out.truncate(n);
    out
}

#[test]
fn cobs_encodes_the_published_examples() {
    let up = |a: u8, b: u8| (a..=b).collect::<Vec<u8>>();
    let cat = |parts: &[&[u8]]| parts.concat();
    // The examples of COBS's Wikipedia article, delimiter left off.
    let cases: Vec<(Vec<u8>, Vec<u8>)> = std::vec![
        (std::vec![0x00], std::vec![0x01, 0x01]),
        (std::vec![0x00, 0x00], std::vec![0x01, 0x01, 0x01]),
        (
            std::vec![0x00, 0x11, 0x00],
            std::vec![0x01, 0x02, 0x11, 0x01]
        ),
        (
            std::vec![0x11, 0x22, 0x00, 0x33],
            std::vec![0x03, 0x11, 0x22, 0x02, 0x33]
        ),
        (
            std::vec![0x11, 0x22, 0x33, 0x44],
            std::vec![0x05, 0x11, 0x22, 0x33, 0x44]
        ),
        (
            std::vec![0x11, 0x00, 0x00, 0x00],
            std::vec![0x02, 0x11, 0x01, 0x01, 0x01]
        ),
        (up(0x01, 0xFE), cat(&[&[0xFF], &up(0x01, 0xFE)])),
        (
            cat(&[&[0x00], &up(0x01, 0xFE)]),
            cat(&[&[0x01, 0xFF], &up(0x01, 0xFE)])
        ),
        (
            up(0x01, 0xFF),
            cat(&[&[0xFF], &up(0x01, 0xFE), &[0x02, 0xFF]])
        ),
        (
            cat(&[&up(0x02, 0xFF), &[0x00]]),
            cat(&[&[0xFF], &up(0x02, 0xFF), &[0x01, 0x01]])
        ),
        (
            cat(&[&up(0x03, 0xFF), &[0x00, 0x01]]),
            cat(&[&[0xFE], &up(0x03, 0xFF), &[0x02, 0x01]]),
        ),
    ];
    for (input, encoded) in cases {
        assert_eq!(cobs_encoded(&input), encoded, "encoding {input:02x?}");
        let mut buf = encoded.clone();
        let n = cobs::decode_in_place(&mut buf).unwrap();
        assert_eq!(&buf[..n], &input[..], "decoding {encoded:02x?}");
    }
}

#[test]
fn cobs_round_trips_random_bytes_without_zeros_and_refuses_broken_encodings() {
    let mut rng = Pcg64Mcg::new(11);
    for len in 0..700 {
        // Zeros often, so that every block length occurs.
        let input: Vec<u8> = (0..len)
            .map(|_| (rng.next_u32() as u8).saturating_sub(40))
            .collect();
        let encoded = cobs_encoded(&input);
        assert!(!encoded.contains(&0));
        assert!(encoded.len() <= cobs::max_encoded_len(len));
        let mut buf = encoded.clone();
        let n = cobs::decode_in_place(&mut buf).unwrap();
        assert_eq!(&buf[..n], &input[..]);
    }
    assert_eq!(cobs::encode(&[1, 2, 3], &mut [0u8; 3]), None);
    assert_eq!(
        cobs::decode_in_place(&mut [0x03, 0x11]),
        Err(cobs::CobsError::Truncated)
    );
    assert_eq!(
        cobs::decode_in_place(&mut [0x03, 0x00, 0x11]),
        Err(cobs::CobsError::Zero)
    );
    assert_eq!(
        cobs::decode_in_place(&mut [0x01, 0x00]),
        Err(cobs::CobsError::Zero)
    );
}

/// One packet of every kind, with values at the ends of their ranges.
fn every_kind() -> Vec<Packet> {
    let info = Info {
        format: Format::Int8,
        hidden: u16::MAX,
        policy: u64::MAX - 1,
        rig: 0x0102_0304_0506_0708,
        period_ns: 20_000_000,
        clock_hz: 15_625_000,
    };
    let reply = |command, scores| {
        Message::Reply(Reply {
            command,
            scores,
            faults: FaultFlags(0x0301),
            ticks: u32::MAX,
        })
    };
    let messages = [
        Message::Hello(Format::F32),
        Message::Hello(Format::Int8),
        Message::Start(Start {
            sensing: Sensing::Observer,
            predict: true,
            monitor: true,
            refine: true,
            dead_time: u8::MAX,
        }),
        Message::Start(Start {
            sensing: Sensing::Exact,
            predict: false,
            monitor: false,
            refine: false,
            dead_time: 0,
        }),
        Message::Start(Start {
            sensing: Sensing::AlphaBeta(0.5),
            predict: false,
            monitor: false,
            refine: false,
            dead_time: 2,
        }),
        Message::Missed,
        Message::State([f32::MIN, -0.0, f32::INFINITY, 1e-40]),
        Message::Counts {
            cart: i32::MIN,
            pole: i32::MAX,
        },
        Message::Info(info),
        Message::Info(Info {
            format: Format::F32,
            ..info
        }),
        Message::Started,
        reply(
            Command::Drive(Duty::LEFT),
            Scores::F32(Values::of([-1.5, f32::MAX])),
        ),
        reply(
            Command::Drive(Duty::RIGHT),
            Scores::I32(Values::of([i32::MIN, 0])),
        ),
        reply(
            Command::Coast,
            Scores::F32(Values::of([f32::NEG_INFINITY; 2])),
        ),
        reply(
            Command::Drive(Duty::OFF),
            Scores::I32(Values::of([i32::MAX; MAX_OUTPUTS])),
        ),
        Message::Refused(Reason::Mode),
        Message::Refused(Reason::Version),
    ];
    messages
        .into_iter()
        .enumerate()
        .map(|(i, message)| Packet {
            seq: 0xFFF0_u16.wrapping_add(i as u16),
            message,
        })
        .collect()
}

fn wire(p: &Packet) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = frame::encode(p, &mut out);
    out[..n].to_vec()
}

pub(super) fn received(bytes: &[u8]) -> Vec<Result<Packet, Reason>> {
    let mut reader = FrameReader::default();
    bytes.iter().filter_map(|&b| reader.push(b)).collect()
}

#[test]
fn every_kind_survives_the_wire_and_one_frame_holds_the_longest() {
    let packets = every_kind();
    let stream: Vec<u8> = packets.iter().flat_map(wire).collect();
    let got = received(&stream);
    assert_eq!(got, packets.iter().map(|p| Ok(*p)).collect::<Vec<_>>());
    let longest = packets.iter().map(|p| wire(p).len()).max().unwrap();
    assert!(longest <= MAX_FRAME, "{longest} > {MAX_FRAME}");
}

#[test]
fn the_bytes_are_those_the_protocol_document_gives() {
    // docs/LINK.md's example: sequence 7, counts -120 and 2047.
    let p = Packet {
        seq: 7,
        message: Message::Counts {
            cart: -120,
            pole: 2047,
        },
    };
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = p.encode(&mut payload);
    assert_eq!(
        &payload[..n],
        &[3, 0x04, 7, 0, 0x88, 0xFF, 0xFF, 0xFF, 0xFF, 0x07, 0, 0]
    );
}

#[test]
fn every_single_bit_error_is_refused() {
    for p in every_kind() {
        let good = wire(&p);
        for bit in 0..(good.len() - 1) * 8 {
            let mut bad = good.clone();
            bad[bit / 8] ^= 1 << (bit % 8);
            for r in received(&bad) {
                assert!(r.is_err(), "{p:?} with bit {bit} flipped read as {r:?}");
            }
        }
    }
}

#[test]
fn malformed_payloads_are_refused_for_what_they_are() {
    let frame_of = |payload: &[u8]| {
        let mut raw = payload.to_vec();
        raw.extend_from_slice(&crc::crc32(payload).to_le_bytes());
        let mut bytes = cobs_encoded(&raw);
        bytes.push(0);
        received(&bytes)
    };
    assert_eq!(frame_of(&[2, 0x01, 0, 0, 0]), [Err(Reason::Version)]);
    assert_eq!(frame_of(&[3, 0x06, 0, 0]), [Err(Reason::Kind)]);
    // A format, a sensing, an option bit the protocol has not; a discount where no filter
    // runs.
    assert_eq!(frame_of(&[3, 0x01, 0, 0, 2]), [Err(Reason::Length)]);
    let start = |b: [u8; 7]| frame_of(&[&[3, 0x02, 0, 0][..], &b].concat());
    assert_eq!(start([3, 0, 0, 0, 0, 0, 0]), [Err(Reason::Length)]);
    assert_eq!(start([1, 8, 0, 0, 0, 0, 0]), [Err(Reason::Length)]);
    assert_eq!(start([1, 0, 0, 0, 0, 0, 0x3F]), [Err(Reason::Length)]);
    assert_eq!(frame_of(&[3, 0x02, 0, 0, 1, 0]), [Err(Reason::Length)]);
    assert_eq!(frame_of(&[3, 0xFF, 0, 0, 0]), [Err(Reason::Length)]);
    assert_eq!(frame_of(&[3, 0x01, 0]), [Err(Reason::Length)]);
    assert_eq!(
        frame_of(&[3, 0x01, 3, 0, 1]),
        [Ok(Packet {
            seq: 3,
            message: Message::Hello(Format::Int8)
        })]
    );
}

#[test]
fn an_oversized_frame_is_dropped_whole_and_the_next_one_read() {
    let next = Packet {
        seq: 1,
        message: Message::Hello(Format::F32),
    };
    let mut bytes = std::vec![0x55u8; 3 * MAX_FRAME];
    bytes.push(0);
    bytes.extend(wire(&next));
    assert_eq!(received(&bytes), [Err(Reason::Oversized), Ok(next)]);
    // Delimiters in a row are no frames; a frame cut short fails its check.
    let mut cut = wire(&next);
    cut.remove(cut.len() - 3);
    assert_eq!(received(&[0, 0, 0]), []);
    assert!(received(&cut)[0].is_err());
}

#[test]
fn fnv1a_gives_the_published_test_vectors() {
    let d = |s: &[u8]| digest::Fnv::default().bytes(s).finish();
    assert_eq!(d(b""), 0xcbf2_9ce4_8422_2325);
    assert_eq!(d(b"a"), 0xaf63_dc4c_8601_ec8c);
    assert_eq!(d(b"foobar"), 0x8594_4171_f739_67e8);
}

#[test]
fn digests_follow_every_parameter() {
    use crate::shipped::policy::{POLICY, RIG};
    use crate::shipped::policy_int::POLICY_INT;
    let mut m = POLICY.clone();
    m.fc3_bias[1] = f32::from_bits(m.fc3_bias[1].to_bits() ^ 1);
    assert_ne!(digest::mlp(&m), digest::mlp(&POLICY));
    let mut q = POLICY_INT.clone();
    q.fc2_requant[63].post_shift += 1;
    assert_ne!(digest::qmlp(&q), digest::qmlp(&POLICY_INT));
    let mut rig = RIG;
    rig.tuning.accel_sd[1] *= 2.0;
    assert_ne!(digest::rig(&rig), digest::rig(&RIG));
    // The float network's digest is that of its parameters' bytes in layout order, as a
    // host computes it from a weights file.
    let bytes: Vec<u8> = [
        POLICY.fc1_weight.as_flattened(),
        &POLICY.fc1_bias,
        POLICY.fc2_weight.as_flattened(),
        &POLICY.fc2_bias,
        POLICY.fc3_weight.as_flattened(),
        &POLICY.fc3_bias,
    ]
    .concat()
    .iter()
    .flat_map(|x| x.to_le_bytes())
    .collect();
    assert_eq!(bytes.len(), 4 * 4610);
    assert_eq!(
        digest::mlp(&POLICY),
        digest::Fnv::default().bytes(&bytes).finish()
    );
}

#[test]
fn the_documented_sizes_hold() {
    // docs/LINK.md, "Frames".
    assert_eq!((MAX_PAYLOAD, MAX_FRAME), (50, 56));
}

#[test]
fn a_session_acts_on_readings_in_sequence_of_its_mode_and_refuses_the_rest() {
    let mut s = Session::default();
    let p = |seq, message| Ok(Packet { seq, message });
    let counts = Message::Counts { cart: 5, pole: -5 };
    let request = Request::Period(Measurement::Counts(5, -5));
    let start = Start {
        sensing: Sensing::Observer,
        predict: true,
        monitor: false,
        refine: false,
        dead_time: 1,
    };
    assert_eq!(
        s.accept(p(9, counts)),
        (9, Request::Refuse(Reason::NotStarted))
    );
    // A Start before any Hello: the format is not known.
    assert_eq!(
        s.accept(p(9, Message::Start(start))),
        (9, Request::Refuse(Reason::NotStarted))
    );
    let hello = Message::Hello(Format::F32);
    assert_eq!(s.accept(p(40, hello)), (40, Request::Hello(Format::F32)));
    assert_eq!(
        s.accept(p(u16::MAX, Message::Start(start))),
        (u16::MAX, Request::Start(start))
    );
    // The sequence wraps; a missed reading counts in it.
    assert_eq!(s.accept(p(0, counts)), (0, request));
    assert_eq!(
        s.accept(p(1, Message::Missed)),
        (1, Request::Period(Measurement::Missing))
    );
    // A replay, a gap, the other mode, a reply's kind, a frame that could not be read.
    assert_eq!(
        s.accept(p(1, counts)),
        (1, Request::Refuse(Reason::Sequence))
    );
    assert_eq!(
        s.accept(p(3, counts)),
        (3, Request::Refuse(Reason::Sequence))
    );
    let state = Message::State([0.0; 4]);
    assert_eq!(s.accept(p(2, state)), (2, Request::Refuse(Reason::Mode)));
    assert_eq!(
        s.accept(p(2, Message::Started)),
        (2, Request::Refuse(Reason::Kind))
    );
    assert_eq!(
        s.accept(Err(Reason::Crc)),
        (1, Request::Refuse(Reason::Crc))
    );
    // None of the refusals moved the sequence on.
    assert_eq!(s.accept(p(2, counts)), (2, request));
    // A new Hello ends the episode.
    assert_eq!(s.accept(p(5, hello)), (5, Request::Hello(Format::F32)));
    assert_eq!(
        s.accept(p(6, counts)),
        (6, Request::Refuse(Reason::NotStarted))
    );
}
