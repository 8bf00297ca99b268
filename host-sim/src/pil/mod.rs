//! The controller in the loop: the board's controller running on a target (the `pil`
//! application in QEMU, a board on a serial port, or the target code built for the host),
//! driven period by period by
//! the twin's world over the link (`docs/LINK.md`), and the same target code in this
//! process fed the same frames: the software-in-the-loop reference every answer is compared
//! with. `docs/PIL.md` has the results.
//!
//! - `board`: which shipped policy the target holds, and the reference holding it here.
//! - `link`: the host's end of the exchange, a target in a process or in this one.
//! - `serial`: a board on a serial port.
//! - `run`: episodes over the link, their statistics, the comparison and the target's time.

use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use anyhow::{Result, bail};

mod board;
pub mod link;
mod reap;
mod run;
pub mod serial;

pub use board::Board;
pub use run::{Check, Mismatch, handshake, run_row};

/// A QEMU machine the `pil` application runs on: one per target of the matrix, the
/// machines the self-test runs on (`.cargo/config.toml`; a test checks they agree).
#[derive(Debug)]
pub struct Machine {
    /// The Rust target.
    pub target: &'static str,
    /// The QEMU program.
    pub program: &'static str,
    /// The machine and CPU.
    pub args: &'static [&'static str],
}

/// The four targets of the matrix.
pub const MACHINES: [Machine; 4] = [
    Machine {
        target: "thumbv7em-none-eabihf",
        program: "qemu-system-arm",
        args: &["-cpu", "cortex-m4", "-machine", "mps2-an386"],
    },
    Machine {
        target: "thumbv6m-none-eabi",
        program: "qemu-system-arm",
        args: &["-cpu", "cortex-m0", "-machine", "microbit"],
    },
    Machine {
        target: "thumbv8m.main-none-eabihf",
        program: "qemu-system-arm",
        args: &["-cpu", "cortex-m33", "-machine", "mps2-an505"],
    },
    Machine {
        target: "riscv32imac-unknown-none-elf",
        program: "qemu-system-riscv32",
        args: &["-machine", "virt", "-bios", "none"],
    },
];

/// QEMU's `-icount` setting, the self-test's runners' (`.cargo/config.toml`, which says why;
/// a test checks they agree): one instruction per 64 ns of virtual time, and a sleeping core
/// jumps to its next timer, so no host time enters the target's clock.
pub const ICOUNT: &str = "shift=6,sleep=off";

/// What QEMU is told besides the machine: virtual time by [`ICOUNT`], no display, monitor or
/// serial port on standard output, and the semihosting console, which carries the link, on
/// standard input and output.
const QEMU_ARGS: [&str; 10] = [
    "-icount",
    ICOUNT,
    "-display",
    "none",
    "-monitor",
    "none",
    "-serial",
    "none",
    "-semihosting-config",
    "enable=on,target=native",
];

/// Nanoseconds of virtual time per instruction under [`ICOUNT`] (`shift=6`).
pub const NS_PER_INSTRUCTION: u32 = 64;

/// Where the target runs.
#[derive(Debug)]
pub enum Place {
    /// The `pil` application for a target, in QEMU.
    Qemu {
        /// The machine.
        machine: &'static Machine,
        /// The application's ELF.
        elf: PathBuf,
    },
    /// A program that speaks the link on its standard input and output (the `pil`
    /// application built for the host).
    Exec(PathBuf),
    /// A board on a serial port (hardware in the loop).
    Serial(PathBuf),
}

impl Place {
    /// The place `spec` names (`qemu:TARGET`, `serial:PATH` or `exec:PATH`), with the ELF
    /// `elf` for QEMU (by default the release build for the target of the application that
    /// holds `board`); refused, naming what was expected, when the target is unknown or the
    /// file is missing.
    pub fn parse(spec: impl AsRef<OsStr>, elf: Option<&Path>, board: Board) -> Result<Place> {
        let spec = spec.as_ref();
        // Quoted (escaped and cut) wherever a message shows them; a path need not be UTF-8,
        // so the place is split from the spec's bytes.
        let (q, shown) = (weights::quote, weights::quote(&spec.to_string_lossy()));
        let targets = || MACHINES.map(|m| m.target).join(", ");
        let bytes = spec.as_bytes();
        let split = bytes.iter().position(|&b| b == b':').map(|i| {
            let kind = std::str::from_utf8(&bytes[..i]).unwrap_or("");
            (kind, Path::new(OsStr::from_bytes(&bytes[i + 1..])))
        });
        let place = match split {
            Some(("qemu", target)) => {
                let target = target.to_str().unwrap_or("");
                let Some(machine) = MACHINES.iter().find(|m| m.target == target) else {
                    bail!(
                        "--pil qemu:TARGET: TARGET must be one of {}, found {}",
                        targets(),
                        q(target)
                    );
                };
                let app = board.app();
                let elf_given = elf.is_some();
                let elf = elf.map_or_else(|| default_elf(target, app), Path::to_path_buf);
                if !elf.is_file() {
                    bail!(
                        "--pil {shown}: no application at {} (build it with `cargo build --release \
                         -p selftest-app --bin {app} --target {target}`, or give --pil-elf)",
                        weights::shown(&elf)
                    );
                }
                if let Err(why) = elf_for(&elf, target) {
                    let given = if elf_given {
                        "--pil-elf"
                    } else {
                        "the application"
                    };
                    bail!("{given} {}: {why}", weights::shown(&elf));
                }
                Place::Qemu { machine, elf }
            }
            Some(("exec", path)) if path.is_file() => Place::Exec(path.into()),
            Some(("exec", path)) => {
                bail!("--pil exec:PATH: no program at {}", weights::shown(path))
            }
            Some(("serial", path)) if is_char_device(path) => Place::Serial(path.into()),
            Some(("serial", path)) => {
                bail!(
                    "--pil serial:PATH: expected a serial port (a character device) at {}",
                    weights::shown(path)
                )
            }
            _ => bail!(
                "--pil must be qemu:TARGET (TARGET one of {}), serial:PATH or exec:PATH, found \
                 {shown}",
                targets()
            ),
        };
        if elf.is_some() && !matches!(place, Place::Qemu { .. }) {
            bail!("--pil-elf goes with --pil qemu:TARGET, found --pil {shown}");
        }
        Ok(place)
    }

