//! The studies. In the paper's tables and `init`, `target` and `fix`, each configuration
//! differs from the paper preset in one field (two for the per-step target period, which has
//! a unit). `shaping` changes the learning reward, the target schedule, or reads one of the
//! paper's ambiguities another way. The `-fixed` tables are the paper's tables again on
//! `paper-fixed`, each row differing from it in one field.

use crate::config::{Algo, Config, Init, TargetUpdate, Unit};

/// Every study, in the order the report lists them, with its figure's title.
pub const STUDIES: [(&str, &str); 12] = [
    ("table1", "Table 1: hidden width"),
    ("table4", "Table 4 / Figure 3: DQN vs Double DQN"),
    ("table5", "Table 5: learning rate"),
    ("table6", "Table 6: target update period"),
    ("init", "Initialisation"),
    ("target", "Hard vs soft target updates"),
    ("fix", "Single changes to the paper preset"),
    (
        "shaping",
        "Learning rewards, target schedules and readings of the paper",
    ),
    ("table1-fixed", "Table 1 on paper-fixed: hidden width"),
    ("table4-fixed", "Table 4 on paper-fixed: DQN vs Double DQN"),
    ("table5-fixed", "Table 5 on paper-fixed: learning rate"),
    ("table6-fixed", "Table 6 on paper-fixed: target copy period"),
];

/// One configuration of one study.
#[derive(Clone, Debug)]
pub struct Variant {
    /// Which study: one of [`STUDIES`].
    pub study: &'static str,
    /// Row label, as the paper writes it.
    pub label: String,
    /// The paper's numbers for this row (convergence, final reward), if it gives them.
    pub paper: Option<(&'static str, &'static str)>,
    /// The configuration.
    pub cfg: Config,
    /// A figure of its own (file name, title) for rows that would crowd their study's; it
    /// also shows the study's first row, the baseline. `None`: the study's figure.
    pub figure: Option<(&'static str, &'static str)>,
}

/// The shaping study's second figure.
const READINGS: Option<(&str, &str)> = Some(("shaping-readings", "Readings of the paper's text"));

/// Every study's rows, built from `base` (the paper preset).
pub fn variants(base: &Config) -> Vec<Variant> {
    let mut all = paper_studies(base);
    all.extend(shaping(base));
    all.extend(tables(
        &base.clone().with_paper_fixes(),
        [
            "table1-fixed",
            "table4-fixed",
            "table5-fixed",
            "table6-fixed",
        ],
    ));
    all
}

fn v(
    study: &'static str,
    label: &str,
    paper: Option<(&'static str, &'static str)>,
    cfg: Config,
) -> Variant {
    Variant {
        study,
        label: label.to_string(),
        paper,
        cfg,
        figure: None,
    }
}

/// The learning rewards of the era's tutorials, alone and with a per-step target copy, and
/// the other readings of the paper's text.
fn shaping(b: &Config) -> Vec<Variant> {
    let mut out = rewards(b);
    out.extend(readings(b).into_iter().map(|r| Variant {
        figure: READINGS,
        ..r
    }));
    out
}

/// The paper preset, each tutorial reward, a per-step target copy, and each reward with it.
fn rewards(b: &Config) -> Vec<Variant> {
    let rewards = [
        ("Morvan's reward", "morvan"),
        ("-10 on failing", "fail-penalty=-10"),
        ("-100 on failing", "fail-penalty=-100"),
        ("reward / 100 (minimalRL)", "scale=0.01"),
    ];
    let step_copy = |c: Config| Config {
        target_period: 100,
        target_period_unit: Unit::Steps,
        ..c
    };
    let mut out = vec![v("shaping", "paper preset", None, b.clone())];
    for (label, spec) in rewards {
        out.push(v(
            "shaping",
            label,
            None,
            Config {
                reward: spec.into(),
                ..b.clone()
            },
        ));
    }
    out.push(v(
        "shaping",
        "copy every 100 steps",
        None,
        step_copy(b.clone()),
    ));
    for (label, spec) in rewards {
        out.push(v(
            "shaping",
            &format!("{label}, copy every 100 steps"),
            None,
            step_copy(Config {
                reward: spec.into(),
                ..b.clone()
            }),
        ));
    }
    out
}

/// Other readings of the paper's text, and the preset with the fixes it reads into it.
fn readings(b: &Config) -> [Variant; 4] {
    [
        v(
            "shaping",
            "reading: epsilon 0.9 is P(greedy), explore 1 -> 0.1",
            None,
            Config {
                eps_start: 1.0,
                eps_end: 0.1,
                ..b.clone()
            },
        ),
        v(
            "shaping",
            "reading: copy every 50 steps",
            None,
            Config {
                target_period_unit: Unit::Steps,
                ..b.clone()
            },
        ),
        v(
            "shaping",
            "reading: minimalRL's schedule (10 updates per episode, copy every 20 ep.)",
            None,
            Config {
                train_unit: Unit::Episodes,
                updates_per_train: 10,
                learning_starts: 2000,
                target_period: 20,
                ..b.clone()
            },
        ),
        v(
            "shaping",
            "paper-fixed: Morvan's reward, copy every 50 steps",
            None,
            b.clone().with_paper_fixes(),
        ),
    ]
}

