//! The monitor's switches against hand-built envelopes and hand-computed LQR signs.

use super::*;
use crate::controller::tests::SignOfTheta;
use crate::controller::{Duty, Levels, Policy, answer};
use crate::fixed;
use crate::rig::Rig;
use crate::shipped::envelope::{ASSURANCE, ENVELOPE, FALLBACK_GAIN, POLICY_DIGEST};

/// Scores that are no numbers.
struct Broken;

impl Policy for Broken {
    type Scores = [f32; 2];
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, _: &[f32; 4]) -> [f32; 2] {
        [f32::NAN, 1.0]
    }
}

/// Envelope 1 m, 1 m/s, 0.1 rad, 1 rad/s on Gymnasium's machine, gain `k = [1, 1, 10, 1]`
/// (so `u = -(x + x_dot + 10 theta + theta_dot)`).
fn assurance() -> Assurance {
    let envelope = Limits::new([1.0, 1.0, 0.1, 1.0]).unwrap();
    Rig::GYMNASIUM
        .assurance(envelope, [1.0, 1.0, 10.0, 1.0])
        .unwrap()
}

fn decide(m: &mut Monitor, obs: [f32; 4], c: &mut FaultCounters) -> (Command, FaultFlags) {
    let (_, command, flags) = m.decide(&obs, &obs, false, &mut SignOfTheta, answer, c);
    (command, flags)
}

#[test]
fn inside_the_envelope_the_policy_decides_alone() {
    let mut m = Monitor::new(assurance());
    let mut c = FaultCounters::default();
    let obs = [0.5, -0.5, 0.05, 0.5];
    let (q, command, flags) = m.decide(&obs, &obs, false, &mut SignOfTheta, answer, &mut c);
    assert_eq!(
        (q, command, flags),
        (
            [0.0, 0.05],
            Command::Drive(Duty::RIGHT),
            FaultFlags::default()
        )
    );
    assert_eq!((m.mode(), c), (Mode::Policy, FaultCounters::default()));
}

#[test]
fn beyond_the_envelope_the_fallback_pushes_by_the_sign_of_minus_k_s() {
    let mut m = Monitor::new(assurance());
    let mut c = FaultCounters::default();
    // x_dot 1.5 is beyond 1 m/s; u = -(0 + 1.5 + 10 * 0.05 + 0) = -2: left, though the
    // pole leans right and the policy would push right.
    let (command, flags) = decide(&mut m, [0.0, 1.5, 0.05, 0.0], &mut c);
    assert_eq!(
        (command, flags),
        (Command::Drive(Duty::LEFT), FaultFlags::FALLBACK)
    );
    // u = -(0 - 1.5 + 0.5) = +1: right.
    let (command, _) = decide(&mut m, [0.0, -1.5, 0.05, 0.0], &mut c);
    assert_eq!(command, Command::Drive(Duty::RIGHT));
    assert_eq!(
        (c.fallbacks, c.fallback_periods, m.mode()),
        (1, 2, Mode::Fallback)
    );
}

#[test]
fn the_policy_returns_after_the_dwell_inside_the_shrunk_envelope_only() {
    let mut m = Monitor::new(assurance());
    let mut c = FaultCounters::default();
    decide(&mut m, [0.0, 2.0, 0.0, 0.0], &mut c);
    // 0.9 m/s is inside the envelope but outside its 0.8 hysteresis: no count towards the
    // return, however long.
    for _ in 0..100 {
        assert_eq!(
            decide(&mut m, [0.0, 0.9, 0.0, 0.0], &mut c).1,
            FaultFlags::FALLBACK
        );
    }
    let calm = [0.0, 0.7, 0.0, 0.0];
    for _ in 1..Assurance::DWELL {
        assert_eq!(decide(&mut m, calm, &mut c).1, FaultFlags::FALLBACK);
    }
    assert_eq!(decide(&mut m, calm, &mut c).1, FaultFlags::default());
    assert_eq!((c.fallbacks, c.recoveries, m.mode()), (1, 1, Mode::Policy));
}

