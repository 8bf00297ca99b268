use super::*;

/// The register's period, found by running it from its first state until it returns.
fn cycle(degree: u8) -> (u32, i32) {
    let mut p = Prbs::new(degree, 0, 1);
    let start = p.state;
    let (mut n, mut sum) = (0u32, 0i32);
    loop {
        sum += i32::from(p.next_level());
        n += 1;
        if p.state == start || n > 1 << 17 {
            return (n, sum);
        }
    }
}

/// A maximal-length register of `d` bits visits all `2^d - 1` non-zero states, and its
/// output holds one more 1 than 0 over the cycle.
#[test]
fn every_register_is_of_maximal_length_and_balanced() {
    for d in Prbs::MIN_DEGREE..=Prbs::MAX_DEGREE {
        assert_eq!(cycle(d), ((1 << d) - 1, 1), "degree {d}");
    }
}

#[test]
fn each_bit_is_held_and_the_degree_covers_the_experiment() {
    let mut held = Prbs::new(5, 7, 3);
    let mut once = Prbs::new(5, 7, 1);
    for _ in 0..40 {
        let l = once.next_level();
        assert_eq!(
            [held.next_level(), held.next_level(), held.next_level()],
            [l; 3]
        );
    }
    // 250 bits of two periods need 255 states: 8 bits.
    assert_eq!(Prbs::degree_for(500, 2), 8);
    assert_eq!(Prbs::degree_for(0, 0), Prbs::MIN_DEGREE);
    assert_eq!(Prbs::degree_for(u32::MAX, 1), Prbs::MAX_DEGREE);
    assert_eq!(Prbs::new(1, 0, 0).degree(), Prbs::MIN_DEGREE);
    assert_eq!(Prbs::new(200, u32::MAX, 0).hold(), 1);
}

/// The duty `cart` commands at cart count `x`.
fn duty(cart: &mut Cart, x: i32) -> i8 {
    match cart.step(x, 0) {
        Step::Log(row) => row.duty,
        other => panic!("expected a row, found {other:?}"),
    }
}

/// Gymnasium's usable track is 2.4 m of 20,480 counts each: the rule turns back once the
/// cart would stop past 1.2 m (24,576 counts) and hands back to the sequence inside 0.48 m
/// (9,830 counts). Without dead time the lookahead is three periods.
#[test]
fn the_safety_rule_turns_the_cart_back_and_hands_over_inside() {
    let rig = Rig::GYMNASIUM;
    let mut cart = Cart::new(&rig, 100, 1, 3);
    let mut prbs = Prbs::new(Prbs::degree_for(100, 1), 3, 1);
    let mut levels = [0i8; 3];
    levels.iter_mut().for_each(|l| *l = prbs.next_level());
    // The first reading has no speed: standing at 24,576 counts is not past.
    assert_eq!(duty(&mut cart, 24_576), levels[0]);
    // Moving by -6 after 0, a change of 6: it would stop at 24,570 - 18 - 72 / 6 = 24,540.
    assert_eq!(duty(&mut cart, 24_570), levels[1]);
    // Moving by 5 after -6, a change of 11: it would stop at 24,575 + 15 + 50 / 11 = 24,594.
    assert_eq!(duty(&mut cart, 24_575), -1);
    // The sequence would have said otherwise where the rule spoke.
    assert_eq!(levels, [-1, -1, 1]);

    // Standing past 24,576 counts, then coming back by 100 a period (a change of 100): it
    // would stop 300 + 2 * 100^2 / 100 = 500 on, never past the far side. Sent back until
    // inside 9,830 counts (9,800, in period 148), then the sequence's.
    let mut cart = Cart::new(&rig, 200, 1, 3);
    let mut prbs = Prbs::new(Prbs::degree_for(200, 1), 3, 1);
    for k in 0..148 {
        prbs.next_level();
        assert_eq!(duty(&mut cart, 24_600 - 100 * k), -1, "period {k}");
    }
    assert_eq!(duty(&mut cart, 9_800), prbs.next_level());

    // The far side sends it towards +x, where the sequence starts towards -x.
    let mut cart = Cart::new(&rig, 100, 1, 3);
    assert_eq!(duty(&mut cart, -30_000), 1);
}

