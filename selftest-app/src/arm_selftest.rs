//! The self-test's Cortex-M part: SysTick as the control period's timer, output over
//! semihosting (or defmt frames over semihosting with the `defmt` feature), the stack
//! pointer.

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;
// The global defmt logger: frames go out over semihosting, decode them with `defmt-print`.
#[cfg(feature = "defmt")]
use defmt_semihosting as _;

use crate::app::{self, Board};
use crate::on_arm::{CORE_HZ, CortexM};

#[exception]
fn SysTick() {
    app::tick();
}

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
