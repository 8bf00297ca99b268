use super::*;
use crate::cartpole::{State, advance};
use crate::controller::predict::MAX_PREDICT;
use crate::estimator::AlphaBeta;
use crate::linear::tests::SCIPY_L;

mod frozen;
mod wrapping;

const FINE: Encoders = Encoders {
    cart_counts_per_m: 20_480,
    pole_counts_per_rev: 4_096,
};

fn coarse(pole: u32) -> Encoders {
    Encoders {
        cart_counts_per_m: 5 * pole,
        pole_counts_per_rev: pole,
    }
}

/// The gain for force_sd 5 N, accel_sd [2, 4] and 20,480 / 4,096 counts is the one scipy
/// gives for the same process and quantisation noise (`linear::tests::SCIPY_L`).
#[test]
fn the_gain_is_scipys_kalman_gain() {
    let tuning = Tuning {
        force_sd: 5.0,
        accel_sd: [2.0, 4.0],
    };
    let o = Observer::new(FINE, &Params::default(), tuning, 0).unwrap();
    for (row, want) in o.gain().iter().zip(SCIPY_L) {
        for (g, w) in row.iter().zip(want) {
            assert!(
                (f64::from(*g) - w).abs() < 1e-6 * w.abs().max(1e-3),
                "{:?}",
                o.gain()
            );
        }
    }
}

/// The plant, with `delay` periods of dead time, under a bang-bang rule that sees the true
/// state, read through `enc` by an observer told `told` periods of dead time and by the
/// alpha-beta filter: the RMS errors of their velocity estimates `[x_dot, theta_dot]` over
/// 20 s.
fn velocity_errors(enc: Encoders, told: usize, delay: usize) -> ([f64; 2], [f64; 2]) {
    let p = Params::default();
    let mut obs = Observer::new(enc, &p, Tuning::DEFAULT, told).unwrap();
    let mut ab = AlphaBeta::new(enc, 0.5, p.tau as f32).unwrap();
    let mut s = State::from_array([0.03, -0.02, 0.02, -0.01]);
    // The plant's own line of commands, written out rather than `DeadTime`, so that the
    // observer's line is checked against something independent of it.
    let mut line = [0.0f64; MAX_PREDICT];
    let (mut eo, mut ea) = ([0.0f64; 2], [0.0f64; 2]);
    let n = 1000usize;
    for k in 0..n {
        let (cx, ct) = enc.counts(s.x, s.theta);
        let (o, a) = (obs.update(cx, ct), ab.update(cx, ct));
        if k >= 50 {
            for (e, est) in [(&mut eo, o), (&mut ea, a)] {
                e[0] += (f64::from(est[1]) - s.x_dot).powi(2);
                e[1] += (f64::from(est[3]) - s.theta_dot).powi(2);
            }
        }
        // Push towards where the pole falls, with some cart centring: a bang-bang loop.
        let u = if s.theta + 0.3 * s.theta_dot + 0.02 * s.x + 0.05 * s.x_dot > 0.0 {
            1.0
        } else {
            -1.0
        };
        obs.command(u as f32);
        let acting = if delay == 0 {
            u
        } else {
            core::mem::replace(&mut line[k % delay], u)
        };
        s = advance(&p, &s, acting, 0.0);
        assert!(s.theta.abs() < 0.2, "the rule keeps the pole up (step {k})");
    }
    let rms = |e: [f64; 2]| e.map(|v| libm::sqrt(v / (n - 50) as f64));
    (rms(eo), rms(ea))
}

#[test]
fn the_observer_recovers_velocities_the_alpha_beta_filter_cannot() {
    // The filter can only difference counts, so its rates are as coarse as the encoder; the
    // observer predicts them from the commanded push. The bounds ask for that gap on every
    // encoder down to a 128-count pole, and with a dead time the observer is told of.
    for (pole, delay) in [(4_096, 0), (512, 0), (128, 0), (512, 3)] {
        let (o, a) = velocity_errors(coarse(pole), delay, delay);
        let ok = o[1] < 0.15 && o[1] * 3.5 < a[1] && o[0] * 5.0 < a[0];
        assert!(ok, "{pole} counts, delay {delay}: {o:?} vs {a:?}");
    }
}

#[test]
fn an_unknown_dead_time_costs_accuracy() {
    // Told the dead time, the observer applies each command when it reaches the motor.
    let (told, _) = velocity_errors(coarse(512), 3, 3);
    let (blind, _) = velocity_errors(coarse(512), 0, 3);
    assert!(told[1] * 2.0 < blind[1], "{told:?} vs {blind:?}");
}

