//! The target's side of the exchange (`docs/LINK.md`, "The exchange" and "Faults"): which
//! frames it acts on, which it refuses and why. The board does the acting
//! ([`super::target::Target`] for one that runs the controller): it answers
//! [`Request::Hello`] with its `Info`, resets its controller on [`Request::Start`], runs one
//! period on a reading, and drives the motor off on [`Request::Refuse`].

use super::message::{Format, Message, Packet, Reason, Start};

/// What the target is asked to do, after the session's checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// Answer with `Info` for a policy of this format, which the episodes that follow run.
    Hello(Format),
    /// Reset the controller, its sensor and its predictor for an episode; answer `Started`.
    Start(Start),
    /// Run one period on this measurement; answer `Reply`.
    Period(Measurement),
    /// Drive the motor off and answer `Refused` with this reason.
    Refuse(Reason),
}

/// What the sensors report in one period: what a host's world sends, and what a board's
/// sensor is handed ([`super::LinkSensor::set`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Measurement {
    /// The state, as an exact sensor reads it.
    State([f32; 4]),
    /// Encoder counts `(cart, pole)`.
    Counts(i32, i32),
    /// No reading arrived (a dropped reading): the sensor returns an error.
    Missing,
}

/// The target's state between frames.
#[derive(Clone, Copy, Debug, Default)]
pub struct Session {
    hello: bool,
    start: Option<Start>,
    seq: u16,
}

impl Session {
    /// What to do with one frame as the reader gave it, and the sequence number the answer
    /// carries (the last good one, for a frame that could not be read).
    pub fn accept(&mut self, frame: Result<Packet, Reason>) -> (u16, Request) {
        let packet = match frame {
            Ok(p) => p,
            Err(reason) => return self.refuse(self.seq, reason),
        };
        let seq = packet.seq;
        let m = match packet.message {
            Message::Hello(format) => {
                (self.seq, self.hello, self.start) = (seq, true, None);
                return (seq, Request::Hello(format));
            }
            Message::Start(_) if !self.hello => return self.refuse(seq, Reason::NotStarted),
            Message::Start(start) => {
                (self.seq, self.start) = (seq, Some(start));
                return (seq, Request::Start(start));
            }
            Message::State(v) => Measurement::State(v),
            Message::Counts { cart, pole } => Measurement::Counts(cart, pole),
            Message::Missed => Measurement::Missing,
            // A target-to-host kind sent to the target.
            _ => return self.refuse(seq, Reason::Kind),
        };
        let Some(start) = self.start else {
            return self.refuse(seq, Reason::NotStarted);
        };
        if matches!(m, Measurement::Counts(..)) != start.sensing.counts()
            && m != Measurement::Missing
        {
            return self.refuse(seq, Reason::Mode);
        }
        if seq != self.seq.wrapping_add(1) {
            return self.refuse(seq, Reason::Sequence);
        }
        self.seq = seq;
        (seq, Request::Period(m))
    }

    /// Ends the episode after a refusal, the session's or the target's: readings are
    /// refused until the next Start.
    pub fn stop(&mut self) {
        self.start = None;
    }

    fn refuse(&mut self, seq: u16, reason: Reason) -> (u16, Request) {
        (seq, Request::Refuse(reason))
    }
}
