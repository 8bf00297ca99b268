extern crate std;
use std::vec::Vec;

use super::*;
use crate::controller::Duty;

/// Gymnasium's machine: 4,096 counts a revolution (2,048 a half), 20,480 a metre, 50 Hz, the
/// pole failing past 12 degrees (0.2094 rad).
const RIG: Rig = Rig::GYMNASIUM;
const PER_RAD: f32 = 4096.0 / core::f32::consts::TAU;

const START: Startup = Startup {
    zero_periods: 4,
    catch_angle: 0.1,
    catch_rate: 1.0,
    catch_periods: 3,
    release_angle: 0.2,
    swing: None,
    trim_rate: 0.0,
    trim_max: 0.0,
    homing: None,
};

/// Feeds `poles` with the cart at `cart`; true if every period held the motor off.
fn feed(s: &mut Sequencer, cart: i32, poles: impl IntoIterator<Item = i32>) -> bool {
    poles
        .into_iter()
        .all(|p| s.period(cart, p) == Act::Hold(Command::Coast))
}

/// A sequencer zeroed with the pole resting at raw count 500 and the cart at 100: upright
/// is 500 + 2,048.
fn zeroed(startup: Startup) -> Sequencer {
    let mut s = Sequencer::new(startup, &RIG).unwrap();
    feed(&mut s, 100, [500; 8]);
    assert_eq!(s.zero(), Some((100, 2548)));
    s
}

/// Counts from `from` through each turning point in turn, 3 counts a period.
fn swing(from: i32, turns: &[i32]) -> Vec<i32> {
    let mut counts = Vec::new();
    let mut at = from;
    for &to in turns {
        let step = if to > at { 3 } else { -3 };
        while (to - at) * step > 3 {
            at += step;
            counts.push(at);
        }
        at = to;
        counts.push(to);
    }
    counts
}

#[test]
fn a_resting_pole_is_zeroed_once_two_windows_agree() {
    let mut s = Sequencer::new(START, &RIG).unwrap();
    // A flicker of one count is rest: the middle of 500 and 501 is 500.5, count 500.
    assert!(feed(&mut s, 100, [500, 501, 500, 501, 501, 500, 501]));
    assert_eq!((s.phase(), s.zero()), (Phase::Zeroing, None));
    assert!(feed(&mut s, 100, [500]));
    assert_eq!(
        (s.phase(), s.zero()),
        (Phase::Waiting, Some((100, 501 + 2048)))
    );
    assert_eq!(s.transitions().zeroed, 1);

    // Two counts is not rest, and a window that moved does not agree with the one before.
    let mut s = Sequencer::new(START, &RIG).unwrap();
    feed(&mut s, 0, [500, 500, 502, 502, 502, 502, 502, 502]);
    assert_eq!(s.zero(), None);
    feed(&mut s, 0, [505; 4]);
    assert_eq!(s.zero(), None);
    feed(&mut s, 0, [505; 4]);
    assert_eq!(s.zero(), Some((0, 505 + 2048)));
}

#[test]
fn a_decaying_swing_is_zeroed_by_its_turning_points() {
    let mut s = Sequencer::new(START, &RIG).unwrap();
    // About 500, losing 2 counts a half swing: the middle of the first two turning points,
    // (520 + 481) / 2, is half a count high, of the next, (481 + 518) / 2, half a count low.
    // (520 + 2 x 481 + 518 + 2) / 4 = 500.5 and (481 + 2 x 518 + 483 + 2) / 4 = 500.5 agree.
    let turns = [520, 481, 518, 483, 516, 485];
    // The fourth turn (483) shows once the count is 2 back up from it.
    let to_fourth = swing(500, &turns[..4]);
    assert!(feed(&mut s, 7, to_fourth.iter().copied()));
    assert_eq!(s.zero(), None);
    assert!(feed(&mut s, 7, [484, 486]));
    assert_eq!(s.zero(), Some((7, 500 + 2048)));
    // Across the counter's wrap, the same.
    let mut s = Sequencer::new(START, &RIG).unwrap();
    let base = i32::MAX - 500;
    let counts = to_fourth.iter().chain(&[484, 486]);
    feed(&mut s, 0, counts.map(|&c| base.wrapping_add(c)));
    assert_eq!(s.zero(), Some((0, base.wrapping_add(500 + 2048))));
}

