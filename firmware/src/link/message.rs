//! The messages, and their bytes inside a frame's payload: a four-byte header (protocol
//! version, kind, sequence number, little-endian) and a body whose length the kind fixes.

use crate::controller::{Command, Duty, FaultFlags};
use crate::network::MAX_OUTPUTS;

pub use super::values::Values;

/// The protocol's version; a frame of another is refused ([`Reason::Version`]).
pub const VERSION: u8 = 3;
/// Version, kind and sequence number.
pub const HEADER_LEN: usize = 4;
/// The longest payload (header and body) of any message.
pub const MAX_PAYLOAD: usize = HEADER_LEN + max_body();

/// What a message says. The host sends [`Message::Hello`], [`Message::Start`] and one
/// reading a period ([`Message::State`], [`Message::Counts`] or [`Message::Missed`]); the
/// target answers each,
/// with [`Message::Info`], [`Message::Started`] and [`Message::Reply`], or with
/// [`Message::Refused`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Message {
    /// Host: which policy of this format, and which rig, do you hold? The format is the
    /// one the episodes that follow run.
    Hello(Format),
    /// Host: a new episode; reset the controller, its sensor and its predictor.
    Start(Start),
    /// Host: this period's exact state, `[x, x_dot, theta, theta_dot]` (state-fed modes).
    State([f32; 4]),
    /// Host: this period's encoder counts (what a board's timers hold).
    Counts {
        /// Cart encoder.
        cart: i32,
        /// Pole encoder.
        pole: i32,
    },
    /// Host: this period's reading did not arrive (a dropped reading): the target runs the
    /// period on a sensor error.
    Missed,
    /// Target: what it holds.
    Info(Info),
    /// Target: the episode has started.
    Started,
    /// Target: what it drives this period.
    Reply(Reply),
    /// Target: the request (or a corrupted frame) was refused, and the motor is off.
    Refused(Reason),
}

/// What a target holds: the answer to [`Message::Hello`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Info {
    /// The policy's arithmetic.
    pub format: Format,
    /// The policy's hidden width.
    pub hidden: u16,
    /// [`super::digest::policy`]: the network's digest ([`super::digest::mlp`] or
    /// [`super::digest::qmlp`]) with the duty levels its outputs drive.
    pub policy: u64,
    /// [`super::digest::rig`] of the rig the target's observer and predictor model.
    pub rig: u64,
    /// The control period the target was built for, ns.
    pub period_ns: u32,
    /// The clock [`Reply::ticks`] counts, Hz.
    pub clock_hz: u32,
}

/// A policy's arithmetic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// f32 network.
    F32,
    /// int8 network on Q3.12 readings.
    Int8,
}

/// How the controller reads the plant: what readings the host sends
/// ([`Message::State`] or [`Message::Counts`]) and what the target estimates the state with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sensing {
    /// The exact state, rounded to f32 (with noise, if any): Gymnasium's observation.
    Exact,
    /// The rig's encoders through the model-based observer, told the commands sent and the
    /// dead time ([`crate::estimator::ObserverSensor`]).
    Observer,
    /// The rig's encoders through the model-free alpha-beta filter of this discount.
    AlphaBeta(f32),
}

impl Sensing {
    /// Whether readings of this sensing are encoder counts.
    pub fn counts(self) -> bool {
        !matches!(self, Sensing::Exact)
    }
}

/// A new episode's configuration: how it senses, and the one part of the rig a host may
/// set per episode, the dead time (a board configured for its measured latency).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Start {
    /// How readings arrive.
    pub sensing: Sensing,
    /// Whether the controller runs its rig's dead-time predictor.
    pub predict: bool,
    /// Whether the controller runs under the runtime monitor
    /// ([`crate::controller::monitor`]) with the envelope the target holds
    /// ([`Target::new`](super::Target::new): a board's `shipped::envelope::ENVELOPE`), its
    /// observer watching for frozen encoders; refused by a target that holds none.
    pub monitor: bool,
    /// Whether the chosen level is refined between its neighbours
    /// ([`crate::controller::Refined`]); refused by a target of two levels, both ends.
    pub refine: bool,
    /// The periods of dead time the observer and predictor assume, in place of the rig's.
    pub dead_time: u8,
}

