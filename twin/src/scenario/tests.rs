use super::*;

#[test]
fn parts_set_what_they_say() {
    let s = Scenario::parse("force=1.2+length=0.8+polemass=1.2+cartmass=0.8").unwrap();
    let d = Params::default();
    assert_eq!(s.params.force_mag, d.force_mag * 1.2);
    assert_eq!(s.params.length, d.length * 0.8);
    assert_eq!(s.params.masspole, d.masspole * 1.2);
    assert_eq!(s.params.masscart, d.masscart * 0.8);
    // The board is not told the physics: its rig stays Gymnasium's.
    assert_eq!(s.rig, Rig::GYMNASIUM);
    assert_eq!(
        Scenario::parse("push=0.3/40").unwrap().push,
        Some(Push {
            impulse: 0.3,
            every: 40
        })
    );
    assert_eq!(
        Scenario::parse("push").unwrap().push,
        Some(Push {
            impulse: 0.5,
            every: 100
        })
    );
    assert_eq!(Scenario::parse("delay").unwrap().delay(), 1);
    assert_eq!(Scenario::parse("delay=3").unwrap().delay(), 3);
    assert_eq!(
        Scenario::parse("noise=2").unwrap().noise_std,
        NOISE_STD.map(|v| v * 2.0)
    );
    let f = Scenario::parse("friction=0.05/0.001").unwrap().params;
    assert_eq!((f.cart_friction, f.pole_friction), (0.05, 0.001));
    let f = Scenario::parse("friction=0.05").unwrap().params;
    assert_eq!(f.pole_friction, 0.0);
    let e = Scenario::parse("encoder=1024").unwrap().rig.encoders;
    assert_eq!((e.pole_counts_per_rev, e.cart_counts_per_m), (1024, 5120));
    let e = Scenario::parse("encoder=4096/20000").unwrap().rig.encoders;
    assert_eq!((e.pole_counts_per_rev, e.cart_counts_per_m), (4096, 20000));
    assert_eq!(Scenario::nominal(), Scenario::parse("nominal").unwrap());
    assert_eq!(Scenario::default_set().len(), 13);
    assert_eq!(Scenario::hard_set().len(), HARD.len());
    // The hard set is chosen from the candidates, whose every spec parses.
    assert_eq!(Scenario::hard_candidates().len(), HARD_CANDIDATES.len());
    for h in HARD {
        assert!(HARD_CANDIDATES.contains(h), "{h}");
    }
}

#[test]
fn a_scenario_is_built_on_its_rig() {
    let rig = Rig {
        params: Params {
            masscart: 0.6,
            tau: 0.01,
            ..Params::default()
        },
        dead_time: 2,
        ..Rig::GYMNASIUM
    };
    let machine = Machine {
        rig,
        integration: Integration::Rk4 { substeps: 10 },
        uncertainty: Default::default(),
    };
    let s = Scenario::parse_on("cartmass=2", &machine).unwrap();
    assert_eq!(s.integration, machine.integration);
    assert_eq!(s.params.masscart, 1.2);
    assert_eq!((s.rig, s.delay()), (rig, 2));
    assert_eq!(Scenario::parse_on("delay=0", &machine).unwrap().delay(), 0);
    // Factors are bounded relative to the rig's own values.
    let e = Scenario::parse_on("cartmass=1000+cartmass=2", &machine).unwrap_err();
    assert!(e.contains("cartmass comes to 2e3 times nominal"), "{e}");
}

#[test]
fn an_encoder_spec_reads_through_the_observer_or_a_filter_of_its_discount() {
    assert_eq!(Scenario::nominal().sensing, Sensing::Exact);
    assert_eq!(
        Scenario::parse("encoder=1024").unwrap().sensing,
        Sensing::Observer
    );
    let s = Scenario::parse("encoder=2400/16000/0").unwrap();
    assert_eq!(s.sensing, Sensing::AlphaBeta(0.0));
    assert_eq!(s.rig.encoders.cart_counts_per_m, 16_000);
    let e = Scenario::parse("encoder=2400/16000/1.5").unwrap_err();
    assert!(
        e.contains("discount must be zero or a normal number in [0, 0.99], found \"1.5\""),
        "{e}"
    );
    assert!(Scenario::parse("encoder=2400/16000/x").is_err());
    // Alone, the part reads the rig's own encoders.
    let gym = Scenario::parse("encoder").unwrap();
    assert_eq!(gym.sensing, Sensing::Observer);
    assert_eq!(gym.rig.encoders, firmware::rig::Rig::GYMNASIUM.encoders);
}