#[test]
fn a_run_of_faulty_readings_hands_over_and_a_sound_one_breaks_the_run() {
    let mut m = Monitor::new(assurance());
    let mut c = FaultCounters::default();
    let bad = FaultFlags::SENSOR_ERROR;
    m.rejected(bad, &mut c);
    m.rejected(bad, &mut c);
    decide(&mut m, [0.0; 4], &mut c);
    m.rejected(bad, &mut c);
    m.rejected(bad, &mut c);
    assert_eq!(m.mode(), Mode::Policy);
    m.rejected(bad, &mut c);
    assert_eq!((m.mode(), c.fallbacks), (Mode::Fallback, 1));
    // Readings from the model alone count as faulty too.
    let mut m = Monitor::new(assurance());
    for k in 1..=Assurance::FAULT_RUN {
        let (_, _, flags) = m.decide(&[0.0; 4], &[0.0; 4], true, &mut SignOfTheta, answer, &mut c);
        assert_eq!(
            flags == FaultFlags::FALLBACK,
            k == Assurance::FAULT_RUN,
            "{k}"
        );
    }
}

#[test]
fn scores_that_are_no_numbers_go_to_the_fallback_and_are_counted() {
    let mut m = Monitor::new(assurance());
    let mut c = FaultCounters::default();
    let obs = [0.0, 0.0, 0.05, 0.0];
    let (q, command, flags) = m.decide(&obs, &obs, false, &mut Broken, answer, &mut c);
    assert!(q[0].is_nan());
    // u = -(10 * 0.05) < 0: left.
    assert_eq!(
        (command, flags),
        (Command::Drive(Duty::LEFT), FaultFlags::FALLBACK)
    );
    assert_eq!((c.non_finite_scores, c.fallbacks), (1, 1));
}

#[test]
fn a_run_beyond_recovery_stops_for_good_and_one_glitch_does_not() {
    let mut m = Monitor::new(assurance());
    let mut c = FaultCounters::default();
    let fallen = [0.0, 0.0, 0.25, 0.0];
    decide(&mut m, fallen, &mut c);
    assert_eq!(decide(&mut m, [0.0; 4], &mut c).1, FaultFlags::FALLBACK);
    for _ in 0..Assurance::FAULT_RUN {
        decide(&mut m, fallen, &mut c);
    }
    assert_eq!(m.mode(), Mode::Stopped);
    for _ in 0..100 {
        assert_eq!(
            decide(&mut m, [0.0; 4], &mut c),
            (Command::Coast, FaultFlags::STOPPED)
        );
    }
    // The cart past the track's end is rejected before it reaches the monitor: a run of
    // such rejections stops it too.
    let mut m = Monitor::new(assurance());
    for _ in 0..Assurance::FAULT_RUN {
        m.rejected(FaultFlags::out_of_range(0), &mut c);
    }
    assert_eq!((m.mode(), c.safe_stops), (Mode::Stopped, 2));
}

#[test]
fn an_integer_reading_meets_the_same_decisions_in_q3_12() {
    let states = [
        [0.5, -0.5, 0.05, 0.5],
        [0.0, 1.5, 0.05, 0.0],
        [0.0, -1.5, 0.05, 0.0],
    ];
    let (mut mf, mut mi) = (Monitor::new(assurance()), Monitor::new(assurance()));
    let mut c = FaultCounters::default();
    for s in states {
        let q = fixed::from_state(&s);
        let mut int_policy = |o: &[i16; 4]| [0, i32::from(o[2])];
        let (_, ci, fi) = mi.decide(
            &q,
            &q,
            false,
            &mut FnPolicy(&mut int_policy),
            answer,
            &mut c,
        );
        assert_eq!((ci, fi), decide(&mut mf, s, &mut c), "{s:?}");
    }
}

/// A closure as an integer policy.
struct FnPolicy<'a>(&'a mut dyn FnMut(&[i16; 4]) -> [i32; 2]);

impl Policy<[i16; 4]> for FnPolicy<'_> {
    type Scores = [i32; 2];
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, obs: &[i16; 4]) -> [i32; 2] {
        (self.0)(obs)
    }
}

#[test]
fn a_gain_that_is_no_number_is_refused() {
    let envelope = Limits::new([1.0; 4]).unwrap();
    let bad = Rig::GYMNASIUM.assurance(envelope, [1.0, f32::NAN, 1.0, 1.0]);
    assert_eq!(bad, Err(ConfigError::NotFinite("assurance.gain")));
}

