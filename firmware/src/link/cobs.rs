//! Consistent Overhead Byte Stuffing (Cheshire and Baker, "Consistent Overhead Byte
//! Stuffing", IEEE/ACM Transactions on Networking 7(2), 1999): a frame's bytes re-coded
//! without zeros, so that a zero ends every frame and a receiver that lost its place, or
//! joined in the middle, finds the next frame at the next zero. The cost is one byte per
//! 254, plus one.

/// Why encoded bytes do not decode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CobsError {
    /// A zero inside the encoded bytes, where none can be.
    Zero,
    /// A block's code byte promises more bytes than follow.
    Truncated,
}

/// The most bytes `n` bytes encode to, without the delimiter.
pub const fn max_encoded_len(n: usize) -> usize {
    n + n / 254 + 1
}

/// Encodes `input` into the front of `out` (no delimiter); the encoded length, or `None` if
/// `out` is too short ([`max_encoded_len`] is always enough).
pub fn encode(input: &[u8], out: &mut [u8]) -> Option<usize> {
    let mut code_at = 0;
    let mut written = 1;
    let mut code = 1u8;
    for (i, &byte) in input.iter().enumerate() {
        if byte != 0 {
            *out.get_mut(written)? = byte;
            written += 1;
            code += 1;
        }
        // A full block of 254 ends without an implied zero; it starts a new block only if
        // bytes follow, so that the canonical encoding has no empty trailing block.
        if byte == 0 || (code == 0xFF && i + 1 < input.len()) {
            *out.get_mut(code_at)? = code;
            code_at = written;
            written += 1;
            code = 1;
        }
    }
    *out.get_mut(code_at)? = code;
    Some(written)
}

/// Decodes `buf` (one frame, delimiter removed) in place: the decoded bytes are the front of
/// `buf`, and their number is returned. Decoding never writes ahead of what it has read, so
/// one buffer serves.
pub fn decode_in_place(buf: &mut [u8]) -> Result<usize, CobsError> {
    let (mut read, mut written) = (0, 0);
    while let Some(&code) = buf.get(read) {
        if code == 0 {
            return Err(CobsError::Zero);
        }
        let end = read + code as usize;
        let block = buf.get(read + 1..end).ok_or(CobsError::Truncated)?;
        if block.contains(&0) {
            return Err(CobsError::Zero);
        }
        buf.copy_within(read + 1..end, written);
        written += code as usize - 1;
        read = end;
        if code != 0xFF && read < buf.len() {
            // written < read here: each block shrinks by its code byte.
            if let Some(b) = buf.get_mut(written) {
                *b = 0;
            }
            written += 1;
        }
    }
    Ok(written)
}
