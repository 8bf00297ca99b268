use super::*;
use crate::config::ConfigError;
use embedded_hal_mock::eh1::MockError;
use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as PinTx};
use embedded_hal_mock::eh1::pwm::{Mock as PwmMock, Transaction as PwmTx};

/// Replays a fixed list of readings, then reports errors.
pub(super) struct Script<'a> {
    pub(super) readings: &'a [Result<[f32; 4], ()>],
    pub(super) next: usize,
}

impl StateSensor for Script<'_> {
    type Reading = [f32; 4];
    type Error = ();
    fn read(&mut self) -> Result<[f32; 4], ()> {
        let r = self.readings.get(self.next).copied().unwrap_or(Err(()));
        self.next += 1;
        r
    }
}

/// Scores fixed by the sign of theta, so the test knows each action in advance: right when
/// the pole leans right.
pub(super) struct SignOfTheta;

impl Policy for SignOfTheta {
    type Scores = [f32; 2];
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, obs: &[f32; 4]) -> [f32; 2] {
        [0.0, obs[2]]
    }
}

const MAX: u16 = 255;
const LEAN_RIGHT: [f32; 4] = [0.0, 0.0, 0.1, 0.0];
const LEAN_LEFT: [f32; 4] = [0.0, 0.0, -0.1, 0.0];

/// The limits the tests read against: a track of +-2.4 m without margin.
fn limits() -> Limits {
    Limits::track(2.4, 0.0).unwrap()
}

fn run(
    readings: &[Result<[f32; 4], ()>],
    pin: &[PinTx],
    pwm: &[PwmTx],
) -> (Vec<Command>, Vec<Record>, FaultCounters) {
    let mut dir = PinMock::new(pin);
    let mut en = PwmMock::new(pwm);
    let sensor = Script { readings, next: 0 };
    let bridge = Bridge::new(dir.clone(), en.clone());
    let mut c: Controller<_, _, _, 8> =
        Controller::with_history(SignOfTheta, sensor, bridge, limits());
    let commands = (0..readings.len()).map(|_| c.step()).collect();
    let records = c.telemetry().copied().collect();
    let faults = c.faults();
    dir.done();
    en.done();
    (commands, records, faults)
}

extern crate std;
use std::vec::Vec;

/// What `set_duty_cycle_fully_on` / `_off` send.
fn push(on: bool) -> Vec<PwmTx> {
    if on {
        std::vec![PwmTx::max_duty_cycle(MAX), PwmTx::set_duty_cycle(MAX)]
    } else {
        std::vec![PwmTx::set_duty_cycle(0)]
    }
}

#[test]
fn first_push_is_off_direction_on() {
    for (reading, level, action) in [
        (LEAN_RIGHT, State::High, Duty::RIGHT),
        (LEAN_LEFT, State::Low, Duty::LEFT),
    ] {
        let pwm = [push(false), push(true)].concat();
        let (cmds, _, faults) = run(&[Ok(reading)], &[PinTx::set(level)], &pwm);
        assert_eq!(cmds, [Command::Drive(action)]);
        assert_eq!(faults, FaultCounters::default());
    }
}

#[test]
fn repeated_push_writes_nothing_and_reversal_breaks_before_make() {
    let readings = [
        Ok(LEAN_RIGHT),
        Ok(LEAN_RIGHT),
        Ok(LEAN_LEFT),
        Ok(LEAN_RIGHT),
    ];
    let pin = [
        PinTx::set(State::High),
        PinTx::set(State::Low),
        PinTx::set(State::High),
    ];
    let pwm = [
        push(false),
        push(true),
        push(false),
        push(true),
        push(false),
        push(true),
    ]
    .concat();
    let (cmds, records, _) = run(&readings, &pin, &pwm);
    assert_eq!(
        cmds,
        [
            Command::Drive(Duty::RIGHT),
            Command::Drive(Duty::RIGHT),
            Command::Drive(Duty::LEFT),
            Command::Drive(Duty::RIGHT)
        ]
    );
    assert_eq!(records.len(), 4);
    assert_eq!(records[2].q, [0.0, -0.1]);
    assert!(records.iter().enumerate().all(|(i, r)| r.step == i as u32));
}

