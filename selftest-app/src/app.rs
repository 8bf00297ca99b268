//! What the application does on any microcontroller: the start-up self-test, then the
//! controller paced by a timer interrupt every control period of the shipped policy's rig
//! (`RIG.params.tau`) in each network format, with overruns counted, the stack measured,
//! and the verdict. The architecture modules (`on_arm`, `on_riscv`) supply the timer, the
//! sleep, the stack pointer and the output.

use core::sync::atomic::{AtomicU32, Ordering};

use firmware::ConfigError;
use firmware::cartpole::{CartPole, Params, State};
use firmware::controller::Policy;
use firmware::estimator::Estimate;
use firmware::loopback;
use shipped::policy::{POLICY, RIG};
use shipped::policy_int::POLICY_INT;

use crate::{period, selftest};

/// The clock the runners model: QEMU's `-icount shift=6` (`.cargo/config.toml`) advances
/// virtual time by 2^6 ns per instruction, a 15.625 MHz core retiring one instruction per
/// cycle. Optimistic for a real core (loads, multiplies and branches take more cycles, flash
/// adds wait states); the report says so.
pub const MODEL_HZ: u32 = 15_625_000;
/// Timer ticks of a `clock_hz` clock in one control period, the shipped rig's `tau`.
pub fn period_ticks(clock_hz: u64) -> u64 {
    libm::round(clock_hz as f64 * RIG.params.tau) as u64
}
/// Periods run under timer pacing per network format (one second of control).
const PACED_PERIODS: u32 = 50;

/// Timer interrupts so far. Only the interrupt writes it (a load and a store: the
/// Cortex-M0 has no atomic read-modify-write), the control loop reads it.
static TICKS: AtomicU32 = AtomicU32::new(0);

/// What the timer interrupt does.
pub fn tick() {
    TICKS.store(
        TICKS.load(Ordering::Relaxed).wrapping_add(1),
        Ordering::Release,
    );
}

