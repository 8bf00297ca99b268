//! The hostile-input suite's harness, shared by the two tools' suites
//! (`policy-export/tests/hostile_suite.rs`, `host-sim/tests/hostile_suite.rs`, which include
//! this file): bad files of every kind, and a runner that holds each refusal to the rules of
//! `docs/HOSTILE_INPUT.md`: exit status 2, a short message that says what was expected (or,
//! for a path that does not exist, that it does not), no panic, nothing on standard output,
//! no file created, changed or removed, and no waiting.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Longest a refusal may take: it must come before any work.
const SLOW: Duration = Duration::from_secs(3);
/// When a case that has not ended is killed.
const DEADLINE: Duration = Duration::from_secs(20);

/// A directory of the suite's own, removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    pub fn new(name: &str) -> Scratch {
        let d = std::env::temp_dir().join(format!("hostile-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Scratch(d)
    }

    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Every entry under `dir` (not following links), with its kind, length and contents for
/// regular files: what a refused command must leave exactly as it was.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, (String, Vec<u8>)> {
    let mut out = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let e = e.unwrap();
            let (p, t) = (e.path(), e.file_type().unwrap());
            // The length and time, and the first MiB (the suite's huge files are sparse).
            let meta = std::fs::symlink_metadata(&p).unwrap();
            let mut body = Vec::new();
            if t.is_file() {
                use std::io::Read;
                let f = std::fs::File::open(&p).unwrap();
                f.take(1 << 20).read_to_end(&mut body).unwrap();
            }
            let seen = format!("{t:?} {} {:?}", meta.len(), meta.modified().ok());
            out.insert(p.clone(), (seen, body));
            if t.is_dir() {
                todo.push(p);
            }
        }
    }
    out
}

/// The kinds of bad file a path argument is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bad {
    Missing,
    Directory,
    Fifo,
    Socket,
    DevZero,
    DanglingLink,
    LinkToDevice,
    Empty,
    Garbage,
    Truncated,
    NotUtf8,
    Huge,
    NonUtf8Name,
}

/// Every kind.
pub const BAD: [Bad; 13] = [
    Bad::Missing,
    Bad::Directory,
    Bad::Fifo,
    Bad::Socket,
    Bad::DevZero,
    Bad::DanglingLink,
    Bad::LinkToDevice,
    Bad::Empty,
    Bad::Garbage,
    Bad::Truncated,
    Bad::NotUtf8,
    Bad::Huge,
    Bad::NonUtf8Name,
];

/// What a slot's files look like: a good one (truncated for [`Bad::Truncated`]), its
/// reader's size cap, the words any refusal of malformed content names, and the kinds
/// that are not bad for it (an empty TOML file is a valid configuration).
pub struct Format {
    pub valid: Vec<u8>,
    pub cap: u64,
    pub malformed: &'static [&'static str],
    pub fine: &'static [Bad],
}

impl Bad {
    /// Makes the bad file in `dir` under a name of its own (`tag` keeps slots apart).
    pub fn make(self, dir: &Path, tag: &str, f: &Format) -> PathBuf {
        let p = dir.join(format!("{tag}-{self:?}"));
        match self {
            Bad::Missing => {}
            Bad::Directory => std::fs::create_dir(&p).unwrap(),
            Bad::Fifo => {
                mkfifo(&p);
            }
            Bad::Socket => {
                std::mem::forget(std::os::unix::net::UnixListener::bind(&p).unwrap());
            }
            Bad::DevZero => return PathBuf::from("/dev/zero"),
            Bad::DanglingLink => std::os::unix::fs::symlink(dir.join("nowhere"), &p).unwrap(),
            Bad::LinkToDevice => std::os::unix::fs::symlink("/dev/zero", &p).unwrap(),
            Bad::Empty => std::fs::write(&p, b"").unwrap(),
            Bad::Garbage => std::fs::write(&p, b"\x00\x01garbage{[\"\xff").unwrap(),
            Bad::Truncated => std::fs::write(&p, &f.valid[..f.valid.len() / 2]).unwrap(),
            Bad::NotUtf8 => {
                let mut b = f.valid.clone();
                b.splice(0..0, [0xff, 0xfe]);
                std::fs::write(&p, b).unwrap();
            }
            // Sparse: a byte past the cap costs no disk.
            Bad::Huge => std::fs::File::create(&p)
                .and_then(|h| h.set_len(f.cap + 1))
                .unwrap(),
            Bad::NonUtf8Name => {
                use std::os::unix::ffi::OsStringExt;
                let name = [format!("{tag}-").into_bytes(), vec![0xff, 0xfe]].concat();
                return dir.join(OsString::from_vec(name));
            }
        }
        p
    }

    /// Words one of which the refusal must contain.
    pub fn expect(self, f: &Format) -> Vec<&'static str> {
        match self {
            Bad::Missing | Bad::DanglingLink => vec!["No such file"],
            // A flag that takes text refuses a name that is not UTF-8 outright.
            Bad::NonUtf8Name => vec!["No such file", "invalid UTF-8"],
            // A policy argument takes a run directory, whose policy file is then missing.
            Bad::Directory => vec!["found a directory", "No such file"],
            Bad::Fifo => vec!["found a FIFO"],
            Bad::Socket => vec!["found a socket"],
            Bad::DevZero | Bad::LinkToDevice => vec!["found a device"],
            Bad::Huge => vec!["expected at most"],
            Bad::Empty | Bad::Garbage | Bad::Truncated | Bad::NotUtf8 => f.malformed.to_vec(),
        }
    }
}

