//! Files in and out, the careful way: inputs are read only if they are regular files, never
//! past a size cap and never blocking (a FIFO or a device is refused, not read); outputs go
//! to a temporary file beside the target and are renamed over it, and only over a regular
//! file, so a crash leaves the old file or the new one and a device node or a directory is
//! never replaced.

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use crate::{Error, Result};

mod apart;
pub use apart::check_apart;

/// Largest policy file read: every supported network fits many times over (width 256 is 270
/// KB), yet `/dev/zero` or a runaway file cannot exhaust memory.
pub const MAX_POLICY_BYTES: u64 = 64 << 20;

/// Opens `path` for reading if it is a regular file, without blocking on a FIFO.
pub fn open_regular(path: &Path) -> Result<File> {
    let mut opts = std::fs::OpenOptions::new();
    opts.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // A FIFO opened for reading blocks until a writer appears; non-blocking, the open
        // returns at once and the type check below refuses it.
        opts.custom_flags(libc::O_NONBLOCK);
    }
    let file = opts.open(path).map_err(|e| {
        // A socket cannot be opened at all: say what it is rather than the system's word.
        Error::Input(match std::fs::metadata(path) {
            Ok(m) if !m.is_file() => format!(
                "{}: expected a regular file, found {}",
                crate::shown(path),
                kind(&m.file_type())
            ),
            _ => format!("{}: {e}", crate::shown(path)),
        })
    })?;
    let meta = file
        .metadata()
        .map_err(|e| Error::Input(format!("{}: {e}", crate::shown(path))))?;
    if !meta.is_file() {
        return Err(Error::Input(format!(
            "{}: expected a regular file, found {}",
            crate::shown(path),
            kind(&meta.file_type())
        )));
    }
    Ok(file)
}

/// The bytes of the regular file `path`, refusing files larger than `max` bytes.
pub fn read_capped(path: &Path, max: u64) -> Result<Vec<u8>> {
    let file = open_regular(path)?;
    // Room for the whole file and the byte that shows it ends, so that reading never
    // doubles the buffer: a file costs its size in memory, not twice or three times it.
    let size = file.metadata().map_or(0, |m| m.len()).min(max);
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0).saturating_add(1));
    // Opened as a regular file, it fails to read for a reason of the system's (an I/O error),
    // not for what was named: exit status 1, Python's OSError, as for a write.
    file.take(max + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::Io(format!("reading {}: {e}", crate::shown(path))))?;
    if bytes.len() as u64 > max {
        return Err(Error::Input(format!(
            "{}: expected at most {max} bytes, found more",
            crate::shown(path)
        )));
    }
    Ok(bytes)
}

/// What a file is, for messages: "a regular file", "a FIFO", "a device", "a directory", ...
pub fn kind(t: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_file() {
        "a regular file"
    } else if t.is_dir() {
        "a directory"
    } else if t.is_symlink() {
        "a symbolic link"
    } else {
        "something that is not a regular file"
    }
}

/// Checks, before the work, every input a command will read and every output it will write,
/// each given with the flag or argument that named it (for the message): each input a
/// regular file this process can open ([`check_input`]), each output a path
/// [`check_output`] accepts against every input. The first refusal is returned, prefixed by
/// its flag; nothing is read or written but a probe of each output's place.
pub fn check_io(inputs: &[(&str, &Path)], outputs: &[(&str, &Path)]) -> Result<()> {
    let labelled = |label: &str, e: Error| match e {
        Error::Input(m) => Error::Input(format!("{label} {m}")),
        other => other,
    };
    for (label, path) in inputs {
        check_input(path).map_err(|e| labelled(label, e))?;
    }
    let all: Vec<&Path> = inputs.iter().map(|(_, p)| *p).collect();
    for (label, path) in outputs {
        check_output(path, &all)
            .and_then(|()| outside_runs(path))
            .map_err(|e| labelled(label, e))?;
    }
    Ok(())
}