/// The policy's scores, one per output, in its arithmetic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scores {
    /// A float policy's Q-values.
    F32(Values<f32>),
    /// An integer policy's outputs.
    I32(Values<i32>),
}

/// One period's answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reply {
    /// What the target drives.
    pub command: Command,
    /// The policy's scores (the controller's "unscored" values when it coasted).
    pub scores: Scores,
    /// Why the reading was rejected, if it was.
    pub faults: FaultFlags,
    /// Ticks of [`Info::clock_hz`] from the reading's arrival to the command.
    pub ticks: u32,
}

/// Why a target refused a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reason {
    /// Another protocol version.
    Version = 1,
    /// An unknown kind.
    Kind = 2,
    /// A body of the wrong length, or a field out of its range.
    Length = 3,
    /// The CRC does not match.
    Crc = 4,
    /// More bytes than the longest frame.
    Oversized = 5,
    /// Not a COBS encoding.
    Encoding = 6,
    /// A reading whose sequence number is not the previous one's plus one.
    Sequence = 7,
    /// A reading before any [`Message::Start`].
    NotStarted = 8,
    /// A reading of the other kind than the episode's [`Sensing`].
    Mode = 9,
    /// A Hello asking for a format the target holds no policy of, or a Start the target's
    /// rig cannot run (its observer or predictor refuses the dead time or the filter).
    Unsupported = 10,
}

const KIND_HELLO: u8 = 0x01;
const KIND_START: u8 = 0x02;
const KIND_STATE: u8 = 0x03;
const KIND_COUNTS: u8 = 0x04;
const KIND_MISSED: u8 = 0x05;
const KIND_INFO: u8 = 0x81;
const KIND_STARTED: u8 = 0x82;
const KIND_REPLY: u8 = 0x83;
const KIND_REFUSED: u8 = 0xFF;

/// A reply's body before its scores: duty, fault flags, ticks, scores' type, count.
const REPLY_FIXED: usize = 10;

/// Every kind and its body's length (a reply's longest, with [`MAX_OUTPUTS`] scores): the
/// one table both directions use.
const KINDS: [(u8, usize); 9] = [
    (KIND_HELLO, 1),
    (KIND_START, 7),
    (KIND_STATE, 16),
    (KIND_COUNTS, 8),
    (KIND_MISSED, 0),
    (KIND_INFO, 27),
    (KIND_STARTED, 0),
    (KIND_REPLY, REPLY_FIXED + 4 * MAX_OUTPUTS),
    (KIND_REFUSED, 1),
];

const fn max_body() -> usize {
    let (mut i, mut max) = (0, 0);
    while i < KINDS.len() {
        if KINDS[i].1 > max {
            max = KINDS[i].1;
        }
        i += 1;
    }
    max
}

/// Whether a body of `len` bytes fits `kind`: its length, or for a reply, one its count
/// (checked as the reply is read) may give.
fn body_fits(kind: u8, len: usize) -> Option<bool> {
    let max = KINDS.iter().find(|k| k.0 == kind)?.1;
    Some(match kind {
        KIND_REPLY => (REPLY_FIXED + 4..=max).contains(&len),
        _ => len == max,
    })
}

/// A message and its sequence number: what one frame carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Packet {
    /// The host numbers its requests; a reply carries its request's number.
    pub seq: u16,
    /// The message.
    pub message: Message,
}

impl Packet {
    /// The payload's bytes, at the front of `out`; their number.
    pub fn encode(&self, out: &mut [u8; MAX_PAYLOAD]) -> usize {
        let kind = self.message.kind();
        let mut w = Writer { out, len: 0 };
        w.put(&[VERSION, kind]);
        w.put(&self.seq.to_le_bytes());
        self.message.encode_body(&mut w);
        w.len
    }