/// Specs refused, and a piece of each refusal.
const BAD_SPECS: &[(&str, &str)] = &[
    (
        "wind",
        "unknown part \"wind\" (expected nominal, or parts joined by + from noise",
    ),
    ("force", "force needs a value, e.g. force=F"),
    (
        "force=-1",
        "factor must be zero or a normal number in [0.001, 1000], found \"-1\"",
    ),
    (
        "push=0.5/0",
        "push interval must be a whole number in [1, 4294967295], found \"0\"",
    ),
    (
        "noise=x",
        "scale must be zero or a normal number in [0, 1000], found \"x\"",
    ),
    (
        "force=0",
        "factor must be zero or a normal number in [0.001, 1000], found \"0\"",
    ),
    // One quantity's factors multiply: each is fine, their product is not.
    ("length=999+length=999", "length comes to 9.98"),
    ("length=1e300", "found \"1e300\""),
    (
        "push=1e9",
        "impulse must be zero or a normal number in [0, 1000]",
    ),
    (
        "delay=17",
        "delay must be a whole number in [0, 16], found \"17\"",
    ),
    ("delay=-1", "delay must be a whole number"),
    ("delay=1.5", "delay must be a whole number"),
    // Cut at the `+` that joins parts.
    ("delay=+2", "found \"\" (a `+` joins a spec's parts"),
    ("noise=1e+0", "found \"1e\" (a `+` joins"),
    (
        "encoder=8",
        "encoder counts per revolution must be a whole number in [16, 16777216]",
    ),
    (
        "encoder=",
        "encoder counts per revolution must be a whole number in [16, 16777216], found \"\"",
    ),
    (
        "friction=2",
        "cart coefficient must be zero or a normal number in [0, 1]",
    ),
    (
        "friction=0.1/0.5",
        "pivot coefficient must be zero or a normal number in [0, 0.1]",
    ),
    ("friction=0.1/0.01/3", "friction takes at most 2 values"),
    (
        "length=0.5..0.9",
        "takes single values, not ranges or shares",
    ),
    ("noise@0.5", "takes single values, not ranges or shares"),
    // Gymnasium's machine has no motor damping to scale.
    (
        "damping=2",
        "damping changes nothing on a machine without motor damping",
    ),
    // A discount the board's f32 would hold as a subnormal.
    (
        "encoder=2400/15000/1e-40",
        "discount must be zero or a normal number in [0, 0.99], found \"1e-40\"",
    ),
];

#[test]
fn bad_specs_are_rejected_with_the_reason() {
    for (spec, needle) in BAD_SPECS {
        let e = Scenario::parse(spec).unwrap_err();
        assert!(e.contains(needle), "{spec}: {e}");
    }
    let long = "noise+".repeat(10_000);
    let e = Scenario::parse(&long).unwrap_err();
    assert!(
        e.contains("expected at most 1000 bytes") && e.len() < 400,
        "{e}"
    );
}

#[test]
fn every_part_of_the_table_changes_the_world_it_is_applied_to() {
    let desk = crate::rigfile::parse(include_str!("../../../rigs/desk.toml"), "desk").unwrap();
    for part in crate::grammar::PARTS {
        // The desk rig has a period of dead time already: its default would change nothing.
        let spec = match part.fields[0].fallback {
            crate::grammar::Fallback::Required => format!("{}=0.5", part.key),
            _ if part.key == "delay" => "delay=3".to_string(),
            _ => part.key.to_string(),
        };
        // Jitter moves only readings through encoders.
        let beside = if part.key == "jitter" {
            "encoder"
        } else {
            "nominal"
        };
        let base = Scenario::parse_on(beside, &desk).unwrap();
        let spec = if part.key == "jitter" {
            format!("{beside}+{spec}")
        } else {
            spec
        };
        let s = Scenario::parse_on(&spec, &desk).unwrap();
        assert!(!s.same_world(&base), "{spec} changed nothing");
    }
}

