//! Protocol Buffers' wire format, as far as reading an ONNX model needs: fields of a
//! message, each a number and a varint, a fixed 32- or 64-bit value, or length-delimited
//! bytes (a string, a nested message, a packed array).
//!
//! Fields are read as they are needed, one at a time, never gathered into a list: a field
//! can be two bytes and its decoded form is larger, so a list of them would grow faster
//! than the file. A message is scanned again for each field asked of it; the readers ask a
//! fixed number of questions per message, so their work stays linear in the file.

use crate::{Error, Result};

/// One field's value as the wire carries it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Wire<'a> {
    /// Wire type 0.
    Varint(u64),
    /// Wire type 1.
    Fixed64(u64),
    /// Wire type 2: a string, bytes, a nested message or a packed array.
    Bytes(&'a [u8]),
    /// Wire type 5.
    Fixed32(u32),
}

fn refuse<T>(why: &str, at: usize) -> Result<T> {
    Err(Error::Input(format!(
        "ONNX: {why} at byte {at} of a message"
    )))
}

/// The fields of one message, in order.
pub struct Fields<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Fields<'a> {
    /// The fields of the message `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Fields { bytes, pos: 0 }
    }

    fn varint(&mut self) -> Result<u64> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let Some(&b) = self.bytes.get(self.pos) else {
                return refuse("the message ends inside a varint", self.pos);
            };
            self.pos += 1;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        refuse("a varint longer than 10 bytes", self.pos)
    }

    fn take(&mut self, n: u64) -> Result<&'a [u8]> {
        let end = usize::try_from(n)
            .ok()
            .and_then(|n| self.pos.checked_add(n))
            .filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return refuse("a field runs past the end of its message", self.pos);
        };
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    /// The next field's number and value, or `None` at the end of the message.
    pub fn next_field(&mut self) -> Result<Option<(u64, Wire<'a>)>> {
        if self.pos == self.bytes.len() {
            return Ok(None);
        }
        let at = self.pos;
        let key = self.varint()?;
        let value = match key & 7 {
            0 => Wire::Varint(self.varint()?),
            1 => Wire::Fixed64(u64::from_le_bytes(self.take(8)?.try_into().expect("8"))),
            2 => {
                let n = self.varint()?;
                Wire::Bytes(self.take(n)?)
            }
            5 => Wire::Fixed32(u32::from_le_bytes(self.take(4)?.try_into().expect("4"))),
            t => return refuse(&format!("wire type {t} (groups are not used by ONNX)"), at),
        };
        if key >> 3 == 0 {
            return refuse("field number 0", at);
        }
        Ok(Some((key >> 3, value)))
    }
}

impl<'a> Iterator for Fields<'a> {
    type Item = Result<(u64, Wire<'a>)>;

    fn next(&mut self) -> Option<Self::Item> {
        let next = self.next_field().transpose();
        if next.as_ref().is_some_and(|r| r.is_err()) {
            // After a malformed field nothing more can be read.
            self.pos = self.bytes.len();
        }
        next
    }
}

/// The last value of field `n` in `bytes` (protobuf's rule for a singular field written
/// more than once).
pub fn last(bytes: &[u8], n: u64) -> Result<Option<Wire<'_>>> {
    let mut found = None;
    for f in Fields::new(bytes) {
        let (k, w) = f?;
        if k == n {
            found = Some(w);
        }
    }
    Ok(found)
}

/// How many times field `n` occurs in `bytes`.
pub fn count(bytes: &[u8], n: u64) -> Result<usize> {
    let mut count = 0;
    for f in Fields::new(bytes) {
        count += usize::from(f?.0 == n);
    }
    Ok(count)
}

/// Up to `max` varints of the repeated integer field `n` of `bytes`, packed (one
/// length-delimited run) or not, and how many there are in all.
pub fn varints(bytes: &[u8], n: u64, max: usize) -> Result<(Vec<u64>, usize)> {
    let mut out = Vec::new();
    let mut all = 0;
    each_varint(bytes, n, |x| {
        all += 1;
        if out.len() < max {
            out.push(x);
        }
        Ok(())
    })?;
    Ok((out, all))
}

/// `f` on each varint of the repeated integer field `n` of `bytes`, packed or not, in
/// order, until it returns an error: for a field too long to hold as a list of `u64`s.
pub fn each_varint(bytes: &[u8], n: u64, mut f: impl FnMut(u64) -> Result<()>) -> Result<()> {
    for field in Fields::new(bytes) {
        match field? {
            (k, _) if k != n => {}
            (_, Wire::Varint(x)) => f(x)?,
            (_, Wire::Bytes(b)) => {
                let mut run = Fields::new(b);
                while run.pos < b.len() {
                    f(run.varint()?)?;
                }
            }
            _ => return refuse("an integer field of another wire type", 0),
        }
    }
    Ok(())
}

/// Length-delimited bytes as UTF-8 text.
pub fn text<'a>(w: &Wire<'a>) -> Result<&'a str> {
    match w {
        Wire::Bytes(b) => {
            std::str::from_utf8(b).or_else(|_| refuse("a string that is not UTF-8", 0))
        }
        _ => refuse("a string field of another wire type", 0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The examples of the Protocol Buffers encoding guide: field 1 = 150 is `08 96 01`,
    /// field 2 = "testing" is `12 07 74 65 73 74 69 6e 67`, a packed field 4 = [3, 270,
    /// 86942] is `22 06 03 8e 02 9e a7 05`.
    fn fields(bytes: &[u8]) -> Result<Vec<(u64, Wire<'_>)>> {
        Fields::new(bytes).collect()
    }

    #[test]
    fn the_encoding_guides_examples_read_as_the_guide_says() {
        assert_eq!(
            fields(&[0x08, 0x96, 0x01]).unwrap(),
            [(1, Wire::Varint(150))]
        );
        let t = fields(b"\x12\x07testing").unwrap();
        assert_eq!((t[0].0, text(&t[0].1).unwrap()), (2, "testing"));
        let packed = [0x22, 0x06, 0x03, 0x8e, 0x02, 0x9e, 0xa7, 0x05];
        assert_eq!(varints(&packed, 4, 8).unwrap(), (vec![3, 270, 86942], 3));
        // Counted in full, kept up to the limit.
        assert_eq!(varints(&packed, 4, 2).unwrap(), (vec![3, 270], 3));
        // The same repeated field unpacked, between other fields.
        let u = [0x20, 0x03, 0x08, 0x01, 0x20, 0x8e, 0x02];
        assert_eq!(varints(&u, 4, 8).unwrap(), (vec![3, 270], 2));
        assert_eq!((count(&u, 4).unwrap(), count(&u, 1).unwrap()), (2, 1));
        assert_eq!(last(&u, 4).unwrap(), Some(Wire::Varint(270)));
        assert_eq!(last(&u, 5).unwrap(), None);
    }

    #[test]
    fn truncated_and_malformed_messages_are_refused() {
        for bad in [
            &[0x08][..],
            &[0x08, 0x96],
            &[0x12, 0x07, b't'],
            &[0x0b],
            &[0x00, 0x01],
            &[
                0x08, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01,
            ],
            &[0x0d, 1, 2],
        ] {
            assert!(fields(bad).unwrap_err().is_input(), "{bad:?}");
            assert!(count(bad, 1).unwrap_err().is_input(), "{bad:?}");
        }
    }
}
