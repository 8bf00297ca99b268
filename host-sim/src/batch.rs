//! Files written together, all or none: a command's pictures, and the files written beside
//! them (`identify`'s rig file). Each is written under a temporary name in a private
//! directory beside its place, then all are put in place together.

use std::path::{Path, PathBuf};

use weights::files::{hidden_name, stale};

/// Files written together, all or none: each under a temporary name ([`Batch::file`]
/// before it is written), then put in place together by [`Batch::commit`]. Dropped
/// uncommitted (a failure on the way), it removes the temporaries and the directories it
/// created ([`Batch::dir`]), so a failed command leaves what was there.
#[derive(Default)]
pub struct Batch {
    /// Each temporary and its place.
    files: Vec<(PathBuf, PathBuf)>,
    /// The private directories the temporaries are in.
    private: Vec<PathBuf>,
    /// The directories created, outermost first.
    created: Vec<PathBuf>,
    committed: bool,
}

/// One place of a commit under way: the old file's other name, if there was one.
struct Placing<'a> {
    path: &'a Path,
    aside: Option<PathBuf>,
    placed: bool,
}

impl Batch {
    /// Creates `dir` and the directories above it that are missing, to be removed again
    /// (if still empty) should the batch fail.
    pub fn dir(&mut self, dir: &Path) -> weights::Result<()> {
        let missing = dir
            .ancestors()
            .take_while(|d| !d.as_os_str().is_empty() && std::fs::symlink_metadata(d).is_err());
        // Recorded first: a creation that fails half-way leaves the outer ones behind.
        let mut missing: Vec<PathBuf> = missing.map(Path::to_path_buf).collect();
        missing.reverse();
        self.created.extend(missing);
        std::fs::create_dir_all(dir)
            .map_err(|e| weights::Error::Io(format!("creating {}: {e}", weights::shown(dir))))
    }

    /// The temporary to write `path`'s new contents to (its name `path`'s, so that an
    /// encoder choosing the format by the extension sees the right one), to be renamed to
    /// `path` by [`Batch::commit`]. It lies in a directory created new for it beside `path`
    /// (`.NAME.PID.d`, mode 0700): the plotting library opens its files by path, and nothing
    /// can be planted in that directory for it to write through (a link at a temporary's
    /// predictable name beside the place was written through, a file elsewhere overwritten).
    pub fn file(&mut self, path: &Path) -> weights::Result<PathBuf> {
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        recover(path);
        let private = dir.join(hidden_name(path, std::process::id(), "d"));
        // Only an earlier process of this id left anything at that name, or someone planted it.
        match std::fs::symlink_metadata(&private) {
            Ok(m) if m.is_dir() => std::fs::remove_dir_all(&private),
            Ok(_) => std::fs::remove_file(&private),
            Err(_) => Ok(()),
        }
        .and_then(|()| {
            use std::os::unix::fs::DirBuilderExt;
            std::fs::DirBuilder::new().mode(0o700).create(&private)
        })
        .map_err(|e| weights::Error::Io(format!("writing {}: {e}", weights::shown(path))))?;
        self.private.push(private.clone());
        let tmp = private.join(path.file_name().unwrap_or_default());
        self.files.push((tmp.clone(), path.to_path_buf()));
        Ok(tmp)
    }

    /// The temporary of `path`, in the private directory of `first`'s temporary (which
    /// [`Batch::file`] made), for a writer that writes both beside each other.
    pub fn beside(&mut self, first: &Path, path: &Path) -> PathBuf {
        let tmp = first.with_file_name(path.file_name().unwrap_or_default());
        self.files.push((tmp.clone(), path.to_path_buf()));
        tmp
    }