/// A cart gaining 10 counts a period each period (at `5 k (k + 1)` counts in period `k`)
/// would stop `3 v + 2 v^2 / 10` on from where it is: in period 30 at 4,650 + 900 + 18,000
/// = 23,550 counts, inside; in period 31 at 4,960 + 930 + 19,220 = 25,110, past 24,576. It
/// is braked there, well inside the inner band.
#[test]
fn the_safety_rule_brakes_by_the_stopping_distance() {
    let mut cart = Cart::new(&Rig::GYMNASIUM, 100, 1, 3);
    let mut prbs = Prbs::new(Prbs::degree_for(100, 1), 3, 1);
    let at = |k: i32| 5 * k * (k + 1);
    for k in 0..31 {
        let level = prbs.next_level();
        assert_eq!(
            cart.step(at(k), 0),
            Step::Log(Row {
                period: k as u32,
                duty: level,
                cart_counts: at(k),
                pole_counts: 0,
            })
        );
    }
    for k in 31..33 {
        assert_eq!(duty(&mut cart, at(k)), -1, "period {k}");
    }
}

#[test]
fn the_cart_experiment_logs_its_periods_then_stops() {
    let mut cart = Cart::new(&Rig::GYMNASIUM, 5, 2, 1);
    let rows: [Step; 6] = core::array::from_fn(|k| cart.step(k as i32, -(k as i32)));
    for (k, s) in rows[..5].iter().enumerate() {
        let Step::Log(r) = s else {
            panic!("period {k}: {s:?}")
        };
        assert_eq!(
            (r.period, r.cart_counts, r.pole_counts),
            (k as u32, k as i32, -(k as i32))
        );
    }
    assert_eq!(rows[5], Step::Done);
}

/// 4,096 counts a revolution: raised past 10 degrees is 113 counts off hanging, a release a
/// fall of 11 counts from the highest point.
#[test]
fn the_swing_waits_for_a_raise_and_logs_after_the_release() {
    let mut swing = Swing::new(Rig::GYMNASIUM.encoders, 3);
    assert_eq!(swing.step(0, 112), Step::Wait);
    // A pole raised the other way, a revolution on: still 113 off hanging.
    let raised = swing.step(5, 4 * 4096 - 113);
    assert!(matches!(
        raised,
        Step::Log(Row {
            period: 0,
            duty: 0,
            ..
        })
    ));
    assert!(matches!(
        swing.step(5, -200),
        Step::Log(Row { period: 1, .. })
    ));
    assert!(matches!(
        swing.step(5, -190),
        Step::Log(Row { period: 2, .. })
    ));
    // 11 counts below the peak of 200: released, then three more periods.
    for period in 3..7 {
        assert!(matches!(swing.step(5, -189), Step::Log(r) if r.period == period));
    }
    assert_eq!(swing.step(5, 0), Step::Done);
    assert_eq!(swing.step(5, 300), Step::Done);
}

#[test]
fn the_log_text_is_the_documented_format() {
    let rig = Rig::GYMNASIUM;
    let cart = Cart::new(&rig, 500, 2, 1);
    let mut csv = Csv(heapless::String::<512>::new());
    csv.header(&cart.header(&rig)).unwrap();
    csv.record(&Row {
        period: 0,
        duty: -1,
        cart_counts: -3,
        pole_counts: 4096,
    })
    .unwrap();
    let expected = "# cart-pole identification log\n# experiment: cart\n# period_s: 0.02\n\
        # cart_counts_per_m: 20480\n# pole_counts_per_rev: 4096\n# pole_zero: hanging\n\
        # prbs: degree 8, hold 2 periods, seed 1; back to the centre once the cart would stop \
        past 0.5 of the usable track (2.4 m), until inside 0.2\nperiod,duty,cart_counts,pole_counts\n0,-1,-3,4096\n";
    assert_eq!(csv.0.as_str(), expected);
    assert_eq!(Experiment::from_name("swing"), Some(Experiment::Swing));
    assert_eq!(Experiment::from_name("Swing"), None);
}

/// Any counts on any rig, however broken its description: rows or the end, never a panic.
#[test]
fn no_input_panics() {
    let mut broken = Rig::GYMNASIUM;
    broken.params.x_threshold = f64::NAN;
    broken.end_stop_margin = f64::INFINITY;
    broken.dead_time = u32::MAX;
    broken.encoders = Encoders {
        cart_counts_per_m: 0,
        pole_counts_per_rev: 0,
    };
    let mut cart = Cart::new(&broken, u32::MAX, u32::MAX, u32::MAX);
    let mut swing = Swing::new(broken.encoders, u32::MAX);
    for x in [i32::MIN, i32::MAX, 0, i32::MIN, -1, i32::MAX] {
        assert!(matches!(cart.step(x, x), Step::Log(_)));
        assert!(!matches!(swing.step(x, x), Step::Done));
    }
}