#[test]
fn a_lifted_pole_is_caught_after_its_periods_inside_and_let_go_past_the_release_angle() {
    let mut s = zeroed(START);
    // From hanging to 10 counts past upright in one period: a rate of 2,038 counts (wrapped
    // across the half turn) in 20 ms, far outside the region's 1 rad/s.
    assert_eq!(s.period(100, 2558), Act::Hold(Command::Coast));
    assert_eq!(s.phase(), Phase::Waiting);
    // Still there: inside (0.015 rad, at rest), three periods, then the controller drives.
    assert_eq!(s.period(100, 2558), Act::Hold(Command::Coast));
    assert_eq!(s.phase(), Phase::Catching);
    assert_eq!(s.period(100, 2558), Act::Hold(Command::Coast));
    assert_eq!(s.period(100, 2558), Act::Balance { engaged: true });
    assert_eq!(s.period(100, 2560), Act::Balance { engaged: false });
    assert_eq!(s.phase(), Phase::Balancing);
    // 0.2 rad is 130.4 counts: 130 past upright is held, 131 is let go.
    assert_eq!(s.period(100, 2548 + 130), Act::Balance { engaged: false });
    assert_eq!(s.period(100, 2548 + 131), Act::Hold(Command::Coast));
    assert_eq!(s.phase(), Phase::Fallen);
    // Motor off until the pole is below horizontal (1,024 counts from upright), then waiting.
    for pole in [2548 + 200, 2548 + 1023, 2548 - 1023] {
        assert_eq!(s.period(100, pole), Act::Hold(Command::Coast));
        assert_eq!(s.phase(), Phase::Fallen);
    }
    assert_eq!(s.period(100, 2548 - 1025), Act::Hold(Command::Coast));
    assert_eq!(s.phase(), Phase::Waiting);
    let t = s.transitions();
    assert_eq!((t.entered, t.caught, t.missed, t.fell), (1, 1, 0, 1));
    const { assert!((130.0 / PER_RAD) < 0.2 && (131.0 / PER_RAD) > 0.2) };
}

#[test]
fn the_cart_past_the_track_lets_go_and_a_pole_leaving_the_region_is_a_miss() {
    let mut s = zeroed(Startup {
        catch_periods: 1,
        ..START
    });
    assert_eq!(s.period(100, 2548), Act::Hold(Command::Coast));
    assert_eq!(s.period(100, 2548), Act::Balance { engaged: true });
    // 2.4 m is 49,152 counts.
    assert_eq!(
        s.period(100 + 49_152, 2548),
        Act::Balance { engaged: false }
    );
    assert_eq!(s.period(100 + 49_153, 2548), Act::Hold(Command::Coast));
    assert_eq!(s.phase(), Phase::Fallen);

    let mut s = zeroed(START);
    s.period(100, 2548);
    s.period(100, 2548);
    assert_eq!(s.phase(), Phase::Catching);
    // 0.1 rad is 65.2 counts; 66 counts in a period is 5 rad/s: out on both.
    assert_eq!(s.period(100, 2548 + 66), Act::Hold(Command::Coast));
    assert_eq!(s.phase(), Phase::Waiting);
    let t = s.transitions();
    assert_eq!((t.entered, t.caught, t.missed), (1, 0, 1));
}

#[test]
fn the_trim_integrates_the_carts_distance_while_balancing_only_and_stops_at_its_bound() {
    let mut s = zeroed(Startup {
        catch_periods: 1,
        trim_rate: 0.5,
        trim_max: 0.01,
        ..START
    });
    // 0.1 m right of the centre (2,048 counts) while catching: nothing yet.
    assert_eq!(s.period(100 + 2048, 2548), Act::Hold(Command::Coast));
    assert_eq!(s.trim, 0.0);
    // Balancing: 0.5 rad/(m s) x 0.1 m x 0.02 s = 0.001 rad a period, to the bound's 0.01.
    assert_eq!(s.period(100 + 2048, 2548), Act::Balance { engaged: true });
    for k in 1..=9 {
        assert_eq!(s.period(100 + 2048, 2548), Act::Balance { engaged: false });
        assert!(
            (s.trim - 0.001 * k as f32).abs() < 1e-7,
            "period {k}: {}",
            s.trim
        );
    }
    s.period(100 + 2048, 2548);
    s.period(100 + 2048, 2548);
    assert_eq!(s.trim, 0.01);
    // Left of the centre it comes back; falling keeps it.
    s.period(100 - 4096, 2548);
    assert!((s.trim - 0.008).abs() < 1e-7);
    let kept = s.trim;
    s.period(100, 2548 + 200);
    assert_eq!((s.phase(), s.trim), (Phase::Fallen, kept));
}