    /// The packet in `payload`, or why it is refused.
    pub fn decode(payload: &[u8]) -> Result<Packet, Reason> {
        let (header, body) = payload.split_at_checked(HEADER_LEN).ok_or(Reason::Length)?;
        if header[0] != VERSION {
            return Err(Reason::Version);
        }
        let kind = header[1];
        if !body_fits(kind, body.len()).ok_or(Reason::Kind)? {
            return Err(Reason::Length);
        }
        let seq = u16::from_le_bytes([header[2], header[3]]);
        let message = Message::decode_body(kind, &mut Reader(body)).ok_or(Reason::Length)?;
        Ok(Packet { seq, message })
    }
}

impl Message {
    fn kind(&self) -> u8 {
        match self {
            Message::Hello(_) => KIND_HELLO,
            Message::Start(_) => KIND_START,
            Message::State(_) => KIND_STATE,
            Message::Counts { .. } => KIND_COUNTS,
            Message::Missed => KIND_MISSED,
            Message::Info(_) => KIND_INFO,
            Message::Started => KIND_STARTED,
            Message::Reply(_) => KIND_REPLY,
            Message::Refused(_) => KIND_REFUSED,
        }
    }

    fn encode_body(&self, w: &mut Writer<'_>) {
        match self {
            Message::Missed | Message::Started => {}
            Message::Hello(format) => w.put(&[*format as u8]),
            Message::Start(s) => {
                let (code, discount) = match s.sensing {
                    Sensing::Exact => (0, 0.0),
                    Sensing::Observer => (1, 0.0),
                    Sensing::AlphaBeta(d) => (2, d),
                };
                let options =
                    u8::from(s.predict) | u8::from(s.monitor) << 1 | u8::from(s.refine) << 2;
                w.put(&[code, options, s.dead_time]);
                w.put(&f32::to_le_bytes(discount));
            }
            Message::State(v) => v.iter().for_each(|x| w.put(&x.to_le_bytes())),
            Message::Counts { cart, pole } => {
                w.put(&cart.to_le_bytes());
                w.put(&pole.to_le_bytes());
            }
            Message::Info(i) => {
                w.put(&[i.format as u8]);
                w.put(&i.hidden.to_le_bytes());
                w.put(&i.policy.to_le_bytes());
                w.put(&i.rig.to_le_bytes());
                w.put(&i.period_ns.to_le_bytes());
                w.put(&i.clock_hz.to_le_bytes());
            }
            Message::Reply(r) => {
                w.put(&command_code(r.command).to_le_bytes());
                w.put(&r.faults.0.to_le_bytes());
                w.put(&r.ticks.to_le_bytes());
                match r.scores {
                    Scores::F32(q) => {
                        w.put(&[0, q.as_slice().len() as u8]);
                        q.as_slice().iter().for_each(|x| w.put(&x.to_le_bytes()));
                    }
                    Scores::I32(q) => {
                        w.put(&[1, q.as_slice().len() as u8]);
                        q.as_slice().iter().for_each(|x| w.put(&x.to_le_bytes()));
                    }
                }
            }
            Message::Refused(reason) => w.put(&[*reason as u8]),
        }
    }

    /// The body of a message of `kind`, whose length was checked; `None` for a field out
    /// of its range.
    fn decode_body(kind: u8, r: &mut Reader<'_>) -> Option<Message> {
        Some(match kind {
            KIND_HELLO => Message::Hello(format(r.u8()?)?),
            KIND_STARTED => Message::Started,
            KIND_MISSED => Message::Missed,
            KIND_START => Message::Start(decode_start(r)?),
            KIND_STATE => Message::State([r.f32()?, r.f32()?, r.f32()?, r.f32()?]),
            KIND_COUNTS => Message::Counts {
                cart: r.i32()?,
                pole: r.i32()?,
            },
            KIND_INFO => Message::Info(Info {
                format: format(r.u8()?)?,
                hidden: u16::from_le_bytes(r.bytes()?),
                policy: u64::from_le_bytes(r.bytes()?),
                rig: u64::from_le_bytes(r.bytes()?),
                period_ns: r.u32()?,
                clock_hz: r.u32()?,
            }),
            KIND_REPLY => Message::Reply(decode_reply(r)?),
            KIND_REFUSED => Message::Refused(reason(r.u8()?)?),
            _ => return None,
        })
    }
}

