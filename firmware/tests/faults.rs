//! Any counts a counter may give, through the estimators and the controller: no panic (the
//! suite's `quick` profile checks the firmware's overflows, as a debug build does), every
//! reading either finite and within the limits or a counted fault, and a single glitch
//! forgotten within a bound.

use firmware::cartpole::{CartPole, State};
use firmware::controller::{Command, Controller, StateSensor};
use firmware::estimator::{AlphaBeta, AlphaBetaSensor, Estimate, ObserverSensor};
use firmware::loopback::{Latest, Pins, duty, pins};
use proptest::prelude::*;
use shipped::policy::{POLICY, RIG};
use shipped::policy_int::POLICY_INT;

/// Periods after a one-period glitch within which the observer's estimate is back within
/// one count (and one count a period) of the estimate without the glitch, on the shipped
/// rig: the worst of [`glitches`]' sweep for each kind; `docs/CONTROL.md` states them. A pole
/// glitch of any size is taken as the smaller move within a revolution, so its size hardly
/// matters; a cart glitch decays at the observer's rate, so larger ones take longer.
const POLE_RECOVERY: usize = 6;
/// See [`POLE_RECOVERY`]: a cart glitch of fewer than [`SMALL`] counts.
const CART_RECOVERY_SMALL: usize = 9;
/// A bound for a cart glitch of any size (fewer than 2^31 counts): one second. Not the
/// worst measured, which grows the more glitches a sweep tries between [`SMALL`] and 2^24
/// counts (`docs/CONTROL.md` gives the figures), so the test holds such glitches to a round
/// bound with room instead.
const CART_RECOVERY: usize = 50;
/// 2^20 counts: 51 m of the shipped rig's track, beyond any real glitch's size.
const SMALL: u32 = 1 << 20;
/// Cart glitches of 2^30 counts (52 km) or more are left out: from some states of the
/// recorded run the f32 estimate does not come back within a count after a glitch of
/// 2^31 - 1 (`docs/CONTROL.md`), and no counter moves so far in a period.
const LARGEST: u32 = 1 << 30;

/// Whether [`BOUNDS`] hold a glitch: any on the pole, one of fewer than [`LARGEST`] counts
/// on the cart.
fn bounded(pole: bool, size: i32) -> bool {
    pole || size.unsigned_abs() < LARGEST
}

/// The bounds [`recovery`] must meet, indexed by [`kind`].
const BOUNDS: [usize; 3] = [POLE_RECOVERY, CART_RECOVERY_SMALL, CART_RECOVERY];

/// Which of [`BOUNDS`] a glitch of `size` counts on the pole's encoder or the cart's falls
/// under.
fn kind(pole: bool, size: i32) -> usize {
    match (pole, size.unsigned_abs() < SMALL) {
        (true, _) => 0,
        (false, true) => 1,
        (false, false) => 2,
    }
}

/// Glitches `(at, pole, size)` of the sweep, on either encoder and of either sign: every
/// power of two below 2^31, 2^31 - 1 and sizes near half a pole revolution at five points of
/// the recorded run; and per power of two 400 sizes log-uniform below the next, at points
/// drawn from a fixed stream (the same every run).
fn glitches() -> impl Iterator<Item = (usize, bool, i32)> {
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let fixed = (0..31)
        .map(|b| 1i64 << b)
        .chain([i64::from(i32::MAX), 2_047, 1_024, 3_000]);
    let mut sizes: Vec<(usize, i64)> = [20, 97, 150, 233, 301]
        .into_iter()
        .flat_map(|at| fixed.clone().map(move |m| (at, m)))
        .collect();
    for b in 0..31 {
        for _ in 0..400 {
            let r = next();
            sizes.push((
                20 + (r % 280) as usize,
                (1i64 << b) | ((r >> 8) as i64 & ((1 << b) - 1)),
            ));
        }
    }
    sizes.into_iter().flat_map(|(at, m)| {
        let m = m as i32;
        [
            (at, false, m),
            (at, false, -m),
            (at, true, m),
            (at, true, -m),
        ]
    })
}

/// A counter's readings: mostly small steps, some jumps of any size, some wrapping through
/// the ends of `i32`.
fn counts() -> impl Strategy<Value = Vec<(i32, i32)>> {
    let step = prop_oneof![
        4 => (-50i32..50, -50i32..50),
        1 => (any::<i32>(), any::<i32>()),
    ];
    (any::<(i32, i32)>(), prop::collection::vec(step, 1..150)).prop_map(|(start, steps)| {
        steps
            .iter()
            .scan(start, |c, &(dc, dp)| {
                *c = (c.0.wrapping_add(dc), c.1.wrapping_add(dp));
                Some(*c)
            })
            .collect()
    })
}

