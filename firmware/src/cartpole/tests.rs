use super::*;

#[test]
fn default_params_are_gymnasiums() {
    let p = Params::default();
    assert_eq!(p.total_mass(), 1.1);
    assert_eq!(p.polemass_length(), 0.05);
    assert_eq!(p.theta_threshold_radians, 0.20943951023931953);
}

#[test]
fn truncates_at_the_limit_but_termination_wins() {
    let mut env = CartPole::new(Params::default(), 3);
    env.reset_to(State::default());
    let a = [Action::Left, Action::Right, Action::Left];
    let t: [Transition; 3] = a.map(|a| env.step(a));
    assert!(!t[0].truncated && !t[1].truncated && t[2].truncated);
    assert!(t.iter().all(|t| !t.terminated && t.reward == 1.0));

    let mut env = CartPole::new(Params::default(), 1);
    env.reset_to(State {
        theta: 0.2094,
        theta_dot: 1.0,
        ..State::default()
    });
    let t = env.step(Action::Left);
    assert!(t.terminated && !t.truncated);
}

#[cfg(feature = "rand")]
#[test]
fn reset_is_uniform_in_the_start_box() {
    use rand_pcg::Pcg64Mcg;
    let mut rng = Pcg64Mcg::new(7);
    let mut env = CartPole::new(Params::default(), 500);
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for _ in 0..2000 {
        env.reset(&mut rng);
        for v in env.state().to_array() {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    assert!((-0.05..-0.0499).contains(&lo), "{lo}");
    assert!((0.0499..0.05).contains(&hi), "{hi}");
}

#[test]
fn friction_follows_florians_equations() {
    let p = Params {
        cart_friction: 0.1,
        ..Params::default()
    };
    // A cart sliding at 1 m/s under an upright pole at rest, no force: the track's normal
    // force is the whole weight M g, the pole tips forward with
    // theta_acc = mu_c g / (l (4/3 - m / M (1 - mu_c))), and the cart decelerates by the
    // friction and the pole's reaction: x_acc = (-m l theta_acc - mu_c M g) / M.
    let s = State {
        x_dot: 1.0,
        ..State::default()
    };
    let n = advance(&p, &s, 0.0, 0.0);
    let xacc = (n.x_dot - s.x_dot) / p.tau;
    let tacc = (n.theta_dot - s.theta_dot) / p.tau;
    let want = 0.1 * 9.8 / (0.5 * (4.0 / 3.0 - 0.1 / 1.1 * 0.9));
    assert!((tacc - want).abs() < 1e-12, "{tacc} vs {want}");
    let want_x = (-0.05 * want - 0.1 * 1.1 * 9.8) / 1.1;
    assert!((xacc - want_x).abs() < 1e-12, "{xacc} vs {want_x}");
    // At rest, Coulomb friction exerts nothing.
    let rest = advance(&p, &State::default(), 0.0, 0.0);
    assert_eq!(rest, State::default());
}

#[test]
fn without_friction_the_friction_equations_are_gymnasiums_to_rounding() {
    // A vanishing friction coefficient takes Florian's equations, zero takes Gymnasium's.
    let s = [0.1, -0.4, 0.15, 1.3];
    let p = Params::default();
    let tiny = Params {
        cart_friction: 1e-300,
        ..p
    };
    let a = Plant::<f64>::new(&p).derivative(&s, 0.7, 0.0);
    let b = Plant::<f64>::new(&tiny).derivative(&s, 0.7, 0.0);
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= 1e-15 * x.abs().max(1.0), "{a:?} {b:?}");
    }
}

#[test]
fn the_motor_loses_force_with_speed_and_duty_scales_it() {
    // Damping c takes c * x_dot from the stall force: the same accelerations as an undamped
    // motor with that force taken away outside it.
    let p = Params {
        motor_damping: 3.0,
        ..Params::default()
    };
    let undamped = Plant::<f64>::new(&Params::default());
    let damped = Plant::<f64>::new(&p);
    let s = [0.0, 0.8, 0.05, -0.2];
    assert_eq!(damped.motor_force(0.5, 0.8), 10.0 * 0.5 - 3.0 * 0.8);
    let a = damped.derivative(&s, 0.5, 0.0);
    let b = undamped.derivative(&s, 0.0, 10.0 * 0.5 - 3.0 * 0.8);
    assert_eq!(a, b);
    // Full duty without damping is Gymnasium's push.
    assert_eq!(undamped.motor_force(1.0, 123.0), 10.0);
    assert_eq!(
        step(&Params::default(), &State::from_array(s), Action::Left),
        advance(&Params::default(), &State::from_array(s), -1.0, 0.0)
    );
}

#[test]
fn the_f32_plant_follows_the_f64_one() {
    // micromath's sine and cosine are within 1.1e-3; one period moves a balancing state by
    // tau times that at most.
    let p = Params::default();
    let s = [0.3, -0.5, 0.08, -0.6];
    let a = Plant::<f64>::new(&p).euler(&s, 1.0, 0.0);
    let b = Plant::<f32>::new(&p).euler(&s.map(|v| v as f32), 1.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        assert!((x - f64::from(y)).abs() < 1e-3, "{a:?} {b:?}");
    }
}

#[test]
fn pivot_friction_takes_energy_out_of_a_swinging_pole() {
    // A pole swinging through upright (theta_dot = 2) slows less without friction.
    let s = State::from_array([0.0, 0.0, 0.0, 2.0]);
    let free = advance(&Params::default(), &s, 0.0, 0.0);
    let damped = advance(
        &Params {
            pole_friction: 0.01,
            ..Params::default()
        },
        &s,
        0.0,
        0.0,
    );
    assert!(damped.theta_dot < free.theta_dot, "{damped:?} {free:?}");
}

#[test]
fn action_indices_round_trip() {
    for a in Action::ALL {
        assert_eq!(Action::from_index(a.index()), a);
    }
    assert_eq!(Action::from_index(7), Action::Left);
}

#[test]
fn sin_cos_is_sin_and_cos_bit_for_bit() {
    // Gymnasium's bits rest on libm's sine and cosine, whichever way the plant asks for both.
    let mut x = -40.0f64;
    while x < 40.0 {
        let (s, c) = Real::sin_cos(x);
        assert_eq!(
            (s.to_bits(), c.to_bits()),
            (libm::sin(x).to_bits(), libm::cos(x).to_bits()),
            "{x}"
        );
        x += 0.012_345_678_9;
    }
    for x in [0.0, -0.0, 1e-300, core::f64::consts::FRAC_PI_4, 1e6, 1e300] {
        let (s, c) = Real::sin_cos(x);
        assert_eq!(
            (s.to_bits(), c.to_bits()),
            (libm::sin(x).to_bits(), libm::cos(x).to_bits()),
            "{x}"
        );
    }
}
