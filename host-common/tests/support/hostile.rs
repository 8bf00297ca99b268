//! The hostile-input suite's harness, shared by the two tools' suites
//! (`policy-export/tests/hostile_suite.rs`, `host-sim/tests/hostile_suite.rs`, which include
//! this file): bad files of every kind, and a runner that holds each refusal to the rules of
//! `docs/HOSTILE_INPUT.md`: exit status 2, a short message that says what was expected (or,
//! for a path that does not exist, that it does not), no panic, nothing on standard output,
//! no file created, changed or removed, and no waiting. The other refusal tests (the tools'
//! CLI tests, the Python scripts') run their commands through [`run_counted`] too.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Most processor time a refusal may use: it must come before any work. The child's own
/// processor time, not the clock's, so that what else the host runs does not count.
pub const SLOW: Duration = Duration::from_secs(3);
/// When a case that has not ended is killed. A child that waits (on a FIFO's writer, say)
/// uses no processor time, so only the clock can show it; far beyond any refusal, this is a
/// watchdog against a hang, not a measure of speed.
const WATCHDOG: Duration = Duration::from_secs(60);

/// How a command ran.
pub struct Ran {
    /// Its exit status; `None` if killed by a signal or at the watchdog.
    pub code: Option<i32>,
    /// Whether it was still running at the watchdog.
    pub hung: bool,
    /// The processor time it used, user and system.
    pub cpu: Duration,
    pub stdout: Vec<u8>,
    pub stderr: String,
}

impl Ran {
    /// Why it broke the rules every refusal keeps (it ended, with exit status 2, within
    /// [`SLOW`] of processor time), if it did.
    pub fn late(&self) -> Option<String> {
        if self.hung {
            Some(format!("still running after {WATCHDOG:?}"))
        } else if self.cpu > SLOW {
            Some(format!(
                "used {:?} of processor time: work before the check",
                self.cpu
            ))
        } else {
            None
        }
    }
}

/// Runs `command` to its end (killed at the watchdog) with no standard input, its output
/// caught in files of its own.
pub fn run_counted(command: &mut Command) -> Ran {
    static RUNS: AtomicUsize = AtomicUsize::new(0);
    let logs = Scratch::new(&format!("run-{}", RUNS.fetch_add(1, Ordering::Relaxed)));
    let (out, err) = (logs.join("stdout"), logs.join("stderr"));
    let child = command
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let ended = finish(child);
    Ran {
        code: ended.and_then(|(code, _)| code),
        hung: ended.is_none(),
        cpu: ended.map_or(Duration::ZERO, |(_, cpu)| cpu),
        stdout: std::fs::read(&out).unwrap(),
        stderr: String::from_utf8_lossy(&std::fs::read(&err).unwrap()).into_owned(),
    }
}