/// A FIFO at `path`: a file no tool may wait on.
pub fn mkfifo(path: &Path) {
    let ok = Command::new("mkfifo").arg(path).status().unwrap().success();
    assert!(ok, "mkfifo {}", path.display());
}

/// Every slot's command line (its tag, file format and arguments around the bad path) given
/// every kind of bad file its format cannot take, made in `dir`.
pub fn bad_input_cases<'a>(
    dir: &Path,
    slots: impl IntoIterator<Item = (&'a str, &'a Format, &'a dyn Fn(&Path) -> Vec<OsString>)>,
) -> Vec<Case> {
    let mut cases = Vec::new();
    for (tag, format, args) in slots {
        for bad in BAD.into_iter().filter(|b| !format.fine.contains(b)) {
            let path = bad.make(dir, tag, format);
            cases.push(Case::new(
                format!("{tag} {bad:?}"),
                &args(&path),
                &bad.expect(format),
            ));
        }
    }
    cases
}

/// One command that must be refused, and what its message must say (any of `expect`).
pub struct Case {
    pub label: String,
    pub args: Vec<OsString>,
    pub expect: Vec<&'static str>,
}

impl Case {
    pub fn new<S: AsRef<std::ffi::OsStr>>(
        label: String,
        args: &[S],
        expect: &[&'static str],
    ) -> Case {
        Case {
            label,
            args: args.iter().map(|a| a.as_ref().to_owned()).collect(),
            expect: expect.to_vec(),
        }
    }
}

/// Runs `exe` with the case's arguments in `cwd`; why it broke a rule, if it did.
fn judge(exe: &Path, cwd: &Path, logs: &Path, case: &Case) -> Result<(), String> {
    let before = snapshot(cwd);
    let (out, err) = (logs.join("stdout"), logs.join("stderr"));
    let started = Instant::now();
    let mut child = Command::new(exe)
        .args(&case.args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if started.elapsed() > DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("still running after {DEADLINE:?}"));
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    let (stdout, stderr) = (
        std::fs::read(&out).unwrap(),
        String::from_utf8_lossy(&std::fs::read(&err).unwrap()).into_owned(),
    );
    let mut broken = Vec::new();
    if started.elapsed() > SLOW {
        broken.push(format!(
            "took {:?}: work before the check",
            started.elapsed()
        ));
    }
    if status.code() != Some(2) {
        broken.push(format!("exit {status}"));
    }
    if !case.expect.iter().any(|w| stderr.contains(w)) {
        broken.push(format!("no word of {:?}", case.expect));
    }
    if stderr.contains("panicked") || stderr.len() > 1_000 || !stdout.is_empty() {
        broken.push(format!(
            "{} bytes on stdout, a long or panicking message",
            stdout.len()
        ));
    }
    if snapshot(cwd) != before {
        broken.push("files changed".into());
    }
    if broken.is_empty() {
        Ok(())
    } else {
        let said: String = stderr.trim().chars().take(300).collect();
        Err(format!("{}; stderr: {said}", broken.join(", ")))
    }
}

/// Runs every case and fails naming each one that broke a rule; returns how many ran.
pub fn run_all(exe: &Path, cwd: &Path, cases: &[Case]) -> usize {
    let logs = Scratch::new("logs");
    let failures: Vec<String> = cases
        .iter()
        .filter_map(|c| {
            judge(exe, cwd, &logs.0, c)
                .err()
                .map(|e| format!("{}: {e}", c.label))
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} cases broke a rule:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    cases.len()
}

/// A safetensors file of a 4-16-16-2 network whose every weight is `w`, its tensors named
/// under `prefix`.
pub fn uniform_policy(path: &Path, w: f32, prefix: &str) {
    let shapes: [(&str, Vec<usize>); 6] = [
        ("fc1.weight", vec![16, 4]),
        ("fc1.bias", vec![16]),
        ("fc2.weight", vec![16, 16]),
        ("fc2.bias", vec![16]),
        ("fc3.weight", vec![2, 16]),
        ("fc3.bias", vec![2]),
    ];
    let (mut header, mut data) = (Vec::new(), Vec::new());
    for (name, shape) in shapes {
        let n: usize = shape.iter().product();
        let start = data.len();
        data.extend(std::iter::repeat_n(w.to_le_bytes(), n).flatten());
        let name = format!("{:?}", format!("{prefix}{name}"));
        header.push(format!(
            "{name}:{{\"dtype\":\"F32\",\"shape\":{shape:?},\"data_offsets\":[{start},{}]}}",
            data.len()
        ));
    }
    let header = format!("{{{}}}", header.join(","));
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(&data);
    std::fs::write(path, bytes).unwrap();
}

/// Runs `exe` with a standard output whose reader has already gone; its exit status and
/// standard error.
pub fn with_stdout_closed(exe: &Path, args: &[OsString], cwd: &Path) -> (Option<i32>, String) {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(exe)
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}