/// The marker an output directory of `policy-export` (`train`, `reproduce`) holds: the list
/// of what its run wrote, each file with its size and digest, which proves them.
pub const RUN_MARKER: &str = ".cartpole-run";

/// Refuses an output at or inside an output directory of `policy-export` (one holding
/// [`RUN_MARKER`]), at any depth, as the system resolves it: it would replace a file the run
/// wrote (the marker itself, which proves the others) or add one, after which the next
/// `train` to that directory refuses to replace it. A directory not made yet is judged by
/// where it would be made (`new/../RUN/x` is in `RUN`: `new` is made, then left).
pub fn outside_runs(path: &Path) -> Result<()> {
    match apart::resolved(path)
        .ancestors()
        .find(|d| std::fs::symlink_metadata(d.join(RUN_MARKER)).is_ok())
    {
        Some(run) => Err(Error::Input(format!(
            "{}: expected a path outside the output directories of policy-export; {} holds \
             its {RUN_MARKER}, which lists what its run wrote",
            crate::shown(path),
            crate::shown(run)
        ))),
        None => Ok(()),
    }
}

/// Checks that `path` can be read: a regular file this process can open (without blocking,
/// so a FIFO is refused, not waited on).
pub fn check_input(path: &Path) -> Result<()> {
    open_regular(path).map(drop)
}

/// Checks that something can be created at `path`: its nearest existing ancestor is a
/// directory in which this process can create an entry. Permissions cannot tell (root
/// ignores them; a read-only mount or `/proc` refuses anyway), so it is tried: a hidden
/// `.NAME.PID.probe` is created there and removed at once.
pub fn check_place(path: &Path) -> Result<()> {
    if let Some(mask) = umask().filter(|m| m & 0o700 != 0) {
        return Err(Error::Input(format!(
            "{}: the process's umask {mask:04o} takes from this process the directories and \
             files it makes (a directory made for the output could not be written in, after \
             the work); expected one that leaves their owner read, write and search, such as \
             0022 or 0077",
            crate::shown(path)
        )));
    }
    for dir in path.ancestors().skip(1) {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        let meta = match std::fs::metadata(dir) {
            Ok(m) => m,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                continue;
            }
            Err(e) => return Err(Error::Input(format!("{}: {e}", crate::shown(dir)))),
        };
        if !meta.is_dir() {
            return Err(Error::Input(format!(
                "{}: expected {} to be a directory, found {}",
                crate::shown(path),
                crate::shown(dir),
                kind(&meta.file_type())
            )));
        }
        return writable(dir, path).map_err(|e| {
            Error::Input(format!(
                "{}: expected a directory this process can write in, but {} refuses: {e}",
                crate::shown(path),
                crate::shown(dir)
            ))
        });
    }
    Ok(())
}

/// The process's file mode creation mask, as Linux reports it (`None` elsewhere): read, not
/// set and restored, which would change it for other threads in between.
fn umask() -> Option<u32> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find_map(|l| l.strip_prefix("Umask:"))?;
    u32::from_str_radix(line.trim(), 8).ok()
}

/// Whether this process can create and remove entries in `dir`, tried (permissions cannot
/// tell: [`check_place`]) with a hidden `.NAME.PID.probe` for `path`, removed at once.
pub fn writable(dir: &Path, path: &Path) -> std::io::Result<()> {
    let probe = dir.join(hidden_name(path, std::process::id(), "probe"));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .and_then(|_| std::fs::remove_file(&probe))
}

/// Whether `path` as written ends in a `.` component (`run/.`): a name the path's
/// components hide, which a rename onto it refuses after the work.
pub fn ends_in_dot(path: &Path) -> bool {
    let text = path.as_os_str().as_encoded_bytes();
    text == b"." || text.ends_with(b"/.")
}

