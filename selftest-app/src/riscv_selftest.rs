//! The self-test's RISC-V part: the CLINT's machine timer as the control period's ticker,
//! output over semihosting, the stack pointer.

use riscv::interrupt::Interrupt;

use crate::app::{self, Board};
use crate::on_riscv::{TIMEBASE_HZ, Virt, mtime};

/// Hart 0's `mtimecmp` in the CLINT: the machine timer interrupt fires when `mtime` reaches
/// it.
const MTIMECMP: usize = 0x0200_4000;

#[allow(unsafe_code)]
fn set_mtimecmp(t: u64) {
    // SAFETY: hart 0's compare register. The high word goes to all ones first, so no
    // intermediate value of the pair lies in the past and fires early.
    unsafe {
        core::ptr::write_volatile((MTIMECMP + 4) as *mut u32, u32::MAX);
        core::ptr::write_volatile(MTIMECMP as *mut u32, t as u32);
        core::ptr::write_volatile((MTIMECMP + 4) as *mut u32, (t >> 32) as u32);
    }
}

/// The next compare value: one period after the last.
static NEXT: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

#[riscv_rt::core_interrupt(Interrupt::MachineTimer)]
fn machine_timer() {
    // Re-armed one period after the previous deadline, not after now, so the ticks keep a
    // fixed rate however late the interrupt is taken.
    let periods = NEXT
        .load(core::sync::atomic::Ordering::Relaxed)
        .wrapping_add(1);
    NEXT.store(periods, core::sync::atomic::Ordering::Relaxed);
    set_mtimecmp(START.load() + u64::from(periods) * PERIOD.load());
    app::tick();
}

/// `mtime` when the ticker started, and the period in `mtime` ticks (each written once,
/// before the interrupt is enabled).
static START: Once = Once(core::cell::Cell::new(0));
static PERIOD: Once = Once(core::cell::Cell::new(0));

struct Once(core::cell::Cell<u64>);

// SAFETY: a single hart; written before the timer interrupt is enabled and only read after.
#[allow(unsafe_code)]
unsafe impl Sync for Once {}

impl Once {
    fn load(&self) -> u64 {
        self.0.get()
    }
}

impl Board for Virt {
    fn line(&mut self, args: core::fmt::Arguments<'_>) {
        riscv_semihosting::hprintln!("{}", args);
    }

    #[allow(unsafe_code)]
    fn start_ticker(&mut self) {
        PERIOD.0.set(app::period_ticks(TIMEBASE_HZ));
        START.0.set(mtime());
        NEXT.store(1, core::sync::atomic::Ordering::Relaxed);
        set_mtimecmp(START.load() + PERIOD.load());
        // SAFETY: the handler above is the only one enabled; it touches only atomics and the
        // CLINT.
        unsafe {
            riscv::register::mie::set_mtimer();
            riscv::interrupt::enable();
        }
    }

    fn stop_ticker(&mut self) {
        riscv::interrupt::disable();
        // SAFETY-free: clearing the enable bit only masks the interrupt.
        #[allow(unsafe_code)]
        unsafe {
            riscv::register::mie::clear_mtimer();
        }
    }

    fn sleep(&self) {
        riscv::asm::wfi();
    }

    fn virtual_ns(&self) -> Option<u64> {
        Some(mtime() * (1_000_000_000 / TIMEBASE_HZ))
    }

    #[inline(never)]
    #[allow(unsafe_code)]
    fn stack_used(&self, f: impl FnOnce()) -> usize {
        unsafe extern "C" {
            /// The lowest address of the stack region (riscv-rt's `.stack` section).
            static mut __estack: u32;
        }
        let sp: usize;
        // SAFETY: reads the stack pointer into a register; no memory, no side effect.
        unsafe { core::arch::asm!("mv {}, sp", out(reg) sp, options(nomem, nostack)) };
        app::paint_and_measure(sp, core::ptr::addr_of_mut!(__estack) as usize, f)
    }
}
