use super::*;
use crate::controller::{Greedy, Levels, Rises, answer, between, nearest};
use crate::network::Mlp;
use proptest::prelude::*;

fn d(t: i16) -> Duty {
    Duty::from_thousandths(t).unwrap()
}

/// The peak of the parabola through three points, by the textbook three-point formula in
/// f64: a reference written apart from [`between`]'s midpoint form.
fn vertex(x: [f64; 3], y: [f64; 3]) -> f64 {
    let denom = (x[0] - x[1]) * (x[0] - x[2]) * (x[1] - x[2]);
    let a = (x[2] * (y[1] - y[0]) + x[1] * (y[0] - y[2]) + x[0] * (y[2] - y[1])) / denom;
    let b =
        (x[2] * x[2] * (y[0] - y[1]) + x[1] * x[1] * (y[2] - y[0]) + x[0] * x[0] * (y[1] - y[2]))
            / denom;
    -b / (2.0 * a)
}

#[test]
fn a_quadratic_value_gives_its_own_peak() {
    // q(u) = -(u - 80)^2 at 0, 50 and 150 thousandths: -6400, -900, -4900.
    assert_eq!(
        between([d(0), d(50), d(150)], Rises::Float(5500.0, 4000.0)),
        d(80)
    );
    // -(u + 120)^2 at -400, -150 and -50: -78400, -900, -4900.
    assert_eq!(
        between([d(-400), d(-150), d(-50)], Rises::Int(77_500, 4_000)),
        d(-120)
    );
}

/// A neighbour that scores as the chosen level puts the peak on their midpoint, which rounds
/// to either: the duty stays a thousandth inside, the chosen level's.
#[test]
fn a_tie_with_a_neighbour_drives_a_thousandth_inside_the_midpoint_and_no_rise_the_level() {
    let l = [d(50), d(150), d(400)];
    for (lower, higher, want) in [(0, 3, 101), (3, 0, 274), (0, 0, 150)] {
        assert_eq!(between(l, Rises::Int(lower, higher)), d(want));
        let float = Rises::Float(lower as f32, higher as f32);
        assert_eq!(between(l, float), d(want));
    }
}

#[test]
fn rises_that_are_no_peak_leave_the_level() {
    let l = [d(-50), d(0), d(50)];
    for rise in [
        (f32::NAN, 1.0),
        (1.0, f32::NAN),
        (f32::INFINITY, 1.0),
        (1.0, f32::INFINITY),
        (f32::INFINITY, f32::INFINITY),
        (-1.0, 1.0),
        (1.0, -1.0),
        (f32::MAX, f32::MAX),
    ] {
        assert_eq!(between(l, Rises::Float(rise.0, rise.1)), d(0), "{rise:?}");
    }
    // Levels out of order are no parabola's either.
    assert_eq!(between([d(50), d(0), d(-50)], Rises::Int(1, 1)), d(0));
    assert_eq!(between([d(0), d(0), d(50)], Rises::Int(1, 1)), d(0));
}

proptest! {
    /// Every peak the textbook formula finds, to the thousandth, from integer scores and from
    /// float ones of any size alike, a thousandth inside a midpoint it falls on; and always
    /// one that rounding to the nearest level gives back as the chosen level.
    #[test]
    fn the_peak_is_the_textbook_vertex_and_rounds_back_to_the_chosen_level(
        lo in -1000i16..=998, gaps in (1i16..=2000, 1i16..=2000),
        rise in (1u32..=u32::MAX, 0u32..=u32::MAX), scale in 1e-9f64..1e-3,
    ) {
        let mid = lo.saturating_add(gaps.0).min(999);
        let hi = mid.saturating_add(gaps.1).min(1000);
        prop_assume!(lo < mid && mid < hi);
        let levels = [d(lo), d(mid), d(hi)];
        let x = [lo, mid, hi].map(f64::from);
        let want = vertex(x, [-f64::from(rise.0), 0.0, -f64::from(rise.1)]);
        let (m1, m2) = (0.5 * (x[0] + x[1]), 0.5 * (x[1] + x[2]));
        prop_assert!(m1 - 1e-6 <= want && want <= m2 + 1e-6);
        let near_midpoint = want - m1 < 1.0 || m2 - want < 1.0;
        let bound = if near_midpoint { 1.0 } else { 0.5 } + 1e-9;
        let float = Rises::Float((f64::from(rise.0) * scale) as f32, (f64::from(rise.1) * scale) as f32);
        // The float scores' own rounding moves the peak by far less than a thousandth.
        for (got, slack) in [(between(levels, Rises::Int(rise.0, rise.1)), 0.0), (between(levels, float), 1e-3)] {
            prop_assert!((f64::from(got.thousandths()) - want).abs() <= bound + slack, "{got:?} against {want}");
            let of = |k: usize| levels.get(k).copied();
            prop_assert_eq!(nearest(of, got.fraction(), 1.0), Some(1));
        }
    }
}

