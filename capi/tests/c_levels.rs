//! A policy of more than two outputs through the C controller: a known state feedback
//! (`weights::feedback::state_feedback`) on seven levels, exported by the float writer, and
//! on five, exported by the int8 one, compiled with `tests/levels_controller.c` as C99, C++11
//! and C++17 against the library. Each period's commanded duty must be the feedback computed
//! here in f64 and rounded to the nearest level, and the bridge's pins must drive it (its
//! sign, its magnitude, the direction kept at zero duty); levels the firmware refuses must
//! be refused with `CARTPOLE_ERR_LEVELS`, writing nothing.

mod common;

use std::fmt::Write as _;

use cartpole_policy::{
    CARTPOLE_ERR_ENVELOPE, CARTPOLE_ERR_FLAGS, CARTPOLE_ERR_LEVELS, CARTPOLE_ERR_NULL, CARTPOLE_OK,
};
use common::{EVERY, compile_and_run, manifest};
use firmware::rig::Rig;
use weights::quant::{self, Granularity};
use weights::source::c_header;

/// The feedback `u = -GAIN . obs` the policies hold, in fractions of the full push.
const GAIN: [f32; 4] = [-0.5, -1.0, -20.0, -3.0];
const SEVEN: [f32; 7] = [-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0];
const FIVE: [f32; 5] = [-1.0, -0.3, 0.0, 0.3, 1.0];

/// States well inside the Gymnasium rig's limits, from a fixed LCG, whose feedback lies at
/// least `margin` from every point halfway between two levels: there the f64 reference
/// and the f32 (or int8) network may round to either.
fn states(levels: &[f32], margin: f64) -> Vec<[f32; 4]> {
    draw(levels, margin, |_| true)
}

/// [`states`] whose feedback rounds to a level between the ends, which a refined duty
/// leaves.
fn inner_states(levels: &[f32], margin: f64) -> Vec<[f32; 4]> {
    let mid = |i: usize| (f64::from(levels[i]) + f64::from(levels[i + 1])) / 2.0;
    let inner = (mid(0), mid(levels.len() - 2));
    draw(levels, margin, |u| inner.0 < u && u < inner.1)
}

/// 150 states as [`states`] describes, of a feedback that `keep`s.
fn draw(levels: &[f32], margin: f64, keep: impl Fn(f64) -> bool) -> Vec<[f32; 4]> {
    let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
    let mut unit = || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut out = Vec::new();
    while out.len() < 150 {
        let s = [0.5 * unit(), unit(), 0.1 * unit(), unit()].map(|v| v as f32);
        let u = feedback(&s);
        let near = levels
            .windows(2)
            .any(|p| (u - (f64::from(p[0]) + f64::from(p[1])) / 2.0).abs() < margin);
        if !near && keep(u) {
            out.push(s);
        }
    }
    out
}

fn feedback(s: &[f32; 4]) -> f64 {
    -GAIN
        .iter()
        .zip(s)
        .map(|(g, v)| f64::from(*g) * f64::from(*v))
        .sum::<f64>()
}

/// The level nearest the feedback of `s`, in thousandths: held at the ends.
fn reference(levels: &[f32], s: &[f32; 4]) -> i64 {
    let u = feedback(s);
    let best = levels
        .iter()
        .map(|l| (f64::from(*l) - u).abs())
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |b, (i, d)| if d < b.1 { (i, d) } else { b },
        )
        .0;
    (f64::from(levels[best]) * 1000.0).round() as i64
}

fn thousandths(level: f32) -> f64 {
    (f64::from(level) * 1000.0).round()
}

/// What the refined controller drives for `s`, in thousandths: the scores `l u - l^2 / 2`
/// are a parabola in the level `l` peaking at the feedback `u`, so the parabola through any
/// three levels' scores peaks at `u` itself, which the controller keeps a thousandth inside
/// the midpoints the chosen level shares with its neighbours; an end level drives itself.
fn refined(levels: &[f32], s: &[f32; 4]) -> f64 {
    let chosen = reference(levels, s) as f64;
    let t: Vec<f64> = levels.iter().map(|l| thousandths(*l)).collect();
    let i = t.iter().position(|l| *l == chosen).unwrap();
    if i == 0 || i == t.len() - 1 {
        return chosen;
    }
    let inside = ((t[i - 1] + t[i]) / 2.0 + 1.0, (t[i] + t[i + 1]) / 2.0 - 1.0);
    (feedback(s) * 1000.0).clamp(inside.0, inside.1)
}

/// Checks `out`, what `levels_controller.c refined` printed for `states`, against
/// [`refined`] within `tolerance` thousandths (the network's rounding): the refusals first,
/// then per period the pins driving the signed duty. Returns how many periods drove a duty
/// other than a level (a refined one may land on a level where the feedback does).
fn check_refined(out: &str, levels: &[f32], states: &[[f32; 4]], tolerance: f64) -> usize {
    let envelope = format!("{CARTPOLE_OK} {CARTPOLE_ERR_ENVELOPE} 1\n");
    let want = format!(
        "{CARTPOLE_ERR_FLAGS} 1\n{CARTPOLE_ERR_FLAGS} 1\n{CARTPOLE_ERR_NULL}\n{envelope}{envelope}"
    );
    assert!(out.starts_with(&want), "{out}");
    let lines: Vec<_> = out[want.len()..].lines().collect();
    assert_eq!(lines.len(), states.len());
    let mut between = 0;
    for (line, s) in lines.iter().zip(states) {
        let f: Vec<i64> = line.split(' ').map(|v| v.parse().expect(line)).collect();
        let (command, direction, duty, signed, faults) = (f[0], f[1], f[2], f[3], f[4]);
        let r = refined(levels, s);
        assert!((signed as f64 - r).abs() <= tolerance, "{line}: {r}");
        assert_eq!(
            (command, duty, faults),
            (signed.signum(), signed.abs(), 0),
            "{line}"
        );
        assert!(signed == 0 || direction == i64::from(signed > 0), "{line}");
        between += usize::from(!levels.iter().any(|l| thousandths(*l) == signed as f64));
    }
    between
}

