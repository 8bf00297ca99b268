//! The files of an output directory as inputs: what `export` reads of a run is checked
//! against the run's marker (what it writes stays out of every run:
//! `weights::files::outside_runs`).

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use weights::Error;

use super::marker::{self, Found, Listing, MARKER};

/// The kinds of output directory a marker can mark.
const KINDS: [&str; 2] = ["train", "reproduce"];

/// The directory holding a marker that covers `file`, as the system resolves it (`.` in a
/// run's `seed-N/`, or a link to it, was read as no run): its own or its parent's (a run's
/// `seed-N/`), where a marker exists at all; with `file` as resolved.
fn marked_dir(file: &Path) -> Option<(PathBuf, PathBuf)> {
    let file = file.canonicalize().ok()?;
    let root = file
        .parent()?
        .ancestors()
        .take(2)
        .find(|d| std::fs::symlink_metadata(d.join(MARKER)).is_ok())?
        .to_path_buf();
    Some((root, file))
}

/// Checks `files`, each in an output directory of this tool's or a directory of one (a
/// run's `seed-N/`), against the marker there: refused, naming it, where a file is not the
/// one the tool wrote (replaced, changed, or never listed), or where the marker is none
/// this tool wrote (junk in its place read as no marker, and a summary from another run
/// was taken). Files no marker covers pass: a directory put together by hand proves
/// nothing either way.
pub fn unchanged(files: &[&Path]) -> Result<()> {
    for file in files {
        let Some((root, resolved)) = marked_dir(file) else {
            continue;
        };
        let name = resolved.strip_prefix(&root).unwrap_or(&resolved);
        let name = name.to_string_lossy().into_owned();
        let read = KINDS.map(|kind| marker::read(&root, kind, std::slice::from_ref(&name)));
        let m = match read {
            [Ok(m), _] | [_, Ok(m)] => m,
            [Err(why), _] => bail!(Error::Input(format!(
                "{}: expected the marker its run wrote, or none: {why}",
                weights::shown(&root.join(MARKER))
            ))),
        };
        if m.listing == Listing::Entries && m.found != [Found::Owned] {
            bail!(Error::Input(format!(
                "{}: expected the file its run wrote, as its {MARKER} lists it, found {}",
                weights::shown(file),
                match m.found.first() {
                    Some(Found::Changed) => "one of another size or content",
                    _ => "one the marker does not list",
                }
            )));
        }
    }
    Ok(())
}