#[test]
fn commands_act_after_the_dead_time() {
    let mut o = Observer::new(FINE, &Params::default(), Tuning::DEFAULT, 3).unwrap();
    let sent = [1.0, -1.0, 0.5, 0.0, -0.25, 1.0];
    let mut acted = [9.0; 6];
    for (a, c) in acted.iter_mut().zip(sent) {
        o.command(c);
        *a = o.acting;
    }
    assert_eq!(acted, [0.0, 0.0, 0.0, 1.0, -1.0, 0.5]);
    let mut now = Observer::new(FINE, &Params::default(), Tuning::DEFAULT, 0).unwrap();
    for (c, want) in [(2.0, 1.0), (f32::NAN, 0.0), (-7.0, -1.0), (0.3, 0.3)] {
        now.command(c);
        assert_eq!(now.acting, want);
    }
}

#[test]
fn the_first_counts_start_it_at_rest_and_reset_forgets() {
    let mut o = Observer::new(FINE, &Params::default(), Tuning::DEFAULT, 2).unwrap();
    let s = o.update(2_048, -10);
    let want = [
        2_048.5 / 20_480.0,
        0.0,
        -9.5 * core::f32::consts::TAU / 4_096.0,
        0.0,
    ];
    assert_eq!(s, want);
    o.command(1.0);
    o.update(2_060, -12);
    o.reset();
    assert_eq!(o.update(2_048, -10), want);
    assert_eq!((o.acting, &o.line), (0.0, &DeadTime::new(2)));
}

#[test]
fn any_counts_and_commands_are_safe() {
    let p = Params::default();
    let mut o = Observer::new(FINE, &p, Tuning::DEFAULT, 16).unwrap();
    for (k, (c, q)) in [
        (i32::MAX, i32::MIN),
        (i32::MIN, i32::MAX),
        (0, 0),
        (i32::MAX, i32::MAX),
        (17, -3),
    ]
    .into_iter()
    .cycle()
    .take(200)
    .enumerate()
    {
        o.command(if k % 3 == 0 { f32::NAN } else { f32::INFINITY });
        // Wild counts may drive the estimate out of range (the controller rejects such a
        // reading), but it never sticks at NaN: a non-finite estimate restarts.
        let s = o.update(c, q);
        assert!(s.iter().all(|v| !v.is_nan()) || !o.started, "{s:?}");
    }
    o.reset();
    assert!(o.update(5, 5).iter().all(|v| v.is_finite()));
    let zero = Encoders {
        cart_counts_per_m: 0,
        pole_counts_per_rev: 4_096,
    };
    let made = Observer::new(zero, &p, Tuning::DEFAULT, 0);
    assert_eq!(
        made.err(),
        Some(ConfigError::NotPositive("encoders.cart_counts_per_m"))
    );
    let late = Observer::new(FINE, &p, Tuning::DEFAULT, MAX_PREDICT + 1);
    assert_eq!(late.err(), Some(ConfigError::TooLarge("dead_time")));
}

#[test]
fn the_fixed_state_is_the_state_rounded_in_q12() {
    let mut o = Observer::new(coarse(128), &Params::default(), Tuning::DEFAULT, 0).unwrap();
    let mut s = State::from_array([0.4, 0.0, 0.05, 0.0]);
    let p = Params::default();
    for k in 0..300 {
        let (cx, ct) = coarse(128).counts(s.x, s.theta);
        let est = o.update(cx, ct);
        for (f, v) in o.fixed_state().iter().zip(est) {
            let want = (f64::from(v) * 4096.0).round().clamp(-32_768.0, 32_767.0);
            assert_eq!(f64::from(*f), want, "step {k}: {est:?}");
        }
        o.command(if k % 7 < 3 { 1.0 } else { -1.0 });
        s = advance(&p, &s, if k % 7 < 3 { 1.0 } else { -1.0 }, 0.0);
    }
    o.estimate = [1e9, -1e9, f32::NAN, 3.0];
    assert_eq!(o.fixed_state(), [32_767, -32_768, 0, 12_288]);
}

#[test]
fn a_trim_moves_the_angle_read_and_outlives_a_reset() {
    let per = core::f32::consts::TAU / 4096.0;
    let mut o = Observer::new(FINE, &Params::default(), Tuning::DEFAULT, 0).unwrap();
    o.trim(0.01);
    // The first reading is the counts' (the middle of count 10) plus the trim.
    assert_eq!(o.update(0, 10)[2], 10.5 * per + 0.01);
    o.reset();
    assert_eq!(o.update(0, -10)[2], -9.5 * per + 0.01);
    o.trim(f32::INFINITY);
    o.reset();
    assert_eq!(o.update(0, -10)[2], -9.5 * per);
}