/// What `levels_controller.c` prints for `states`: `command direction duty signed_duty
/// faults` a period, the direction pin kept while the duty is zero.
fn expected(levels: &[f32], states: &[[f32; 4]]) -> String {
    let mut direction = 0;
    let mut out = String::new();
    for s in states {
        let d = reference(levels, s);
        if d != 0 {
            direction = i64::from(d > 0);
        }
        let _ = writeln!(out, "{} {direction} {} {d} 0", d.signum(), d.abs());
    }
    out
}

/// `tests/levels_controller.c` with the header `text`, `init` and `a` outputs, compiled by
/// every standard, run with `args`; the output, the same for every standard.
fn run(text: &str, init: &str, a: usize, args: &[String]) -> String {
    let mut outs = Vec::new();
    for compiler in EVERY {
        let name = format!("levels-{init}-{}{}", args[0], compiler.std);
        let dir = std::env::temp_dir().join(format!("cartpole-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("exported.h"), text).unwrap();
        let main =
            format!("#define INIT {init}\n#define A {a}\n#include \"levels_controller.c\"\n");
        std::fs::write(dir.join("main.c"), main).unwrap();
        let tests = manifest().join("tests");
        outs.push(compile_and_run(
            compiler,
            &name,
            &[&dir.join("main.c")],
            &[&manifest().join("include"), &dir, &tests],
            args,
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
    assert!(outs.windows(2).all(|p| p[0] == p[1]), "{outs:?}");
    outs.swap_remove(0)
}

fn args(first: &str, states: &[[f32; 4]]) -> Vec<String> {
    std::iter::once(first.to_string())
        .chain(states.iter().flatten().map(|v| format!("{v:e}")))
        .collect()
}

/// The refusals `levels_controller.c` prints: good levels built, then every bad list
/// refused, writing nothing; NULL levels refused as a NULL.
fn refusals() -> String {
    let bad = format!("{CARTPOLE_ERR_LEVELS} 1\n").repeat(6);
    format!("{CARTPOLE_OK}\n{bad}{CARTPOLE_ERR_NULL} 1\n")
}

#[test]
fn a_float_policy_of_seven_levels_drives_the_feedback_rounded_to_its_levels() {
    let w = weights::feedback::state_feedback(64, &SEVEN, GAIN).unwrap();
    let text = c_header(&w, "test_policy", &[], &Rig::GYMNASIUM).unwrap();
    let init = "cartpole_controller_init_mlp64x7";
    let states = states(&SEVEN, 1e-4);
    let out = run(&text, init, 7, &args("steps", &states));
    assert_eq!(out, expected(&SEVEN, &states));
    // Every level is driven, and the ends hold the feedback beyond them.
    for l in SEVEN {
        let d = format!(" {} 0\n", (l * 1000.0).round() as i64);
        assert!(
            out.lines().any(|line| format!(" {line}\n").ends_with(&d)),
            "{l}"
        );
    }
    assert_eq!(run(&text, init, 7, &args("refusals", &[])), refusals());
    let states = inner_states(&SEVEN, 1e-4);
    let out = run(&text, init, 7, &args("refined", &states));
    assert!(check_refined(&out, &SEVEN, &states, 1.0) > states.len() * 9 / 10);
    let out = run(&text, init, 7, &args("unrefined", &states));
    assert_eq!(out, expected(&SEVEN, &states));
}

#[test]
fn an_int8_policy_of_five_levels_drives_the_feedback_rounded_to_its_levels() {
    let w = weights::feedback::state_feedback(64, &FIVE, GAIN).unwrap();
    let calibration = states(&[], 0.0);
    let q = quant::quantise(&w, &calibration, Granularity::PerChannel).unwrap();
    let text = quant::c_header(&q, "test_policy", &[], &Rig::GYMNASIUM).unwrap();
    let init = "cartpole_controller_init_qmlp64x5";
    // Q3.12 readings and int8 weights move the feedback by a little: states near a
    // halfway point are left out by more.
    let states = states(&FIVE, 0.05);
    let out = run(&text, init, 5, &args("steps", &states));
    assert_eq!(out, expected(&FIVE, &states));
    assert_eq!(run(&text, init, 5, &args("refusals", &[])), refusals());
    // The peak moves by the scores' rounding over their rises near it: a twelfth of the
    // 300-thousandth gap between the levels.
    let states = inner_states(&FIVE, 0.05);
    let out = run(&text, init, 5, &args("refined", &states));
    assert!(check_refined(&out, &FIVE, &states, 25.0) > states.len() * 9 / 10);
}
