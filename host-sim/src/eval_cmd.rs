//! `host-sim eval`'s checks of its flags, before any work: the counts (the rows are
//! `host_sim::eval::check_rows`'s).

use anyhow::Result;
use clap::ValueEnum;
use host_sim::eval::{ControllerKind, MAX_EPISODES, MAX_HORIZON};

use super::EvalArgs;
use host_sim::eval::names;

/// Checks `eval`'s counts before any work.
pub(super) fn check_eval(a: &EvalArgs) -> Result<()> {
    if let Some(m) = a.min_success {
        anyhow::ensure!(
            // At 0 every row passes: a gate that checks nothing.
            m > 0.0 && m <= 1.0 && weights::plain(m),
            "--min-success must lie in (0, 1], normal, got {m:?}"
        );
        // It judges the network's rows alone: without one it checked nothing and exited 0,
        // a gate that always passes.
        let controllers = a.controllers();
        if !controllers.iter().any(|k| k.runs_policy()) {
            let drivers: Vec<ControllerKind> = (ControllerKind::value_variants().iter())
                .filter(|k| k.runs_policy())
                .copied()
                .collect();
            anyhow::bail!(
                "--min-success judges the rows the network drives; expected a controller \
                 among {}, found {}",
                names(&drivers),
                names(&controllers)
            );
        }
    }
    anyhow::ensure!(
        (1..=MAX_EPISODES).contains(&a.episodes),
        "--episodes must be in [1, {MAX_EPISODES}], got {}",
        a.episodes
    );
    if let Some(h) = a.horizon.iter().find(|&&h| !(1..=MAX_HORIZON).contains(&h)) {
        anyhow::bail!("--horizon must be in [1, {MAX_HORIZON}], got {h}");
    }
    Ok(())
}
