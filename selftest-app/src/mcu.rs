//! The microcontroller side of the binary: reset entry, SysTick-paced control loop, stack
//! measurement, reporting and exit over semihosting.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use firmware::cartpole::{CartPole, Params, State};
use firmware::ffi::cartpole_policy_forward;
use firmware::loopback;
use firmware::policy::POLICY;
use firmware::selftest;
// The global defmt logger: frames go out over semihosting, decode them with `defmt-print`.
#[cfg(feature = "defmt")]
use defmt_semihosting as _;

/// Core clock of the QEMU machine: mps2-an386 runs at 25 MHz, the micro:bit at 16 MHz.
#[cfg(target_abi = "eabihf")]
const CORE_HZ: u32 = 25_000_000;
#[cfg(not(target_abi = "eabihf"))]
const CORE_HZ: u32 = 16_000_000;

/// Control rate: the plant's tau of 20 ms.
const CONTROL_HZ: u32 = 50;
/// Periods run under SysTick pacing after the self-test (one second of control).
const PACED_PERIODS: u32 = 50;

/// Set by the SysTick interrupt, cleared by the control loop: one control period has begun.
static TICK: AtomicBool = AtomicBool::new(false);

#[exception]
fn SysTick() {
    TICK.store(true, Ordering::Release);
}

/// One line of output, to defmt or to the semihosting console.
fn line(args: core::fmt::Arguments<'_>) {
    #[cfg(feature = "defmt")]
    {
        let mut s = heapless::String::<128>::new();
        let _ = core::fmt::write(&mut s, args);
        defmt::println!("{=str}", s.as_str());
    }
    #[cfg(not(feature = "defmt"))]
    cortex_m_semihosting::hprintln!("{}", args);
}

#[entry]
fn main() -> ! {
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        exit(false)
    };
    // Probes go through the C entry point by address, so the linker keeps it as a real
    // function in this ELF (the instruction counts are taken from it).
    let forward: extern "C" fn(Option<&[f32; 4]>, Option<&mut [f32; 2]>) =
        core::hint::black_box(cartpole_policy_forward);
    let mut ok = selftest::report(&POLICY, |o, q| forward(Some(o), Some(q)), line);

    // The structure a board uses: SysTick interrupts at 50 Hz, the core sleeps in between.
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(CORE_HZ / CONTROL_HZ - 1);
    cp.SYST.clear_current();
    cp.SYST.enable_interrupt();
    cp.SYST.enable_counter();
    let mut plant = CartPole::new(Params::default(), PACED_PERIODS);
    plant.reset_to(State::from_array([0.02, 0.0, -0.03, 0.05]));
    let paced = loopback::run(&POLICY, &mut plant, || {
        // Load and store, not swap: the Cortex-M0 has no atomic read-modify-write, and a
        // tick landing between the two belongs to the period that is starting anyway.
        while !TICK.load(Ordering::Acquire) {
            cortex_m::asm::wfi();
        }
        TICK.store(false, Ordering::Release);
    });
    cp.SYST.disable_interrupt();
    cp.SYST.disable_counter();
    ok &= paced.success;
    line(format_args!(
        "paced: {} periods at {CONTROL_HZ} Hz on SysTick ({} core cycles each), {}",
        paced.steps,
        CORE_HZ / CONTROL_HZ,
        if paced.success { "balanced" } else { "FELL" }
    ));

    let forward_bytes = stack::used(|| {
        let mut q = [0.0; 2];
        forward(Some(&selftest::PROBES[1]), Some(&mut q));
        core::hint::black_box(q);
    });
    let step_bytes = stack::used(|| {
        let mut plant = CartPole::new(Params::default(), 1);
        plant.reset_to(State::from_array([0.01, 0.0, 0.02, 0.0]));
        core::hint::black_box(loopback::run(&POLICY, &mut plant, || {}));
    });
    line(format_args!(
        "stack: forward pass {forward_bytes} bytes, control period with plant {step_bytes} bytes"
    ));
    line(format_args!("{}", if ok { "PASS" } else { "FAIL" }));
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
    line(format_args!("panic: {info}"));
    exit(false)
}

/// High-water-mark stack measurement: paint the free stack, run, find the deepest write.
#[allow(unsafe_code)]
mod stack {
    const PAINT: u32 = 0xA5A5_A5A5;
    /// Bytes below the current stack pointer left alone for this function's own frame.
    const MARGIN: usize = 64;

    unsafe extern "C" {
        /// End of .bss and .uninit: the lowest address the stack may grow to (cortex-m-rt).
        static mut __sheap: u32;
    }

    /// Bytes of stack `f` used below the caller's frame.
    #[inline(never)]
    pub fn used(f: impl FnOnce()) -> usize {
        let sp = cortex_m::register::msp::read() as usize - MARGIN;
        let bottom = core::ptr::addr_of_mut!(__sheap) as usize;
        let words = sp.saturating_sub(bottom) / 4;
        let base = bottom as *mut u32;
        // SAFETY: [bottom, sp) is RAM that cortex-m-rt reserves for the stack and that lies
        // below every live frame (MARGIN keeps this one's); nothing else owns it.
        for i in 0..words {
            unsafe { base.add(i).write_volatile(PAINT) };
        }
        f();
        // SAFETY: the same region, read back after `f` returned.
        let untouched = (0..words)
            .take_while(|&i| unsafe { base.add(i).read_volatile() } == PAINT)
            .count();
        (words - untouched) * 4
    }
}
