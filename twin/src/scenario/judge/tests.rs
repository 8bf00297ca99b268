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
    // A tenth of a millimetre is half a count of 5120 per metre, rounded up.
    for spec in [
        "encoder+jitter",
        "encoder=1024+zero=0.2",
        "encoder=1024+zero=0/0.1",
        "zero=0.01/0.01",
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