/// Runs `c` over `seq`: each period's reading is finite and within the limits, or it is
/// rejected, coasted and counted.
fn every_reading_is_sane_or_counted<P, S>(mut c: Controller<P, S, Pins>, seq: &[(i32, i32)])
where
    P: firmware::controller::Policy<S::Reading>,
    S: StateSensor + CounterOf,
    S::Reading: Si,
{
    let limits = RIG.limits().unwrap().max_abs();
    let mut rejected = 0;
    for &counts in seq {
        c.sensor_mut().set(counts);
        let command = c.step();
        let r = *c.last().unwrap();
        let obs = r.obs.si();
        if r.faults.reading_rejected() {
            rejected += 1;
            assert_eq!(command, Command::Coast);
        } else {
            assert!(obs.iter().all(|v| v.is_finite()), "{obs:?}");
            assert!(obs.iter().zip(limits).all(|(v, m)| v.abs() <= m), "{obs:?}");
            assert!(matches!(command, Command::Drive(_)));
        }
    }
    assert_eq!(c.faults().rejected_readings, rejected);
}

/// A sensor whose counter the test sets.
trait CounterOf {
    fn set(&mut self, counts: (i32, i32));
}

impl<O> CounterOf for ObserverSensor<Latest, O> {
    fn set(&mut self, counts: (i32, i32)) {
        self.counter_mut().0 = counts;
    }
}

impl<O> CounterOf for AlphaBetaSensor<Latest, O> {
    fn set(&mut self, counts: (i32, i32)) {
        self.counter_mut().0 = counts;
    }
}

/// A reading in SI units: Q3.12 back to floats.
trait Si {
    fn si(self) -> [f32; 4];
}

impl Si for [f32; 4] {
    fn si(self) -> [f32; 4] {
        self
    }
}

impl Si for [i16; 4] {
    fn si(self) -> [f32; 4] {
        firmware::fixed::to_state(&self)
    }
}

fn observer_sensor<O: Estimate>() -> ObserverSensor<Latest, O> {
    ObserverSensor::new(RIG.observer().unwrap(), Latest::default())
}

fn filter_sensor<O: Estimate>() -> AlphaBetaSensor<Latest, O> {
    let tau = RIG.params.tau as f32;
    AlphaBetaSensor::new(
        AlphaBeta::new(RIG.encoders, 0.5, tau).unwrap(),
        Latest::default(),
    )
}

proptest! {
    #[test]
    fn the_float_controller_on_the_observer_is_sane_or_counts(seq in counts()) {
        let c = Controller::new(&POLICY, observer_sensor::<[f32; 4]>(), pins(), RIG.limits().unwrap());
        every_reading_is_sane_or_counted(c, &seq);
    }

    #[test]
    fn the_integer_controller_on_the_observer_is_sane_or_counts(seq in counts()) {
        let sensor = observer_sensor::<[i16; 4]>();
        let c = Controller::new(&POLICY_INT, sensor, pins(), RIG.limits().unwrap());
        every_reading_is_sane_or_counted(c, &seq);
    }

    #[test]
    fn the_controller_on_the_alpha_beta_filter_is_sane_or_counts(seq in counts()) {
        let c = Controller::new(&POLICY, filter_sensor::<[f32; 4]>(), pins(), RIG.limits().unwrap());
        every_reading_is_sane_or_counted(c, &seq);
        let sensor = filter_sensor::<[i16; 4]>();
        let c = Controller::new(&POLICY_INT, sensor, pins(), RIG.limits().unwrap());
        every_reading_is_sane_or_counted(c, &seq);
    }

    #[test]
    fn the_estimators_angles_stay_in_one_revolution(seq in counts(), levels in prop::collection::vec(any::<f32>(), 150)) {
        let mut o = RIG.observer().unwrap();
        let mut f = AlphaBeta::new(RIG.encoders, 0.9, 0.02).unwrap();
        let pi = core::f32::consts::PI;
        for (&(cart, pole), level) in seq.iter().zip(levels) {
            let s = o.update(cart, pole);
            o.command(level);
            prop_assert!(s[2].is_nan() || (s[2] > -pi && s[2] <= pi), "{:?}", s);
            let a = f.update(cart, pole);
            prop_assert!(a.iter().all(|v| v.is_finite()), "{:?}", a);
            prop_assert!(a[2] > -pi - 1e-6 && a[2] <= pi + 1e-6, "{:?}", a);
            f.fixed_state();
        }
    }

}

