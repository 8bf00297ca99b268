//! The files of an output directory as inputs: what `export` reads of a run is checked
//! against the run's marker, and what it writes stays out of every run.

use std::path::Path;

use anyhow::{Result, bail};
use weights::Error;

use super::marker::{self, Found, Listing, MARKER};

/// The kinds of output directory a marker can mark.
const KINDS: [&str; 2] = ["train", "reproduce"];

/// The directory holding a marker that covers `file`: its own or its parent's (a run's
/// `seed-N/`), where a marker exists at all.
fn marked_dir(file: &Path) -> Option<&Path> {
    let dir = file.parent()?;
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    dir.ancestors()
        .take(2)
        .find(|d| std::fs::symlink_metadata(d.join(MARKER)).is_ok())
}

/// Checks `files`, each in an output directory of this tool's or a directory of one (a
/// run's `seed-N/`), against the marker there: refused, naming it, where a file is not the
/// one the tool wrote (replaced, changed, or never listed), or where the marker is none
/// this tool wrote (junk in its place read as no marker, and a summary from another run
/// was taken). Files no marker covers pass: a directory put together by hand proves
/// nothing either way.
pub fn unchanged(files: &[&Path]) -> Result<()> {
    for file in files {
        let Some(root) = marked_dir(file) else {
            continue;
        };
        let name = file.strip_prefix(root).unwrap_or(file);
        let name = name.to_string_lossy().into_owned();
        let read = KINDS.map(|kind| marker::read(root, kind, std::slice::from_ref(&name)));
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

/// Refuses an output file (`flag` names it) inside an output directory of this tool's, at
/// any depth: it would replace a file the run wrote (its marker, which proves the others,
/// or its metrics), or add one, after which `train` or `reproduce` refuses to replace the
/// run. The directory is judged as the system resolves it (`runs/x/../y.rs` is in `runs`);
/// one that does not exist yet is inside none.
pub fn outside_runs(flag: &str, out: &Path) -> Result<()> {
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let Ok(parent) = parent.canonicalize() else {
        return Ok(());
    };
    match parent
        .ancestors()
        .find(|d| std::fs::symlink_metadata(d.join(MARKER)).is_ok())
    {
        Some(dir) => bail!(Error::Input(format!(
            "{flag} {}: expected a path outside the output directories of {}; {} holds its \
             {MARKER}, which lists what its run wrote",
            weights::shown(out),
            env!("CARGO_PKG_NAME"),
            weights::shown(dir)
        ))),
        None => Ok(()),
    }
}
