use super::*;
use crate::lockstep::run_episode;
use crate::run::Frame;
use shipped::policy::POLICY;

/// The frames and statistics of a few episodes of the shipped policy, told the dead time,
/// in `spec` built on Gymnasium's machine without the judgement.
fn episodes(spec: &str) -> Vec<(Vec<Frame>, crate::EpisodeStats)> {
    let s = Scenario::build_on(spec, &Machine::GYMNASIUM).unwrap();
    (0..4)
        .map(|episode| {
            let mut frames = Vec::new();
            let stats = run_episode(&POLICY, &s, 300, 11, episode, true, |f| frames.push(f));
            (frames, stats)
        })
        .collect()
}

/// What the judgement takes out of a world changes nothing in its episodes, period by
/// period; beside the part it needs, or larger, the same part changes them.
#[test]
fn a_part_without_what_it_needs_changes_nothing_in_an_episode() {
    for (without, with, changed) in [
        (
            "noise",
            "noise+jitter=0.5",
            ["encoder+noise", "encoder+noise+jitter=0.5"],
        ),
        (
            "encoder=1024",
            "encoder=1024+zero=0.1/0.09",
            ["encoder=1024", "encoder=1024+zero=0.2/0.09"],
        ),
        // Every reading lost, but where a stuck sensor repeats one the drop did not reach.
        (
            "drop=1",
            "drop=1+noise+zero=1/5+glitch=100/1",
            ["stuck=2/4+drop=1", "stuck=2/4+drop=1+noise"],
        ),
        (
            "encoder+drop=1",
            "encoder+drop=1+jitter=0.5",
            ["encoder+drop=2", "encoder+drop=2+jitter=0.5"],
        ),
        // Readings frozen at the first: a fault of later periods, but not one of the first.
        (
            "stuck=7/7",
            "stuck=7/7+glitch+drop",
            ["stuck=7/7", "stuck=7/7+glitch=100/1"],
        ),
    ] {
        let built = Scenario::build_on(with, &Machine::GYMNASIUM).unwrap();
        assert_ne!(
            built,
            Scenario::build_on(without, &Machine::GYMNASIUM).unwrap()
        );
        assert!(
            episodes(without) == episodes(with),
            "{with} changed an episode"
        );
        let [base, runs] = changed;
        assert!(episodes(base) != episodes(runs), "{runs} changed nothing");
    }
}

#[test]
fn a_scenario_whose_part_lacks_what_it_needs_is_refused_naming_it() {
    for (spec, want) in [
        (
            "jitter",
            "scenario \"jitter\": jitter changes nothing under exact sensing, where no encoder \
             is read early or late; expected an encoder part beside it",
        ),
        ("noise+jitter=0.5", "jitter changes nothing under exact"),
        (
            "encoder=1024+zero=0.1/0.09",
            "zero changes nothing through encoders of 1024 counts per revolution and 5120 per \
             metre, which round its errors to no count; expected an error of half a count or \
             more",
        ),
    ] {
        let e = Scenario::parse(spec).unwrap_err();
        assert!(e.contains(want), "{spec}: {e}");
    }
    for (spec, want) in [
        (
            "drop=1+noise",
            "noise changes nothing where every reading is lost (drop=1, and no stuck sensor to \
             repeat one); expected a drop that lets some through, or the part left out",
        ),
        (
            "encoder+drop=1+zero=1",
            "zero changes nothing where every reading is lost",
        ),
        (
            "stuck=3/3+glitch",
            "glitch changes nothing where the readings freeze for good at the first (stuck \
             with K = EVERY), a period it misses; expected EVERY 1, or the part left out",
        ),
        (
            "stuck=3/3+drop=2",
            "drop changes nothing where the readings freeze",
        ),
    ] {
        let e = Scenario::parse(spec).unwrap_err();
        assert!(e.contains(want), "{spec}: {e}");
    }
    // A domain's part, where it changes nothing at every end; at one end is enough.
    for spec in ["drop=1+noise=0.5..2", "stuck=3/3+glitch=1..9/50"] {
        let e = crate::Domain::parse(spec).unwrap_err();
        assert!(e.contains("changes nothing"), "{spec}: {e}");
    }
    for spec in ["drop=1..2+noise", "stuck=2..3/3+glitch"] {
        crate::Domain::parse(spec).unwrap();
    }
    // A tenth of a millimetre is half a count of 5120 per metre, rounded up.
    for spec in [
        "encoder+jitter",
        "encoder=1024+zero=0.2",
        "encoder=1024+zero=0/0.1",
        "zero=0.01/0.01",
        "drop=1",
        "stuck+drop=1+noise",
        "stuck=3/3+noise",
        "stuck=3/3+glitch=100/1+drop=1",
    ] {
        Scenario::parse(spec).unwrap();
    }
}