#[test]
fn every_bad_value_on_every_channel_coasts_and_counts() {
    for channel in 0..4 {
        for (bad, flag) in [
            (f32::NAN, FaultFlags::non_finite(channel)),
            (f32::INFINITY, FaultFlags::non_finite(channel)),
            (f32::NEG_INFINITY, FaultFlags::non_finite(channel)),
            (1e30, FaultFlags::out_of_range(channel)),
            (-1e30, FaultFlags::out_of_range(channel)),
        ] {
            let mut reading = LEAN_RIGHT;
            reading[channel] = bad;
            // Push right, then coast on the bad reading, then push right again.
            let readings = [Ok(LEAN_RIGHT), Ok(reading), Ok(LEAN_RIGHT)];
            let pin = [PinTx::set(State::High), PinTx::set(State::High)];
            let pwm = [push(false), push(true), push(false), push(true)].concat();
            let (cmds, records, faults) = run(&readings, &pin, &pwm);
            let what = std::format!("channel {channel}, value {bad}");
            assert_eq!(cmds[1], Command::Coast, "{what}");
            assert_eq!(records[1].faults, flag, "{what}");
            assert!(records[1].q.iter().all(|q| q.is_nan()), "{what}");
            assert_eq!(records[1].obs[channel].to_bits(), bad.to_bits(), "{what}");
            assert!(records[0].faults.is_empty() && records[2].faults.is_empty());
            let (nf, oor) = if bad.is_finite() { (0, 1) } else { (1, 0) };
            assert_eq!(
                faults,
                FaultCounters {
                    rejected_readings: 1,
                    non_finite: nf,
                    out_of_range: oor,
                    ..FaultCounters::default()
                },
                "{what}"
            );
        }
    }
}

#[test]
fn limits_are_inclusive_and_all_bad_channels_are_flagged() {
    let l = limits();
    assert!(l.max_abs().flags(&l).is_empty());
    let neg = l.max_abs().map(|v| -v);
    assert!(neg.flags(&l).is_empty());
    let flags = [f32::NAN, 21.0, -0.5, f32::INFINITY].flags(&l);
    assert_eq!(flags.0, 0b0110_1001);
    assert!(flags.reading_rejected());
}

/// The reported failure: a NaN bound compares as nothing, so that the check either rejects
/// every reading (the controller coasts for ever, without a fault it could name) or, written
/// the other way round, none (1e30 passes). No such bound is built.
#[test]
fn a_bound_that_is_no_bound_is_refused() {
    let ok = [2.4, 20.0, 0.42, 20.0];
    for (channel, bad, why) in [
        (0, f32::NAN, ConfigError::NotFinite("limits.max_abs[0]")),
        (
            2,
            f32::INFINITY,
            ConfigError::NotFinite("limits.max_abs[2]"),
        ),
        (3, -1.0, ConfigError::Negative("limits.max_abs[3]")),
    ] {
        let mut max_abs = ok;
        max_abs[channel] = bad;
        assert_eq!(Limits::new(max_abs), Err(why));
    }
    let l = Limits::new(ok).unwrap();
    assert_eq!(l.max_abs(), ok);
    assert_eq!(
        [1e30f32, 0.0, 0.0, 0.0].flags(&l),
        FaultFlags::out_of_range(0)
    );
    // Zero is a bound: only zero passes.
    let still = Limits::new([0.0; 4]).unwrap();
    assert!([0.0f32; 4].flags(&still).is_empty());
    assert_eq!([0i16, 0, 1, 0].flags(&still), FaultFlags::out_of_range(2));
    // Checked as a board's `static` is compiled.
    const TRACK: Limits = match Limits::track(0.5, 0.05) {
        Ok(l) => l,
        Err(_) => panic!("a track"),
    };
    assert_eq!(TRACK.max_abs()[0], 0.45);
}

