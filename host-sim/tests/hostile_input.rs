//! The trajectory and scenario parsers against hostile text: nothing panics, every refusal
//! is a short message, and whatever is accepted is usable (finite physics, checked cases).

use host_sim::replay;
use proptest::prelude::*;
use proptest::test_runner::Config;
use twin::Scenario;
use twin::grammar::{FACTOR_RANGE, PARTS};

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
