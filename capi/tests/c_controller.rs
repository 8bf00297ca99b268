//! The whole controller from C: a C program (compiled as C99, C++11 and C++17 against the
//! header and the host build of the library) runs a script of calls, and every line it
//! prints must equal what the same calls give on a firmware `Controller` built here, in
//! Rust, from the shipped policies' `RIG`s, as a Rust board builds it: encoder counts through
//! an `ObserverSensor`, or measured states, period by period, command, pins, scores and
//! faults; then the counters and the control period; and the same under the runtime monitor
//! through a frozen encoder. The refusals (NULL pointers,
//! uninitialised memory, unknown policies, mixed inputs) must return their codes and write
//! nothing.

mod common;
#[path = "c_controller/startup.rs"]
mod startup;
#[path = "common/steps.rs"]
mod steps;

use std::collections::HashSet;
use std::fmt::Write as _;
use std::mem::{align_of, offset_of, size_of};
use std::path::PathBuf;

use cartpole_policy::{
    CARTPOLE_ERR_ENVELOPE, CARTPOLE_ERR_FLAGS, CARTPOLE_ERR_INPUT, CARTPOLE_ERR_NO_STARTUP,
    CARTPOLE_ERR_NULL, CARTPOLE_ERR_POLICY_KIND, CARTPOLE_ERR_RIG, CARTPOLE_ERR_UNINITIALISED,
    CARTPOLE_OK, CARTPOLE_POLICY_F32, CARTPOLE_POLICY_INT, CARTPOLE_STARTUP_HOME,
    CARTPOLE_STARTUP_SWING_UP, CONTROLLER_SIZE, CartpoleCommand, CartpoleController,
    CartpoleCounters, CartpolePhase,
};
use common::{Compiler, EVERY, compile_and_run, manifest};
use firmware::cartpole::{State, advance};
use firmware::controller::{Command, Controller, FaultFlags, Policy, Reading, StateSensor};
use firmware::estimator::ObserverSensor;
use firmware::fixed;
use firmware::loopback::{self, Latest, MAX_DUTY, Pins};
use firmware::rig::{Options, Rig};
use firmware::startup::{Phase, Sequencer, Startup};
use shipped::envelope::ENVELOPE;
use shipped::{policy, policy_int};
use steps::Scores;

/// Periods of each closed loop.
const PERIODS: usize = 400;

/// A reading format as the header reports it: the float policy's scores in `q`, the integer
/// one's in `q_int`, zero in the other.
trait Format: Scores {
    /// A measured state in this format.
    fn measured_as(state: &[f32; 4]) -> Self;
    /// The flag of `channel` measured NaN or infinite.
    fn not_finite(channel: usize) -> FaultFlags;
}

impl Format for [f32; 4] {
    fn measured_as(state: &[f32; 4]) -> Self {
        *state
    }
    fn not_finite(channel: usize) -> FaultFlags {
        FaultFlags::non_finite(channel)
    }
}

/// In Q3.12, rounded and saturated, a NaN saturated too: out of range, as the header says.
impl Format for [i16; 4] {
    fn measured_as(state: &[f32; 4]) -> Self {
        state.map(|v| {
            if v.is_nan() {
                i16::MIN
            } else {
                fixed::from_f32(v)
            }
        })
    }
    fn not_finite(channel: usize) -> FaultFlags {
        FaultFlags::out_of_range(channel)
    }
}

/// The state the test hands the controller.
struct Given<O>(O);

impl<O: Reading> StateSensor for Given<O> {
    type Reading = O;
    type Error = ();
    fn read(&mut self) -> Result<O, ()> {
        Ok(self.0)
    }
}

/// A controller as a Rust board builds one from `rig`.
fn board<P: Policy<S::Reading>, S: StateSensor>(
    policy: P,
    sensor: S,
    rig: &Rig,
) -> Controller<P, S, Pins> {
    let options = Options {
        predict: true,
        monitor: None,
    };
    rig.controller(policy, sensor, loopback::pins(), options)
        .unwrap()
}

/// The calls for the C program and what it must print for them.
#[derive(Default)]
struct Script {
    calls: String,
    want: String,
}

impl Script {
    fn call(&mut self, call: &str, want: &str) {
        writeln!(self.calls, "{call}").unwrap();
        writeln!(self.want, "{want}").unwrap();
    }
}

