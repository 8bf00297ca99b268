//! The host's end of the link (`docs/LINK.md`): requests out, answers back within a
//! timeout, every answer checked for its kind and sequence number. A [`Remote`] is a target
//! in another process (QEMU, or the target built for the host) or the same target code in
//! this one, the software-in-the-loop reference.

use std::io::{Read, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::Duration;

use anyhow::{Result, anyhow, bail};
use firmware::link::{
    Format, FrameReader, Info, MAX_FRAME, Measurement, Message, Packet, Reason, Reply, Start,
    Target, frame,
};

/// A target the host's world talks to, one request and its answer at a time.
pub trait Remote {
    /// Sends `message` numbered `seq` and returns the answer, checked to carry `seq`.
    fn exchange(&mut self, seq: u16, message: Message) -> Result<Message>;
}

impl<R: Remote + ?Sized> Remote for Box<R> {
    fn exchange(&mut self, seq: u16, message: Message) -> Result<Message> {
        (**self).exchange(seq, message)
    }
}

/// The message of an answer to request `seq` as the frame reader gave it, or why it is
/// none: a frame that could not be read, or one numbered for another request.
pub fn answer(frame: Result<Packet, Reason>, seq: u16) -> Result<Message> {
    let packet = frame.map_err(|r| anyhow!("a corrupted answer: {}", describe(r)))?;
    if packet.seq != seq {
        bail!(
            "an answer numbered {} to request {seq}: the link lost or repeated a frame",
            packet.seq
        );
    }
    Ok(packet.message)
}

/// Numbers the requests to a [`Remote`] and checks that each answer is of the kind asked
/// for: the host's side of the exchange.
pub struct Session<R> {
    remote: R,
    seq: u16,
}

impl<R: Remote> Session<R> {
    /// A session with `remote`, starting at sequence number 0.
    pub fn new(remote: R) -> Self {
        Session { remote, seq: 0 }
    }

    /// What the target holds for `format`.
    pub fn hello(&mut self, format: Format) -> Result<Info> {
        match self.request(Message::Hello(format))? {
            Message::Info(info) => Ok(info),
            other => Err(unexpected("Info", other)),
        }
    }

    /// Starts an episode.
    pub fn start(&mut self, start: Start) -> Result<()> {
        match self.request(Message::Start(start))? {
            Message::Started => Ok(()),
            other => Err(unexpected("Started", other)),
        }
    }

    /// One period on `m`.
    pub fn period(&mut self, m: Measurement) -> Result<Reply> {
        let message = match m {
            Measurement::State(v) => Message::State(v),
            Measurement::Counts(cart, pole) => Message::Counts { cart, pole },
            Measurement::Missing => Message::Missed,
        };
        match self.request(message)? {
            Message::Reply(r) => Ok(r),
            other => Err(unexpected("Reply", other)),
        }
    }

    fn request(&mut self, message: Message) -> Result<Message> {
        self.seq = self.seq.wrapping_add(1);
        self.remote.exchange(self.seq, message)
    }
}

fn unexpected(wanted: &str, got: Message) -> anyhow::Error {
    match got {
        Message::Refused(reason) => anyhow!("the target refused the request: {}", describe(reason)),
        other => anyhow!("the target answered {other:?} where {wanted} was due"),
    }
}

/// What a refusal's reason means, as `docs/LINK.md` says.
pub fn describe(reason: Reason) -> &'static str {
    match reason {
        Reason::Version => "another protocol version",
        Reason::Kind => "an unknown kind",
        Reason::Length => "a body of the wrong length, or a field out of its range",
        Reason::Crc => "a corrupted frame (CRC)",
        Reason::Oversized => "a frame longer than the longest",
        Reason::Encoding => "not a COBS encoding",
        Reason::Sequence => "a reading out of sequence",
        Reason::NotStarted => "a reading before any Start",
        Reason::Mode => "a reading of the other kind than Start said",
        Reason::Unsupported => "a format or a Start its policy or rig cannot run",
    }
}

