//! The Cortex-M side of the binary: reset entry, SysTick, stack pointer, output and exit over
//! semihosting (or defmt frames over semihosting with the `defmt` feature).

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
// The global defmt logger: frames go out over semihosting, decode them with `defmt-print`.
#[cfg(feature = "defmt")]
use defmt_semihosting as _;

use crate::app::{self, Board};

/// The core clock SysTick counts on the QEMU machine: mps2-an386 at 25 MHz, mps2-an505 at
/// 20 MHz, the micro:bit at 16 MHz. Under `-icount` they tick in virtual time.
#[cfg(all(target_abi = "eabihf", not(selftest_m33)))]
const CORE_HZ: u32 = 25_000_000;
#[cfg(selftest_m33)]
const CORE_HZ: u32 = 20_000_000;
#[cfg(not(target_abi = "eabihf"))]
const CORE_HZ: u32 = 16_000_000;

#[exception]
fn SysTick() {
    app::tick();
}

struct CortexM(SYST);

impl Board for CortexM {
    fn line(&mut self, args: core::fmt::Arguments<'_>) {
        #[cfg(feature = "defmt")]
        {
            let mut s = heapless::String::<128>::new();
            let _ = core::fmt::write(&mut s, args);
            defmt::println!("{=str}", s.as_str());
        }
        #[cfg(not(feature = "defmt"))]
        cortex_m_semihosting::hprintln!("{}", args);
    }

    fn start_ticker(&mut self) {
        self.0.set_clock_source(SystClkSource::Core);
        self.0
            .set_reload(app::period_ticks(CORE_HZ.into()) as u32 - 1);
        self.0.clear_current();
        self.0.enable_interrupt();
        self.0.enable_counter();
    }

    fn stop_ticker(&mut self) {
        self.0.disable_interrupt();
        self.0.disable_counter();
    }

    fn sleep(&self) {
        cortex_m::asm::wfi();
    }

    #[inline(never)]
    #[allow(unsafe_code)]
    fn stack_used(&self, f: impl FnOnce()) -> usize {
        unsafe extern "C" {
            /// End of .bss and .uninit: the lowest address the stack may grow to (cortex-m-rt).
            static mut __sheap: u32;
        }
        let sp = cortex_m::register::msp::read() as usize;
        app::paint_and_measure(sp, core::ptr::addr_of_mut!(__sheap) as usize, f)
    }
}

#[entry]
fn main() -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        exit(false)
    };
    let ok = app::run(&mut CortexM(cp.SYST));
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