/// Refuses a directory output (`flag`'s) that does not exist and whose last component is
/// `.` or `..` after others (`out/new/.`, `out/new/../`): the first was refused by the
/// system after the work, the second made `out/new` and wrote in `out`. One that exists
/// (`a/.`, `../..`) is the directory it names.
pub fn check_dir_name(flag: &str, path: &Path) -> Result<()> {
    let text = path.as_os_str().as_encoded_bytes();
    // Trailing slashes name the same directory: `new/../` is `new/..`.
    let trimmed = &text[..text.iter().rposition(|&b| b != b'/').map_or(0, |i| i + 1)];
    let last = trimmed.rsplit(|&b| b == b'/').next().unwrap_or_default();
    let dotted = trimmed.contains(&b'/') && (last == b"." || last == b"..");
    if dotted && !path.is_dir() {
        return Err(Error::Input(format!(
            "{flag} {}: expected a directory named by its own name, found a new path ending \
             in '/{}'",
            crate::shown(path),
            String::from_utf8_lossy(last)
        )));
    }
    Ok(())
}

/// Checks that `path` can be an output: absent, or a regular file (which will be replaced),
/// not the same file as any of `inputs`, in a place this process can write
/// ([`check_place`]). Call it before the work that produces the output, so a bad `--out`
/// costs nothing.
pub fn check_output(path: &Path, inputs: &[&Path]) -> Result<()> {
    // A trailing `/` names a directory, which a file cannot be written as: its name
    // (`file_name` reads past the slash) passed, and the write failed after the work.
    let slash = path.as_os_str().as_encoded_bytes().ends_with(b"/");
    if path.file_name().is_none() || ends_in_dot(path) || slash {
        return Err(Error::Input(format!(
            "{}: expected an output file name{}",
            crate::shown(path),
            if slash {
                ", found a path ending in '/'"
            } else {
                ""
            }
        )));
    }
    match std::fs::symlink_metadata(path) {
        // A missing parent, or a file where one should be: check_place says which.
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
            ) => {}
        Err(e) => return Err(Error::Input(format!("{}: {e}", crate::shown(path)))),
        Ok(meta) if !meta.is_file() => {
            return Err(Error::Input(format!(
                "{}: expected a regular file to replace (or no file), found {}",
                crate::shown(path),
                kind(&meta.file_type())
            )));
        }
        Ok(_) => {}
    }
    for input in inputs {
        if same_file(path, input) {
            return Err(Error::Input(format!(
                "{}: the output would overwrite the input {}",
                crate::shown(path),
                crate::shown(input)
            )));
        }
    }
    check_place(path)
}

fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(a), Ok(b)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return a.dev() == b.dev() && a.ino() == b.ino();
        }
    }
    matches!(
        (a.canonicalize(), b.canonicalize()),
        (Ok(a), Ok(b)) if a == b
    )
}

/// Longest output name its hidden siblings keep whole. A longer one keeps its first bytes up
/// to this many, then `~` and its whole name's digest ([`hidden_stem`]): with a process id
/// (10 digits at most) and a suffix (7 bytes at most: `partial`) a hidden name stays within a
/// file system's 255 bytes, where a name of 243 bytes or more made the probe fail and a valid
/// output refused; and two outputs sharing their first bytes still have hidden names of their
/// own.
const HIDDEN_WHOLE_MAX: usize = 218;

/// The hidden sibling `.STEM.PID.SUFFIX` of `path` (a temporary, a probe, a staging
/// directory), its stem the name itself or, past [`HIDDEN_WHOLE_MAX`] bytes, a cut of it
/// unique to it; [`stale`] finds those of writers that are gone.
pub fn hidden_name(path: &Path, pid: u32, suffix: &str) -> String {
    format!(".{}.{pid}.{suffix}", hidden_stem(path))
}

/// `path`'s name, or past [`HIDDEN_WHOLE_MAX`] bytes (or not UTF-8) its beginning, `~` and
/// the 64-bit FNV-1a digest of the whole name's bytes in hexadecimal: at least 14 bytes
/// longer than any name kept whole, so never one's stem. A name that is not UTF-8 is shown
/// lossily, so two that differ only in their invalid bytes part by the digest alone.
fn hidden_stem(path: &Path) -> String {
    let raw = path.file_name().unwrap_or_default();
    let name = raw.to_string_lossy();
    if name.len() <= HIDDEN_WHOLE_MAX && raw.to_str().is_some() {
        return name.into_owned();
    }
    let mut end = HIDDEN_WHOLE_MAX.min(name.len());
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    let digest = firmware::link::digest::Fnv::default()
        .bytes(raw.as_encoded_bytes())
        .finish();
    format!("{}~{digest:016x}", &name[..end])
}

