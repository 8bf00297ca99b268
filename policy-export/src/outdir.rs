//! Output directories (`train --out`, `reproduce --out`): written as a unit, and replaced
//! only when this tool can prove it wrote them.
//!
//! A directory is built in a hidden sibling (`.NAME.PID.partial`, [`Staging`]) and renamed
//! into place when complete, so a killed run leaves the old directory (or none), never a mix
//! of two runs. Its marker file, [`MARKER`], names the tool, its version, the kind of output
//! and every entry the tool wrote there, each file with its size and digest (`marker.rs`).
//! An existing directory is replaced only if it is empty, or if its marker names this tool
//! and the same kind and it holds nothing but the entries the marker lists, each file as it
//! was written: a file added by hand (an export, notes), one changed since or listed by a
//! marker written by hand, or a directory of another program, even one with a
//! `summary.json`, is refused with exit status 2, named, with the reason. A killed run's
//! sibling is removed by the next run on the same proof.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use weights::Error;
use weights::files::{check_place, kind};

mod marker;
mod runs;
use marker::{Found, Listing};
pub use marker::{MARKER, MAX_MARKER_BYTES};
pub use runs::unchanged;

/// Most entries an output directory may hold to be replaced (a `--seeds` run at its limit
/// has about 50,000).
const MAX_ENTRIES: usize = 200_000;
/// Entries named in a refusal.
const NAMED: usize = 3;