/// The line the program prints for a step that ran.
fn step_line<P, S>(c: &Controller<P, S, Pins>) -> String
where
    P: Policy<S::Reading, Scores = <S::Reading as Scores>::Scores>,
    S: StateSensor,
    S::Reading: Format,
{
    steps::step_line(0, c.last().unwrap(), c.actuator())
}

/// An outside force on the cart in period `k`, N: a shove the policy recovers from, then one
/// that topples the pole, whose fall the controller must coast through.
fn shove(k: usize) -> f64 {
    match k {
        100..=104 => 15.0,
        250..=280 => -30.0,
        _ => 0.0,
    }
}

/// Runs `c` in closed loop against `rig`'s plant; `hand` gives the sensor period `k`'s input
/// from the plant's state and returns the script's call for it. Asserts that the periods
/// pushed both ways and coasted, and that period `k` raised `flag` for each of `faults`: the
/// comparison with the C program means something only then.
fn closed_loop<P, S>(
    mut c: Controller<P, S, Pins>,
    (rig, faults): (&Rig, &[(usize, FaultFlags)]),
    script: &mut Script,
    mut hand: impl FnMut(&mut S, &State, usize) -> String,
) -> Controller<P, S, Pins>
where
    P: Policy<S::Reading, Scores = <S::Reading as Scores>::Scores>,
    S: StateSensor,
    S::Reading: Format,
{
    let mut s = State::from_array([0.02, 0.0, 0.03, 0.0]);
    let mut commands = HashSet::new();
    let mut flags = Vec::new();
    for k in 0..PERIODS {
        let call = hand(c.sensor_mut(), &s, k);
        commands.insert(c.step());
        flags.push(c.last().unwrap().faults);
        script.call(&call, &step_line(&c));
        s = advance(&rig.params, &s, loopback::duty(c.actuator()), shove(k));
    }
    let every = [
        firmware::controller::Duty::LEFT,
        firmware::controller::Duty::RIGHT,
    ]
    .map(Command::Drive);
    assert!(
        every
            .iter()
            .chain([&Command::Coast])
            .all(|c| commands.contains(c))
    );
    for &(k, flag) in faults {
        assert!(
            flags[k].contains(flag),
            "period {k}: {:?}, not {flag:?}",
            flags[k]
        );
    }
    c
}

/// The encoders' counts of `s`, wild in a few periods.
fn counts(rig: &Rig, s: &State, k: usize) -> (i32, i32) {
    match k {
        320 => (i32::MAX, i32::MIN),
        321 => (i32::MIN, 0),
        _ => rig.encoders.counts(s.x, s.theta),
    }
}

/// The measured state of `s`, with bad channels in a few periods.
fn measured(s: &State, k: usize) -> [f32; 4] {
    let mut m = s.observation();
    match k {
        50 => m[2] = f32::NAN,
        60 => m[1] = f32::INFINITY,
        70 => m[0] = 1e30,
        _ => {}
    }
    m
}

/// The calls after a closed loop: the other input refused, overruns, totals, the period.
fn epilogue<P: Policy<S::Reading>, S: StateSensor>(
    mut c: Controller<P, S, Pins>,
    rig: &Rig,
    other: &str,
    script: &mut Script,
) {
    script.call(other, &format!("refused {CARTPOLE_ERR_INPUT} 1"));
    c.record_overruns(3);
    script.call("overrun 3", &format!("overrun {CARTPOLE_OK}"));
    let f = c.faults();
    let counters = format!(
        "counters {CARTPOLE_OK} {} {} {} {} {} {} {} {} {} {} {} {} {}",
        c.steps(),
        f.rejected_readings,
        f.sensor_errors,
        f.non_finite,
        f.out_of_range,
        f.actuator_errors,
        f.overruns,
        f.model_only,
        f.fallbacks,
        f.recoveries,
        f.fallback_periods,
        f.non_finite_scores,
        f.safe_stops
    );
    script.call("counters", &counters);
    let us = (rig.params.tau * 1e6).round() as u32;
    script.call("period", &format!("period {CARTPOLE_OK} {us}"));
}

