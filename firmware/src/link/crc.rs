//! CRC-32 as Ethernet, zlib and PNG compute it (reflected polynomial 0xEDB88320, initial
//! value and final XOR all ones), a nibble at a time from a 16-entry table: 64 bytes of
//! flash rather than the byte table's 1 KiB, at two table lookups a byte.

const POLY: u32 = 0xEDB8_8320;

/// The remainder of each nibble, shifted in from the low end.
const TABLE: [u32; 16] = {
    let mut table = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut bit = 0;
        while bit < 4 {
            c = if c & 1 == 1 { (c >> 1) ^ POLY } else { c >> 1 };
            bit += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
};

/// The CRC-32 of `data`.
pub fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &byte in data {
        c = TABLE[((c ^ byte as u32) & 0xF) as usize] ^ (c >> 4);
        c = TABLE[((c ^ (byte as u32 >> 4)) & 0xF) as usize] ^ (c >> 4);
    }
    !c
}
