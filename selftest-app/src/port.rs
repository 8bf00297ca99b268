//! The link's byte stream in QEMU, and the clock periods are timed on.
//!
//! The bytes go over the semihosting console (`SYS_READ` and `SYS_WRITE` on `:tt`), which
//! QEMU connects to a character device of the host's choosing. Not over a UART model:
//! there QEMU hands the guest one byte (CMSDK, nRF51) or one FIFO trigger's worth (16550)
//! per round of its main loop while the polling core holds the emulator's lock, 1,000 to
//! 2,300 periods a second; a semihosting read halts the core until the bytes are there, and
//! the exchange runs several times faster (docs/PIL.md, "Speed"). The frames are the same
//! either way.

#![allow(unsafe_code)]

#[cfg(target_arch = "arm")]
use cortex_m_semihosting as sh;
use firmware::link::MAX_FRAME;
#[cfg(target_arch = "riscv32")]
use riscv_semihosting as sh;

/// A free-running clock to time periods on: what the target asks of its machine.
pub trait Clock {
    /// Ticks per second.
    const HZ: u32;
    /// Starts the clock.
    fn start(&mut self);
    /// The clock.
    fn now(&self) -> u32;
    /// Ticks from `earlier` to `later`, the clock's width allowing for its wrap.
    fn since(earlier: u32, later: u32) -> u32;
}

/// The semihosting console, opened for reading and for writing, and the bytes read but not
/// yet taken.
pub struct Port {
    input: usize,
    output: usize,
    buf: [u8; MAX_FRAME],
    pos: usize,
    len: usize,
}

/// `SYS_OPEN`'s modes for reading and writing (`"r"`, `"w"`).
const READ: usize = 0;
const WRITE: usize = 4;

fn open(mode: usize) -> Option<usize> {
    const NAME: &[u8] = b":tt\0";
    // SAFETY: the name is a NUL-terminated string of the given length less its NUL.
    let handle = unsafe { sh::syscall(sh::nr::OPEN, &[NAME.as_ptr() as usize, mode, 3]) };
    (handle != usize::MAX).then_some(handle)
}

impl Port {
    /// The console, or `None` where the host connected none.
    pub fn open() -> Option<Port> {
        Some(Port {
            input: open(READ)?,
            output: open(WRITE)?,
            buf: [0; MAX_FRAME],
            pos: 0,
            len: 0,
        })
    }

    /// The next byte, waiting for it (the core halts); `None` once the host closed the link.
    pub fn read(&mut self) -> Option<u8> {
        if self.pos == self.len {
            let ptr = self.buf.as_mut_ptr() as usize;
            // SAFETY: reads at most `buf.len()` bytes into `buf`.
            let left = unsafe { sh::syscall(sh::nr::READ, &[self.input, ptr, self.buf.len()]) };
            self.len = self.buf.len().checked_sub(left).filter(|&n| n > 0)?;
            self.pos = 0;
        }
        self.pos += 1;
        self.buf.get(self.pos - 1).copied()
    }

    /// Sends `bytes`; whether all went.
    pub fn write(&mut self, bytes: &[u8]) -> bool {
        let (ptr, len) = (bytes.as_ptr() as usize, bytes.len());
        // SAFETY: reads `len` bytes from `bytes`.
        unsafe { sh::syscall(sh::nr::WRITE, &[self.output, ptr, len]) == 0 }
    }
}

#[cfg(target_arch = "arm")]
mod clock {
    use cortex_m::peripheral::SYST;
    use cortex_m::peripheral::syst::SystClkSource;

    use super::Clock;
    use crate::on_arm::{CORE_HZ, CortexM};

    /// SysTick's counter is 24 bits wide.
    const SYST_MASK: u32 = 0x00FF_FFFF;

    impl Clock for CortexM {
        const HZ: u32 = CORE_HZ;

        fn start(&mut self) {
            self.0.set_clock_source(SystClkSource::Core);
            self.0.set_reload(SYST_MASK);
            self.0.clear_current();
            self.0.enable_counter();
        }

        /// SysTick counts down; this counts up.
        fn now(&self) -> u32 {
            SYST_MASK - SYST::get_current()
        }

        fn since(earlier: u32, later: u32) -> u32 {
            later.wrapping_sub(earlier) & SYST_MASK
        }
    }
}

#[cfg(target_arch = "riscv32")]
mod clock {
    use super::Clock;
    use crate::on_riscv::{TIMEBASE_HZ, Virt, mtime};

    impl Clock for Virt {
        const HZ: u32 = TIMEBASE_HZ as u32;

        /// `mtime` runs from reset.
        fn start(&mut self) {}

        fn now(&self) -> u32 {
            mtime() as u32
        }

        fn since(earlier: u32, later: u32) -> u32 {
            later.wrapping_sub(earlier)
        }
    }
}
