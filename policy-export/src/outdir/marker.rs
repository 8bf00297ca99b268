//! The marker of an output directory, [`MARKER`]: the tool that wrote it, its version, the
//! kind of output, and each entry it wrote there, every file with its size and 64-bit FNV-1a
//! digest (`firmware::link::digest::Fnv`). A file is the run's only while it is as the run
//! wrote it: a marker that lists a file the run did not write (by hand, or after the file
//! was replaced) proves nothing of it. A check against mistakes, like the link's digests,
//! not against someone who computes digests of their own files to have them removed.
//!
//! Read as it streams, each entry judged against the directory and none kept: a marker at
//! its cap of 16 MiB costs about 8 KB, where parsed whole a list of short names took about
//! 100 MB.

use std::io::{BufReader, Read};
use std::path::Path;

use firmware::link::digest::Fnv;
use serde::de::Visitor;
use serde::de::{DeserializeSeed, Deserializer, Error as _, IgnoredAny, MapAccess, SeqAccess};
use serde::{Deserialize, Serialize};
use weights::files::{open_regular, write_atomic};

/// The marker file of an output directory.
pub const MARKER: &str = weights::files::RUN_MARKER;
/// Largest marker read: a `--seeds` run of 10,000 seeds lists about 50,000 entries, in about
/// 5 MB.
pub const MAX_MARKER_BYTES: u64 = 16 << 20;

/// One entry as a marker lists it: a directory (`seed-1/`), or a file with its size and
/// digest.
#[derive(Serialize, Deserialize)]
struct Entry {
    path: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    bytes: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fnv1a64: Option<String>,
}

/// What a marker writes.
#[derive(Serialize)]
struct Written<'a> {
    tool: &'a str,
    version: &'a str,
    kind: &'a str,
    entries: Vec<Entry>,
}

/// Writes the marker of `dir`, an output of `kind`: each of `entries` (relative, sorted,
/// directories ending in `/`) with, for a file, its size and digest as it is now.
pub fn write(dir: &Path, kind: &str, entries: &[String]) -> anyhow::Result<()> {
    let mut listed = Vec::with_capacity(entries.len());
    for path in entries {
        let (bytes, fnv1a64) = if path.ends_with('/') {
            (None, None)
        } else {
            let (n, h) = digest(&dir.join(path))?;
            (Some(n), Some(hex(h)))
        };
        let path = path.clone();
        listed.push(Entry {
            path,
            bytes,
            fnv1a64,
        });
    }
    let marker = Written {
        tool: env!("CARGO_PKG_NAME"),
        version: env!("CARGO_PKG_VERSION"),
        kind,
        entries: listed,
    };
    Ok(write_atomic(
        &dir.join(MARKER),
        &serde_json::to_vec_pretty(&marker)?,
    )?)
}

/// The size and digest of the regular file `path`, read in blocks.
fn digest(path: &Path) -> weights::Result<(u64, u64)> {
    let mut file = open_regular(path)?;
    let mut block = vec![0u8; 64 << 10];
    let (mut size, mut fnv) = (0u64, Fnv::default());
    loop {
        let n = file
            .read(&mut block)
            .map_err(|e| weights::Error::Io(format!("reading {}: {e}", weights::shown(path))))?;
        if n == 0 {
            return Ok((size, fnv.finish()));
        }
        size += n as u64;
        fnv = fnv.bytes(&block[..n]);
    }
}

/// A digest as a marker writes it: 16 hexadecimal digits.
fn hex(digest: u64) -> String {
    format!("{digest:016x}")
}

/// What a marker shows of an entry found in its directory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Found {
    /// Not listed: not the tool's.
    Foreign,
    /// Listed, but a file no longer of the size or digest the tool wrote (or unreadable).
    Changed,
    /// Listed, and a directory or a file as the tool wrote it.
    Owned,
}

/// Which list a marker holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Listing {
    /// `entries`, each file with its size and digest.
    Entries,
    /// `files`, names alone: an earlier version's, which proves nothing of their contents.
    Names,
}

/// A marker of this tool for the kind asked, read against its directory.
#[derive(Debug)]
pub struct Marker {
    pub listing: Listing,
    /// For each entry found in the directory (in the order given), what the marker shows.
    pub found: Vec<Found>,
}

