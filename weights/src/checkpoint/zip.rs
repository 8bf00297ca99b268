//! The zip archives PyTorch and Stable-Baselines3 write, read in place: their entries are
//! stored, not compressed, so an entry is a slice of the file, checked against its CRC-32
//! when first read and never copied.
//!
//! What is kept per entry is a fixed 28 bytes, less than the central directory's 46 bytes
//! per entry, so the index is smaller than the file. Entries may not overlap (each local
//! header and its data lie apart from every other's and before the central directory), so
//! the bytes checked are at most the file's, however many names the archive gives them.

use std::cell::Cell;

use firmware::link::crc::crc32;

use crate::{Error, Result, few, quote};

/// One entry of the central directory, by offsets into the file.
struct Entry {
    name: u32,
    name_len: u16,
    method: u16,
    flags: u16,
    checked: Cell<bool>,
    crc: u32,
    local: u32,
    data: u32,
    size: u32,
}

/// A zip archive's entries, sorted by name.
pub struct Zip<'a> {
    bytes: &'a [u8],
    entries: Vec<Entry>,
}

fn refuse<T>(why: String) -> Result<T> {
    Err(Error::Input(format!("not a readable zip file: {why}")))
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(
        b.get(at..at.checked_add(2)?)?.try_into().ok()?,
    ))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(
        b.get(at..at.checked_add(4)?)?.try_into().ok()?,
    ))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(
        b.get(at..at.checked_add(8)?)?.try_into().ok()?,
    ))
}

/// The end-of-central-directory record's offset: the one whose comment ends the file.
fn end_record(b: &[u8]) -> Option<usize> {
    let last = b.len().checked_sub(22)?;
    (last.saturating_sub(0xffff)..=last).rev().find(|&at| {
        b[at..].starts_with(b"PK\x05\x06") && u16_at(b, at + 20) == Some((last - at) as u16)
    })
}

/// The central directory's entry count, offset and size, from the end record (or its zip64
/// record where the end record's fields are saturated, as Python writes for large files).
fn directory(b: &[u8]) -> Option<(u64, u64, u64)> {
    let end = end_record(b)?;
    let count = u64::from(u16_at(b, end + 10)?);
    let size = u64::from(u32_at(b, end + 12)?);
    let offset = u64::from(u32_at(b, end + 16)?);
    if count != 0xffff && size != 0xffff_ffff && offset != 0xffff_ffff {
        return Some((count, offset, size));
    }
    let locator = end.checked_sub(20)?;
    if !b[locator..].starts_with(b"PK\x06\x07") {
        return None;
    }
    let z = usize::try_from(u64_at(b, locator + 8)?).ok()?;
    if !b.get(z..)?.starts_with(b"PK\x06\x06") {
        return None;
    }
    Some((u64_at(b, z + 32)?, u64_at(b, z + 48)?, u64_at(b, z + 40)?))
}

impl<'a> Zip<'a> {
    /// The archive in `bytes`, its central directory read and every entry's place checked.
    pub fn open(bytes: &'a [u8]) -> Result<Zip<'a>> {
        if bytes.len() > u32::MAX as usize {
            return refuse(format!(
                "{} bytes, more than a zip without zip64 offsets holds",
                bytes.len()
            ));
        }
        let Some((count, offset, size)) = directory(bytes) else {
            return refuse("no end of central directory record ends it".into());
        };
        let start = usize::try_from(offset).unwrap_or(usize::MAX);
        let Some(dir) = usize::try_from(size)
            .ok()
            .and_then(|s| bytes.get(start..start.checked_add(s)?))
        else {
            return refuse(format!(
                "its central directory ({size} bytes at {offset}) lies outside it"
            ));
        };
        // Each record is at least 46 bytes: a count beyond that is a lie, refused before the
        // index is allocated.
        if count > (dir.len() / 46) as u64 {
            return refuse(format!(
                "{count} entries declared in a central directory of {} bytes",
                dir.len()
            ));
        }
        let mut entries = Vec::with_capacity(count as usize);
        let mut at = start;
        for k in 0..count {
            let entry = record(bytes, at, start).ok_or_else(|| {
                Error::Input(format!("not a readable zip file: central directory entry {k} at byte {at} is malformed or points outside the file"))
            })?;
            at = entry.1;
            entries.push(entry.0);
        }
        disjoint(&mut entries)?;
        let name = |e: &Entry| &bytes[e.name as usize..e.name as usize + usize::from(e.name_len)];
        entries.sort_unstable_by(|a, b| name(a).cmp(name(b)));
        if let Some(w) = entries.windows(2).find(|w| name(&w[0]) == name(&w[1])) {
            return refuse(format!(
                "entry {} appears twice",
                quote(&String::from_utf8_lossy(name(&w[0])))
            ));
        }
        Ok(Zip { bytes, entries })
    }

    fn name(&self, e: &Entry) -> &'a [u8] {
        &self.bytes[e.name as usize..e.name as usize + usize::from(e.name_len)]
    }

