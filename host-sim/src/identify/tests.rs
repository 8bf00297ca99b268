//! Identification against worlds nobody tuned it to: machines drawn at random (seeded), run
//! through the board's own experiments (`synthetic`) in a finer world than the fit's, their
//! encoders zeroed anywhere within a count and jittering, the rig file the fit starts from
//! wrong in everything it is meant to find.

use super::*;
use firmware::rig::Rig;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use synthetic::{Reading, Zero};
use twin::machine::Integration;

mod conventions;
mod independent;
mod misfits;
mod refusals;
mod safety;

/// The goal's tolerances: the stall force and the damping within 5%, the pole's effective
/// length within 2%, the dead time exact.
const FORCE_TOLERANCE: f64 = 0.05;
const DAMPING_TOLERANCE: f64 = 0.05;
const LENGTH_TOLERANCE: f64 = 0.02;

fn uniform(rng: &mut Pcg64Mcg, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * firmware::cartpole::unit_f64(rng)
}

/// A true machine drawn from `rng` (a desk-sized rig: the masses, the length, the motor,
/// both frictions and the dead time each uniform over a plausible range) with the goal's
/// encoders, its world integrated five times finer than a rig file's default, and the rig
/// file its builder would write: the masses right, the length off by up to 10%, the motor
/// by up to a factor 2, no friction and a dead time of 1.
fn random_rig(rng: &mut Pcg64Mcg, tau: f64, half: f64) -> (Machine, Machine) {
    let masspole = uniform(rng, 0.05, 0.3);
    let length = uniform(rng, 0.1, 0.5);
    let params = Params {
        masscart: uniform(rng, 0.3, 2.0),
        masspole,
        length,
        force_mag: uniform(rng, 2.0, 15.0),
        motor_damping: uniform(rng, 0.5, 6.0),
        tau,
        x_threshold: half,
        cart_friction: uniform(rng, 0.0, 0.05),
        // A swing's amplitude decaying at 1% to 10% a second.
        pole_friction: 8.0 * masspole * length * length * uniform(rng, 0.01, 0.1) / 3.0,
        ..Params::default()
    };
    let rig = Rig {
        params,
        encoders: firmware::estimator::Encoders {
            cart_counts_per_m: 15_000,
            pole_counts_per_rev: 2_400,
        },
        dead_time: rng.next_u32() % 4,
        end_stop_margin: 0.05,
        tuning: firmware::estimator::Tuning::DEFAULT,
    };
    let truth = Machine {
        rig,
        integration: Integration::rk4(tau, 0.0002),
        uncertainty: Default::default(),
    };
    let mut measured = Machine {
        rig,
        integration: Integration::rk4(tau, twin::rigfile::DEFAULT_SUBSTEP_S),
        uncertainty: Default::default(),
    };
    let p = &mut measured.rig.params;
    p.length *= uniform(rng, 0.9, 1.1);
    p.force_mag *= uniform(rng, 0.5, 2.0);
    p.motor_damping *= uniform(rng, 0.5, 2.0);
    p.cart_friction = 0.0;
    p.pole_friction = 0.0;
    measured.rig.dead_time = 1;
    (truth, measured)
}

/// Encoders zeroed anywhere within a count, jittering by `jitter` counts.
fn random_reading(rng: &mut Pcg64Mcg, jitter: f64) -> Reading {
    Reading {
        zero: Zero {
            cart: uniform(rng, 0.0, 1.0),
            pole: uniform(rng, 0.0, 1.0),
        },
        jitter_counts: jitter,
        seed: rng.next_u64(),
    }
}

/// The logs of one cart and one swing experiment as the board running `measured` records
/// them on `truth`.
fn logs(truth: &Machine, measured: &Machine, seed: u32, reading: Reading) -> Vec<Log> {
    let [cart, swing] = synthetic::experiments(truth, &measured.rig, seed, reading);
    let mut logs = log::parse(&cart, "cart").unwrap();
    logs.extend(log::parse(&swing, "swing").unwrap());
    logs
}

fn relative(found: f64, truth: f64) -> f64 {
    (found / truth - 1.0).abs()
}

