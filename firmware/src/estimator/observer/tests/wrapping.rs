//! Counts that wrap: a counter through `i32::MAX`, a pole through a whole revolution.

use super::*;
use crate::controller::{Command, Controller, FaultFlags};
use crate::estimator::ObserverSensor;
use crate::loopback::{Latest, pins};
use crate::shipped::policy::{POLICY, RIG};

/// 4,096 counts a revolution: a pole that leaves upright at 3 rad/s, turns once in 100
/// periods and comes to rest upright again, then held there.
fn one_turn() -> impl Iterator<Item = i32> {
    let turn = (0..100).map(|k: i32| k * 4_096 / 100);
    turn.chain(core::iter::repeat_n(4_096, 200))
}

/// The reported failure: the observer kept the angle a turn on (2 pi), beyond the
/// controller's limit, so that the controller coasted for ever after one revolution.
#[test]
fn a_pole_turned_once_reads_upright_and_the_controller_pushes_again() {
    let sensor = ObserverSensor::new(RIG.observer().unwrap(), Latest((0, 0)));
    let mut c = Controller::new(&POLICY, sensor, pins(), RIG.limits().unwrap());
    for pole in one_turn() {
        c.sensor_mut().counter_mut().0 = (0, pole);
        c.step();
    }
    let last = *c.last().unwrap();
    assert!(last.obs[2].abs() < 0.01, "{:?}", last.obs);
    assert!(last.faults.is_empty(), "{last:?}");
    assert!(matches!(last.command, Command::Drive(_)));
    // It coasted while the pole was down, and only then.
    assert!(c.faults().rejected_readings < 100, "{:?}", c.faults());
    assert_eq!(last.faults, FaultFlags::default());
}

/// Every angle the observer hands out is in (-pi, pi], through turns either way.
#[test]
fn the_angle_stays_in_one_revolution() {
    let mut o = RIG.observer().unwrap();
    for k in 0..2_000i32 {
        // Five turns one way at up to 40 counts a period, then back and on the other way.
        let pole = 200 * (k % 400) - 20 * (k % 400) * (k % 400) / 400 - 10 * k;
        let s = o.update(k, pole);
        o.command(if k % 3 == 0 { 1.0 } else { -1.0 });
        let pi = core::f32::consts::PI;
        assert!(s[2] > -pi && s[2] <= pi, "period {k}: {s:?}");
    }
}

/// Counts from a counter that wraps through `i32::MAX` give the estimate of counts that do
/// not. The pole's bit for bit: its angle is its count in the revolution, wherever the
/// counter started.
#[test]
fn a_pole_counter_wrapping_through_i32_max_reads_as_one_that_does_not() {
    let start = i32::MAX - 50;
    // The same place in the revolution: 2^31 - 1 is 4,095 mod 4,096.
    let same = -51;
    assert_eq!((i64::from(start) - i64::from(same)).rem_euclid(4_096), 0);
    let (mut wrapping, mut plain) = (RIG.observer().unwrap(), RIG.observer().unwrap());
    let ab = || AlphaBeta::new(RIG.encoders, 0.5, 0.02).unwrap();
    let (mut ab_wrapping, mut ab_plain) = (ab(), ab());
    for k in 0..200i32 {
        let moved = 3 * k - k * k / 100;
        let (pole, reference) = (start.wrapping_add(moved), same + moved);
        assert_eq!(wrapping.update(k, pole), plain.update(k, reference), "{k}");
        assert_eq!(ab_wrapping.update(k, pole), ab_plain.update(k, reference));
        let level = if k % 4 < 2 { 1.0 } else { -1.0 };
        wrapping.command(level);
        plain.command(level);
    }
    assert!(
        start.wrapping_add(3 * 199 - 199 * 199 / 100) < 0,
        "the counter wrapped"
    );
}

/// The cart's counter through `i32::MAX`: 2^31 counts is a hundred kilometres on this
/// encoder, where an f32 holds the observer's position to 8 mm, so its estimate moves on by
/// its counts to that; the integer filter's to the count.
#[test]
fn a_cart_counter_wrapping_through_i32_max_moves_the_estimate_by_its_counts() {
    let start = i32::MAX - 50;
    let per_m = f64::from(RIG.encoders.cart_counts_per_m);
    let mut o = RIG.observer().unwrap();
    let ab = || AlphaBeta::new(RIG.encoders, 0.5, 0.02).unwrap();
    let (mut ab_wrapping, mut ab_plain) = (ab(), ab());
    let mut last: Option<f32> = None;
    for k in 0..200i32 {
        let moved = 3 * k;
        let s = o.update(start.wrapping_add(moved), 0);
        o.command(0.0);
        let truth = (f64::from(start) + f64::from(moved) + 0.5) / per_m;
        assert!(
            (f64::from(s[0]) - truth).abs() < 0.02,
            "{k}: {s:?} vs {truth}"
        );
        if let Some(x) = last {
            assert!((s[0] - x).abs() < 0.02, "{k}: from {x} to {s:?}");
        }
        last = Some(s[0]);
        ab_wrapping.update(start.wrapping_add(moved), 0);
        ab_plain.update(moved, 0);
        let (w, p) = (ab_wrapping.raw(), ab_plain.raw());
        assert_eq!(w[0] - p[0], i64::from(start) << 12, "{k}");
        assert_eq!(w[1..], p[1..], "{k}");
    }
    assert!(start.wrapping_add(3 * 199) < 0, "the counter wrapped");
}