#[test]
fn fixed_point_readings_are_checked_in_q3_12_and_saturation_is_a_fault() {
    let l = Limits::track(0.5, 0.05).unwrap();
    // 0.45 m is 1843.2 in Q3.12: 1843 passes, 1844 does not.
    assert!([1843i16, 0, 0, 0].flags(&l).is_empty());
    assert_eq!([-1844i16, 0, 0, 0].flags(&l), FaultFlags::out_of_range(0));
    // A rate bound of 20 is beyond the format's 8: only a saturated value is rejected.
    assert!([0i16, 32_766, 0, -32_766].flags(&l).is_empty());
    assert_eq!(
        [0i16, i16::MAX, 0, i16::MIN].flags(&l),
        FaultFlags::out_of_range(1).with(FaultFlags::out_of_range(3))
    );
}

#[test]
fn sensor_error_coasts_with_zeros_recorded() {
    let pwm = push(false);
    let (cmds, records, faults) = run(&[Err(())], &[], &pwm);
    assert_eq!(cmds, [Command::Coast]);
    assert_eq!(records[0].faults, FaultFlags::SENSOR_ERROR);
    assert_eq!(records[0].obs, [0.0; 4]);
    assert_eq!(faults.sensor_errors, 1);
    assert_eq!(faults.rejected_readings, 1);
}

#[test]
fn actuator_error_is_counted_and_the_next_push_resends_everything() {
    let readings = [Ok(LEAN_RIGHT), Ok(LEAN_RIGHT)];
    let pin = [
        PinTx::set(State::High).with_error(MockError::Io(std::io::ErrorKind::Other)),
        PinTx::set(State::High),
    ];
    let pwm = [push(false), push(false), push(true)].concat();
    let (cmds, records, faults) = run(&readings, &pin, &pwm);
    assert_eq!(cmds, [Command::Drive(Duty::RIGHT); 2]);
    assert_eq!(records[0].faults, FaultFlags::ACTUATOR_ERROR);
    assert!(!records[0].faults.reading_rejected());
    assert!(records[1].faults.is_empty());
    assert_eq!(faults.actuator_errors, 1);
    assert_eq!(faults.rejected_readings, 0);
}

#[test]
fn telemetry_keeps_the_last_n_oldest_first() {
    let readings = [Ok(LEAN_RIGHT); 11];
    let pwm = [push(false), push(true)].concat();
    let (_, records, _) = run(&readings, &[PinTx::set(State::High)], &pwm);
    let steps: Vec<u32> = records.iter().map(|r| r.step).collect();
    assert_eq!(steps, (3..11).collect::<Vec<_>>());
}

#[test]
fn a_real_track_interlocks_its_ends() {
    let l = Limits::track(0.5, 0.05).unwrap();
    assert_eq!(l.max_abs()[0], 0.45);
    let at = |x: f32| [x, 0.0, 0.05, 0.0].flags(&l);
    assert!(at(0.3).is_empty() && at(-0.45).is_empty());
    assert_eq!(at(0.46), FaultFlags::out_of_range(0));
    assert_eq!(at(-0.5), FaultFlags::out_of_range(0));
    assert!(
        ![2.0f32, 0.0, 0.0, 0.0]
            .flags(&Limits::track(2.4, 0.5).unwrap())
            .is_empty()
    );
    // Nonsense lengths and margins are refused, naming which.
    for (half, margin, why) in [
        (f32::NAN, 0.1, ConfigError::NotFinite("params.x_threshold")),
        (0.0, 0.0, ConfigError::NotPositive("params.x_threshold")),
        (0.1, 0.2, ConfigError::NoTrack),
        (0.1, 0.1, ConfigError::NoTrack),
        (1.0, f32::NAN, ConfigError::NotFinite("end_stop_margin")),
        (1.0, -3.0, ConfigError::Negative("end_stop_margin")),
    ] {
        assert_eq!(Limits::track(half, margin), Err(why), "{half} {margin}");
    }
}