/// Asserts the goal's tolerances on `fit` of `truth`; `what` names the case.
fn assert_recovered(fit: &Fit, truth: &Machine, what: &str) {
    let (q, p) = (&fit.params, &truth.rig.params);
    let errors = [
        ("force", relative(q.force_mag, p.force_mag), FORCE_TOLERANCE),
        (
            "damping",
            relative(q.motor_damping, p.motor_damping),
            DAMPING_TOLERANCE,
        ),
        ("length", relative(q.length, p.length), LENGTH_TOLERANCE),
    ];
    for (name, error, tolerance) in errors {
        assert!(
            error <= tolerance,
            "{what}: {name} off by {:.3}% (tolerance {}%): found {q:?}, truth {p:?}",
            100.0 * error,
            100.0 * tolerance
        );
    }
    assert_eq!(fit.dead_time, truth.rig.dead_time, "{what}: dead time");
}

/// Rigs drawn at random on both periods, each dead time from 0 to 3 given to one, their
/// encoders jittering by half a count: the goal's tolerances from 30 s of logs.
#[test]
fn random_rigs_are_recovered_within_the_goals_tolerances() {
    let mut rng = Pcg64Mcg::new(11);
    for i in 0..6u32 {
        let tau = if i % 2 == 0 { 0.02 } else { 0.01 };
        let (mut truth, measured) = random_rig(&mut rng, tau, 1.0);
        truth.rig.dead_time = [0, 3, 1, 2, 3, 0][i as usize];
        let reading = random_reading(&mut rng, 0.5);
        let fit = identify(&logs(&truth, &measured, i, reading), &measured).unwrap();
        assert_recovered(&fit, &truth, &format!("rig {i}"));
        assert!(misfit::findings(&fit).is_empty(), "rig {i}");
    }
}

/// Gymnasium's machine (Euler steps, no dead time, no damping, no friction) from its own
/// logs, the fit started from a rig file with half its force, some damping, a pole 10% long
/// and a dead time of 2: Gymnasium's values, the force within 0.1% and the length within
/// 0.5%.
#[test]
fn gymnasiums_machine_is_identified_as_gymnasiums() {
    let truth = Machine::GYMNASIUM;
    let mut measured = truth;
    let p = &mut measured.rig.params;
    p.force_mag *= 0.5;
    p.motor_damping = 1.0;
    p.length *= 1.1;
    measured.rig.dead_time = 2;
    let reading = Reading {
        zero: Zero {
            cart: 0.3,
            pole: 0.7,
        },
        ..Reading::default()
    };
    let logs = logs(&truth, &measured, 1, reading);
    let fit = identify(&logs, &measured).unwrap();
    let (q, g) = (&fit.params, &truth.rig.params);
    assert_eq!(fit.dead_time, 0);
    assert!(relative(q.force_mag, g.force_mag) < 1e-3, "{q:?}");
    assert!(relative(q.length, g.length) < 5e-3, "{q:?}");
    assert!(q.motor_damping < 1e-3, "{q:?}");
    assert!(q.cart_friction < 1e-4, "{q:?}");
    assert!(q.pole_friction < 1e-5, "{q:?}");
    let rest = Params {
        force_mag: g.force_mag,
        motor_damping: g.motor_damping,
        cart_friction: g.cart_friction,
        pole_friction: g.pole_friction,
        length: g.length,
        ..*q
    };
    assert_eq!(&rest, g, "nothing but the unknowns moves");
}

/// Each estimate's interval is stated, and the truth lies in it for the well-determined
/// unknowns of a rig with no jitter: the intervals are intervals of the estimate.
#[test]
fn the_intervals_cover_the_truth() {
    let mut rng = Pcg64Mcg::new(3);
    let (truth, measured) = random_rig(&mut rng, 0.02, 1.0);
    let reading = random_reading(&mut rng, 0.0);
    let fit = identify(&logs(&truth, &measured, 7, reading), &measured).unwrap();
    let p = &truth.rig.params;
    for (i, field) in [(model::FORCE, "force"), (model::LENGTH, "length")] {
        let e = fit.estimates[i];
        let h = e
            .half_width
            .unwrap_or_else(|| panic!("{field}: no interval"));
        let t = model::get(p, i);
        // Within four half-widths: the rounding's residuals are not quite independent.
        assert!((e.value - t).abs() <= 4.0 * h, "{field}: {e:?}, truth {t}");
        assert!(h < 0.01 * t, "{field}: {e:?}");
    }
    let report = report::format(&fit, &logs(&truth, &measured, 7, reading));
    assert!(report.contains("actuator.stall_force_n"), "{report}");
    assert!(report.contains("dead_time_periods"), "{report}");
}