fn decode_start(r: &mut Reader<'_>) -> Option<Start> {
    let (code, options, dead_time) = (r.u8()?, r.u8()?, r.u8()?);
    if options > 0b111 {
        return None;
    }
    let discount = r.f32()?;
    let sensing = match (code, discount.to_bits()) {
        (0, 0) => Sensing::Exact,
        (1, 0) => Sensing::Observer,
        (2, _) => Sensing::AlphaBeta(discount),
        _ => return None,
    };
    Some(Start {
        sensing,
        predict: options & 1 != 0,
        monitor: options & 0b10 != 0,
        refine: options & 0b100 != 0,
        dead_time,
    })
}

fn format(b: u8) -> Option<Format> {
    [Format::F32, Format::Int8].get(b as usize).copied()
}

/// A reply's body; `None` for a duty, a scores' type or a count out of its range, or a
/// count the body's length disagrees with.
fn decode_reply(r: &mut Reader<'_>) -> Option<Reply> {
    let command = match i16::from_le_bytes(r.bytes()?) {
        COAST => Command::Coast,
        t => Command::Drive(Duty::from_thousandths(t)?),
    };
    let faults = FaultFlags(u16::from_le_bytes(r.bytes()?));
    let ticks = r.u32()?;
    let (kind, n) = (r.u8()?, usize::from(r.u8()?));
    if !(1..=MAX_OUTPUTS).contains(&n) || r.0.len() != 4 * n {
        return None;
    }
    let scores = match kind {
        0 => Scores::F32(Values::from_fn(n, || r.bytes().map(f32::from_le_bytes))?),
        1 => Scores::I32(Values::from_fn(n, || r.bytes().map(i32::from_le_bytes))?),
        _ => return None,
    };
    Some(Reply {
        command,
        scores,
        faults,
        ticks,
    })
}

/// A reply's duty code of a coast: no duty a level can have.
const COAST: i16 = i16::MIN;

/// A reply's duty code: the duty in thousandths of the full push, or [`COAST`].
fn command_code(c: Command) -> i16 {
    match c {
        Command::Drive(d) => d.thousandths(),
        Command::Coast => COAST,
    }
}

fn reason(b: u8) -> Option<Reason> {
    use Reason::*;
    [
        Version,
        Kind,
        Length,
        Crc,
        Oversized,
        Encoding,
        Sequence,
        NotStarted,
        Mode,
        Unsupported,
    ]
    .into_iter()
    .find(|r| *r as u8 == b)
}

struct Writer<'a> {
    out: &'a mut [u8; MAX_PAYLOAD],
    len: usize,
}

impl Writer<'_> {
    /// Every body fits by [`MAX_PAYLOAD`]'s definition; the tests encode each kind.
    fn put(&mut self, bytes: &[u8]) {
        let end = self.len + bytes.len();
        if let Some(dst) = self.out.get_mut(self.len..end) {
            dst.copy_from_slice(bytes);
            self.len = end;
        }
    }
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn bytes<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, rest) = self.0.split_first_chunk::<N>()?;
        self.0 = rest;
        Some(*head)
    }
    fn u8(&mut self) -> Option<u8> {
        self.bytes::<1>().map(|[b]| b)
    }
    fn u32(&mut self) -> Option<u32> {
        self.bytes().map(u32::from_le_bytes)
    }
    fn i32(&mut self) -> Option<i32> {
        self.bytes().map(i32::from_le_bytes)
    }
    fn f32(&mut self) -> Option<f32> {
        self.bytes().map(f32::from_le_bytes)
    }
}