#[test]
fn homing_stalls_at_the_stop_then_centres_and_the_zero_is_the_homed_centre() {
    let mut s = Sequencer::new(
        Startup {
            homing: Some(Homing {
                duty: 0.3,
                stall_periods: 3,
            }),
            ..START
        },
        &RIG,
    )
    .unwrap();
    let push = |f: f32| Act::Hold(Command::Drive(Duty::from_fraction(f).unwrap()));
    // Towards -x at the homing duty while the cart moves, and through the stall's periods.
    for cart in [1000, 950, 900, 500, 500, 500, 500] {
        assert_eq!(s.period(cart, 0), push(-0.3), "cart at {cart}");
        assert_eq!(s.phase(), Phase::Homing);
    }
    // Stalled at 500: the centre is 2.4 m (49,152 counts) on. Away from the stop, capped.
    assert_eq!(s.period(500, 0), push(0.3));
    let near = 500 + 49_152 - 100;
    // Within a hundredth of the half-length (492 counts) for three periods: arrived.
    for _ in 0..3 {
        assert_eq!(s.phase(), Phase::Homing);
        s.period(near, 0);
    }
    assert_eq!((s.phase(), s.transitions().homed), (Phase::Zeroing, 1));
    assert!(feed(&mut s, near, [500; 12]));
    assert_eq!(s.zero(), Some((500 + 49_152, 2548)));
    // Homing is over: the cart's counts no longer drive anything until the catch.
    assert_eq!(s.period(near - 5000, 500), Act::Hold(Command::Coast));
}

#[test]
fn regions_a_rig_cannot_run_are_refused_naming_the_field() {
    let refused = |s: Startup| Sequencer::new(s, &RIG).err();
    let above = ConfigError::AboveLimit;
    assert_eq!(
        refused(Startup {
            catch_angle: 0.2,
            ..START
        }),
        Some(above("startup.catch_angle", "below startup.release_angle"))
    );
    assert_eq!(
        refused(Startup {
            release_angle: 0.21,
            ..START
        }),
        Some(above(
            "startup.release_angle",
            "at most params.theta_threshold_radians"
        ))
    );
    assert_eq!(
        refused(Startup {
            catch_rate: f32::NAN,
            ..START
        }),
        Some(ConfigError::NotFinite("startup.catch_rate"))
    );
    assert_eq!(
        refused(Startup {
            catch_angle: 0.0,
            ..START
        }),
        Some(ConfigError::NotPositive("startup.catch_angle"))
    );
    assert_eq!(
        refused(Startup {
            zero_periods: 1,
            ..START
        }),
        Some(ConfigError::TooFew("startup.zero_periods"))
    );
    // A catch the board would wait minutes for: refused on the board as in a rig file.
    assert_eq!(
        refused(Startup {
            catch_periods: MAX_CATCH_PERIODS + 1,
            ..START
        }),
        Some(above(
            "startup.catch_periods",
            "at most MAX_CATCH_PERIODS periods"
        ))
    );
    assert_eq!(
        refused(Startup {
            trim_rate: -1e-3,
            ..START
        }),
        Some(ConfigError::Negative("startup.trim_rate"))
    );
    assert_eq!(
        refused(Startup {
            trim_max: 0.1,
            ..START
        }),
        Some(above("startup.trim_max", "below startup.catch_angle"))
    );
    let homing = |duty, stall_periods| Startup {
        homing: Some(Homing {
            duty,
            stall_periods,
        }),
        ..START
    };
    assert_eq!(
        refused(homing(1.5, 10)),
        Some(above("startup.homing.duty", "at most 1"))
    );
    assert_eq!(
        refused(homing(0.0, 10)),
        Some(ConfigError::NotPositive("startup.homing.duty"))
    );
    assert_eq!(
        refused(homing(0.3, 1)),
        Some(ConfigError::TooFew("startup.homing.stall_periods"))
    );
    let swing = Swing {
        energy_gain: 0.5,
        max_accel: f32::INFINITY,
        centring: [1.0, 2.0],
        overshoot: 0.0,
    };
    assert_eq!(
        refused(Startup {
            swing: Some(swing),
            ..START
        }),
        Some(ConfigError::NotFinite("startup.swing.max_accel"))
    );
}

