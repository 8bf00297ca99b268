use firmware::cartpole::{Params, advance};
use firmware::controller::FaultFlags;
use rand_pcg::Pcg64Mcg;

use super::*;
use crate::scenario::Scenario;
use crate::world::tests::world;
use crate::{Episode, Machine};

/// Duty of period `k` in the tests below: no two periods in a row alike for long.
fn duty(k: u32) -> f64 {
    [1.0, -1.0, -1.0, 1.0, 0.0][k as usize % 5]
}

#[test]
fn windows_are_the_last_periods_of_every_interval() {
    let one = Window::every(100);
    let hits: Vec<u32> = (0..400).filter(|&k| one.holds(k)).collect();
    assert_eq!(hits, [99, 199, 299, 399]);
    let five = Window {
        periods: 5,
        every: 200,
    };
    let hits: Vec<u32> = (0..400).filter(|&k| five.holds(k)).collect();
    assert_eq!(hits, [195, 196, 197, 198, 199, 395, 396, 397, 398, 399]);
    let all = Window {
        periods: 9,
        every: 4,
    };
    assert!((0..20).all(|k| all.holds(k)));
}

#[test]
fn the_parts_set_the_faults_with_their_defaults() {
    let f = |spec: &str| Scenario::parse(spec).unwrap().faults;
    let w = Window::every;
    assert_eq!(f("glitch").glitch, Some((100, w(100))));
    assert_eq!(f("glitch=7/3").glitch, Some((7, w(3))));
    assert_eq!(
        f("stuck").stuck,
        Some(Window {
            periods: 5,
            every: 200
        })
    );
    assert_eq!(f("drop=9").drop, Some(w(9)));
    assert_eq!(f("late").late, Some(w(50)));
    assert_eq!(
        f("weak=0.25").weak,
        Some((
            0.25,
            Window {
                periods: 50,
                every: 500
            }
        ))
    );
    assert_eq!(f("reset=40").reset, Some(w(40)));
    assert_eq!(f("zero=-2").zero, Some(((-2.0f64).to_radians(), 0.0)));
    assert_eq!(f("zero=1/-25").zero, Some((1.0f64.to_radians(), -0.025)));
    assert_eq!(f("noise+delay"), Faults::default());
    for bad in [
        "weak",
        "weak=1.5",
        "glitch=0",
        "drop=0",
        "stuck=2/0",
        "late=-1",
        "zero",
        "zero=6",
        "zero=1/101",
    ] {
        assert!(Scenario::parse(bad).is_err(), "{bad} was accepted");
    }
}

/// Two worlds with the same start, noise and pushes, one sound, one with `faults`; the
/// same duties in both. `check` sees each period's measurements (sound, faulty).
fn side_by_side(spec: &str, faults: &str, mut check: impl FnMut(u32, Measurement, Measurement)) {
    let sound = Scenario::parse(spec).unwrap();
    let faulty = match spec {
        "nominal" => Scenario::parse(faults),
        _ => Scenario::parse(&format!("{spec}+{faults}")),
    }
    .unwrap();
    let (mut a, mut b) = (world(&sound), world(&faulty));
    for k in 0..60 {
        check(k, a.measure(), b.measure());
        a.apply(duty(k));
        b.apply(duty(k));
        assert_eq!(
            a.state(),
            b.state(),
            "{faults}: a sensing fault moved the plant"
        );
    }
}

#[test]
fn a_glitch_adds_its_counts_to_the_pole_for_one_period() {
    side_by_side("encoder=1024+noise", "glitch=37/7", |k, sound, got| {
        let Measurement::Counts(c, p) = sound else {
            panic!()
        };
        let want = if k % 7 == 6 {
            Measurement::Counts(c, p + 37)
        } else {
            sound
        };
        assert_eq!(got, want, "period {k}");
    });
    // Exact sensing: the angle off by as many counts of the rig's pole encoder.
    let count = core::f64::consts::TAU / 4096.0;
    side_by_side("nominal", "glitch=3/7", |k, sound, got| {
        let (Measurement::State(s), Measurement::State(g)) = (sound, got) else {
            panic!()
        };
        let off = if k % 7 == 6 { 3.0 * count } else { 0.0 };
        assert_eq!(g[2], (f64::from(s[2]) + off) as f32, "period {k}");
        assert_eq!((g[0], g[1], g[3]), (s[0], s[1], s[3]));
    });
}