/// The paper's Tables 1, 4, 5 and 6 on `b`, in the studies `names`, with the paper's numbers
/// beside each row; Table 6's periods count `b`'s target-period unit.
fn tables(b: &Config, names: [&'static str; 4]) -> Vec<Variant> {
    let [t1, t4, t5, t6] = names;
    let mut out = Vec::from(widths_and_algorithms(b, t1, t4));
    out.extend(learning_rates(b, t5));
    out.extend(target_periods(b, t6));
    out
}

/// Table 1 (hidden width) in study `t1` and Table 4 (DQN against Double DQN) in `t4`.
fn widths_and_algorithms(f: &Config, t1: &'static str, t4: &'static str) -> [Variant; 5] {
    [
        v(
            t1,
            "width 16",
            Some(("no convergence", "< 100")),
            Config {
                width: 16,
                ..f.clone()
            },
        ),
        v(t1, "width 64", Some(("~160", "196.5")), f.clone()),
        v(
            t1,
            "width 128",
            Some(("~200", "195.1")),
            Config {
                width: 128,
                ..f.clone()
            },
        ),
        v(
            t4,
            "DQN",
            Some(("~200", "192.3")),
            Config {
                algo: Algo::Dqn,
                ..f.clone()
            },
        ),
        v(t4, "Double DQN", Some(("~160", "196.5")), f.clone()),
    ]
}

/// Table 5 (learning rate) in study `t5`.
fn learning_rates(f: &Config, t5: &'static str) -> [Variant; 3] {
    [
        v(
            t5,
            "lr 0.0001",
            Some(("> 250", "193.1")),
            Config {
                lr: 1e-4,
                ..f.clone()
            },
        ),
        v(t5, "lr 0.0005", Some(("~160", "196.5")), f.clone()),
        v(
            t5,
            "lr 0.001",
            Some(("unstable", "< 180")),
            Config {
                lr: 1e-3,
                ..f.clone()
            },
        ),
    ]
}

/// Table 6 (target update period, in `f`'s unit) in study `t6`.
fn target_periods(f: &Config, t6: &'static str) -> [Variant; 3] {
    let unit = match f.target_period_unit {
        Unit::Episodes => "ep.",
        Unit::Steps => "steps",
    };
    [
        v(
            t6,
            &format!("every 10 {unit}"),
            Some(("~200", "193.8")),
            Config {
                target_period: 10,
                ..f.clone()
            },
        ),
        v(
            t6,
            &format!("every 50 {unit}"),
            Some(("~160", "196.5")),
            f.clone(),
        ),
        v(
            t6,
            &format!("every 100 {unit}"),
            Some(("~220", "194.2")),
            Config {
                target_period: 100,
                ..f.clone()
            },
        ),
    ]
}

/// The paper's own tables and the single changes to its preset.
fn paper_studies(base: &Config) -> Vec<Variant> {
    let b = base.clone();
    let mut out = tables(&b, ["table1", "table4", "table5", "table6"]);
    out.extend([
        v("init", "Xavier normal", None, b.clone()),
        v(
            "init",
            "N(0, 0.1)",
            None,
            Config {
                init: Init::Normal01,
                ..b.clone()
            },
        ),
        v("target", "hard, every 50 ep.", None, b.clone()),
        v(
            "target",
            "soft, tau 0.005 per step",
            None,
            Config {
                target_update: TargetUpdate::Soft,
                ..b.clone()
            },
        ),
        v("fix", "paper preset", None, b.clone()),
        v(
            "fix",
            "epsilon per episode (scale 200 ep.)",
            None,
            Config {
                eps_unit: Unit::Episodes,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "slower epsilon (scale 2,000 steps)",
            None,
            Config {
                eps_decay: 2000.0,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "buffer 50,000",
            None,
            Config {
                buffer_size: 50_000,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "hard copy every 100 steps",
            None,
            Config {
                target_period: 100,
                target_period_unit: Unit::Steps,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "500-step episodes",
            None,
            Config {
                max_steps: 500,
                ..b.clone()
            },
        ),
    ]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fields in which `cfg` differs from `base`.
    fn changed(base: &Config, cfg: &Config) -> Vec<String> {
        let (base, cfg) = (
            serde_json::to_value(base).unwrap(),
            serde_json::to_value(cfg).unwrap(),
        );
        base.as_object()
            .unwrap()
            .iter()
            .filter(|(k, val)| cfg[k.as_str()] != **val)
            .map(|(k, _)| k.clone())
            .collect()
    }

    #[test]
    fn every_variant_changes_only_what_its_study_is_about() {
        let (paper, fixed) = (Config::paper(), Config::paper_fixed());
        let all = variants(&paper);
        for (study, _) in STUDIES {
            assert!(all.iter().any(|v| v.study == study), "{study} has no rows");
        }
        for v in &all {
            v.cfg.validate().unwrap();
            let (base, most) = match v.study {
                s if s.ends_with("-fixed") => (&fixed, 1),
                // A reward with a per-step copy (period and unit): three; the minimalRL
                // schedule: four.
                "shaping" if v.label.contains("minimalRL's schedule") => (&paper, 4),
                "shaping" => (&paper, 3),
                // A per-step target period changes the period and its unit.
                _ => (&paper, 2),
            };
            let c = changed(base, &v.cfg);
            assert!(c.len() <= most, "{}: {c:?}", v.label);
        }
        // paper-fixed is exactly its two documented changes.
        let mut c = changed(&paper, &fixed);
        c.sort();
        assert_eq!(c, ["reward", "target_period_unit"]);
    }
}