/// Both inputs for one shipped policy, each on a freshly initialised instance.
fn policy_script<O: Format, P: Policy<O, Scores = <O as Scores>::Scores> + Copy>(
    policy: P,
    rig: &Rig,
    kind: i32,
    script: &mut Script,
) {
    script.call(&format!("init {kind}"), &format!("init {CARTPOLE_OK}"));
    let sensor = ObserverSensor::<_, O>::new(rig.observer().unwrap(), Latest::default());
    let wild = [(320, FaultFlags::out_of_range(0))];
    let c = closed_loop(
        board(policy, sensor, rig),
        (rig, &wild),
        script,
        |sensor, s, k| {
            let (cart, pole) = counts(rig, s, k);
            sensor.counter_mut().0 = (cart, pole);
            format!("count {cart} {pole}")
        },
    );
    epilogue(c, rig, "state 0 0 0 0", script);

    script.call(&format!("init {kind}"), &format!("init {CARTPOLE_OK}"));
    let bad = [
        (50, O::not_finite(2)),
        (60, O::not_finite(1)),
        (70, FaultFlags::out_of_range(0)),
    ];
    let c = closed_loop(
        board(policy, Given(O::ZERO), rig),
        (rig, &bad),
        script,
        |sensor, s, k| {
            let m = measured(s, k);
            sensor.0 = O::measured_as(&m);
            let bits = m.map(|v| format!("{:08x}", v.to_bits())).join(" ");
            format!("state {bits}")
        },
    );
    epilogue(c, rig, "count 0 0", script);
    monitored_script(policy, rig, kind, script);
    startup::script(policy, rig, kind, script, CARTPOLE_STARTUP_SWING_UP);
    startup::script(
        policy,
        rig,
        kind,
        script,
        CARTPOLE_STARTUP_SWING_UP | CARTPOLE_STARTUP_HOME,
    );
}

/// Under the runtime monitor with the shipped envelope, the encoders frozen for half a
/// second: the observer predicts through the freeze (flagged), the fallback takes over, and
/// the shove that topples the pole ends in coasting.
fn monitored_script<O: Format, P: Policy<O, Scores = <O as Scores>::Scores> + Copy>(
    policy: P,
    rig: &Rig,
    kind: i32,
    script: &mut Script,
) {
    script.call(&format!("init {kind}"), &format!("init {CARTPOLE_OK}"));
    script.call("monitor", &format!("monitor {CARTPOLE_OK}"));
    let observer = rig.observer().unwrap().watching();
    let sensor = ObserverSensor::<_, O>::new(observer, Latest::default());
    let assurance = rig.lqr_assurance(ENVELOPE).unwrap();
    let frozen = [(160, FaultFlags::MODEL_ONLY), (160, FaultFlags::FALLBACK)];
    let mut held = (0, 0);
    let c = closed_loop(
        board(policy, sensor, rig).with_monitor(assurance),
        (rig, &frozen),
        script,
        |sensor, s, k| {
            if !(150..175).contains(&k) {
                held = counts(rig, s, k);
            }
            sensor.counter_mut().0 = held;
            format!("count {} {}", held.0, held.1)
        },
    );
    let f = c.faults();
    assert!(f.model_only >= 20 && f.fallbacks >= 1, "{f:?}");
    epilogue(c, rig, "state 0 0 0 0", script);
}

/// Compiles the program with `compiler` and runs it with `args`.
fn program(compiler: &Compiler, args: &[String]) -> String {
    let name = format!("controller-{}{}", args[0], compiler.std);
    compile_and_run(
        compiler,
        &name,
        &[&manifest().join("tests/controller.c")],
        &[&manifest().join("include")],
        args,
    )
}

#[test]
fn a_c_program_runs_the_firmware_controller_period_for_period() {
    let mut script = Script::default();
    policy_script::<[f32; 4], _>(
        &policy::POLICY,
        &policy::RIG,
        CARTPOLE_POLICY_F32,
        &mut script,
    );
    policy_script::<[i16; 4], _>(
        &policy_int::POLICY_INT,
        &policy_int::RIG,
        CARTPOLE_POLICY_INT,
        &mut script,
    );
    let path: PathBuf =
        std::env::temp_dir().join(format!("cartpole-controller-script-{}", std::process::id()));
    std::fs::write(&path, &script.calls).unwrap();
    for compiler in EVERY {
        let out = program(compiler, &["script".into(), path.display().to_string()]);
        let calls = script.calls.lines();
        let mut lines = calls.zip(out.lines().zip(script.want.lines()));
        if let Some((call, (got, want))) = lines.find(|(_, (got, want))| got != want) {
            panic!(
                "{}: after `{call}` the C program printed\n  {got}\nthe firmware's controller\n  {want}",
                compiler.std
            );
        }
        assert_eq!(
            out.lines().count(),
            script.want.lines().count(),
            "{}",
            compiler.std
        );
        assert_eq!(
            out.lines().count(),
            script.want.lines().count(),
            "{}",
            compiler.std
        );
    }
    std::fs::remove_file(&path).unwrap();
}

