//! The link between a world simulated on a host and a controller on a target, one exchange
//! per control period: the host sends what a board would read (encoder counts, or the
//! state), the target answers with what it drives, its policy's scores, its fault flags and
//! the time the period took. The protocol is `docs/LINK.md`; this module is both ends'
//! codec: fixed-size buffers, no allocation, no panics on any bytes.
//!
//! ```
//! use firmware::link::{FrameReader, MAX_FRAME, Message, Packet, frame};
//! let mut wire = [0u8; MAX_FRAME];
//! let sent = Packet { seq: 7, message: Message::Counts { cart: -120, pole: 2047 } };
//! let n = frame::encode(&sent, &mut wire);
//! let mut reader = FrameReader::default();
//! let got: Vec<_> = wire[..n].iter().filter_map(|&b| reader.push(b)).collect();
//! assert_eq!(got, [Ok(sent)]);
//! ```

pub mod cobs;
pub mod crc;
pub mod digest;
pub mod frame;
mod message;
mod sensor;
pub mod session;
pub mod target;
mod values;

pub use frame::{FrameReader, MAX_FRAME};

/// The line rate of the link on a UART (USB CDC-ACM ignores it).
pub const BAUD: u32 = 115_200;
pub use message::{
    Format, HEADER_LEN, Info, MAX_PAYLOAD, Message, Packet, Reason, Reply, Scores, Sensing, Start,
    VERSION, Values,
};
pub use sensor::{LinkSensor, Missing};
pub use session::{Measurement, Request, Session};
pub use target::{Target, period_ns};

#[cfg(test)]
mod tests;
