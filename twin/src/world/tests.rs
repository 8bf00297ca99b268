use super::*;
use firmware::cartpole::{Action, Params, advance};
use rand_pcg::Pcg64Mcg;

/// A world of `s` from the streams every world test uses (the faults' tests too).
pub(crate) fn world(s: &Scenario) -> World<'_, Pcg64Mcg> {
    World::start(
        s,
        500,
        &mut Pcg64Mcg::new(1),
        Pcg64Mcg::new(2),
        Pcg64Mcg::new(3),
    )
}

#[test]
fn the_nominal_world_is_the_plant() {
    let nominal = Scenario::nominal();
    let mut w = world(&nominal);
    let mut plant = CartPole::new(Params::default(), 500);
    let mut obs = plant.reset(&mut Pcg64Mcg::new(1));
    for k in 0..100 {
        assert_eq!(w.measure(), Measurement::State(obs));
        let a = Action::from_index(k % 3 / 2);
        assert_eq!(w.apply(a.level()), plant.step(a));
        obs = plant.state().observation();
    }
}

#[test]
fn dead_time_delivers_each_duty_n_periods_late() {
    for d in [1, 2, 5] {
        let s = Scenario::parse(&format!("delay={d}")).unwrap();
        let mut w = world(&s);
        let p = Params::default();
        let mut state = w.state();
        // Duty k is full right on odd k: it acts in period k + d; before the first, none.
        let duty = |k: i64| match k {
            k if k < 0 => 0.0,
            k if k % 2 == 1 => 1.0,
            _ => -1.0,
        };
        for k in 0..40 {
            w.measure();
            w.apply(duty(k));
            state = advance(&p, &state, duty(k - d), 0.0);
            assert_eq!(w.state(), state, "delay {d}, period {k}");
        }
    }
}

#[test]
fn encoders_count_the_noisy_true_positions() {
    let s = Scenario::parse("encoder=1024+noise").unwrap();
    let mut w = world(&s);
    let mut noise = Pcg64Mcg::new(2);
    for _ in 0..50 {
        let truth = w.state();
        let g = |r: &mut Pcg64Mcg| -> f64 { StandardNormal.sample(r) };
        let x = truth.x + 0.01 * g(&mut noise);
        let theta = truth.theta + 0.005 * g(&mut noise);
        let (c, p) = s.rig.encoders.counts(x, theta);
        assert_eq!(w.measure(), Measurement::Counts(c, p));
        w.apply(1.0);
    }
}

#[test]
fn a_push_adds_its_impulse_over_one_period() {
    let s = Scenario::parse("push=0.3/4").unwrap();
    let mut w = world(&s);
    let p = Params::default();
    let mut sides = Pcg64Mcg::new(3);
    let mut state = w.state();
    for k in 1..=12u32 {
        w.apply(0.0);
        let external = if k % 4 == 0 {
            let side = if unit_f64(&mut sides) < 0.5 {
                -1.0
            } else {
                1.0
            };
            side * 0.3 / p.tau
        } else {
            0.0
        };
        state = advance(&p, &state, 0.0, external);
        assert_eq!(w.state(), state, "period {k}");
    }
}

#[test]
fn jittered_encoders_count_the_positions_moved_on_over_the_draw() {
    let s = Scenario::parse("encoder=8192/40960+jitter=0.1").unwrap();
    let mut w = world(&s);
    // The same noise stream: one uniform draw a reading, nothing else (no noise part).
    let mut draws = Pcg64Mcg::new(2);
    let tau = s.params.tau;
    let (mut earliest, mut latest) = (0.0f64, 0.0f64);
    for k in 0..200 {
        let truth = w.state();
        let dt = 0.1 * tau * (2.0 * unit_f64(&mut draws) - 1.0);
        let want = s.rig.encoders.counts(
            truth.x + dt * truth.x_dot,
            truth.theta + dt * truth.theta_dot,
        );
        assert_eq!(
            w.measure(),
            Measurement::Counts(want.0, want.1),
            "period {k}"
        );
        (earliest, latest) = (earliest.min(dt), latest.max(dt));
        w.apply(if k % 4 < 2 { 1.0 } else { -1.0 });
    }
    // The draws fill the window on both sides.
    assert!(
        earliest < -0.09 * tau && latest > 0.09 * tau,
        "{earliest} {latest}"
    );
    let on_time = Scenario::parse("encoder=8192/40960").unwrap();
    assert_eq!(on_time.jitter, 0.0);
    assert!(Scenario::parse("jitter=0.6").is_err());
}
