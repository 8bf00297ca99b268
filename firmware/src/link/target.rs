//! A target that runs the board's controller for a host's world: the policy in either
//! format, its rig's observer or filter, predictor and limits, one controller period per
//! reading, the time each took. What a processor- or hardware-in-the-loop build runs
//! between its serial port and its clock; the host's software-in-the-loop check runs the
//! same code.

use crate::controller::{
    Assurance, Controller, FaultFlags, Greedy, Levels, Limits, Policy, Refinable, Scores as _,
    StateSensor,
};
use crate::estimator::{Estimate, Observer};
use crate::loopback::{Pins, pins};
use crate::network::Mlp;
use crate::network::int::QMlp;
use crate::rig::{Options, Rig};

use super::frame::{self, FrameReader, MAX_FRAME};
use super::message::{Format, Info, Message, Packet, Reason, Reply, Scores, Start, Values};
use super::sensor::LinkSensor;
use super::session::{Request, Session};
use super::{Measurement, digest};

/// What a target holds: both formats of its policy of width `H` and `A` outputs, the duty
/// level each output drives (the paper's two by default), the rig it was built for and the
/// policy's envelope.
pub struct Target<'p, const H: usize, const A: usize = 2> {
    policy: Greedy<&'p Mlp<H, A>, A>,
    policy_int: Greedy<&'p QMlp<H, A>, A>,
    rig: Rig,
    envelope: Option<Limits>,
    clock_hz: u32,
    session: Session,
    reader: FrameReader,
    out: [u8; MAX_FRAME],
    refused: u32,
    format: Format,
    running: Running<'p, H, A>,
    /// The last observer built, and the dead time it was built for: a Start with the same
    /// dead time copies it rather than solving its gain again.
    observer: Option<(u8, Observer)>,
    /// The runtime monitor's configuration, once a Start asked for it: its LQR gain is
    /// solved once (it depends on the rig's plant, not on the dead time a Start sets).
    assurance: Option<Assurance>,
}

/// `rig`'s control period in whole nanoseconds, as `Info` carries it.
pub fn period_ns(rig: &Rig) -> u32 {
    libm::round(rig.params.tau * 1e9) as u32
}

type Float<'p, const H: usize, const A: usize> =
    Controller<Refinable<Greedy<&'p Mlp<H, A>, A>>, LinkSensor<[f32; 4]>, Pins>;
type Int<'p, const H: usize, const A: usize> =
    Controller<Refinable<Greedy<&'p QMlp<H, A>, A>>, LinkSensor<[i16; 4]>, Pins>;