/// Waits for `child`: its exit status and processor time, or `None` if it was still running
/// at the watchdog (then killed).
fn finish(mut child: Child) -> Option<(Option<i32>, Duration)> {
    let started = Instant::now();
    let stat = format!("/proc/{}/stat", child.id());
    loop {
        // An ended child that is not yet reaped still shows its times; reaping removes them.
        if let Some(cpu) = cpu_of_ended(&stat) {
            return Some((child.wait().unwrap().code(), cpu));
        }
        if started.elapsed() > WATCHDOG {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The processor time of the process whose `/proc/PID/stat` is `stat`, once it has ended
/// (a zombie); `None` while it runs.
fn cpu_of_ended(stat: &str) -> Option<Duration> {
    let text = std::fs::read_to_string(stat).ok()?;
    // After the command name's closing parenthesis: the state first, then utime and stime
    // as the 12th and 13th fields, in ticks of Linux's USER_HZ, fixed at 100.
    let fields: Vec<&str> = text.rsplit_once(')')?.1.split_whitespace().collect();
    if fields.first() != Some(&"Z") {
        return None;
    }
    let ticks: u64 = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    Some(Duration::from_millis(ticks * 10))
}

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

/// The names in `dir`, sorted (the file-writing suites', not the hostile suites').
#[allow(dead_code)]
pub fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
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
    /// Garbage under a name with an escape sequence and a line break, which a message
    /// must show escaped.
    ControlName,
}

/// Every kind.
pub const BAD: [Bad; 14] = [
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
    Bad::ControlName,
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
            Bad::ControlName => {
                let p = dir.join(format!("{tag}-\u{1b}[2J\nerror: fake"));
                std::fs::write(&p, b"\x00\x01garbage{[\"\xff").unwrap();
                return p;
            }
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
            Bad::NonUtf8Name => vec!["No such file", "expected UTF-8 text"],
            // A policy argument takes a run directory, whose policy file is then missing.
            Bad::Directory => vec!["found a directory", "No such file"],
            Bad::Fifo => vec!["found a FIFO"],
            Bad::Socket => vec!["found a socket"],
            Bad::DevZero | Bad::LinkToDevice => vec!["found a device"],
            Bad::Huge => vec!["expected at most"],
            Bad::Empty | Bad::Garbage | Bad::Truncated | Bad::NotUtf8 => f.malformed.to_vec(),
            // The name shown, escaped.
            Bad::ControlName => vec!["\\u{1b}[2J\\nerror: fake"],
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
fn judge(exe: &Path, cwd: &Path, case: &Case) -> Result<(), String> {
    let before = snapshot(cwd);
    let ran = run_counted(Command::new(exe).args(&case.args).current_dir(cwd));
    let mut broken = Vec::new();
    broken.extend(ran.late());
    if ran.code != Some(2) {
        broken.push(format!("exit {:?}", ran.code));
    }
    if !case.expect.iter().any(|w| ran.stderr.contains(w)) {
        broken.push(format!("no word of {:?}", case.expect));
    }
    if ran.stderr.chars().any(|c| c.is_control() && c != '\n') {
        broken.push("a raw control character on stderr".into());
    }
    if ran.stderr.contains("panicked") || ran.stderr.len() > 1_000 || !ran.stdout.is_empty() {
        broken.push(format!(
            "{} bytes on stdout, a long or panicking message",
            ran.stdout.len()
        ));
    }
    if snapshot(cwd) != before {
        broken.push("files changed".into());
    }
    if broken.is_empty() {
        Ok(())
    } else {
        let said: String = ran.stderr.trim().chars().take(300).collect();
        Err(format!("{}; stderr: {said}", broken.join(", ")))
    }
}

/// Runs every case and fails naming each one that broke a rule; returns how many ran.
pub fn run_all(exe: &Path, cwd: &Path, cases: &[Case]) -> usize {
    let failures: Vec<String> = cases
        .iter()
        .filter_map(|c| {
            judge(exe, cwd, c)
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

/// A line break, an escape sequence and a carriage return, as a value or in a flag's name:
/// a message that copied it raw printed a forged error line, moved the cursor, or overwrote
/// its own line. The CLI suites', not the hostile suites'.
#[allow(dead_code)]
pub const FORGED: &str = "a\u{1b}[2J\r\nerror: fake";

/// [`FORGED`] as a message shows it, escaped.
#[allow(dead_code)]
pub const FORGED_SHOWN: &str = "a\\u{1b}[2J\\r\\nerror: fake";

/// Holds the command-line parser's refusal of `args`, which hold [`FORGED`], to the rules:
/// exit status 2 within the refusals' processor time; one line that begins `error`, the
/// first, naming `flag` and showing the forged text escaped; no control character but the line
/// breaks between clap's lines (its reason, tip, usage and pointer to `--help`).
#[allow(dead_code)]
#[track_caller]
pub fn refused_escaped(exe: &Path, args: &[&str], flag: &str) {
    let ran = run_counted(Command::new(exe).args(args));
    let err = &ran.stderr;
    let seen = format!("{args:?}: exit {:?}: {err:?}", ran.code);
    assert_eq!(ran.code, Some(2), "{seen}");
    assert!(ran.late().is_none(), "{seen}");
    assert!(ran.stdout.is_empty(), "{seen}");
    assert!(!err.chars().any(|c| c.is_control() && c != '\n'), "{seen}");
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error")).collect();
    assert_eq!(errors.len(), 1, "{seen}");
    assert!(err.starts_with(errors[0]), "{seen}");
    assert!(errors[0].starts_with("error: "), "{seen}");
    assert!(errors[0].contains(flag), "{seen}");
    assert!(errors[0].contains(FORGED_SHOWN), "{seen}");
}
