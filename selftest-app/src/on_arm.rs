//! The Cortex-M side of every binary: reset entry, the core's clock, exit and panics over
//! semihosting. The self-test's part is `arm_selftest`, the link's is in `port`.

use cortex_m::peripheral::SYST;
use cortex_m_rt::entry;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};

/// The core clock SysTick counts on the QEMU machine: mps2-an386 at 25 MHz, mps2-an505 at
/// 20 MHz, the micro:bit at 16 MHz. Under `-icount` they tick in virtual time.
#[cfg(all(target_abi = "eabihf", not(selftest_m33)))]
pub(crate) const CORE_HZ: u32 = 25_000_000;
#[cfg(selftest_m33)]
pub(crate) const CORE_HZ: u32 = 20_000_000;
#[cfg(not(target_abi = "eabihf"))]
pub(crate) const CORE_HZ: u32 = 16_000_000;

/// The core's SysTick: the self-test's period timer, the link's clock.
pub(crate) struct CortexM(pub(crate) SYST);

#[entry]
fn main() -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        exit(false)
    };
    let ok = crate::run(&mut CortexM(cp.SYST));
    exit(ok)
}

fn exit(ok: bool) -> ! {
    debug::exit(if ok { EXIT_SUCCESS } else { EXIT_FAILURE });
    // Semihosting exit returns only without a debugger attached; then wait for reset.
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m_semihosting::hprintln!("panic: {}", info);
    exit(false)
}