/// The episode's controller, in the format Hello asked for.
enum Running<'p, const H: usize, const A: usize> {
    Idle,
    F32(Float<'p, H, A>),
    Int8(Int<'p, H, A>),
}

impl<'p, const H: usize, const A: usize> Target<'p, H, A> {
    /// A target holding `policy`, its integer version `policy_int`, the duty `levels` their
    /// outputs drive, `rig` and the envelope its runtime monitor lets the policy drive in
    /// (the board's `POLICY`, `POLICY_INT`, `LEVELS`, `RIG` and `ENVELOPE`; with no
    /// envelope, a Start that asks for the monitor is refused, and with two levels one that
    /// asks for them refined), timing periods on a clock of `clock_hz` ticks a second.
    pub fn new(
        policy: &'p Mlp<H, A>,
        policy_int: &'p QMlp<H, A>,
        levels: Levels<A>,
        rig: Rig,
        envelope: Option<Limits>,
        clock_hz: u32,
    ) -> Self {
        Target {
            policy: Greedy {
                net: policy,
                levels,
            },
            policy_int: Greedy {
                net: policy_int,
                levels,
            },
            rig,
            envelope,
            clock_hz,
            session: Session::default(),
            reader: FrameReader::default(),
            out: [0; MAX_FRAME],
            refused: 0,
            format: Format::F32,
            running: Running::Idle,
            observer: None,
            assurance: None,
        }
    }

    /// Takes one byte as it arrives; at a frame's end, the answer's bytes to send. `elapsed`
    /// reads the clock's ticks since this byte arrived (see [`Target::handle`]).
    pub fn receive(&mut self, byte: u8, elapsed: impl Fn() -> u32) -> Option<&[u8]> {
        let frame = self.reader.push(byte)?;
        let answer = self.handle(frame, elapsed);
        let n = frame::encode(&answer, &mut self.out);
        self.out.get(..n)
    }

    /// The answer to one frame as the reader gave it. `elapsed` reads the clock's ticks
    /// since the frame's last byte arrived: a reply's ticks are its reading at the command.
    pub fn handle(&mut self, frame: Result<Packet, Reason>, elapsed: impl Fn() -> u32) -> Packet {
        let (seq, request) = self.session.accept(frame);
        let message = match request {
            Request::Hello(format) => {
                self.format = format;
                self.running = Running::Idle;
                Message::Info(self.info())
            }
            Request::Start(start) => match self.start(start) {
                Some(running) => {
                    self.running = running;
                    Message::Started
                }
                None => self.refuse(Reason::Unsupported),
            },
            Request::Period(m) => match self.period(m) {
                Some(mut reply) => {
                    reply.ticks = elapsed();
                    Message::Reply(reply)
                }
                None => self.refuse(Reason::NotStarted),
            },
            Request::Refuse(reason) => self.refuse(reason),
        };
        Packet { seq, message }
    }

    /// Frames refused so far (saturating): a board logs them when its link ends.
    pub fn refused(&self) -> u32 {
        self.refused
    }

    /// The rig the target was built for, with the dead time it was built with.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// Whether the target's policy has levels between its ends, so that a Start may ask for
    /// them refined.
    pub fn refines(&self) -> bool {
        self.policy.refinable()
    }

    /// Whether the target holds an envelope, so that a Start may ask for the runtime
    /// monitor.
    pub fn monitors(&self) -> bool {
        self.envelope.is_some()
    }

    fn info(&self) -> Info {
        let (format, network) = match self.format {
            Format::F32 => (Format::F32, digest::mlp(self.policy.net)),
            Format::Int8 => (Format::Int8, digest::qmlp(self.policy_int.net)),
        };
        let policy = digest::policy(network, &self.policy.levels);
        Info {
            format,
            hidden: H as u16,
            policy,
            rig: digest::rig(&self.rig),
            period_ns: period_ns(&self.rig),
            clock_hz: self.clock_hz,
        }
    }

    /// The episode's controller: the rig with the Start's dead time, its sensor, limits and
    /// (if asked) predictor and runtime monitor, with the policy's envelope, its levels
    /// refined if asked; `None` for a Start the rig refuses, one that asks for a monitor
    /// without an envelope, or refined levels the controller refuses (two levels, or under
    /// the monitor: [`Controller::refine`]).
    fn start(&mut self, start: Start) -> Option<Running<'p, H, A>> {
        let rig = Rig {
            dead_time: u32::from(start.dead_time),
            ..self.rig
        }
        .check()
        .ok()?;
        let monitor = match (start.monitor, self.assurance, self.envelope) {
            (false, ..) => None,
            (true, Some(a), _) => Some(a),
            (true, None, Some(e)) => Some(*self.assurance.insert(rig.lqr_assurance(e).ok()?)),
            (true, None, None) => return None,
        };
        let cache = &mut self.observer;
        let observer = || {
            let o = match cache {
                Some((d, o)) if *d == start.dead_time => o.clone(),
                _ => {
                    let o = rig.observer()?;
                    *cache = Some((start.dead_time, o.clone()));
                    o
                }
            };
            Ok(if start.monitor { o.watching() } else { o })
        };
        let options = Options {
            predict: start.predict,
            monitor,
        };
        let mut running = match self.format {
            Format::F32 => Running::F32(
                rig.controller(
                    Refinable {
                        policy: self.policy,
                        refine: false,
                    },
                    LinkSensor::new(start.sensing, &rig, observer).ok()?,
                    pins(),
                    options,
                )
                .ok()?,
            ),
            Format::Int8 => Running::Int8(
                rig.controller(
                    Refinable {
                        policy: self.policy_int,
                        refine: false,
                    },
                    LinkSensor::new(start.sensing, &rig, observer).ok()?,
                    pins(),
                    options,
                )
                .ok()?,
            ),
        };
        let refined = match &mut running {
            Running::Idle => Ok(()),
            Running::F32(c) => c.refine(start.refine),
            Running::Int8(c) => c.refine(start.refine),
        };
        refined.ok().map(|()| running)
    }

    /// One controller period on `m`; `None` when no episode runs.
    fn period(&mut self, m: Measurement) -> Option<Reply> {
        Some(match &mut self.running {
            Running::Idle => return None,
            Running::F32(c) => step(c, m, |q| Scores::F32(Values::of(q))),
            Running::Int8(c) => step(c, m, |q| Scores::I32(Values::of(q))),
        })
    }

    /// Ends the episode (the motor is off, and readings are refused, until the next Start),
    /// counts the refusal and answers `reason`.
    fn refuse(&mut self, reason: Reason) -> Message {
        self.running = Running::Idle;
        self.session.stop();
        self.refused = self.refused.saturating_add(1);
        Message::Refused(reason)
    }
}

fn step<P, O: Estimate>(
    c: &mut Controller<P, LinkSensor<O>, Pins>,
    m: Measurement,
    scores: impl Fn(P::Scores) -> Scores,
) -> Reply
where
    P: Policy<O>,
    LinkSensor<O>: StateSensor<Reading = O>,
{
    c.sensor_mut().set(m);
    let command = c.step();
    let last = c.last();
    Reply {
        command,
        scores: scores(last.map_or(P::Scores::UNSCORED, |r| r.q)),
        faults: last.map_or(FaultFlags::SENSOR_ERROR, |r| r.faults),
        ticks: 0,
    }
}

#[cfg(test)]
mod tests;
