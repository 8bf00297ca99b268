//! The trajectory and scenario parsers against hostile text: nothing panics, every refusal
//! is a short message, and whatever is accepted is usable (finite physics, checked cases).

use std::collections::HashMap;

use host_sim::replay;
use proptest::prelude::*;
use proptest::test_runner::Config;
use twin::grammar::{FACTOR_RANGE, PARTS};
use twin::scenario::{NOISE_STD, Sensing};
use twin::{Push, Scenario};

fn cases() -> Config {
    Config {
        cases: 512,
        failure_persistence: None,
        ..Config::default()
    }
}

fn first_case() -> String {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/gym_traj_public.jsonl"
    ))
    .unwrap();
    text.lines().next().unwrap().to_string()
}

fn check_replay(text: &str) {
    match replay::parse(text, "fuzz.jsonl") {
        Ok(cases) => {
            for c in &cases {
                // Accepted cases replay without error (the report may well be a mismatch).
                replay::replay_case(c, &firmware::cartpole::Params::default()).unwrap();
            }
        }
        Err(e) => assert!(
            format!("{e:#}").len() < 2_000,
            "{} bytes",
            format!("{e:#}").len()
        ),
    }
}

fn check_scenario(spec: &str) {
    match Scenario::parse(spec) {
        Ok(s) => {
            let p = s.params;
            let nominal = firmware::cartpole::Params::default();
            for (v, n) in [
                (p.force_mag, nominal.force_mag),
                (p.length, nominal.length),
                (p.masspole, nominal.masspole),
                (p.masscart, nominal.masscart),
            ] {
                assert!(
                    (FACTOR_RANGE.0..=FACTOR_RANGE.1).contains(&(v / n)),
                    "{spec}"
                );
            }
            assert!(s.noise_std.iter().all(|v| v.is_finite() && *v >= 0.0));
            check_parsed(spec, &s);
            // The plant stays finite for a step under the full force.
            let next = firmware::cartpole::advance(
                &p,
                &firmware::cartpole::State::from_array([0.0, 0.0, 0.1, 0.0]),
                1.0,
                0.0,
            );
            assert!(
                next.to_array().iter().all(|v| v.is_finite()),
                "{spec}: {next:?}"
            );
        }
        Err(e) => assert!(e.len() < 1_000, "{} bytes", e.len()),
    }
    // The same text as a domain: each world drawn from it must be physical too.
    if let Ok(d) = twin::Domain::parse(spec) {
        let mut rng = rand_pcg::Pcg64Mcg::new(7);
        for _ in 0..4 {
            let p = d.sample(&mut rng).params;
            let next = firmware::cartpole::advance(
                &p,
                &firmware::cartpole::State::from_array([0.0, 0.0, 0.1, 0.0]),
                1.0,
                0.0,
            );
            assert!(next.to_array().iter().all(|v| v.is_finite()), "{spec}");
        }
    }
}

/// The values each kind of part of an accepted `spec` gave, read from the text here (a kind
/// repeats only if it is a factor, whose values are checked against their bounds alone), a
/// point range as its value, a share dropped.
fn given(spec: &str) -> HashMap<&str, Vec<f64>> {
    let mut last = HashMap::new();
    for part in spec.split('+') {
        let body = part.split_once('@').map_or(part, |(body, _)| body);
        let (key, text) = body.split_once('=').unwrap_or((body, ""));
        let values = text
            .split('/')
            .filter(|t| !t.is_empty())
            .map(|t| {
                let point = t.split_once("..").map_or(t, |(lo, _)| lo);
                point
                    .parse::<f64>()
                    .unwrap_or_else(|_| panic!("{spec}: accepted {t:?}"))
            })
            .collect();
        last.insert(key, values);
    }
    last
}

