//! The microcontroller side of the binary: reset entry, SysTick-paced control loop, stack
//! measurement, reporting and exit over semihosting.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use firmware::cartpole::{CartPole, Params, State};
use firmware::ffi::{cartpole_policy_forward, cartpole_policy_forward_int};
use firmware::loopback;
use firmware::policy::POLICY;
use firmware::policy_int::POLICY_INT;
use firmware::selftest;
// The global defmt logger: frames go out over semihosting, decode them with `defmt-print`.
#[cfg(feature = "defmt")]
use defmt_semihosting as _;

/// The clock the runners model: QEMU's `-icount shift=6` (`.cargo/config.toml`) advances
/// virtual time by 2^6 ns per instruction, a 15.625 MHz core retiring one instruction per
/// cycle. Optimistic for a real core (loads, multiplies and branches take more cycles, flash
/// adds wait states), pessimistic against the M4F's 25 MHz; the report says so.
const MODEL_HZ: u32 = 15_625_000;
/// The core clock SysTick counts on the QEMU machine: mps2-an386 at 25 MHz, mps2-an505 at
/// 20 MHz, the micro:bit at 16 MHz. Under `-icount` they tick in virtual time.
#[cfg(all(target_abi = "eabihf", not(selftest_m33)))]
const CORE_HZ: u32 = 25_000_000;
#[cfg(selftest_m33)]
const CORE_HZ: u32 = 20_000_000;
#[cfg(not(target_abi = "eabihf"))]
const CORE_HZ: u32 = 16_000_000;

/// Control rate: the plant's tau of 20 ms.
const CONTROL_HZ: u32 = 50;
/// Periods run under SysTick pacing per network format (one second of control).
const PACED_PERIODS: u32 = 50;

/// SysTick interrupts so far. Only the interrupt writes it (a load and a store: the
/// Cortex-M0 has no atomic read-modify-write), the control loop reads it.
static TICKS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    TICKS.store(
        TICKS.load(Ordering::Relaxed).wrapping_add(1),
        Ordering::Release,
    );
}

/// One paced run of `policy`: waits for each SysTick, counts the ticks that arrive while a
/// step still runs (an overrun each), including the last step's.
fn paced<P: firmware::controller::Policy>(policy: P) -> loopback::Outcome {
    let mut plant = CartPole::new(Params::default(), PACED_PERIODS);
    plant.reset_to(State::from_array([0.02, 0.0, -0.03, 0.05]));
    // The tick whose period is running; ticks beyond it arrived during the step.
    let mut current = TICKS.load(Ordering::Acquire);
    let mut first = true;
    let mut out = loopback::run(policy, &mut plant, || {
        let late = if first {
            0
        } else {
            TICKS.load(Ordering::Acquire).wrapping_sub(current)
        };
        first = false;
        while TICKS.load(Ordering::Acquire) == current {
            cortex_m::asm::wfi();
        }
        // A step that overran starts at once, on the latest tick: late ticks are not
        // made up for, they are counted.
        current = TICKS.load(Ordering::Acquire);
        late
    });
    out.overruns += TICKS.load(Ordering::Acquire).wrapping_sub(current);
    out
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
    let forward_int: extern "C" fn(Option<&[i16; 4]>, Option<&mut [i32; 2]>) =
        core::hint::black_box(cartpole_policy_forward_int);
    let mut ok = selftest::report(
        &POLICY,
        &POLICY_INT,
        |o, q| forward(Some(o), Some(q)),
        |o, q| forward_int(Some(o), Some(q)),
        line,
    );

    // The structure a board uses: SysTick interrupts at 50 Hz, the core sleeps in between.
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(CORE_HZ / CONTROL_HZ - 1);
    cp.SYST.clear_current();
    cp.SYST.enable_interrupt();
    cp.SYST.enable_counter();
    let runs = [("f32", paced(&POLICY)), ("int8", paced(&POLICY_INT))];
    cp.SYST.disable_interrupt();
    cp.SYST.disable_counter();
    for (format, run) in runs {
        ok &= run.success;
        line(format_args!(
            "paced {format}: {} periods, {} overruns ({} MHz model: -icount shift=6, 1 \
             instruction per cycle), {}",
            run.steps,
            run.overruns,
            MODEL_HZ as f32 / 1e6,
            if run.success { "balanced" } else { "FELL" }
        ));
    }

    let forward_bytes = stack::used(|| {
        let mut q = [0.0; 2];
        forward(Some(&selftest::PROBES[1]), Some(&mut q));
        core::hint::black_box(q);
    });
    let forward_int_bytes = stack::used(|| {
        let mut q = [0; 2];
        forward_int(Some(&selftest::INT_PROBES[1]), Some(&mut q));
        core::hint::black_box(q);
    });
    let step_bytes = stack::used(|| {
        let mut plant = CartPole::new(Params::default(), 1);
        plant.reset_to(State::from_array([0.01, 0.0, 0.02, 0.0]));
        core::hint::black_box(loopback::run(&POLICY, &mut plant, || 0));
    });
    let step_int_bytes = stack::used(|| {
        let mut plant = CartPole::new(Params::default(), 1);
        plant.reset_to(State::from_array([0.01, 0.0, 0.02, 0.0]));
        core::hint::black_box(loopback::run(&POLICY_INT, &mut plant, || 0));
    });
    line(format_args!(
        "stack: forward pass f32 {forward_bytes} bytes, int8 {forward_int_bytes} bytes; control \
         period with plant f32 {step_bytes} bytes, int8 {step_int_bytes} bytes"
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