/// A network whose output `i` scores `-(i - 3.3)^2`: every observation peaks between
/// outputs 3 and 4, nearer 3.
fn peaked() -> Mlp<1, 7> {
    let mut net = Mlp::<1, 7>::zeroed();
    for (i, b) in net.fc3_bias.iter_mut().enumerate() {
        *b = -(i as f32 - 3.3).powi(2);
    }
    net
}

#[test]
fn a_refined_policy_moves_its_choice_and_leaves_the_ends() {
    let levels = Levels::new([-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0]).unwrap();
    let net = peaked();
    let mut greedy = Greedy { net: &net, levels };
    let obs = [0.0; 4];
    let (q, plain) = answer(&mut greedy, &obs);
    assert_eq!(plain, Some(d(0)));
    let (refined_q, refined) = answer(&mut Refined(greedy), &obs);
    assert_eq!(refined_q, q, "the scores are the network's");
    // Uniform levels 200 apart, peak 0.3 of a gap above level 3's.
    assert_eq!(refined, Some(d(60)));
    let ends = Refined(greedy);
    assert_eq!(ends.drive(&q, 0), Some(d(-1000)));
    assert_eq!(ends.drive(&q, 6), Some(d(1000)));
    assert_eq!(ends.drive(&q, 7), None);
    // The paper's two levels are both ends: refined, the network drives as before.
    let two = Mlp::<1, 2>::zeroed();
    let mut bang = Refined(Greedy {
        net: &two,
        levels: Levels::BANG_BANG,
    });
    assert_eq!(answer(&mut bang, &obs).1, Some(Duty::LEFT));
}

#[test]
fn a_refinable_policy_drives_as_its_choice_says_from_the_next_period() {
    let levels = Levels::new([-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0]).unwrap();
    let net = peaked();
    let greedy = Greedy { net: &net, levels };
    let mut p = Refinable {
        policy: greedy,
        refine: false,
    };
    let obs = [0.0; 4];
    assert_eq!(answer(&mut p, &obs).1, Some(d(0)));
    p.refine = true;
    assert_eq!(answer(&mut p, &obs).1, Some(d(60)));
    assert!(p.refinable());
    p.refine = false;
    assert_eq!(answer(&mut p, &obs).1, Some(d(0)));
    let two = Mlp::<1, 2>::zeroed();
    let bang = Greedy {
        net: &two,
        levels: Levels::BANG_BANG,
    };
    assert!(!bang.refinable());
}

#[test]
fn integer_scores_rise_without_overflow() {
    let q = [i32::MIN, i32::MAX, i32::MIN];
    let rise = q.rises(1).unwrap();
    assert_eq!(rise, Rises::Int(u32::MAX, u32::MAX));
    assert_eq!(between([d(-10), d(0), d(10)], rise), d(0));
    // The higher neighbour scores as the middle: a thousandth inside their midpoint.
    assert_eq!(
        between([d(-1000), d(0), d(1000)], Rises::Int(u32::MAX, 0)),
        d(499)
    );
    assert_eq!(q.rises(0), None);
    assert_eq!(q.rises(2), None);
    // A neighbour above: no peak between them.
    assert_eq!([0, -1, 5].rises(1), None);
    assert_eq!([1.0f32, 2.0].rises(1), None);
}
