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
};

/// Feeds `poles` with the cart at `cart`, returning what each period did.
fn feed(s: &mut Sequencer, cart: i32, poles: &[i32]) -> [Act; 8] {
    let mut acts = [Act::Hold(Command::Coast); 8];
    for (a, &p) in acts.iter_mut().zip(poles) {
        *a = s.period(cart, p);
    }
    acts
}

/// A sequencer zeroed with the pole hanging at raw count 500 and the cart at 100: upright
/// is 500 + 2,048.
fn zeroed(startup: Startup) -> Sequencer {
    let mut s = Sequencer::new(startup, &RIG).unwrap();
    feed(&mut s, 100, &[490, 500, 510, 500, 491, 509, 500, 495]);
    assert_eq!(s.zero(), Some((100, 2548)));
    s
}

#[test]
fn the_zero_is_the_middle_of_the_swing_once_two_windows_agree() {
    let mut s = Sequencer::new(START, &RIG).unwrap();
    // Windows of four: 490..=510 has its middle at 500 ((0 + 20 + 1) / 2 = 10 past 490), so
    // has 491..=509 ((0 + 18 + 1) / 2 = 9 past 491).
    let acts = feed(&mut s, 100, &[490, 500, 510, 500, 491, 509, 500]);
    assert!(acts.iter().all(|a| *a == Act::Hold(Command::Coast)));
    assert_eq!((s.phase(), s.zero()), (Phase::Zeroing, None));
    assert_eq!(s.period(100, 495), Act::Hold(Command::Coast));
    assert_eq!((s.phase(), s.zero()), (Phase::Waiting, Some((100, 2548))));
    assert_eq!(s.transitions().zeroed, 1);
    assert_eq!(s.about_upright((101, 2548 + 7)), (1, 7));

    // Middles of 500, then 503 (a hand moved it), then 503 again: the third window's.
    let mut s = Sequencer::new(START, &RIG).unwrap();
    feed(&mut s, 0, &[490, 500, 510, 500, 493, 503, 513, 503]);
    assert_eq!(s.zero(), None);
    feed(&mut s, 0, &[494, 512, 503, 503]);
    assert_eq!(s.zero(), Some((0, 503 + 2048)));
}

#[test]
fn a_zero_is_taken_across_the_counter_wrapping() {
    let mut s = Sequencer::new(START, &RIG).unwrap();
    let m = i32::MAX;
    feed(
        &mut s,
        0,
        &[
            m - 5,
            m,
            m.wrapping_add(5),
            m,
            m - 4,
            m,
            m.wrapping_add(4),
            m,
        ],
    );
    assert_eq!(s.zero(), Some((0, m.wrapping_add(2048))));
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
    assert_eq!(s.period(100, 2548 + 200), Act::Hold(Command::Coast));
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
    let swing = Swing {
        energy_gain: 0.5,
        max_accel: f32::INFINITY,
        centring: [1.0, 2.0],
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
};

#[test]
fn the_swing_law_by_hand() {
    let pump = Pump::new(SWING, &RIG.params, 2.4);
    // Hanging at rest: energy -2; the sign taken as +, so 0.5 g (-2) = -9.8 saturates at -3;
    // less 1 x 0.1 and 2 x 0.2: -3.5 m/s^2, times 1.1 kg over 10 N: -0.385 of full duty.
    let hanging = [0.1, 0.2, core::f32::consts::PI, 0.0];
    assert_eq!(pump.energy(hanging[2], 0.0), -2.0);
    let drive = |t| Command::Drive(Duty::from_thousandths(t).unwrap());
    assert_eq!(pump.command(&hanging), drive(-385));
    // Level with the pivot (cos 0) at 2 rad/s: 2 l / 3 g x 4 = 0.1361 above -1.
    assert!((pump.energy(core::f32::consts::FRAC_PI_2, -2.0) + 0.863_946).abs() < 1e-5);
    // Near the top, 0.0340 - 0.0050 = 0.0290 over, rising (theta_dot cos theta > 0): 0.5 x
    // 9.8 x 0.0290 = 0.1422 m/s^2, times 1.1 kg over 10 N: 0.0156 of full duty.
    let top = [0.0, 0.0, 0.1, 1.0];
    assert!((pump.energy(0.1, 1.0) - 0.029_018).abs() < 1e-5);
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
    // Hanging at the zero, the cart at the centre. Moving 5 counts from the last zeroing
    // period's 495 (0.38 rad/s, theta_dot cos theta < 0): 0.5 x 9.8 x 1.995 = 9.8 saturated
    // at 3 m/s^2, 0.33 of full duty; then still (the sign taken as +): -0.33.
    let drive = |t| Act::Hold(Command::Drive(Duty::from_thousandths(t).unwrap()));
    assert_eq!(s.period(100, 500), drive(330));
    assert_eq!(s.period(100, 500), drive(-330));
    assert_eq!(s.phase(), Phase::SwingingUp);
}