/// Every entry under `dir` but the marker, relative and sorted, directories ending in `/`;
/// refused if any is neither a regular file nor a directory (the tool writes no other kind),
/// or if there are more than [`MAX_ENTRIES`].
fn listing(dir: &Path) -> std::result::Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut todo = vec![PathBuf::new()];
    while let Some(rel) = todo.pop() {
        let entries = std::fs::read_dir(dir.join(&rel)).map_err(|e| e.to_string())?;
        for e in entries {
            let e = e.map_err(|e| e.to_string())?;
            let r = rel.join(e.file_name());
            let shown = r.to_string_lossy().replace('\\', "/");
            let t = e.file_type().map_err(|e| e.to_string())?;
            if t.is_dir() {
                out.push(format!("{shown}/"));
                todo.push(r);
            } else if t.is_file() {
                if shown != MARKER {
                    out.push(shown);
                }
            } else {
                return Err(format!(
                    "it holds {} {}, which this tool never writes",
                    kind(&t),
                    weights::quote(&shown)
                ));
            }
            if out.len() > MAX_ENTRIES {
                return Err(format!("it holds more than {MAX_ENTRIES} entries"));
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Whether `dir` (an existing directory) may be replaced by an output of `kind`: empty, or
/// marked by this tool for `kind` and holding only what its marker lists, each file as the
/// tool wrote it; else why not.
fn replaceable(dir: &Path, kind: &str) -> std::result::Result<(), String> {
    let found = listing(dir)?;
    if found.is_empty() && std::fs::symlink_metadata(dir.join(MARKER)).is_err() {
        return Ok(());
    }
    let verdicts = proof(dir, kind, &found)?;
    unproven(&found, &verdicts)?;
    removable(dir, &found)
}

/// Refuses an earlier output whose directories this process cannot write in (made
/// read-only): its files could not be removed once the new output is in place, which was
/// found only after the work.
fn removable(dir: &Path, found: &[String]) -> std::result::Result<(), String> {
    let subdirs = found
        .iter()
        .filter(|e| e.ends_with('/'))
        .map(|e| dir.join(e));
    for d in std::iter::once(dir.to_path_buf()).chain(subdirs) {
        weights::files::writable(&d, dir).map_err(|e| {
            format!(
                "{} cannot be written in ({e}), so its files could not be removed after the \
                 work; make it writable, or choose another --out",
                weights::shown(&d)
            )
        })?;
    }
    Ok(())
}

/// What the marker in `dir` shows of each of `found`, if it is this tool's for `kind` and
/// lists each file's size and digest.
fn proof(dir: &Path, kind: &str, found: &[String]) -> std::result::Result<Vec<Found>, String> {
    let marker = marker::read(dir, kind, found)?;
    if marker.listing == Listing::Names {
        return Err(format!(
            "its {MARKER} is an earlier version's, which lists files without their sizes and \
             digests, so nothing shows they are still those {} wrote (move what you keep, \
             then remove the directory)",
            env!("CARGO_PKG_NAME")
        ));
    }
    Ok(marker.found)
}

/// Refuses the entries of `found` that their verdicts do not show the tool's: first those
/// the marker does not list, then the files it lists with another size or digest.
fn unproven(found: &[String], verdicts: &[Found]) -> std::result::Result<(), String> {
    let with = |verdict: Found| -> Vec<&String> {
        let both = found.iter().zip(verdicts);
        both.filter(|(_, v)| **v == verdict)
            .map(|(f, _)| f)
            .collect()
    };
    let tool = env!("CARGO_PKG_NAME");
    let foreign = with(Found::Foreign);
    if !foreign.is_empty() {
        let n = count(foreign.len(), "entry", "entries");
        return Err(format!(
            "it holds {n} {tool} did not write ({})",
            named(&foreign)
        ));
    }
    let changed = with(Found::Changed);
    if !changed.is_empty() {
        let n = count(changed.len(), "file", "files");
        return Err(format!(
            "it holds {n} no longer as {tool} wrote (its {MARKER} lists another size or \
             digest: {})",
            named(&changed)
        ));
    }
    Ok(())
}

/// `n` and the noun for it.
fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// The first [`NAMED`] of `entries`, quoted, then `...` if there are more.
fn named(entries: &[&String]) -> String {
    let shown: Vec<String> = entries
        .iter()
        .take(NAMED)
        .map(|f| weights::quote(f))
        .collect();
    let more = if entries.len() > NAMED { ", ..." } else { "" };
    shown.join(", ") + more
}

/// Removes `dir`, an earlier output of `kind` (moved aside by a commit, or left by a killed
/// one), as far as its marker proves it the tool's: each entry it lists as written, deepest
/// first, then the marker and the directory. Anything else (a file changed or added since
/// it was checked) is kept, with the directory, and named in the error.
fn clear(dir: &Path, kind: &str) -> std::result::Result<(), String> {
    let found = listing(dir)?;
    let marked = std::fs::symlink_metadata(dir.join(MARKER)).is_ok();
    if marked || !found.is_empty() {
        let verdicts = proof(dir, kind, &found)?;
        for (entry, verdict) in found.iter().zip(&verdicts).rev() {
            let path = dir.join(entry);
            if *verdict == Found::Owned {
                // A directory that still holds something kept stays.
                let _ = match entry.ends_with('/') {
                    true => std::fs::remove_dir(&path),
                    false => std::fs::remove_file(&path),
                };
            }
        }
        unproven(&found, &verdicts)?;
        std::fs::remove_file(dir.join(MARKER)).map_err(|e| e.to_string())?;
    }
    std::fs::remove_dir(dir).map_err(|e| format!("it holds what was added since ({e})"))
}

/// Checks, before any work, that `dir` can receive an output directory of `kind`: a new path
/// in a place this process can write, an empty directory, or an earlier output of the same
/// kind that holds only what this tool wrote ([`MARKER`]), which the new one replaces whole.
pub fn check_output_dir(dir: &Path, kind: &str) -> Result<()> {
    let refuse = |why: String| -> Result<()> {
        bail!(Error::Input(format!(
            "--out {}: expected a new path, an empty directory or an earlier output of `{} \
             {kind}`; not replacing it: {why}",
            weights::shown(dir),
            env!("CARGO_PKG_NAME")
        )))
    };
    if dir.file_name().is_none() || weights::files::ends_in_dot(dir) {
        return refuse("it is not a directory's name".into());
    }
    // The name itself, as the commit finds it: with a trailing slash (`LINK/`) the system
    // follows a link, which passed here and was refused only after the run.
    let dir = &dir.components().collect::<PathBuf>();
    let why = match std::fs::symlink_metadata(dir) {
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
            ) =>
        {
            Ok(())
        }
        Err(e) => Err(e.to_string()),
        Ok(m) if !m.is_dir() => Err(format!("it is {}", weights::files::kind(&m.file_type()))),
        Ok(_) => replaceable(dir, kind),
    };
    match why.and_then(|()| check_place(dir).map_err(|e| e.to_string())) {
        Ok(()) => Ok(()),
        Err(why) => refuse(why),
    }
}

/// An output directory being written: a hidden sibling of the destination, marked as this
/// tool's from the start, renamed over the destination by [`Staging::commit`], removed if
/// dropped uncommitted.
pub struct Staging {
    tmp: PathBuf,
    /// The destination as given, for messages.
    dest: PathBuf,
    /// The destination in its parent as resolved once, before any move: a path that runs
    /// through the destination itself (`run/../run`) no longer leads there once the earlier
    /// output is moved aside.
    place: PathBuf,
    kind: &'static str,
    /// The directories above it that `new` made, deepest first: a run that fails leaves
    /// none of them behind.
    made: Vec<PathBuf>,
}

impl Staging {
    /// A fresh staging directory for `dest`, which must pass [`check_output_dir`] for
    /// `kind`; the siblings killed runs left are removed first, if they are this tool's.
    pub fn new(dest: &Path, kind: &'static str) -> Result<Staging> {
        check_output_dir(dest, kind)?;
        let parent = match dest.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let made: Vec<PathBuf> = (parent.ancestors())
            .take_while(|a| !a.as_os_str().is_empty() && a.symlink_metadata().is_err())
            .map(Path::to_path_buf)
            .collect();
        let parent = std::fs::create_dir_all(&parent)
            .and_then(|()| std::fs::canonicalize(&parent))
            .map_err(|e| {
                Error::Input(format!(
                    "--out {}: creating {}: {e}",
                    weights::shown(dest),
                    weights::shown(&parent)
                ))
            })?;
        let place = parent.join(dest.file_name().context("check_output_dir saw its name")?);
        for old in weights::files::stale(dest, &["partial", "old"]) {
            if old.extension().is_some_and(|e| e == "old") {
                // An earlier output a killed commit moved aside: what its marker proves.
                let _ = clear(&old, kind);
            } else if marker::read(&old, kind, &[]).is_ok() {
                // A killed run's staging, marked when created, its files not yet listed.
                let _ = std::fs::remove_dir_all(&old);
            }
        }
        let tmp = parent.join(weights::files::hidden_name(
            dest,
            std::process::id(),
            "partial",
        ));
        std::fs::create_dir(&tmp).map_err(|e| {
            Error::Input(format!(
                "--out {}: creating {}: {e}",
                weights::shown(dest),
                weights::shown(&tmp)
            ))
        })?;
        let staging = Staging {
            tmp,
            dest: dest.to_path_buf(),
            place,
            kind,
            made,
        };
        marker::write(&staging.tmp, kind, &[])
            .with_context(|| format!("marking {}", weights::shown(&staging.tmp)))?;
        Ok(staging)
    }

    /// Where to write the output's files.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Lists what was written in the marker, each file with its size and digest, and puts
    /// the directory in place of the destination, which is checked again first. The earlier
    /// output is moved aside and removed as far as its marker proves it the tool's: a file
    /// changed or added in between is kept there, named in the error.
    pub fn commit(self) -> Result<()> {
        check_output_dir(&self.place, self.kind)?;
        let entries = listing(&self.tmp).map_err(anyhow::Error::msg)?;
        marker::write(&self.tmp, self.kind, &entries)?;
        let old = self.tmp.with_extension("old");
        let had_old = self.place.exists();
        if had_old {
            std::fs::rename(&self.place, &old)
                .with_context(|| format!("moving {} aside", weights::shown(&self.dest)))?;
        }
        if let Err(e) = std::fs::rename(&self.tmp, &self.place) {
            // Never a state with no output at the name: the earlier one goes back.
            let back = had_old && std::fs::rename(&old, &self.place).is_ok();
            bail!(
                "renaming onto {}: {e}{}",
                weights::shown(&self.dest),
                if back {
                    "; the earlier output is back in place"
                } else {
                    ""
                }
            );
        }
        if had_old && let Err(why) = clear(&old, self.kind) {
            bail!(
                "{} is written, but the earlier output moved aside to {} is kept: {why}",
                weights::shown(&self.dest),
                weights::shown(&old)
            );
        }
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        // Only this process's own staging directory, created by `new`, and the directories
        // it made above, each only if empty (a committed output is in one of them).
        // One made unreadable (under `umask 777`) cannot be listed, but is empty.
        if std::fs::remove_dir_all(&self.tmp).is_err() {
            let _ = std::fs::remove_dir(&self.tmp);
        }
        for dir in &self.made {
            let _ = std::fs::remove_dir(dir);
        }
    }
}

#[cfg(test)]
mod tests;
