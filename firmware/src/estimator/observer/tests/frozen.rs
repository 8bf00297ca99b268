//! The frozen-encoder watch against the f64 plant: a freeze in the middle of a balanced run.

use super::*;

/// The plant under the bang-bang rule of `velocity_errors` acting on the observer's
/// estimate, as a board's controller does, read through `FINE` encoders whose counters
/// freeze for periods `freeze`; the largest error of the angle estimate during and just
/// after the freeze (infinite if the pole fell), and the periods the observer called frozen.
fn freeze(watch: bool, freeze: core::ops::Range<usize>) -> (f64, usize) {
    let p = Params::default();
    let o = Observer::new(FINE, &p, Tuning::DEFAULT, 0).unwrap();
    let mut o = if watch { o.watching() } else { o };
    let mut s = State::from_array([0.03, -0.02, 0.02, -0.01]);
    let mut held = (0, 0);
    let (mut worst, mut frozen) = (0.0f64, 0);
    for k in 0..400 {
        if !freeze.contains(&k) {
            held = FINE.counts(s.x, s.theta);
        }
        let est = o.update(held.0, held.1);
        frozen += usize::from(o.frozen());
        if k >= freeze.start && k < freeze.end + 5 {
            worst = worst.max((f64::from(est[2]) - s.theta).abs());
        }
        let [x, x_dot, theta, theta_dot] = est.map(f64::from);
        let u = if theta + 0.3 * theta_dot + 0.02 * x + 0.05 * x_dot > 0.0 {
            1.0
        } else {
            -1.0
        };
        o.command(u as f32);
        s = advance(&p, &s, u, 0.0);
        if s.theta.abs() > p.theta_threshold_radians {
            return (f64::INFINITY, frozen);
        }
    }
    (worst, frozen)
}

#[test]
fn a_frozen_counter_is_seen_and_predicted_through() {
    // Half a second frozen: believed, the counts hold the estimate where the pole was.
    let (blind, none) = freeze(false, 200..225);
    let (watched, frozen) = freeze(true, 200..225);
    assert_eq!((none, frozen), (0, 25));
    // A count of the pole encoder is 1.5 mrad: predicted, the estimate stays within a few
    // counts of the truth through the freeze; held, it lets the pole fall most of the way.
    assert!(watched < 0.005, "predicted: {watched} rad");
    assert!(
        blind > 10.0 * watched,
        "held {blind} rad against predicted {watched} rad"
    );
    // Without a freeze, the watch never fires on a pole the rule keeps moving.
    assert_eq!(freeze(true, 0..0).1, 0);
}

#[test]
fn a_pole_hanging_at_rest_repeats_its_counts_and_is_not_frozen() {
    let o = Observer::new(FINE, &Params::default(), Tuning::DEFAULT, 0).unwrap();
    let mut o = o.watching();
    for _ in 0..50 {
        o.update(100, 2_048);
        o.command(0.0);
        assert!(!o.frozen());
    }
}
