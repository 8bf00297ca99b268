//! Frames on the wire: a packet's payload and its CRC-32 (little-endian), COBS-encoded and
//! ended by a zero byte.

use super::cobs;
use super::crc::crc32;
use super::message::{HEADER_LEN, MAX_PAYLOAD, Packet, Reason};

const CRC_LEN: usize = 4;
/// The longest frame on the wire, its delimiter included.
pub const MAX_FRAME: usize = cobs::max_encoded_len(MAX_PAYLOAD + CRC_LEN) + 1;

/// `packet` as the bytes to send, at the front of `out`; their number.
pub fn encode(packet: &Packet, out: &mut [u8; MAX_FRAME]) -> usize {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = packet.encode(&mut payload);
    let mut raw = [0u8; MAX_PAYLOAD + CRC_LEN];
    let (body, crc) = raw.split_at_mut(n);
    body.copy_from_slice(&payload[..n]);
    crc[..CRC_LEN].copy_from_slice(&crc32(&payload[..n]).to_le_bytes());
    // MAX_FRAME holds the encoding of the longest payload and its delimiter.
    let len = cobs::encode(&raw[..n + CRC_LEN], out).unwrap_or(0);
    if let Some(d) = out.get_mut(len) {
        *d = 0;
    }
    len + 1
}

/// Gathers bytes as they arrive into frames, in a buffer of [`MAX_FRAME`] bytes: what a
/// target's serial interrupt or polling loop feeds, one byte at a time.
#[derive(Clone, Debug)]
pub struct FrameReader {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflowed: bool,
}

impl Default for FrameReader {
    fn default() -> Self {
        FrameReader {
            buf: [0; MAX_FRAME],
            len: 0,
            overflowed: false,
        }
    }
}

impl FrameReader {
    /// Takes one byte; at a frame's end, the packet it carried or why it was refused. Empty
    /// frames (delimiters in a row, which a sender may use to resynchronise) are skipped; an
    /// oversized frame is dropped whole and reported at its end.
    pub fn push(&mut self, byte: u8) -> Option<Result<Packet, Reason>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) if self.len < MAX_FRAME - 1 => {
                    *slot = byte;
                    self.len += 1;
                }
                _ => self.overflowed = true,
            }
            return None;
        }
        let (len, overflowed) = (self.len, self.overflowed);
        self.len = 0;
        self.overflowed = false;
        if overflowed {
            return Some(Err(Reason::Oversized));
        }
        if len == 0 {
            return None;
        }
        Some(self.check(len))
    }

    fn check(&mut self, len: usize) -> Result<Packet, Reason> {
        let frame = &mut self.buf[..len];
        let n = cobs::decode_in_place(frame).map_err(|_| Reason::Encoding)?;
        if n < HEADER_LEN + CRC_LEN {
            return Err(Reason::Length);
        }
        let (payload, crc) = frame[..n].split_at(n - CRC_LEN);
        let sent = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        if crc32(payload) != sent {
            return Err(Reason::Crc);
        }
        Packet::decode(payload)
    }
}
