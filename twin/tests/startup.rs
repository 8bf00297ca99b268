//! The desk rig from power-on, in its true continuous world through its encoders and dead
//! time, its board told the identified rig and running the shipped integer desk policy: the
//! hanging zero, the swing-up, a hand's catch, and a knock that drops the pole.

use firmware::cartpole::State;
use firmware::controller::Greedy;
use firmware::startup::Startup;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use shipped::desk_int::{LEVELS, POLICY_INT, RIG};
use twin::Machine;
use twin::rigfile::load;
use twin::startup::{Events, Knock, Lift, Outcome, power_on};

/// A minute at 50 Hz.
const MINUTE: u32 = 3000;

fn world() -> Machine {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    load(&repo.join("rigs/desk.toml")).unwrap()
}

/// Uniform in [-1, 1).
fn unit(rng: &mut Pcg64Mcg) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

/// The pole hanging, swinging by up to `swing` rad, the cart within a centimetre of the
/// centre.
fn hanging(rng: &mut Pcg64Mcg, swing: f64) -> State {
    State::from_array([
        0.01 * unit(rng),
        0.0,
        std::f64::consts::PI + swing * unit(rng),
        0.05 * unit(rng),
    ])
}

fn run(startup: Startup, start: State, events: Events<'_>) -> Outcome {
    let policy = Greedy {
        net: &POLICY_INT,
        levels: LEVELS,
    };
    power_on(&world(), &RIG, startup, policy, start, events).unwrap()
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
    let episodes = 200;
    let events = Events {
        periods: 500 + MINUTE,
        ..Events::default()
    };
    let outcomes: Vec<Outcome> = (0..episodes)
        .map(|_| run(startup, hanging(&mut rng, 0.02), events))
        .collect();
    let up = outcomes.iter().filter(|o| balanced_within(o, 500)).count();
    let clear = outcomes.iter().filter(|o| o.max_abs_x <= margin).count();
    assert!(up >= 198, "{up} of {episodes} balanced within 10 s");
    assert!(clear >= 198, "{clear} of {episodes} kept off the margin");
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
    let events = Events {
        periods: 600,
        ..Events::default()
    };
    for _ in 0..100 {
        let start = hanging(&mut rng, 30f64.to_radians());
        let o = run(startup, start, events);
        let error = o.zero_error.expect("zeroed within 12 s");
        assert!(error.abs() <= 1, "{error} counts off from {start:?}");
    }
}

#[test]
fn a_pole_lifted_by_hand_into_the_catch_region_is_caught_and_held_a_minute() {
    let startup = Startup {
        swing: None,
        ..Startup::suggested(&RIG).unwrap()
    };
    let mut rng = Pcg64Mcg::new(43);
    let (mut caught, episodes) = (0, 200);
    for _ in 0..episodes {
        let lift = Lift {
            from: 250 + (50.0 * (1.0 + unit(&mut rng))) as u32,
            periods: 25 + (37.5 * (1.0 + unit(&mut rng))) as u32,
            release: (
                0.8 * f64::from(startup.catch_angle) * unit(&mut rng),
                0.5 * f64::from(startup.catch_rate) * unit(&mut rng),
            ),
        };
        let events = Events {
            periods: 500 + MINUTE,
            lift: Some(lift),
            ..Events::default()
        };
        let start = hanging(&mut rng, 0.0);
        let o = run(startup, start, events);
        assert_eq!(o.transitions.zeroed, 1);
        caught += usize::from(balanced_within(&o, 500));
    }
    assert!(caught >= 198, "{caught} of {episodes} caught");
}

#[test]
fn a_knock_that_drops_the_pole_is_recovered_by_the_swing_up_without_a_reset() {
    let startup = Startup::suggested(&RIG).unwrap();
    let mut rng = Pcg64Mcg::new(44);
    let knocks = [Knock {
        period: 1000,
        force: 40.0,
    }];
    let events = Events {
        periods: 1000 + MINUTE,
        knocks: &knocks,
        ..Events::default()
    };
    let o = run(startup, hanging(&mut rng, 0.02), events);
    assert!(o.transitions.fell >= 1, "{o:?}");
    assert!(o.balanced_from.is_some_and(|b| b > 1000), "{o:?}");
    assert_eq!(o.transitions.zeroed, 1);
}
