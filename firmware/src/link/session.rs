//! The target's side of the exchange (`docs/LINK.md`, "The exchange" and "Faults"): which
//! frames it acts on, which it refuses and why. The board does the acting: it answers
//! [`Request::Hello`] with its `Info`, resets its controller on [`Request::Start`], runs one
//! period on a reading, and drives the motor off on [`Request::Refuse`].

use super::message::{Message, Packet, Reason, Sensing, Start};

/// What the target is asked to do, after the session's checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// Answer with `Info`.
    Hello,
    /// Reset the controller, its sensor and its predictor for an episode; answer `Started`.
    Start(Start),
    /// Run one period on this state; answer `Reply`.
    State([f32; 4]),
    /// Run one period on these counts; answer `Reply`.
    Counts {
        /// Cart encoder.
        cart: i32,
        /// Pole encoder.
        pole: i32,
    },
    /// Drive the motor off and answer `Refused` with this reason.
    Refuse(Reason),
}

/// The target's state between frames.
#[derive(Clone, Copy, Debug, Default)]
pub struct Session {
    start: Option<Start>,
    seq: u16,
    refused: u32,
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
        match packet.message {
            Message::Hello => {
                self.seq = seq;
                (seq, Request::Hello)
            }
            Message::Start(start) => {
                self.seq = seq;
                self.start = Some(start);
                (seq, Request::Start(start))
            }
            Message::State(v) => self.reading(seq, Sensing::State, Request::State(v)),
            Message::Counts { cart, pole } => {
                self.reading(seq, Sensing::Encoders, Request::Counts { cart, pole })
            }
            // A target-to-host kind sent to the target.
            _ => self.refuse(seq, Reason::Kind),
        }
    }

    /// Frames refused so far (saturating).
    pub fn refused(&self) -> u32 {
        self.refused
    }

    fn reading(&mut self, seq: u16, sensing: Sensing, request: Request) -> (u16, Request) {
        let Some(start) = self.start else {
            return self.refuse(seq, Reason::NotStarted);
        };
        if start.sensing != sensing {
            return self.refuse(seq, Reason::Mode);
        }
        if seq != self.seq.wrapping_add(1) {
            return self.refuse(seq, Reason::Sequence);
        }
        self.seq = seq;
        (seq, request)
    }

    fn refuse(&mut self, seq: u16, reason: Reason) -> (u16, Request) {
        self.refused = self.refused.saturating_add(1);
        (seq, Request::Refuse(reason))
    }
}
