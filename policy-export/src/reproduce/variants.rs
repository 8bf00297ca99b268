//! The studies: each configuration differs from the paper preset in one field (two for the
//! per-step target period, which has a unit).

use crate::config::{Algo, Config, Init, TargetUpdate, Unit};

/// One configuration of one study.
#[derive(Clone, Debug)]
pub struct Variant {
    /// Which study: `table1`, `table4`, `table5`, `table6`, `init`, `target`, `fix`.
    pub study: &'static str,
    /// Row label, as the paper writes it.
    pub label: String,
    /// The paper's numbers for this row (convergence, final reward), if it gives them.
    pub paper: Option<(&'static str, &'static str)>,
    /// The configuration.
    pub cfg: Config,
}

/// Every study's rows, built from `base` (the paper preset).
pub fn variants(base: &Config) -> Vec<Variant> {
    let v = |study, label: &str, paper, cfg| Variant {
        study,
        label: label.to_string(),
        paper,
        cfg,
    };
    let b = base.clone();
    vec![
        v(
            "table1",
            "width 16",
            Some(("no convergence", "< 100")),
            Config {
                width: 16,
                ..b.clone()
            },
        ),
        v("table1", "width 64", Some(("~160", "196.5")), b.clone()),
        v(
            "table1",
            "width 128",
            Some(("~200", "195.1")),
            Config {
                width: 128,
                ..b.clone()
            },
        ),
        v(
            "table4",
            "DQN",
            Some(("~200", "192.3")),
            Config {
                algo: Algo::Dqn,
                ..b.clone()
            },
        ),
        v("table4", "Double DQN", Some(("~160", "196.5")), b.clone()),
        v(
            "table5",
            "lr 0.0001",
            Some(("> 250", "193.1")),
            Config {
                lr: 1e-4,
                ..b.clone()
            },
        ),
        v("table5", "lr 0.0005", Some(("~160", "196.5")), b.clone()),
        v(
            "table5",
            "lr 0.001",
            Some(("unstable", "< 180")),
            Config {
                lr: 1e-3,
                ..b.clone()
            },
        ),
        v(
            "table6",
            "every 10 ep.",
            Some(("~200", "193.8")),
            Config {
                target_period: 10,
                ..b.clone()
            },
        ),
        v("table6", "every 50 ep.", Some(("~160", "196.5")), b.clone()),
        v(
            "table6",
            "every 100 ep.",
            Some(("~220", "194.2")),
            Config {
                target_period: 100,
                ..b.clone()
            },
        ),
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
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_variant_differs_from_the_paper_preset_in_at_most_one_field() {
        let base = serde_json::to_value(Config::paper()).unwrap();
        for v in variants(&Config::paper()) {
            let cfg = serde_json::to_value(&v.cfg).unwrap();
            let changed: Vec<&String> = base
                .as_object()
                .unwrap()
                .iter()
                .filter(|(k, val)| cfg[k.as_str()] != **val)
                .map(|(k, _)| k)
                .collect();
            // The per-step target row changes the period and its unit.
            assert!(changed.len() <= 2, "{}: {changed:?}", v.label);
            v.cfg.validate().unwrap();
        }
    }
}
