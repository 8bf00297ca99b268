//! A target on a serial port: a board running the link over USB CDC-ACM or a UART
//! (hardware in the loop), opened raw at [`BAUD`] (which USB CDC-ACM ignores).

use std::io::{ErrorKind, Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use firmware::link::{BAUD, FrameReader, MAX_FRAME, Message, Packet, frame};
use serialport::{SerialPort, TTYPort};

use super::link::{Remote, answer};

/// A board on a serial port.
pub struct Serial {
    port: TTYPort,
    reader: FrameReader,
    timeout: Duration,
    what: String,
}

impl Serial {
    /// Opens the port at `path`; answers later than `timeout` end the run.
    pub fn open(path: &Path, timeout: Duration) -> Result<Serial> {
        let what = format!("the board on {}", weights::shown(path));
        let name = path
            .to_str()
            .context("a serial port's path must be UTF-8")?;
        let mut port = serialport::new(name, BAUD)
            .timeout(timeout)
            .open_native()
            .with_context(|| format!("could not open {} as a serial port", weights::shown(path)))?;
        // Whatever a board sent before the host came is no answer to it, and a zero ends
        // whatever line noise the board read before this frame.
        port.clear(serialport::ClearBuffer::All)?;
        port.write_all(&[0])?;
        Ok(Serial {
            port,
            reader: FrameReader::default(),
            timeout,
            what,
        })
    }
}

impl Remote for Serial {
    fn exchange(&mut self, seq: u16, message: Message) -> Result<Message> {
        let mut out = [0u8; MAX_FRAME];
        let n = frame::encode(&Packet { seq, message }, &mut out);
        // Not flushed: draining a tty waits without a timeout on a board that stopped
        // reading; a frame is far smaller than the tty's buffer.
        self.port
            .write_all(&out[..n])
            .with_context(|| format!("writing to {}", self.what))?;
        let deadline = Instant::now() + self.timeout;
        let mut buf = [0u8; 64];
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!(
                    "{} did not answer within {} s",
                    self.what,
                    self.timeout.as_secs_f64()
                );
            }
            self.port.set_timeout(left)?;
            let got = match self.port.read(&mut buf) {
                Ok(0) => bail!("{} closed the link", self.what),
                Ok(k) => k,
                Err(e) if e.kind() == ErrorKind::TimedOut => continue,
                Err(e) => return Err(anyhow!(e).context(format!("reading from {}", self.what))),
            };
            // A frame's answer ends its exchange: bytes after it belong to none.
            if let Some(frame) = buf[..got].iter().find_map(|&b| self.reader.push(b)) {
                return answer(frame, seq);
            }
        }
    }
}
