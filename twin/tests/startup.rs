//! The desk rig from power-on, in its true continuous world through its encoders and dead
//! time, its board told the identified rig and running the shipped integer desk policy: the
//! hanging zero, the swing-up, a hand's catch, and a knock that drops the pole.

use firmware::controller::Greedy;
use firmware::startup::{Homing, Startup};
use rand_pcg::Pcg64Mcg;
use shipped::desk_int::{LEVELS, POLICY_INT, RIG};
use twin::rigfile::load;
use twin::startup::{Begin, Events, Knock, Outcome, power_on};

/// A minute at 50 Hz.
const MINUTE: u32 = 3000;

/// An episode begun as `begin` (drawn from `rng`), run for `periods` with `knocks`.
fn episode(
    begin: Begin,
    startup: Startup,
    rng: &mut Pcg64Mcg,
    periods: u32,
    knocks: &[Knock],
) -> Outcome {
    episode_off(begin, startup, rng, (periods, knocks), 0)
}

/// [`episode`], the zero read `zero_off` pole counts off once taken.
fn episode_off(
    begin: Begin,
    startup: Startup,
    rng: &mut Pcg64Mcg,
    (periods, knocks): (u32, &[Knock]),
    zero_off: i32,
) -> Outcome {
    let world = load(&repo().join("rigs/desk.toml")).unwrap();
    let (start, lift) = begin.draw(rng, &startup, RIG.params.tau);
    let policy = Greedy {
        net: &POLICY_INT,
        levels: LEVELS,
    };
    let events = Events {
        periods,
        lift,
        knocks,
        zero_off,
    };
    power_on::<[i16; 4], _>(&world, &RIG, startup, (policy, start), events, |_, _| {}).unwrap()
}

/// The repository's root.
fn repo() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Balanced from a period within `within` and held to the end.
fn balanced_within(o: &Outcome, within: u32) -> bool {
    o.balanced_from.is_some_and(|b| b <= within)
}

#[test]
fn the_hanging_pole_is_swung_up_within_ten_seconds_and_held_a_minute_off_the_end_stops() {
    let startup = Startup::suggested(&RIG).unwrap();
    let margin = RIG.limits().unwrap().max_abs()[0] as f64;
    let mut rng = Pcg64Mcg::new(41);
    let outcomes: Vec<Outcome> = (0..200)
        .map(|_| episode(Begin::Hanging, startup, &mut rng, 500 + MINUTE, &[]))
        .collect();
    let up = outcomes.iter().filter(|o| balanced_within(o, 500)).count();
    let clear = outcomes.iter().filter(|o| o.max_abs_x <= margin).count();
    assert!(up >= 198, "{up} of 200 balanced within 10 s");
    assert!(clear >= 198, "{clear} of 200 kept off the margin");
    assert!(
        outcomes
            .iter()
            .all(|o| o.zero_error.is_some_and(|e| e.abs() <= 1))
    );
}

#[test]
fn a_pole_swinging_thirty_degrees_at_power_on_is_zeroed_within_a_count() {
    let startup = Startup::suggested(&RIG).unwrap();
    let mut rng = Pcg64Mcg::new(42);
    for _ in 0..100 {
        let o = episode(Begin::Swinging, startup, &mut rng, 600, &[]);
        let error = o.zero_error.expect("zeroed within 12 s");
        assert!(error.abs() <= 1, "{error} counts off");
    }
}

#[test]
fn a_pole_lifted_by_hand_into_the_catch_region_is_caught_and_held_a_minute() {
    let startup = Startup {
        swing: None,
        ..Startup::suggested(&RIG).unwrap()
    };
    let mut rng = Pcg64Mcg::new(43);
    let mut caught = 0;
    for _ in 0..200 {
        let o = episode(Begin::Lifted, startup, &mut rng, 500 + MINUTE, &[]);
        assert_eq!(o.transitions.zeroed, 1);
        caught += usize::from(balanced_within(&o, 500));
    }
    assert!(caught >= 198, "{caught} of 200 caught");
}