/// A sensor that records each command it is told, with how many readings it had given.
struct Told {
    readings: [[f32; 4]; 3],
    next: usize,
    told: Vec<(usize, Command)>,
}

impl StateSensor for Told {
    type Reading = [f32; 4];
    type Error = ();
    fn read(&mut self) -> Result<[f32; 4], ()> {
        let r = self.readings[self.next % 3];
        self.next += 1;
        Ok(r)
    }
    fn commanded(&mut self, command: Command) {
        self.told.push((self.next, command));
    }
}

#[test]
fn the_sensor_is_told_each_command_after_its_reading() {
    let sensor = Told {
        readings: [LEAN_RIGHT, [0.0, f32::NAN, 0.0, 0.0], LEAN_LEFT],
        next: 0,
        told: Vec::new(),
    };
    let mut c = Controller::new(SignOfTheta, sensor, crate::loopback::pins(), limits());
    let sent: Vec<Command> = (0..3).map(|_| c.step()).collect();
    assert_eq!(
        sent,
        [
            Command::Drive(Duty::RIGHT),
            Command::Coast,
            Command::Drive(Duty::LEFT)
        ]
    );
    let (_, sensor, _) = c.release();
    assert_eq!(sensor.told, [(1, sent[0]), (2, sent[1]), (3, sent[2])]);
}

/// The fixed-point bounds computed as the limits are built are the ones the reading's
/// conversion gives (`fixed::from_f32`, held below the saturated value).
#[test]
fn fixed_point_bounds_are_the_conversions_of_the_float_ones() {
    let mut v = 0.0f32;
    while v < 10.0 {
        let l = Limits::new([v; 4]).unwrap();
        let want = i32::from(crate::fixed::from_f32(v)).min(i32::from(i16::MAX) - 1);
        assert_eq!(i32::from(l.fixed()[0]), want, "{v}");
        // Halves of a Q3.12 step, where rounding decides, and the values between.
        v += 1.0 / 8192.0 + 1e-7;
    }
    let half = Limits::new([0.5 / 4096.0, 1.5 / 4096.0, 2.5 / 4096.0, 1e30]).unwrap();
    assert_eq!(half.fixed(), [1, 2, 3, i16::MAX - 1]);
}

/// Partial duties: a duty the same way writes the duty alone, a reversal breaks before it
/// makes, a zero duty is the motor off, and coasting when off writes nothing.
#[test]
fn levels_drive_their_duty_and_reversals_break_before_make() {
    let duty = |t: i16| Command::Drive(Duty::from_fraction(f32::from(t) / 1000.0).unwrap());
    let fraction = |t: u16| {
        std::vec![
            PwmTx::max_duty_cycle(MAX),
            PwmTx::set_duty_cycle((u32::from(t) * u32::from(MAX) / 1000) as u16),
        ]
    };
    let pin = [
        PinTx::set(State::High),
        PinTx::set(State::Low),
        PinTx::set(State::High),
    ];
    let pwm = [
        push(false),
        fraction(200),
        fraction(500),
        push(false),
        fraction(500),
        push(false),
        push(true),
    ]
    .concat();
    let (mut dir, mut en) = (PinMock::new(&pin), PwmMock::new(&pwm));
    let mut bridge = Bridge::new(dir.clone(), en.clone());
    for c in [
        duty(200),
        duty(500),
        duty(500),
        duty(-500),
        duty(0),
        Command::Coast,
        duty(1000),
    ] {
        bridge.drive(c).unwrap();
    }
    dir.done();
    en.done();
}