#[test]
fn a_part_at_values_that_change_nothing_is_refused_and_those_values_do_change_nothing() {
    use crate::grammar::{Idle, PARTS, Part, Span};
    let desk = crate::rigfile::parse(include_str!("../../../rigs/desk.toml"), "desk").unwrap();
    let read = Scenario::parse_on("encoder+noise", &desk).unwrap();
    for part in PARTS {
        let (at, every) = match part.idle {
            Idle::Never => continue,
            Idle::First(v) => (v, false),
            Idle::Every(v) => (v, true),
        };
        if part.key == "noise" {
            assert_eq!(Scenario::nominal_on(&desk).noise_std, [0.0; 4]);
            continue;
        }
        // The part applied at its idle values, past the parser: the same readings and
        // states as without it, period by period.
        let values: Vec<Option<f64>> = (0..part.fields.len())
            .map(|i| (i == 0 || every).then_some(at))
            .collect();
        let spans = values.iter().map(|v| v.map(|x| Span { lo: x, hi: x }));
        let idle = Part {
            spec: part,
            values: spans.collect(),
            share: 1.0,
        };
        let mut s = read.clone();
        s.apply(&idle, &values);
        assert!(
            periods(&s) == periods(&read),
            "{} at {at} changed the world",
            part.key
        );
        let spec = format!("{}={at}", part.key);
        let e = Scenario::parse_on(&spec, &desk).unwrap_err();
        assert!(e.contains("changes nothing"), "{spec}: {e}");
    }
    // A part idle in one field only still acts through the others; a range is not idle.
    for spec in ["zero=0/5", "push=0.5/7", "weak=0.5/3"] {
        assert!(Scenario::parse_on(spec, &desk).is_ok(), "{spec}");
    }
    for spec in ["push=0/7", "weak=1/3/9", "zero=0/0", "noise+zero=0"] {
        assert!(Scenario::parse_on(spec, &desk).is_err(), "{spec}");
    }
    let e = crate::grammar::parse("noise=0@0.5", "domain").unwrap_err();
    assert!(e.contains("noise changes nothing with scale 0"), "{e}");
    assert!(crate::grammar::parse("noise=0..0.5", "domain").is_ok());
}

/// 300 periods of `s` under a fixed sequence of duties: each period's reading and state.
fn periods(s: &Scenario) -> Vec<(firmware::link::Measurement, firmware::cartpole::State)> {
    let mut world = crate::run::Draws::of(7).world(s, 300, 0);
    (0..300u32)
        .map(|k| {
            let m = world.measure();
            world.apply(f64::from(k * 7919 % 11) / 5.0 - 1.0);
            (m, world.state())
        })
        .collect()
}

/// The named sets build on every machine the repository describes: their specs are parsed
/// on the machine at hand, and a refusal there would panic (`parse_all`). `hard-candidates`,
/// Gymnasium's pool, is refused with exit status 2's message on every other machine, so no
/// run reads a Gymnasium world as the machine's.
#[test]
fn the_named_sets_build_on_every_rig() {
    let rigs = [
        include_str!("../../../rigs/desk.toml"),
        include_str!("../../../rigs/desk-identified.toml"),
        include_str!("../../../rigs/desk-measured.toml"),
        include_str!("../../../rigs/desk-100hz.toml"),
        include_str!("../../../rigs/desk-100hz-identified.toml"),
        include_str!("../../../rigs/desk-100hz-measured.toml"),
        include_str!("../../../rigs/lab.toml"),
        include_str!("../../../rigs/lab-identified.toml"),
        include_str!("../../../rigs/lab-measured.toml"),
        include_str!("../../../rigs/gymnasium.toml"),
        include_str!("../../../rigs/gymnasium-100hz.toml"),
    ];
    let mut machines = vec![Machine::GYMNASIUM];
    machines.extend(rigs.map(|text| crate::rigfile::parse(text, "rig").unwrap()));
    for machine in &machines {
        for set in ["all", "hard", "faults"] {
            let built = Scenario::words_on(&[set.to_string()], machine).unwrap();
            assert!(!built.is_empty(), "{set}");
            assert!(
                built
                    .iter()
                    .all(|s| s.rig.params.tau == machine.rig.params.tau)
            );
        }
        let candidates = words_on(&["nominal", "hard-candidates"], machine);
        let built = Scenario::words_built_on(&["hard-candidates".to_string()], machine);
        if *machine == Machine::GYMNASIUM {
            assert_eq!(candidates.unwrap().len(), 1 + HARD_CANDIDATES.len());
            assert_eq!(built.unwrap().len(), HARD_CANDIDATES.len());
        } else {
            for e in [candidates.unwrap_err(), built.unwrap_err()] {
                assert!(
                    e.contains("expected `hard-candidates` on Gymnasium's machine")
                        && e.contains("found another rig or world"),
                    "{e}"
                );
            }
        }
    }
    // Gymnasium's rig file is Gymnasium's machine, so the word stays usable through it.
    assert_eq!(machines[machines.len() - 2], machines[0]);
}

/// A `-0` builds the world its `0` builds, and is refused beside it as one world twice.
#[test]
fn a_negative_zero_is_the_world_of_its_zero() {
    let gym = Machine::GYMNASIUM;
    for (a, b) in [
        ("friction=0/0.001", "friction=-0/0.001"),
        (
            "encoder+jitter=0.1+friction=0.1/0",
            "encoder+jitter=0.1+friction=0.1/-0",
        ),
    ] {
        let e = words_on(&[a, b], &gym).unwrap_err();
        let want = format!(
            "found {} and {}, which build one world",
            weights::quote(a),
            weights::quote(b)
        );
        assert!(e.contains(&want), "{e}");
    }
}