    /// Puts every file in place, or none: each old file is first given a second name
    /// (`.NAME.PID.old`, a hard link, so the place is never empty), every place checked to
    /// hold a regular file or nothing, then each temporary renamed over its place. A failure
    /// puts back the old files, removes the new ones and the temporaries, and says which
    /// file failed.
    pub fn commit(mut self) -> weights::Result<()> {
        let mut placing = Vec::new();
        let done = set_aside(&self.files, &mut placing).and_then(|()| {
            for ((tmp, path), p) in self.files.iter().zip(&mut placing) {
                std::fs::rename(tmp, path).map_err(|e| failed(path, &e))?;
                p.placed = true;
            }
            Ok(())
        });
        if let Err(m) = done {
            return Err(weights::Error::Io(m + &restore(&placing)));
        }
        for aside in placing.iter().filter_map(|p| p.aside.as_ref()) {
            let _ = std::fs::remove_file(aside);
        }
        for private in &self.private {
            let _ = std::fs::remove_dir_all(private);
        }
        self.committed = true;
        Ok(())
    }
}

fn failed(path: &Path, e: &dyn std::fmt::Display) -> String {
    format!("writing {}: {e}", weights::shown(path))
}

/// Gives each old file among `files`' places a second name, recording each place in
/// `placing`; refuses a place that holds anything but a regular file.
fn set_aside<'a>(
    files: &'a [(PathBuf, PathBuf)],
    placing: &mut Vec<Placing<'a>>,
) -> std::result::Result<(), String> {
    for (_, path) in files {
        let old = match std::fs::symlink_metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
            Err(e) => return Err(failed(path, &e)),
            Ok(m) if m.is_file() => true,
            // Taken while the work ran (it was checked before).
            Ok(m) => {
                let found = weights::files::kind(&m.file_type());
                return Err(failed(
                    path,
                    &format!("expected a regular file (or nothing), found {found}"),
                ));
            }
        };
        let mut p = Placing {
            path,
            aside: None,
            placed: false,
        };
        if old {
            let aside = path.with_file_name(hidden_name(path, std::process::id(), "old"));
            // Moved where the file system has no hard links.
            std::fs::hard_link(path, &aside)
                .or_else(|_| std::fs::rename(path, &aside))
                .map_err(|e| failed(path, &e))?;
            p.aside = Some(aside);
        }
        placing.push(p);
    }
    Ok(())
}

/// Undoes a commit that failed: each old file back in its place (a hard link's rename
/// onto the same file does nothing, so the second name is then removed), each new file
/// that had none removed; what could not be put back, said.
fn restore(placing: &[Placing<'_>]) -> String {
    let mut kept = String::new();
    for p in placing.iter().rev() {
        match &p.aside {
            Some(aside) => match std::fs::rename(aside, p.path) {
                Ok(()) => {
                    let _ = std::fs::remove_file(aside);
                }
                Err(e) => {
                    kept += &format!(
                        "; the old {} is kept as {} ({e})",
                        weights::shown(p.path),
                        weights::shown(aside)
                    );
                }
            },
            None if p.placed => {
                let _ = std::fs::remove_file(p.path);
            }
            None => {}
        }
    }
    kept
}

impl Drop for Batch {
    fn drop(&mut self) {
        if self.committed {
            return;
        }
        for private in &self.private {
            let _ = std::fs::remove_dir_all(private);
        }
        // Innermost first; one that holds anything else stays.
        for dir in self.created.iter().rev() {
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// What killed writers left beside `path`: their private directories are removed, and a
/// killed commit's old file (`.NAME.PID.old`) is put back where its place is empty (the
/// commit had moved it aside), or removed where the place holds a file again.
fn recover(path: &Path) {
    for d in stale(path, &["d"]) {
        if std::fs::symlink_metadata(&d).is_ok_and(|m| m.is_dir()) {
            let _ = std::fs::remove_dir_all(&d);
        }
    }
    for old in stale(path, &["old"]) {
        if !std::fs::symlink_metadata(&old).is_ok_and(|m| m.is_file()) {
            continue;
        }
        if std::fs::symlink_metadata(path).is_err() {
            let _ = std::fs::rename(&old, path);
        } else {
            let _ = std::fs::remove_file(&old);
        }
    }
}