/// An accepted scenario holds what its text says: every value within its field's bounds in
/// [`PARTS`], and the dead time, noise, friction, encoders and pushes as written, or the
/// defaults the table of parts documents where left out.
fn check_parsed(spec: &str, s: &Scenario) {
    let given = given(spec);
    for (key, values) in &given {
        if let Some(part) = PARTS.iter().find(|p| p.key == *key) {
            for (v, f) in values.iter().zip(part.fields) {
                assert!((f.lo..=f.hi).contains(v), "{spec}: {key} {}", f.name);
            }
        }
    }
    let (nominal, p) = (Scenario::nominal(), &s.params);
    let at = |key: &str, i: usize| given.get(key).and_then(|v| v.get(i).copied());
    let delay = given
        .get("delay")
        .map_or(0, |_| at("delay", 0).unwrap_or(1.0) as u32);
    assert_eq!(s.delay(), delay, "{spec}");
    let noise = given
        .get("noise")
        .map_or(0.0, |_| at("noise", 0).unwrap_or(1.0));
    assert_eq!(s.noise_std, NOISE_STD.map(|v| v * noise), "{spec}");
    let friction = (
        at("friction", 0).unwrap_or(0.0),
        at("friction", 1).unwrap_or(0.0),
    );
    assert_eq!((p.cart_friction, p.pole_friction), friction, "{spec}");
    let push = given.get("push").map(|_| Push {
        impulse: at("push", 0).unwrap_or(0.5),
        every: at("push", 1).map_or(100, |k| k as u32),
    });
    assert_eq!(s.push, push, "{spec}");
    let (encoders, sensing) = match (given.get("encoder"), at("encoder", 0)) {
        (None, _) => (nominal.rig.encoders, Sensing::Exact),
        (Some(_), n) => {
            let mut e = nominal.rig.encoders;
            if let Some(n) = n {
                e.pole_counts_per_rev = n as u32;
                e.cart_counts_per_m = at("encoder", 1).unwrap_or(5.0 * n) as u32;
            }
            let d = at("encoder", 2).map(|d| d as f32);
            (e, d.map_or(Sensing::Observer, Sensing::AlphaBeta))
        }
    };
    assert_eq!((s.rig.encoders, s.sensing), (encoders, sensing), "{spec}");
}

/// Specs that random text seldom makes whole: each part alone, with and without its
/// optional values, at its bounds, and factors repeated; a part that is not a factor,
/// repeated, is refused rather than replaced.
#[test]
fn written_scenarios_hold_what_they_say() {
    for spec in [
        "delay",
        "delay=16+noise=2",
        "friction=0.1",
        "friction=1/0.1",
        "encoder",
        "encoder=512",
        "encoder=16777216",
        "encoder=2400/15000",
        "encoder=128/640/0.5",
        "push",
        "push=1.1/50",
        "noise+delay=4+push=0.2+friction=0.3/0.01+encoder=1024/2048+length=2+length=0.75",
    ] {
        let s = Scenario::parse(spec).unwrap_or_else(|e| panic!("{spec}: {e}"));
        check_parsed(spec, &s);
    }
    let e = Scenario::parse("noise+delay=3+delay=4").unwrap_err();
    assert!(e.contains("found delay again"), "{e}");
}

/// A part of the grammar: every key of [`PARTS`] (and one that is not), with up to three
/// values, each a number, a range, or text that is neither, and sometimes a share.
fn part() -> impl Strategy<Value = String> {
    let number = prop_oneof![
        any::<f64>().prop_map(|v| format!("{v}")),
        (0.0..2000.0f64).prop_map(|v| format!("{v}")),
        (0u32..100_000).prop_map(|v| format!("{v}")),
        Just("1e300".to_string()),
        Just("nan".to_string()),
        "[0-9./e-]{0,8}",
    ];
    let value = prop_oneof![
        number.clone(),
        (number.clone(), number).prop_map(|(a, b)| format!("{a}..{b}")),
    ];
    let mut keys: Vec<&'static str> = PARTS.iter().map(|p| p.key).collect();
    keys.push("wind");
    (
        proptest::sample::select(keys),
        proptest::collection::vec(value, 0..4),
        proptest::option::of("[0-9.]{0,4}"),
    )
        .prop_map(|(k, values, share)| {
            let mut s = k.to_string();
            if !values.is_empty() {
                s = format!("{s}={}", values.join("/"));
            }
            if let Some(p) = share {
                s = format!("{s}@{p}");
            }
            s
        })
}

proptest! {
    #![proptest_config(cases())]

    #[test]
    fn random_trajectory_text_never_panics(text in "\\PC{0,300}") {
        check_replay(&text);
    }

    #[test]
    fn mutated_trajectories_never_panic(
        edits in proptest::collection::vec((any::<proptest::sample::Index>(), "\\PC"), 1..6)
    ) {
        let mut line: Vec<char> = first_case().chars().collect();
        for (at, c) in edits {
            let i = at.index(line.len());
            line[i] = c.chars().next().unwrap_or(' ');
        }
        check_replay(&line.into_iter().collect::<String>());
    }

    #[test]
    fn random_scenario_text_never_panics(spec in "\\PC{0,80}") {
        check_scenario(&spec);
    }

    #[test]
    fn scenarios_from_the_grammar_are_physical_or_refused(
        parts in proptest::collection::vec(part(), 1..5)
    ) {
        check_scenario(&parts.join("+"));
    }
}