#[test]
fn a_knock_that_drops_the_pole_is_recovered_by_the_swing_up_without_a_reset() {
    let startup = Startup::suggested(&RIG).unwrap();
    let mut rng = Pcg64Mcg::new(44);
    let knocks = [Knock {
        period: 1000,
        force: 40.0,
    }];
    let o = episode(Begin::Hanging, startup, &mut rng, 1000 + MINUTE, &knocks);
    assert!(o.transitions.fell >= 1, "{o:?}");
    assert!(o.balanced_from.is_some_and(|b| b > 1000), "{o:?}");
    assert_eq!(o.transitions.zeroed, 1);
}

#[test]
fn the_trim_keeps_the_cart_centred_where_the_zero_alone_lets_it_park_off_centre() {
    let suggested = Startup::suggested(&RIG).unwrap();
    let untrimmed = Startup {
        trim_rate: 0.0,
        ..suggested
    };
    // The cart's RMS distance from the centre over each episode's second half, sorted.
    let steady = |startup: Startup| {
        let mut rng = Pcg64Mcg::new(44);
        let mut rms: Vec<f64> = (0..40)
            .map(|_| episode(Begin::Hanging, startup, &mut rng, 500 + MINUTE, &[]))
            .map(|o| o.steady.expect("balancing in the second half").rms_x)
            .collect();
        rms.sort_by(f64::total_cmp);
        rms
    };
    let (trimmed, untrimmed) = (steady(suggested), steady(untrimmed));
    assert!(trimmed[39] < 0.05, "trimmed: {trimmed:?}");
    // How far the zero alone lets the cart park depends on the policy; the trim at least
    // halves it.
    assert!(
        2.0 * trimmed[20] < untrimmed[20],
        "trimmed: {trimmed:?}, untrimmed: {untrimmed:?}"
    );
}

#[test]
fn a_lifted_pole_is_caught_and_the_cart_centred_with_the_zero_a_degree_off() {
    let startup = Startup {
        swing: None,
        ..Startup::suggested(&RIG).unwrap()
    };
    // 7 counts of the desk's 2,400 a turn: 1.05 degrees, either way.
    let mut rng = Pcg64Mcg::new(45);
    for off in [7, -7] {
        for _ in 0..20 {
            let o = episode_off(Begin::Lifted, startup, &mut rng, (500 + MINUTE, &[]), off);
            assert!(balanced_within(&o, 500), "{off} counts: {o:?}");
            let rms_x = o.steady.expect("balancing in the second half").rms_x;
            assert!(rms_x < 0.05, "{off} counts: RMS x {rms_x} m");
        }
    }
}

#[test]
fn a_cart_left_anywhere_on_the_track_is_homed_to_the_centre_and_the_pole_swung_up() {
    let startup = Startup {
        homing: Some(Homing::suggested(RIG.params.tau)),
        ..Startup::suggested(&RIG).unwrap()
    };
    let world = load(&repo().join("rigs/desk.toml")).unwrap();
    let mut rng = Pcg64Mcg::new(46);
    for _ in 0..40 {
        let (mut start, _) = Begin::Hanging.draw(&mut rng, &startup, RIG.params.tau);
        start.x = 0.3 * (2.0 * firmware::cartpole::unit_f64(&mut rng) - 1.0);
        let policy = Greedy {
            net: &POLICY_INT,
            levels: LEVELS,
        };
        let events = Events {
            periods: 1000 + MINUTE,
            ..Events::default()
        };
        let o = power_on::<[i16; 4], _>(&world, &RIG, startup, (policy, start), events, |_, _| {})
            .unwrap();
        let error = o.centre_error.expect("homed and zeroed");
        // 15,000 counts a metre: within a millimetre.
        assert!(
            error.abs() <= 15,
            "from x = {:.3} m: {error} counts off",
            start.x
        );
        assert_eq!(o.transitions.homed, 1);
        assert!(
            balanced_within(&o, 1000),
            "from x = {:.3} m: {o:?}",
            start.x
        );
        assert!(o.steady.is_some_and(|s| s.rms_x < 0.05), "{o:?}");
    }
}