const SWING: Swing = Swing {
    energy_gain: 0.5,
    max_accel: 3.0,
    centring: [1.0, 2.0],
    overshoot: 0.0,
};

#[test]
fn the_swing_law_by_hand() {
    let pump = Pump::new(SWING, &RIG.params, 2.4);
    // Hanging at rest: energy -2, the rate taken as +1 rad/s, cos theta -1: 0.5 g (-2) (+1)
    // (-1) = 9.8 saturates at 3; less 1 x 0.1 and 2 x 0.2: 2.5 m/s^2, times 1.1 kg over 10 N:
    // 0.275 of full duty.
    let hanging = [0.1, 0.2, core::f32::consts::PI, 0.0];
    assert_eq!(pump.energy(hanging[2], 0.0), -2.0);
    let drive = |t| Command::Drive(Duty::from_thousandths(t).unwrap());
    assert_eq!(pump.command(&hanging), drive(275));
    // Level with the pivot (cos 0) at 2 rad/s: 2 l / 3 g x 4 = 0.1361 above -1.
    assert!((pump.energy(core::f32::consts::FRAC_PI_2, -2.0) + 0.863_946).abs() < 1e-5);
    // Near the top at 0.1 rad and 1 rad/s: the energy is taken half a period back, at 0.09
    // rad: 0.0340 - 0.0040 = 0.0300 over; 0.5 x 9.8 x 0.0300 x 1 x cos 0.1 = 0.146 m/s^2,
    // times 1.1 kg over 10 N: 0.016 of full duty.
    let top = [0.0, 0.0, 0.1, 1.0];
    assert!((pump.energy(0.1, 1.0) - 0.029_018).abs() < 1e-5);
    assert!((pump.energy(0.09, 1.0) - 0.029_967).abs() < 1e-5);
    assert_eq!(pump.command(&top), drive(16));
    // Stopping from 2 m/s at 3 m/s^2 takes 0.667 m: from 2.0 m that passes 2.4, so full
    // braking; from 1.5 m/s (0.375 m) it does not.
    assert_eq!(
        pump.command(&[2.0, 2.0, 0.1, 1.0]),
        Command::Drive(Duty::LEFT)
    );
    let near = pump.command(&[2.0, 1.5, 0.1, 1.0]);
    assert_ne!(near, Command::Drive(Duty::LEFT));
    assert_eq!(pump.command(&[f32::NAN, 0.0, 0.0, 0.0]), Command::Coast);
}

#[test]
fn with_a_swing_the_machine_pumps_instead_of_waiting() {
    let mut s = zeroed(Startup {
        swing: Some(SWING),
        ..START
    });
    assert_eq!(s.phase(), Phase::SwingingUp);
    // Hanging still at the zero, the cart at the centre: 0.5 g (-2) (+1) (-1) = 9.8,
    // saturated at 3 m/s^2: 0.33 of full duty.
    let drive = |t| Act::Hold(Command::Drive(Duty::from_thousandths(t).unwrap()));
    assert_eq!(s.period(100, 500), drive(330));
    assert_eq!(s.phase(), Phase::SwingingUp);
}

#[test]
fn the_suggested_start_up_by_hand() {
    // Gymnasium's pole: w = sqrt(3 x 9.8 / (4 x 0.5)) = 3.834 rad/s, half a swing 0.819 s =
    // 40.97 periods; the failure angle 12 degrees (0.2094 rad). The sway limit 0.3 x 2.4 x
    // 14.7 = 10.58 m/s^2 is above half the stall acceleration, 10 N / 1.1 kg / 2 = 4.545.
    let s = Startup::suggested(&RIG).unwrap();
    assert_eq!((s.zero_periods, s.catch_periods), (41, 3));
    assert!((s.catch_angle - 0.146_608).abs() < 1e-6);
    assert!((s.catch_rate - 0.958_514).abs() < 1e-6);
    assert!((s.release_angle - 0.198_968).abs() < 1e-6);
    let swing = s.swing.unwrap();
    assert!((swing.max_accel - 4.545_454).abs() < 1e-5);
    // A 10 cm track with no margin: 0.3 x 0.1 x 14.7 = 0.441 m/s^2 is the lower.
    let mut short = RIG;
    short.params.x_threshold = 0.1;
    let swing = Startup::suggested(&short).unwrap().swing.unwrap();
    assert!((swing.max_accel - 0.441).abs() < 1e-6);
}