proptest! {
    // A fixed seed: the bounds are the worst of a sweep, not proven, and a glitch the sweep
    // missed must fail this test when it is written, not some later run.
    #![proptest_config(ProptestConfig {
        rng_seed: prop::test_runner::RngSeed::Fixed(20_261_203),
        ..ProptestConfig::default()
    })]

    #[test]
    fn a_single_glitch_is_forgotten_within_the_bound(
        at in 20usize..300,
        pole in any::<bool>(),
        bits in 0u32..31,
        low in any::<u32>(),
        negative in any::<bool>(),
    ) {
        // Sizes log-uniform, so that every order of magnitude is tried as often.
        let m = ((1u32 << bits) | (low & ((1 << bits) - 1))) as i32;
        let size = if negative { -m } else { m };
        prop_assume!(bounded(pole, size));
        let periods = recovery(recorded(), at, pole, size);
        prop_assert!(periods <= BOUNDS[kind(pole, size)], "{} periods", periods);
    }
}

/// The shipped policy balancing the plant through the observer, from a lean: each period's
/// counts and the duty commanded (recorded once).
fn recorded() -> &'static [((i32, i32), f32)] {
    static RUN: std::sync::OnceLock<Vec<((i32, i32), f32)>> = std::sync::OnceLock::new();
    RUN.get_or_init(record)
}

fn record() -> Vec<((i32, i32), f32)> {
    let mut plant = CartPole::new(RIG.params, 400);
    plant.reset_to(State::from_array([0.1, -0.2, 0.05, 0.3]));
    let mut c = Controller::new(
        &POLICY,
        observer_sensor::<[f32; 4]>(),
        pins(),
        RIG.limits().unwrap(),
    );
    let mut out = Vec::new();
    for _ in 0..400 {
        let s = plant.state();
        let counts = RIG.encoders.counts(s.x, s.theta);
        c.sensor_mut().set(counts);
        let command = c.step();
        out.push((counts, command.level()));
        assert!(!plant.advance(duty(c.actuator()), 0.0).terminated);
    }
    out
}

/// Periods from a glitch of `size` counts at period `at` (on the pole, or the cart) until
/// the observer's estimate is back, for good, within one count and one count a period of
/// the estimate without it.
fn recovery(run: &[((i32, i32), f32)], at: usize, pole: bool, size: i32) -> usize {
    let per = [
        1.0 / RIG.encoders.cart_counts_per_m as f32,
        core::f32::consts::TAU / RIG.encoders.pole_counts_per_rev as f32,
    ];
    let tau = RIG.params.tau as f32;
    let tolerance = [per[0], per[0] / tau, per[1], per[1] / tau];
    let (mut clean, mut glitched) = (RIG.observer().unwrap(), RIG.observer().unwrap());
    let mut last_off = at;
    for (k, &((cart, p), level)) in run.iter().enumerate() {
        let (gc, gp) = match (k == at, pole) {
            (true, true) => (cart, p.wrapping_add(size)),
            (true, false) => (cart.wrapping_add(size), p),
            (false, _) => (cart, p),
        };
        let (a, b) = (clean.update(cart, p), glitched.update(gc, gp));
        clean.command(level);
        glitched.command(level);
        if a.iter()
            .zip(b)
            .zip(tolerance)
            .any(|((a, b), t)| (a - b).abs() > t)
        {
            last_off = k;
        }
    }
    assert!(last_off + 50 < run.len(), "recovered before the run ended");
    last_off + 1 - at
}

#[test]
fn the_recovery_bounds_are_the_worst_glitches_measured() {
    let run = recorded();
    let mut worst = [0; 3];
    for (at, pole, size) in glitches().filter(|&(_, pole, size)| bounded(pole, size)) {
        let k = kind(pole, size);
        worst[k] = worst[k].max(recovery(run, at, pole, size));
    }
    assert_eq!(
        worst[..2],
        BOUNDS[..2],
        "the measured worst: pole, cart under 2^20"
    );
    assert!(
        (CART_RECOVERY_SMALL..=CART_RECOVERY).contains(&worst[2]),
        "a cart glitch of 2^20 counts or more: {} periods",
        worst[2]
    );
}