/// Where C's flat `cartpole_counters_t` has each field: where Rust's has it, the controller's
/// `FaultCounters` nested after the period count.
fn counters_offsets() -> String {
    let offsets = [
        offset_of!(CartpoleCounters, faults.rejected_readings),
        offset_of!(CartpoleCounters, faults.sensor_errors),
        offset_of!(CartpoleCounters, faults.non_finite),
        offset_of!(CartpoleCounters, faults.out_of_range),
        offset_of!(CartpoleCounters, faults.actuator_errors),
        offset_of!(CartpoleCounters, faults.overruns),
        offset_of!(CartpoleCounters, faults.model_only),
        offset_of!(CartpoleCounters, faults.fallbacks),
        offset_of!(CartpoleCounters, faults.recoveries),
        offset_of!(CartpoleCounters, faults.fallback_periods),
        offset_of!(CartpoleCounters, faults.non_finite_scores),
        offset_of!(CartpoleCounters, faults.safe_stops),
    ];
    let offsets: Vec<String> = offsets.iter().map(usize::to_string).collect();
    format!("counters-offsets {}", offsets.join(" "))
}

#[test]
fn refused_calls_return_their_codes_and_write_nothing() {
    let uninit = CARTPOLE_ERR_UNINITIALISED;
    let null = CARTPOLE_ERR_NULL;
    for (kind, rig) in [
        (CARTPOLE_POLICY_F32, &policy::RIG),
        (CARTPOLE_POLICY_INT, &policy_int::RIG),
    ] {
        let us = (rig.params.tau * 1e6).round() as u32;
        let want = [
            format!(
                "sizes {} {} {} {}",
                size_of::<CartpoleController>(),
                align_of::<CartpoleController>(),
                size_of::<CartpoleCommand>(),
                size_of::<CartpoleCounters>()
            ),
            format!(
                "constants {CONTROLLER_SIZE} {MAX_DUTY} {} {} {CARTPOLE_OK} {null} {uninit} \
                 {CARTPOLE_ERR_POLICY_KIND} {CARTPOLE_ERR_INPUT} {CARTPOLE_POLICY_F32} \
                 {CARTPOLE_POLICY_INT} -1 0 1",
                FaultFlags::non_finite(2).0,
                FaultFlags::out_of_range(3).0
            ),
            counters_offsets(),
            format!(
                "monitor-constants {CARTPOLE_ERR_RIG} {CARTPOLE_ERR_ENVELOPE} {} {} {}",
                FaultFlags::FALLBACK.0,
                FaultFlags::STOPPED.0,
                FaultFlags::MODEL_ONLY.0
            ),
            format!(
                "startup-constants {CARTPOLE_ERR_NO_STARTUP} {CARTPOLE_ERR_FLAGS} 0 1 2 3 4 5 6 \
                 {CARTPOLE_STARTUP_SWING_UP} {CARTPOLE_STARTUP_HOME} {} {} {}",
                size_of::<CartpolePhase>(),
                offset_of!(CartpolePhase, fell),
                offset_of!(CartpolePhase, trim)
            ),
            format!("zeroed {uninit} {uninit} {uninit} {uninit} {uninit} {uninit} {uninit} 1"),
            format!("garbage {uninit} {uninit} {uninit} {uninit} {uninit} {uninit} {uninit} 1"),
            format!("kinds {0} {0} {0}", CARTPOLE_ERR_POLICY_KIND),
            format!(
                "after-bad-kinds {uninit} {uninit} {uninit} {uninit} {uninit} {uninit} {uninit} 1"
            ),
            format!("init-null {null}"),
            format!("null {null} {null} {null} {null} {null} {null} {null} 1"),
            format!("init {CARTPOLE_OK}"),
            format!("null-outputs {null} {null} {null} {null} 1"),
            // A negative bound is refused; a huge one is an envelope the policy never leaves.
            format!("monitor {CARTPOLE_ERR_ENVELOPE} {CARTPOLE_OK}"),
            format!("ran {CARTPOLE_OK} 0 {CARTPOLE_OK} {us}"),
        ]
        .join("\n")
            + "\n";
        for compiler in EVERY {
            let out = program(compiler, &["refusals".into(), kind.to_string()]);
            assert_eq!(out, want, "{} kind {kind}", compiler.std);
        }
    }
}