    /// Every entry's name, in byte order.
    pub fn names(&self) -> impl ExactSizeIterator<Item = &'a [u8]> + '_ {
        self.entries.iter().map(|e| self.name(e))
    }

    /// A few of the entries' names, for a message.
    pub fn listing(&self) -> String {
        match self.entries.len() {
            0 => "nothing".into(),
            _ => few(self.names().map(|n| quote(&String::from_utf8_lossy(n))), 5),
        }
    }

    /// The entry whose name is `parts` joined, if there is one.
    fn find(&self, parts: &[&str]) -> Option<&Entry> {
        let want = || parts.iter().flat_map(|p| p.bytes());
        self.entries
            .binary_search_by(|e| self.name(e).iter().copied().cmp(want()))
            .ok()
            .map(|k| &self.entries[k])
    }

    /// Whether the archive has the entry `parts` joined.
    pub fn has(&self, parts: &[&str]) -> bool {
        self.find(parts).is_some()
    }

    /// The bytes of the entry `parts` joined: refused if it is missing, compressed,
    /// encrypted, or not what its CRC-32 says.
    pub fn read(&self, parts: &[&str]) -> Result<&'a [u8]> {
        let shown = || quote(&parts.concat());
        let Some(e) = self.find(parts) else {
            return Err(Error::Input(format!("zip entry {} is missing", shown())));
        };
        if e.method != 0 || e.flags & 1 != 0 {
            return Err(Error::Input(format!(
                "zip entry {} is compressed or encrypted (method {}); PyTorch and \
                 Stable-Baselines3 store their entries as they are",
                shown(),
                e.method
            )));
        }
        let data = &self.bytes[e.data as usize..e.data as usize + e.size as usize];
        if !e.checked.get() {
            if crc32(data) != e.crc {
                return Err(Error::Input(format!(
                    "zip entry {} does not match its CRC-32",
                    shown()
                )));
            }
            e.checked.set(true);
        }
        Ok(data)
    }
}

/// The central directory record at `at` (the directory starts at `dir`) and where the next
/// one starts, if it is well formed and its local header and data lie before the directory.
fn record(b: &[u8], at: usize, dir: usize) -> Option<(Entry, usize)> {
    if !b.get(at..)?.starts_with(b"PK\x01\x02") {
        return None;
    }
    let name_len = u16_at(b, at + 28)?;
    let extra_len = usize::from(u16_at(b, at + 30)?);
    let next = at + 46 + usize::from(name_len) + extra_len + usize::from(u16_at(b, at + 32)?);
    let extra =
        b.get(at + 46 + usize::from(name_len)..at + 46 + usize::from(name_len) + extra_len)?;
    let mut compressed = u64::from(u32_at(b, at + 20)?);
    let mut size = u64::from(u32_at(b, at + 24)?);
    let mut local = u64::from(u32_at(b, at + 42)?);
    // Saturated fields are in the zip64 extra field (id 1), in this order, 8 bytes each.
    let mut z64 = zip64(extra)
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")));
    for field in [&mut size, &mut compressed, &mut local] {
        if *field == 0xffff_ffff {
            *field = z64.next()?;
        }
    }
    let local = u32::try_from(local).ok()?;
    let l = local as usize;
    if !b.get(l..)?.starts_with(b"PK\x03\x04") {
        return None;
    }
    let data = l + 30 + usize::from(u16_at(b, l + 26)?) + usize::from(u16_at(b, l + 28)?);
    let end = data.checked_add(usize::try_from(compressed).ok()?)?;
    let method = u16_at(b, at + 10)?;
    if end > dir || next > b.len() || (method == 0 && compressed != size) {
        return None;
    }
    let entry = Entry {
        name: u32::try_from(at + 46).ok()?,
        name_len,
        method,
        flags: u16_at(b, at + 8)?,
        checked: Cell::new(false),
        crc: u32_at(b, at + 16)?,
        local,
        data: u32::try_from(data).ok()?,
        size: u32::try_from(compressed).ok()?,
    };
    Some((entry, next))
}

/// The zip64 extra field's body among `extra`'s fields (empty if there is none).
fn zip64(extra: &[u8]) -> &[u8] {
    let mut at = 0;
    while let (Some(id), Some(len)) = (u16_at(extra, at), u16_at(extra, at + 2)) {
        let body = extra
            .get(at + 4..at + 4 + usize::from(len))
            .unwrap_or_default();
        if id == 1 {
            return body;
        }
        at += 4 + usize::from(len);
    }
    &[]
}

/// Refuses entries whose local headers and data overlap: names sharing one entry's bytes
/// would have them checked (and a reader that copies, copied) once per name.
fn disjoint(entries: &mut [Entry]) -> Result<()> {
    entries.sort_unstable_by_key(|e| e.local);
    match entries
        .windows(2)
        .find(|w| w[1].local < w[0].data + w[0].size)
    {
        Some(w) => refuse(format!(
            "entries at bytes {} and {} overlap",
            w[0].local, w[1].local
        )),
        None => Ok(()),
    }
}