/// The architecture's part.
pub trait Board {
    /// One line of output.
    fn line(&mut self, args: core::fmt::Arguments<'_>);
    /// Starts the control period's timer interrupt ([`period_ticks`]), which calls [`tick`].
    fn start_ticker(&mut self);
    /// Stops it.
    fn stop_ticker(&mut self);
    /// Sleeps until an interrupt.
    fn sleep(&self);
    /// Bytes of stack `f` uses below the caller's frame.
    fn stack_used(&self, f: impl FnOnce()) -> usize;
    /// Virtual nanoseconds so far, where a fine clock is at hand (RISC-V's `mtime`): under
    /// `-icount shift=6` each instruction takes 64 of them, so the difference over a call
    /// counts its instructions. Arm's are counted off the device (`scripts/count_insns.py`).
    fn virtual_ns(&self) -> Option<u64> {
        None
    }
}

/// One paced run of `policy` on a board's pipeline (encoders, observer, controller, in the
/// reading format `O` of the policy): waits for each tick, counts the ticks that arrive
/// while a step still runs (an overrun each), including the last step's. Refused as the
/// firmware refuses the rig's observer.
fn paced<O: Estimate, P: Policy<O>>(
    board: &impl Board,
    policy: P,
) -> Result<loopback::Outcome, ConfigError> {
    let mut plant = CartPole::new(Params::default(), PACED_PERIODS);
    plant.reset_to(State::from_array([0.02, 0.0, -0.03, 0.05]));
    // The tick whose period is running; ticks beyond it arrived during the step.
    let mut current = TICKS.load(Ordering::Acquire);
    let mut first = true;
    let mut out = loopback::run_with_encoders::<O, P>(policy, &mut plant, &RIG, || {
        // The first period starts on a fresh tick, as a board's loop starts with its ticker:
        // the controller's set-up (the observer's gain) takes ticks of its own, and a
        // period begun part-way through one would be charged for them.
        let late = if first {
            current = TICKS.load(Ordering::Acquire);
            0
        } else {
            TICKS.load(Ordering::Acquire).wrapping_sub(current)
        };
        first = false;
        while TICKS.load(Ordering::Acquire) == current {
            board.sleep();
        }
        // A step that overran starts at once, on the latest tick: late ticks are not
        // made up for, they are counted.
        current = TICKS.load(Ordering::Acquire);
        late
    })?;
    out.overruns += TICKS.load(Ordering::Acquire).wrapping_sub(current);
    Ok(out)
}

/// The self-test's C entry point for the float network.
type Forward = extern "C" fn(Option<&[f32; 4]>, Option<&mut [f32; 2]>);
/// And for the integer one.
type ForwardInt = extern "C" fn(Option<&[i16; 4]>, Option<&mut [i32; 2]>);

/// The entry points of the nine-level policy.
type ForwardLevels = extern "C" fn(Option<&[f32; 4]>, Option<&mut [f32; 9]>);
/// And of its integer version.
type ForwardLevelsInt = extern "C" fn(Option<&[i16; 4]>, Option<&mut [i32; 9]>);

/// The whole run; whether everything passed.
pub fn run(board: &mut impl Board) -> bool {
    // Probes go through C entry points by address, so the linker keeps them as real
    // functions in this ELF (the instruction counts are taken from them).
    let forward: Forward = core::hint::black_box(selftest::selftest_forward);
    let forward_int: ForwardInt = core::hint::black_box(selftest::selftest_forward_int);
    let monitored: ForwardInt = core::hint::black_box(selftest::selftest_monitored_int);
    let mut ok = selftest::report(
        &POLICY,
        &POLICY_INT,
        |o, q| forward(Some(o), Some(q)),
        |o, q| forward_int(Some(o), Some(q)),
        |l| board.line(l),
    );
    // The nine-level policy's entry points too, by address, for their instruction counts.
    let levels: ForwardLevels = core::hint::black_box(selftest::selftest_forward_levels);
    let levels_int: ForwardLevelsInt = core::hint::black_box(selftest::selftest_forward_levels_int);
    let refine: ForwardLevelsInt = core::hint::black_box(selftest::selftest_refine_int);
    selftest::levels_probes(
        |o, q| levels(Some(o), Some(q)),
        |o, q| levels_int(Some(o), Some(q)),
        |l| board.line(l),
    );
    selftest::refine_probe(|a, o| refine(Some(a), Some(o)), |l| board.line(l));
    ok &= levels_int_check(board, levels_int);
    ok &= paced_runs(board);
    ok &= startup_check(board);
    ok &= monitor_check(board, forward_int, monitored);
    stack_report(board, forward, forward_int);
    instruction_report(board, forward, [forward_int, monitored]);
    board.line(format_args!("{}", if ok { "PASS" } else { "FAIL" }));
    ok
}

/// The nine-level integer policy's forward pass through the target's kernels (its odd last
/// row has one of its own on Arm) against the portable definition, on the random
/// observations of [`selftest::int_check`]. Whether none differs.
fn levels_int_check(board: &mut impl Board, levels_int: ForwardLevelsInt) -> bool {
    if !selftest::OWN_INT_KERNELS {
        board.line(format_args!(
            "int, nine levels: the portable forward pass itself on this target"
        ));
        return true;
    }
    let kernel = |obs: &[i16; 4]| {
        let mut q = [0; 9];
        levels_int(Some(obs), Some(&mut q));
        q
    };
    let bad = selftest::int_check(&shipped::desk_int::POLICY_INT, kernel);
    board.line(format_args!(
        "int, nine levels: {bad} of {} random observations differ from the portable forward \
         pass",
        selftest::INT_CASES
    ));
    bad == 0
}

/// The start-up from power-on around the desk board's controller: the pole zeroed hanging,
/// then caught upright and balanced. Whether the last period balanced.
fn startup_check(board: &mut impl Board) -> bool {
    // By address, as the probes: its instructions are counted from this ELF.
    let periods: StartupPeriods = core::hint::black_box(period::selftest_startup_periods);
    let mut out = [0; 2];
    periods(Some(&[STARTUP_PERIODS, 0, 0, 0]), Some(&mut out));
    let [balancing, balanced] = out;
    board.line(format_args!(
        "start-up: {} after {STARTUP_PERIODS} periods, {balanced} of them balancing",
        if balancing == 1 {
            "balancing"
        } else {
            "NOT BALANCING"
        }
    ));
    balancing == 1
}

/// Periods [`startup_check`] runs: the desk rig's two windows of rest, the catch, and more.
const STARTUP_PERIODS: i16 = 200;

/// The start-up's entry point ([`period::selftest_startup_periods`]).
type StartupPeriods = extern "C" fn(Option<&[i16; 4]>, Option<&mut [i32; 2]>);

/// Both network formats paced by the timer, as a board runs them: a timer interrupt every
/// control period, the core asleep in between. Whether both balanced.
fn paced_runs(board: &mut impl Board) -> bool {
    board.start_ticker();
    let runs = [
        ("f32", paced::<[f32; 4], _>(board, &POLICY)),
        ("int8", paced::<[i16; 4], _>(board, &POLICY_INT)),
    ];
    board.stop_ticker();
    let mut ok = true;
    for (format, run) in runs {
        let run = match run {
            Ok(run) => run,
            Err(e) => {
                board.line(format_args!("paced {format}: refused: {e}"));
                ok = false;
                continue;
            }
        };
        ok &= run.success;
        board.line(format_args!(
            "paced {format}: {} periods, {} overruns ({} MHz model: -icount shift=6, 1 \
             instruction per cycle), {}",
            run.steps,
            run.overruns,
            MODEL_HZ as f32 / 1e6,
            if run.success { "balanced" } else { "FELL" }
        ));
    }
    ok
}

/// The stack a forward pass and a control period with the plant take, in each format.
fn stack_report(board: &mut impl Board, forward: Forward, forward_int: ForwardInt) {
    let forward_bytes = board.stack_used(|| {
        let mut q = [0.0; 2];
        forward(Some(&selftest::PROBES[1]), Some(&mut q));
        core::hint::black_box(q);
    });
    let forward_int_bytes = board.stack_used(|| {
        let mut q = [0; 2];
        forward_int(Some(&selftest::INT_PROBES[1]), Some(&mut q));
        core::hint::black_box(q);
    });
    let step_bytes = board.stack_used(|| {
        let mut plant = CartPole::new(Params::default(), 1);
        plant.reset_to(State::from_array([0.01, 0.0, 0.02, 0.0]));
        let run = loopback::run::<[f32; 4], _>;
        core::hint::black_box(run(&POLICY, &mut plant, selftest::LIMITS, || 0));
    });
    let step_int_bytes = board.stack_used(|| {
        let mut plant = CartPole::new(Params::default(), 1);
        plant.reset_to(State::from_array([0.01, 0.0, 0.02, 0.0]));
        core::hint::black_box(loopback::run::<[i16; 4], _>(
            &POLICY_INT,
            &mut plant,
            selftest::LIMITS,
            || 0,
        ));
    });
    board.line(format_args!(
        "stack: forward pass f32 {forward_bytes} bytes, int8 {forward_int_bytes} bytes; control \
         period with plant f32 {step_bytes} bytes, int8 {step_int_bytes} bytes"
    ));
}

/// Whether the monitor lets the integer policy decide a balanced state (the same outputs)
/// and hands a state beyond the envelope's rates to the fallback (no outputs).
fn monitor_check(board: &mut impl Board, forward_int: ForwardInt, monitored: ForwardInt) -> bool {
    let inside = &selftest::INT_PROBES[1];
    let (mut want, mut got) = ([0; 2], [1; 2]);
    forward_int(Some(inside), Some(&mut want));
    monitored(Some(inside), Some(&mut got));
    let mut fallback = [1; 2];
    monitored(Some(&[0, i16::MAX - 1, 0, 0]), Some(&mut fallback));
    let ok = want == got && fallback == [0; 2];
    board.line(format_args!(
        "monitor: the policy inside the envelope, the fallback beyond it: {}",
        if ok { "yes" } else { "NO" }
    ));
    ok
}

/// Instructions per forward pass in each format, and per integer pass under the monitor,
/// where the board has a fine clock.
fn instruction_report(board: &mut impl Board, forward: Forward, int: [ForwardInt; 2]) {
    let Some(before) = board.virtual_ns() else {
        return;
    };
    // Ten calls each, so the clock's 100 ns grain is under a tenth of an instruction.
    let mut q = [0.0; 2];
    for _ in 0..10 {
        forward(
            Some(core::hint::black_box(&selftest::PROBES[1])),
            Some(&mut q),
        );
    }
    let mid = board.virtual_ns().unwrap_or(before);
    let mut ends = [mid; 2];
    let mut qi = [0; 2];
    for (end, f) in ends.iter_mut().zip(int) {
        for _ in 0..10 {
            f(
                Some(core::hint::black_box(&selftest::INT_PROBES[1])),
                Some(&mut qi),
            );
        }
        *end = board.virtual_ns().unwrap_or(mid);
    }
    core::hint::black_box((q, qi));
    let per_call = |ns: u64| ns / 10 / (1_000_000_000 / u64::from(MODEL_HZ));
    board.line(format_args!(
        "instructions per forward pass: f32 {}, int8 {}, int8 under the monitor {} (virtual \
         time under -icount)",
        per_call(mid - before),
        per_call(ends[0] - mid),
        per_call(ends[1] - ends[0])
    ));
}

/// High-water-mark stack measurement: paint `[bottom, sp - 64)`, run `f`, find the deepest
/// overwritten word. Inlined into the architecture's `stack_used`, which reads `sp` (its own
/// stack pointer, after its prologue) and `bottom` (the lowest address the stack may grow
/// to); the 64 bytes below `sp` are left for that function's own spills.
#[allow(unsafe_code)]
#[inline(always)]
pub fn paint_and_measure(sp: usize, bottom: usize, f: impl FnOnce()) -> usize {
    const PAINT: u32 = 0xA5A5_A5A5;
    const MARGIN: usize = 64;
    let top = sp.saturating_sub(MARGIN);
    let words = top.saturating_sub(bottom) / 4;
    let base = bottom as *mut u32;
    // SAFETY: [bottom, top) is RAM the runtime reserves for the stack and that lies below
    // every live frame (MARGIN keeps this one's); nothing else owns it.
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