/// The generated envelope belongs to the shipped policy and its fallback to the shipped rig.
#[test]
fn the_shipped_assurance_is_the_shipped_policys_and_rigs() {
    use crate::link::digest;
    use crate::shipped::policy::{LEVELS, POLICY, RIG};
    assert_eq!(POLICY_DIGEST, digest::policy(digest::mlp(&POLICY), &LEVELS));
    let k = crate::linear::balance_gain(&RIG.params).map(|k| k as f32);
    assert_eq!(FALLBACK_GAIN, k);
    assert_eq!(RIG.lqr_assurance(ENVELOPE), Ok(ASSURANCE));
}

/// A policy of the given levels whose scores never matter here.
struct Stepped<const A: usize>(Levels<A>);

impl<const A: usize> Policy for Stepped<A> {
    type Scores = [f32; A];
    fn duty(&self, i: usize) -> Option<Duty> {
        self.0.duty(i)
    }
    fn scores(&mut self, _: &[f32; 4]) -> [f32; A] {
        [0.0; A]
    }
}

/// What a fresh monitor commands at state `s` with a policy of `levels`: the duty, and who
/// decided.
fn command_of<const A: usize>(levels: [f32; A], s: [f32; 4]) -> (f32, FaultFlags) {
    let mut policy = Stepped(Levels::new(levels).unwrap());
    let mut m = Monitor::new(assurance());
    let mut c = FaultCounters::default();
    let (_, command, flags) = m.decide(&s, &s, false, &mut policy, answer, &mut c);
    (command.level(), flags)
}

#[test]
fn with_finer_levels_the_fallback_drives_the_one_nearest_its_force() {
    let nine = [-1.0, -0.4, -0.15, -0.05, 0.0, 0.05, 0.15, 0.4, 1.0];
    // Full duty is Gymnasium's 10 N; each state lies beyond the envelope's 1 m/s.
    for (s, want) in [
        // u = -(1.5 + 0.5) = -2 N, -0.2 of full: between the midpoints -0.275 and -0.1.
        ([0.0, 1.5, 0.05, 0.0], -0.15),
        // u = 1.5 - 0.1 = 1.4 N: 0.14, between 0.1 and 0.275.
        ([0.0, -1.5, 0.01, 0.0], 0.15),
        // u = -(1.5 + 0.9 + 0.5) = -2.9 N: -0.29, below -0.275.
        ([0.0, 1.5, 0.09, 0.5], -0.4),
        // u = -(1.2 - 0.2 - 0.5) = -0.5 N: -0.05, a level itself.
        ([0.0, 1.2, -0.02, -0.5], -0.05),
    ] {
        assert_eq!(command_of(nine, s), (want, FaultFlags::FALLBACK), "{s:?}");
    }
}

#[test]
fn levels_that_stop_short_of_full_duty_leave_the_fallback_its_whole_force() {
    // u = -2.9 N and 2.9 N of 10 N: -0.29 and 0.29, nearer the half levels (midpoints
    // -0.75, -0.25, 0.25, 0.75); u = -(1.5 + 2 + 5) = -8.5 N: -0.85, nearer full duty.
    for (s, want) in [
        ([0.0, 1.5, 0.09, 0.5], -0.5),
        ([0.0, -1.5, -0.09, -0.5], 0.5),
        ([0.0, 1.5, 0.2, 5.0], -1.0),
        ([0.0, -1.5, -0.2, -5.0], 1.0),
    ] {
        assert_eq!(command_of([-0.5, 0.0, 0.5], s).0, want, "{s:?}");
    }
}

#[test]
fn an_assurance_needs_a_motor_that_pushes() {
    let envelope = Limits::new([1.0, 1.0, 0.1, 1.0]).unwrap();
    for (full, want) in [
        (0.0, ConfigError::NotPositive("assurance.full_force")),
        (-1.0, ConfigError::NotPositive("assurance.full_force")),
        (f32::NAN, ConfigError::NotFinite("assurance.full_force")),
        (
            f32::INFINITY,
            ConfigError::NotFinite("assurance.full_force"),
        ),
    ] {
        let got = Assurance::new(envelope, envelope, [1.0; 4], full);
        assert_eq!(got, Err(want), "{full}");
    }
}