/// Two specs that run one world are one row, though their fields differ.
#[test]
fn rows_that_run_one_world_are_one_row() {
    let built = Scenario::build_on("noise+jitter", &Machine::GYMNASIUM).unwrap();
    assert!(built.same_world(&Scenario::parse("noise").unwrap()));
    assert!(!built.same_world(&Scenario::parse("noise=2").unwrap()));
    let e = Scenario::words_on(&["all".into(), "noise".into()], &Machine::GYMNASIUM);
    assert!(e.unwrap_err().contains("\"noise\" and \"noise\""));
}

/// A stretch of K periods of every EVERY is at most its interval; a weak motor in every
/// period is `force=F`, its one spelling.
#[test]
fn a_stretch_past_its_interval_is_refused_and_a_weak_motor_always_is_a_force() {
    for (spec, want) in [
        (
            "stuck=10/5",
            "stuck takes K periods of every EVERY: expected K at most EVERY in every world (K \
             = EVERY is every period), found K 10 and EVERY 5",
        ),
        ("stuck=201", "found K 201 and EVERY 200"),
        (
            "weak=0.5/500/500",
            "weak takes K periods of every EVERY: expected K below EVERY (K = EVERY is every \
             period, the world force=F builds: write that), found K 500 and EVERY 500",
        ),
        (
            "weak=0.5/600",
            "expected K below EVERY (K = EVERY is every period, the world",
        ),
        ("weak=0/9/9", "expected K below EVERY"),
    ] {
        let e = Scenario::parse(spec).unwrap_err();
        assert!(e.contains(want), "{spec}: {e}");
    }
    for (spec, want) in [
        ("stuck=1..10/5..200", "found K 1..10 and EVERY 5..200"),
        (
            "weak=0..0.5/20/10..400",
            "expected K at most EVERY in every world",
        ),
        ("weak=0.5/9/9@0.5", "expected K below EVERY"),
    ] {
        let e = crate::Domain::parse(spec).unwrap_err();
        assert!(e.contains(want), "{spec}: {e}");
    }
    for spec in ["stuck=5/5", "stuck=200", "weak=0.5/499/500", "weak=0/9/10"] {
        Scenario::parse(spec).unwrap();
    }
    // A draw of K = EVERY is one world among others.
    for spec in ["stuck=1..5/5..9", "weak=0..0.5/20/20..400"] {
        crate::Domain::parse(spec).unwrap();
    }
}

/// One world spelt twice is one row: a stuck sensor in every period whatever K, a zero
/// error through encoders by the whole counts it adds.
#[test]
fn specs_of_one_world_run_one_row() {
    for (a, b) in [
        ("stuck=5/5", "stuck=1/1"),
        ("encoder+stuck=9/9", "encoder+stuck=2/2"),
        ("encoder+zero=0.06", "encoder+zero=0.07"),
        ("encoder=1024+zero=0.3/0.2", "encoder=1024+zero=0.4/0.25"),
    ] {
        assert!(episodes(a) == episodes(b), "{a} and {b} ran otherwise");
        let e = Scenario::words_on(&[a.into(), b.into()], &Machine::GYMNASIUM).unwrap_err();
        assert!(e.contains("which build one world"), "{a}, {b}: {e}");
    }
    // Read exactly, a zero error is not rounded; a stretch short of its interval holds less.
    for (a, b) in [
        ("zero=0.06", "zero=0.07"),
        ("stuck=4/5", "stuck=5/5"),
        ("encoder+zero=0.06", "encoder+zero=0.15"),
    ] {
        assert!(episodes(a) != episodes(b), "{a} and {b} ran alike");
        Scenario::words_on(&[a.into(), b.into()], &Machine::GYMNASIUM).unwrap();
    }
}
