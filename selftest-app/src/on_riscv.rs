//! The RISC-V side of every binary, for QEMU's `virt` machine (`riscv32imac`, no FPU, like
//! most RISC-V microcontrollers): riscv-rt entry, the CLINT's `mtime` as the link's clock,
//! exit and panics over semihosting. The self-test's part is `riscv_selftest`, the link's
//! is in `port`.

use riscv_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};

/// The CLINT of QEMU's `virt` machine: `mtime` counts at 10 MHz (in virtual time under
/// `-icount`).
const MTIME: usize = 0x0200_BFF8;
pub(crate) const TIMEBASE_HZ: u64 = 10_000_000;

#[allow(unsafe_code)]
pub(crate) fn mtime() -> u64 {
    // SAFETY: the CLINT's registers on this machine; two 32-bit reads, retried across a
    // carry of the low word.
    unsafe {
        loop {
            let hi = core::ptr::read_volatile((MTIME + 4) as *const u32);
            let lo = core::ptr::read_volatile(MTIME as *const u32);
            if core::ptr::read_volatile((MTIME + 4) as *const u32) == hi {
                return u64::from(hi) << 32 | u64::from(lo);
            }
        }
    }
}

/// The `virt` machine's hart.
pub(crate) struct Virt;

#[riscv_rt::entry]
fn main() -> ! {
    let ok = crate::run(&mut Virt);
    exit(ok)
}

fn exit(ok: bool) -> ! {
    debug::exit(if ok { EXIT_SUCCESS } else { EXIT_FAILURE });
    loop {
        riscv::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    riscv_semihosting::hprintln!("panic: {}", info);
    exit(false)
}