    /// The target, started (or its port opened), as a link's remote; answers later than
    /// `timeout` end the run.
    pub fn start(&self, timeout: Duration) -> Result<Box<dyn link::Remote>> {
        let (command, what) = match self {
            Place::Qemu { machine, elf } => {
                let mut c = Command::new(machine.program);
                c.args(machine.args).args(QEMU_ARGS).arg("-kernel").arg(elf);
                (c, format!("QEMU ({})", machine.target))
            }
            // The file checked, not one the search path finds: a bare `tgt` is `./tgt`.
            Place::Exec(path) => (
                Command::new(Path::new(".").join(path)),
                weights::shown(path),
            ),
            Place::Serial(path) => return Ok(Box::new(serial::Serial::open(path, timeout)?)),
        };
        Ok(Box::new(link::Process::spawn(command, what, timeout)?))
    }

    /// The place as the tables name it.
    pub fn name(&self) -> String {
        match self {
            Place::Qemu { machine, .. } => format!("qemu:{}", machine.target),
            Place::Exec(path) => format!("exec:{}", weights::shown(path)),
            Place::Serial(path) => format!("serial:{}", weights::shown(path)),
        }
    }
}

fn is_char_device(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::metadata(path).is_ok_and(|m| m.file_type().is_char_device())
}

/// The release build of `selftest-app`'s binary `app` for `target`, in cargo's target
/// directory.
fn default_elf(target: &str, app: &str) -> PathBuf {
    let dir = std::env::var_os("CARGO_TARGET_DIR").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../target"),
        PathBuf::from,
    );
    dir.join(target).join("release").join(app)
}

/// Refuses an application at `elf` that is no 32-bit little-endian ELF file for `target`'s
/// processor family (Arm, or RISC-V), before QEMU runs it: QEMU ran any bytes, and dumped its registers.
fn elf_for(elf: &Path, target: &str) -> Result<(), String> {
    use std::io::Read;
    let (machine, name) = match target.starts_with("riscv") {
        true => (243u16, "RISC-V"),
        false => (40, "Arm"),
    };
    let mut head = Vec::with_capacity(20);
    let read = std::fs::File::open(elf).and_then(|f| f.take(20).read_to_end(&mut head));
    let found = match read {
        Err(e) => format!("a file that cannot be read: {e}"),
        Ok(n) if n < 20 || head[..4] != *b"\x7fELF" => "no ELF file".into(),
        // Class 1, 32-bit; data 1, little-endian: every target here.
        Ok(_) if head[4..6] != [1, 1] => "an ELF file not 32-bit and little-endian".into(),
        Ok(_) if u16::from_le_bytes([head[18], head[19]]) != machine => {
            format!(
                "an ELF file for machine {}",
                u16::from_le_bytes([head[18], head[19]])
            )
        }
        Ok(_) => return Ok(()),
    };
    Err(format!(
        "expected a 32-bit little-endian ELF application for {name} ({target}), found {found}"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_elf_is_the_build_of_the_application_holding_the_policy() {
        let elf = default_elf("thumbv6m-none-eabi", Board::Desk.app());
        assert!(
            elf.ends_with("thumbv6m-none-eabi/release/pil-desk"),
            "{elf:?}"
        );
        let missing = Place::parse(
            "qemu:thumbv6m-none-eabi",
            Some(Path::new("/no/such")),
            Board::Desk,
        );
        let e = missing.unwrap_err().to_string();
        assert!(
            e.contains("--bin pil-desk --target thumbv6m-none-eabi"),
            "{e}"
        );
    }
}