fn words_on(words: &[&str], machine: &Machine) -> Result<Vec<Scenario>, String> {
    let words: Vec<String> = words.iter().map(|w| w.to_string()).collect();
    Scenario::words_on(&words, machine)
}

/// What a part changes depends on the machine: it is judged on the worlds built there, so a
/// spec that reads as a change and builds the machine's own world is refused on that machine
/// alone, and the named sets, built without the judgement, keep their rows on every rig.
#[test]
fn a_part_that_changes_nothing_on_the_machine_at_hand_is_refused_there() {
    let rig = |text: &str| crate::rigfile::parse(text, "rig").unwrap();
    let desk = rig(include_str!("../../../rigs/desk.toml"));
    let desk100 = rig(include_str!("../../../rigs/desk-100hz.toml"));
    let gym = Machine::GYMNASIUM;
    for (words, machine, found) in [
        (
            &["nominal", "delay"][..],
            &desk,
            "\"delay\": delay changes nothing on this machine, whose own dead time is 1 period;",
        ),
        (
            &["delay=2"],
            &desk100,
            "delay changes nothing on this machine",
        ),
        (&["delay=0"], &gym, "whose own dead time is 0 periods"),
        (
            &["friction=0"],
            &desk,
            "friction changes nothing on this machine, which has it",
        ),
        (
            &["damping=2+length=2"],
            &gym,
            "damping changes nothing on a machine without motor damping",
        ),
        (
            &["noise+length=2+length=0.5"],
            &gym,
            "length changes nothing on this machine: its factors multiply to 1",
        ),
        (
            &["length=0.5+cartmass=2+length=4+length=0.5"],
            &desk,
            "length changes nothing on this machine: its factors multiply to 1",
        ),
        // Two specs of one world, the rig's own encoders each.
        (
            &["encoder", "encoder=4096"],
            &gym,
            "expected each row once, found \"encoder\" and \"encoder=4096\", which build one \
             world on this machine",
        ),
        (
            &["encoder=2400/15000", "encoder"],
            &desk,
            "found \"encoder=2400/15000\" and \"encoder\", which build one",
        ),
        // A spec that builds a named set's row.
        (
            &["all", "force=0.4+force=2"],
            &gym,
            "found \"force=0.8\" and",
        ),
    ] {
        let e = words_on(words, machine).unwrap_err();
        assert!(e.contains(found), "{words:?}: {e}");
    }
    for (words, machine) in [
        (&["nominal", "delay"][..], &gym),
        (&["delay=0", "delay=2"], &desk),
        (&["damping=2", "friction=0.1"], &desk),
        (&["encoder", "encoder=4096"], &desk),
        (&["length=2+length=0.25"], &gym),
        // The default set's `delay` is the desk's `nominal`: the set's own rows.
        (&["all"], &desk),
    ] {
        let built = words_on(words, machine).unwrap();
        assert!(built.len() >= words.len(), "{words:?}");
    }
    // Built, not judged: for a check before the machine is known.
    assert!(
        Scenario::build_on("delay", &desk)
            .unwrap()
            .same_world(&Scenario::nominal_on(&desk))
    );
    let built = Scenario::words_built_on(&["nominal".into(), "delay".into()], &desk).unwrap();
    assert!(built[0].same_world(&built[1]));
}

/// A quantity's factors multiply to the same bits in any order: reordered specs are one world.
#[test]
fn factors_given_again_multiply_in_one_order_whatever_the_spec_says() {
    let (a, b, c) = (0.9, 1.6, 1.5);
    let orders = [
        (a, b, c),
        (a, c, b),
        (b, a, c),
        (b, c, a),
        (c, a, b),
        (c, b, a),
    ];
    let lengths: Vec<u64> = orders
        .iter()
        .map(|(x, y, z)| {
            let spec = format!("length={x}+length={y}+length={z}");
            Scenario::parse(&spec).unwrap().params.length.to_bits()
        })
        .collect();
    // Multiplied in the spec's order, these factors differ in the last bit.
    let l = Params::default().length;
    assert_ne!((l * a * b * c).to_bits(), (l * c * b * a).to_bits());
    assert!(
        lengths.iter().all(|&bits| bits == lengths[0]),
        "{lengths:?}"
    );
}

/// Read as 0 where no command line's check saw it (Python's `scenario=`).
#[test]
fn a_number_that_reads_as_zero_is_refused_wherever_the_spec_came_from() {
    let e = Scenario::parse("noise=1e-400").unwrap_err();
    assert!(
        e.contains("scale must be zero or a normal number in [0, 1000], found \"1e-400\""),
        "{e}"
    );
}
