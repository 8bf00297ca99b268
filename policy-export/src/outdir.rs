//! Output directories (`train --out`, `reproduce --out`): written as a unit, and replaced
//! only when this tool can prove it wrote them.
//!
//! A directory is built in a hidden sibling (`.NAME.PID.partial`, [`Staging`]) and renamed
//! into place when complete, so a killed run leaves the old directory (or none), never a mix
//! of two runs. Its marker file, [`MARKER`], names the tool, its version, the kind of output
//! and every file the tool wrote there. An existing directory is replaced only if it is
//! empty, or if its marker names this tool and the same kind and it holds nothing but the
//! files the marker lists: a file added by hand (an export, notes) or a directory of another
//! program, even one with a `summary.json`, is refused with exit status 2, named, with the
//! reason. A killed run's sibling is removed by the next run on the same proof.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use weights::Error;
use weights::files::{check_place, kind, read_capped, write_atomic};

/// The marker file of an output directory.
pub const MARKER: &str = ".cartpole-run";
/// Largest marker read: a `--seeds` run of 10,000 seeds lists about 50,000 entries.
const MAX_MARKER_BYTES: u64 = 16 << 20;
/// Most entries an output directory may hold to be replaced (a `--seeds` run at its limit
/// has about 50,000).
const MAX_ENTRIES: usize = 200_000;
/// Entries named in a refusal.
const NAMED: usize = 3;

/// What [`MARKER`] holds.
#[derive(Debug, Serialize, Deserialize)]
struct Marker {
    tool: String,
    version: String,
    kind: String,
    /// Every entry the tool wrote, relative, `/`-separated, directories ending in `/`.
    files: Vec<String>,
}

impl Marker {
    fn new(kind: &str, files: Vec<String>) -> Marker {
        Marker {
            tool: env!("CARGO_PKG_NAME").into(),
            version: env!("CARGO_PKG_VERSION").into(),
            kind: kind.into(),
            files,
        }
    }

    /// The marker in `dir`, if it is one of this tool's for outputs of `kind`; else why not.
    fn read(dir: &Path, kind: &str) -> std::result::Result<Marker, String> {
        let path = dir.join(MARKER);
        if std::fs::symlink_metadata(&path).is_err() {
            return Err(format!(
                "it holds no {MARKER} marker, so nothing shows that {} wrote it",
                env!("CARGO_PKG_NAME")
            ));
        }
        let bytes = read_capped(&path, MAX_MARKER_BYTES).map_err(|e| e.to_string())?;
        let mut m: Marker = weights::json::parse_bytes(&bytes)
            .map_err(|_| format!("its {MARKER} is not a marker this tool wrote"))?;
        m.files.sort();
        if m.tool != env!("CARGO_PKG_NAME") || m.kind != kind {
            return Err(format!(
                "its {MARKER} marks an output of {} {}, not of {} {kind}",
                weights::quote(&m.tool),
                weights::quote(&m.kind),
                env!("CARGO_PKG_NAME")
            ));
        }
        Ok(m)
    }
}

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
/// marked by this tool for `kind` and holding only what its marker lists; else why not.
fn replaceable(dir: &Path, kind: &str) -> std::result::Result<(), String> {
    let found = listing(dir)?;
    if found.is_empty() && std::fs::symlink_metadata(dir.join(MARKER)).is_err() {
        return Ok(());
    }
    let marker = Marker::read(dir, kind)?;
    let foreign: Vec<&String> = found
        .iter()
        .filter(|f| marker.files.binary_search(f).is_err())
        .collect();
    if foreign.is_empty() {
        return Ok(());
    }
    let named: Vec<String> = foreign
        .iter()
        .take(NAMED)
        .map(|f| weights::quote(f))
        .collect();
    Err(format!(
        "it holds {} {} {} did not write ({}{})",
        foreign.len(),
        if foreign.len() == 1 {
            "entry"
        } else {
            "entries"
        },
        env!("CARGO_PKG_NAME"),
        named.join(", "),
        if foreign.len() > NAMED { ", ..." } else { "" }
    ))
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
    if dir.file_name().is_none() {
        return refuse("it is not a directory's name".into());
    }
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
    dest: PathBuf,
    kind: &'static str,
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
        std::fs::create_dir_all(&parent).map_err(|e| {
            Error::Input(format!(
                "--out {}: creating {}: {e}",
                weights::shown(dest),
                weights::shown(&parent)
            ))
        })?;
        for old in weights::files::stale(dest, &["partial", "old"]) {
            if Marker::read(&old, kind).is_ok() {
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
            kind,
        };
        staging.mark(Vec::new())?;
        Ok(staging)
    }

    /// Where to write the output's files.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    fn mark(&self, files: Vec<String>) -> Result<()> {
        let marker = serde_json::to_vec_pretty(&Marker::new(self.kind, files))?;
        Ok(write_atomic(&self.tmp.join(MARKER), &marker)?)
    }

    /// Lists what was written in the marker and puts the directory in place of the
    /// destination, which is checked again first.
    pub fn commit(self) -> Result<()> {
        check_output_dir(&self.dest, self.kind)?;
        self.mark(listing(&self.tmp).map_err(anyhow::Error::msg)?)?;
        let old = self.tmp.with_extension("old");
        let had_old = self.dest.exists();
        if had_old {
            std::fs::rename(&self.dest, &old)
                .with_context(|| format!("moving {} aside", weights::shown(&self.dest)))?;
        }
        std::fs::rename(&self.tmp, &self.dest)
            .with_context(|| format!("renaming onto {}", weights::shown(&self.dest)))?;
        if had_old {
            std::fs::remove_dir_all(&old)
                .with_context(|| format!("removing {}", weights::shown(&old)))?;
        }
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        // Only this process's own staging directory, created by `new`.
        let _ = std::fs::remove_dir_all(&self.tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("outdir-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_committed_staging_replaces_only_its_own_kind_holding_only_its_files() {
        let dir = scratch("commit");
        let dest = dir.join("run");
        let st = Staging::new(&dest, "train").unwrap();
        std::fs::create_dir(st.path().join("seed-1")).unwrap();
        std::fs::write(st.path().join("seed-1/summary.json"), b"{}").unwrap();
        std::fs::write(st.path().join("aggregate.json"), b"{}").unwrap();
        st.commit().unwrap();
        let marker = Marker::read(&dest, "train").unwrap();
        assert_eq!(
            marker.files,
            ["aggregate.json", "seed-1/", "seed-1/summary.json"]
        );
        check_output_dir(&dest, "train").unwrap();
        let e = check_output_dir(&dest, "reproduce")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not of policy-export reproduce"), "{e}");
        std::fs::write(dest.join("seed-1/notes.txt"), b"mine").unwrap();
        let e = check_output_dir(&dest, "train").unwrap_err().to_string();
        assert!(
            e.contains("1 entry policy-export did not write (\"seed-1/notes.txt\")"),
            "{e}"
        );
        std::fs::remove_file(dest.join("seed-1/notes.txt")).unwrap();
        std::os::unix::fs::symlink("/etc", dest.join("link")).unwrap();
        let e = check_output_dir(&dest, "train").unwrap_err().to_string();
        assert!(
            e.contains("a symbolic link \"link\", which this tool never writes"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// `reproduce --out docs/reproduction`, as the documents give it, may replace the
    /// committed run: its marker lists every file in it.
    #[test]
    fn the_committed_reproduction_is_marked_as_this_tools() {
        let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/reproduction");
        check_output_dir(&committed, "reproduce").unwrap();
    }
}