/// The marker in `dir`, if it is one of this tool's for outputs of `kind`, each of `found`
/// (entries of `dir`, relative, sorted) judged against it; else why not.
pub fn read(dir: &Path, kind: &str, found: &[String]) -> Result<Marker, String> {
    let path = dir.join(MARKER);
    if std::fs::symlink_metadata(&path).is_err() {
        return Err(format!(
            "it holds no {MARKER} marker, so nothing shows that {} wrote it",
            env!("CARGO_PKG_NAME")
        ));
    }
    let file = open_regular(&path).map_err(|e| e.to_string())?;
    if file.metadata().is_ok_and(|m| m.len() > MAX_MARKER_BYTES) {
        return Err(format!(
            "its {MARKER} is larger than {MAX_MARKER_BYTES} bytes, more than a marker this \
             tool writes"
        ));
    }
    let mut reading = Reading {
        dir,
        found,
        verdicts: vec![Found::Foreign; found.len()],
        tool: None,
        kind: None,
        listing: None,
    };
    let mut de = serde_json::Deserializer::from_reader(BufReader::new(file.take(MAX_MARKER_BYTES)));
    (&mut reading)
        .deserialize(&mut de)
        .and_then(|()| de.end())
        .map_err(|_| format!("its {MARKER} is not a marker this tool wrote"))?;
    let (Some(tool), Some(marked), Some(listing)) = (reading.tool, reading.kind, reading.listing)
    else {
        return Err(format!("its {MARKER} is not a marker this tool wrote"));
    };
    if tool != env!("CARGO_PKG_NAME") || marked != kind {
        return Err(format!(
            "its {MARKER} marks an output of {} {}, not of {} {kind}",
            weights::quote(&tool),
            weights::quote(&marked),
            env!("CARGO_PKG_NAME")
        ));
    }
    Ok(Marker {
        listing,
        found: reading.verdicts,
    })
}

/// A marker being read: its header's fields, and a verdict on each entry found.
struct Reading<'a> {
    dir: &'a Path,
    found: &'a [String],
    verdicts: Vec<Found>,
    tool: Option<String>,
    kind: Option<String>,
    listing: Option<Listing>,
}

impl Reading<'_> {
    /// Judges one listed entry, if it is among those found: a directory is the tool's; a
    /// file is if its size and digest are those listed.
    fn judge(&mut self, e: Entry) -> Result<(), String> {
        let listed = match (e.path.ends_with('/'), e.bytes, e.fnv1a64) {
            (true, None, None) => None,
            (false, Some(bytes), Some(digest)) => Some((bytes, digest)),
            _ => return Err("an entry is a directory or a file with its size and digest".into()),
        };
        // Listed but not found: removed since, which makes nothing else of the run less its.
        let Ok(i) = self.found.binary_search(&e.path) else {
            return Ok(());
        };
        if self.verdicts[i] == Found::Owned {
            return Ok(());
        }
        let owned = listed.is_none_or(|(bytes, listed)| {
            digest(&self.dir.join(&e.path)).is_ok_and(|(n, h)| n == bytes && hex(h) == listed)
        });
        self.verdicts[i] = if owned { Found::Owned } else { Found::Changed };
        Ok(())
    }
}

/// Sets a header field given once.
fn once<E: serde::de::Error>(field: &mut Option<String>, value: String) -> Result<(), E> {
    match field.replace(value) {
        None => Ok(()),
        Some(_) => Err(E::custom("a field given twice")),
    }
}

impl<'de> DeserializeSeed<'de> for &mut Reading<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for &mut Reading<'_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a marker")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key::<String>()? {
            let listing = match key.as_str() {
                "tool" => {
                    once(&mut self.tool, map.next_value()?)?;
                    continue;
                }
                "kind" => {
                    once(&mut self.kind, map.next_value()?)?;
                    continue;
                }
                "entries" => {
                    map.next_value_seed(Entries(&mut *self))?;
                    Listing::Entries
                }
                "files" => {
                    map.next_value::<Vec<IgnoredAny>>()?;
                    Listing::Names
                }
                _ => {
                    map.next_value::<IgnoredAny>()?;
                    continue;
                }
            };
            if self.listing.replace(listing).is_some() {
                return Err(A::Error::custom("two lists of entries"));
            }
        }
        Ok(())
    }
}

/// A marker's `entries`, each judged as it is read.
struct Entries<'r, 'a>(&'r mut Reading<'a>);

impl<'de> DeserializeSeed<'de> for Entries<'_, '_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for Entries<'_, '_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a list of entries")
    }

    fn visit_seq<S: SeqAccess<'de>>(self, mut seq: S) -> Result<(), S::Error> {
        while let Some(entry) = seq.next_element::<Entry>()? {
            self.0.judge(entry).map_err(S::Error::custom)?;
        }
        Ok(())
    }
}