/// The temporary name `write_atomic` uses for `path`: hidden, beside it, unique to this
/// process: `.NAME.PID.tmp`.
pub fn temp_path(path: &Path) -> PathBuf {
    path.with_file_name(hidden_name(path, std::process::id(), "tmp"))
}

/// Makes way for this process's own temporary `tmp`. Whatever is there (a file, a symbolic
/// link, a FIFO) was left by an earlier process of the same id, or planted: never a live
/// writer's. A symbolic link there was followed (a file elsewhere overwritten, the output
/// made a link to it) and a FIFO blocked the write for ever; a directory is left, and the
/// create that follows fails.
pub fn clear_own(tmp: &Path) {
    if std::fs::symlink_metadata(tmp).is_ok_and(|m| !m.is_dir()) {
        let _ = std::fs::remove_file(tmp);
    }
}

/// Whether process `pid` is still running. Only Linux can tell (`/proc`); elsewhere every
/// process counts as running, so nothing a live writer owns is ever removed.
pub fn pid_alive(pid: u32) -> bool {
    pid == std::process::id()
        || !Path::new("/proc/self").exists()
        || Path::new(&format!("/proc/{pid}")).exists()
}

/// Removes what killed writers left beside `path`: regular files `.NAME.PID.SUFFIX` (for
/// each of `suffixes`) whose process is gone. Directories are never removed here: a writer
/// of directories proves each is its own first ([`stale`] finds them).
pub fn remove_stale(path: &Path, suffixes: &[&str]) {
    for p in stale(path, suffixes) {
        if std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_file()) {
            let _ = std::fs::remove_file(&p);
        }
    }
}

/// The entries `.STEM.PID.SUFFIX` beside `path` ([`hidden_name`], for each of `suffixes`)
/// whose process is gone: what killed writers of `path` left.
pub fn stale(path: &Path, suffixes: &[&str]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let (Some(name), Some(dir)) = (path.file_name(), path.parent()) else {
        return found;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    // Earlier versions named a hidden sibling after the whole name, however long: a killed
    // one's are found too (not those of the one that cut names at 200 bytes, without a
    // digest: such a cut is no one output's).
    let prefixes = [
        format!(".{}.", hidden_stem(Path::new(name))),
        format!(".{}.", name.to_string_lossy()),
    ];
    let Ok(entries) = std::fs::read_dir(dir) else {
        return found;
    };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let rest = prefixes.iter().find_map(|p| file.strip_prefix(p.as_str()));
        let Some((pid, suffix)) = rest.and_then(|r| r.split_once('.')) else {
            continue;
        };
        if suffixes.contains(&suffix) && pid.parse().is_ok_and(|p| !pid_alive(p)) {
            found.push(e.path());
        }
    }
    found
}

/// Writes `bytes` to a file created new at `tmp` (`O_EXCL`): never through a link, or into
/// a FIFO, put there since the name was cleared.
pub fn write_new(tmp: &Path, bytes: &[u8]) -> std::io::Result<()> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(tmp)
        .and_then(|mut f| f.write_all(bytes))
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so
/// a crash leaves either the old file or the new one, never half of one. Refuses (before
/// writing anything) a `path` that exists and is not a regular file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    check_output(path, &[])?;
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::Io(format!("creating {}: {e}", crate::shown(dir))))?;
    // A killed writer's temporary, or a probe of check_place.
    remove_stale(path, &["tmp", "probe"]);
    let tmp = temp_path(path);
    clear_own(&tmp);
    write_new(&tmp, bytes)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::Io(format!("writing {}: {e}", crate::shown(path)))
        })
}

#[cfg(test)]
mod tests;