/// The target code in this process: the software-in-the-loop reference a processor-in-
/// the-loop run is compared with, frame for frame. Its ticks are 0.
pub struct Local<const H: usize, const A: usize = 2>(pub Target<'static, H, A>);

impl<const H: usize, const A: usize> Remote for Local<H, A> {
    fn exchange(&mut self, seq: u16, message: Message) -> Result<Message> {
        Ok(self.0.handle(Ok(Packet { seq, message }), || 0).message)
    }
}

/// A target in a child process that speaks the link on its standard input and output
/// (QEMU with the target's semihosting console there, or the target built for the host).
pub struct Process {
    child: Child,
    input: ChildStdin,
    frames: Receiver<Result<Packet, Reason>>,
    /// Ends when the target's standard error has been shown.
    errors: Receiver<()>,
    timeout: Duration,
    what: String,
    /// What the target and every process it starts carry in their environment.
    mark: super::reap::Mark,
}

impl Process {
    /// Starts `command`; `what` names it in messages; answers later than `timeout` end the
    /// run.
    pub fn spawn(mut command: Command, what: String, timeout: Duration) -> Result<Process> {
        let mark = super::reap::Mark::new();
        mark.set(&mut command);
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                // The program is there (the place was checked): the system's "No such file
                // or directory" is of what runs it, the program its `#!` line names.
                let there = std::path::Path::new(command.get_program()).is_file();
                if e.kind() == std::io::ErrorKind::NotFound && there {
                    anyhow!(
                        "could not start {what}: the program that runs it (its #! line's \
                         interpreter, or its loader) was not found"
                    )
                } else {
                    anyhow!("could not start {what}: {e}")
                }
            })?;
        let (Some(input), Some(mut output), Some(errors)) =
            (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            bail!("{what} has no standard input or output");
        };
        let errors = forward_escaped(errors, what.clone());
        let (tx, frames) = channel();
        // Bytes are read as they come and gathered into frames, so that an answer's wait
        // can time out.
        std::thread::spawn(move || {
            let mut reader = FrameReader::default();
            let mut buf = [0u8; 4096];
            while let Ok(n @ 1..) = output.read(&mut buf) {
                for &b in &buf[..n] {
                    if let Some(f) = reader.push(b)
                        && tx.send(f).is_err()
                    {
                        return;
                    }
                }
            }
        });
        Ok(Process {
            child,
            input,
            frames,
            errors,
            timeout,
            what,
            mark,
        })
    }

    /// Why no answer came: the process ended, or the timeout passed.
    fn silent(&mut self, e: RecvTimeoutError) -> anyhow::Error {
        match (e, self.child.try_wait()) {
            (_, Ok(Some(status))) => anyhow!("{} ended ({status}) without answering", self.what),
            (RecvTimeoutError::Timeout, _) => anyhow!(
                "{} did not answer within {} s",
                self.what,
                self.timeout.as_secs_f64()
            ),
            (RecvTimeoutError::Disconnected, _) => anyhow!("{} closed the link", self.what),
        }
    }
}

impl Remote for Process {
    fn exchange(&mut self, seq: u16, message: Message) -> Result<Message> {
        let mut out = [0u8; MAX_FRAME];
        let n = frame::encode(&Packet { seq, message }, &mut out);
        if self.input.write_all(&out[..n]).is_err() {
            return Err(self.silent(RecvTimeoutError::Disconnected));
        }
        match self.frames.recv_timeout(self.timeout) {
            Ok(frame) => answer(frame, seq),
            Err(e) => Err(self.silent(e)),
        }
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        super::reap::end(&mut self.child, &self.mark);
        // Its last words before this tool's: bounded, should a process outside its group
        // hold the pipe open.
        let _ = self.errors.recv_timeout(Duration::from_secs(1));
    }
}

/// Lines a target writes on its standard error, on this process's, each escaped and cut
/// ([`weights::quote`]) and named as the target's: a target could clear the screen, or
/// forge this tool's `error:` lines. At most [`TARGET_LINES`] lines; the receiver hears when
/// the last is shown.
fn forward_escaped(errors: std::process::ChildStderr, what: String) -> Receiver<()> {
    let (done, ended) = channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        let mut reader = std::io::BufReader::new(errors);
        let mut line = Vec::new();
        // Read in pieces of at most a line's length, so an endless line costs no memory;
        // past the last line shown the rest is drained, so the target never blocks on it.
        for k in 0.. {
            line.clear();
            let piece = (&mut reader)
                .take(TARGET_LINE_BYTES)
                .read_until(b'\n', &mut line);
            if !matches!(piece, Ok(1..)) {
                break;
            }
            let text = String::from_utf8_lossy(&line);
            match k.cmp(&TARGET_LINES) {
                std::cmp::Ordering::Less => host_common::errln!(
                    "{what} says: {}",
                    weights::quote(text.trim_end_matches('\n'))
                ),
                std::cmp::Ordering::Equal => host_common::errln!("{what} says more, not shown"),
                std::cmp::Ordering::Greater => {}
            }
        }
        let _ = done.send(());
    });
    ended
}

/// Bytes of a target's line shown as one: a longer one is shown in pieces.
const TARGET_LINE_BYTES: u64 = 1024;

/// Lines of a target's standard error shown.
const TARGET_LINES: usize = 100;