#[test]
fn a_zero_error_offsets_every_reading_by_its_whole_counts() {
    // 1 degree of a 1,024-count pole encoder is 2.84 counts, read as 3; 5 mm of the cart's
    // 5,120 counts a metre is 25.6, read as 26. A glitch adds its counts on top.
    side_by_side("encoder=1024", "zero=1/5+glitch=10/4", |k, sound, got| {
        let Measurement::Counts(c, p) = sound else {
            panic!()
        };
        let glitch = if k % 4 == 3 { 10 } else { 0 };
        assert_eq!(
            got,
            Measurement::Counts(c + 26, p + 3 + glitch),
            "period {k}"
        );
    });
    side_by_side("encoder=1024", "zero=-1/-5", |k, sound, got| {
        let Measurement::Counts(c, p) = sound else {
            panic!()
        };
        assert_eq!(got, Measurement::Counts(c - 26, p - 3), "period {k}");
    });
    // Exact sensing: the angle and the position off by the amounts themselves.
    side_by_side("nominal", "zero=2/-30", |k, sound, got| {
        let (Measurement::State(s), Measurement::State(g)) = (sound, got) else {
            panic!()
        };
        assert_eq!(g[0], (f64::from(s[0]) - 0.03) as f32, "period {k}");
        assert_eq!(g[2], (f64::from(s[2]) + 2.0f64.to_radians()) as f32);
        assert_eq!((g[1], g[3]), (s[1], s[3]));
    });
}

#[test]
fn a_stuck_sensor_repeats_the_reading_before_and_a_dropped_one_is_missing() {
    let mut before = None;
    side_by_side("encoder=1024", "stuck=3/10", |k, sound, got| {
        if k % 10 >= 7 {
            assert_eq!(Some(got), before, "period {k}");
        } else {
            assert_eq!(got, sound, "period {k}");
            before = Some(sound);
        }
    });
    side_by_side("noise", "drop=4", |k, sound, got| {
        let want = if k % 4 == 3 {
            Measurement::Missing
        } else {
            sound
        };
        assert_eq!(got, want, "period {k}");
    });
}

/// The plant under `faults` with the duties of [`duty`], against Gymnasium's step under
/// `acting(k)`.
fn motor_faults(faults: &str, acting: impl Fn(u32) -> f64) {
    let s = Scenario::parse(faults).unwrap();
    let mut w = world(&s);
    let p = Params::default();
    let mut state = w.state();
    for k in 0..60 {
        w.measure();
        w.apply(duty(k));
        state = advance(&p, &state, acting(k), 0.0);
        assert_eq!(w.state(), state, "{faults}, period {k}");
    }
}

#[test]
fn a_late_command_leaves_the_bridge_on_the_one_before_and_a_weak_motor_scales_the_force() {
    // Late periods 3, 7, 11, ...: the bridge keeps the previous duty, through any run of
    // late periods.
    motor_faults("late=4", |k| if k % 4 == 3 { duty(k - 1) } else { duty(k) });
    motor_faults("weak=0.3/2/5", |k| {
        if k % 5 >= 3 { 0.3 * duty(k) } else { duty(k) }
    });
}

#[test]
fn dropped_readings_coast_and_late_periods_and_restarts_are_counted_by_the_board() {
    let s = Scenario::parse_on("encoder+drop=5+late=7+reset=11", &Machine::GYMNASIUM).unwrap();
    let policy = &shipped::policy::POLICY;
    let mut ep = Episode::start(
        policy,
        &s,
        200,
        &mut Pcg64Mcg::new(1),
        (Pcg64Mcg::new(2), Pcg64Mcg::new(3)),
        true,
    );
    for k in 0..50u32 {
        let command = ep.decide();
        let record = *ep.controller().last().unwrap();
        if k % 5 == 4 {
            assert_eq!(command, firmware::controller::Command::Coast, "period {k}");
            assert_eq!(record.faults, FaultFlags::SENSOR_ERROR);
        } else {
            assert!(record.faults.is_empty(), "period {k}: {:?}", record.faults);
        }
        ep.apply();
    }
    let counters = ep.controller().faults();
    assert_eq!(counters.rejected_readings, 10);
    assert_eq!(counters.overruns, 7, "late periods 6, 13, ..., 48");
}
