//! A run directory: what `policy-export train --out DIR` leaves behind.
//!
//! `metrics.csv` (one row per episode), `summary.json` (the full configuration, the seed,
//! the headline numbers), `policy.safetensors` (PyTorch names) and `policy.rs` (the const-
//! array module `firmware` compiles). Every file is written atomically.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use crate::config::Config;
use crate::export;
use crate::nn::Kernel;
use crate::train::{EvalResult, RunResult, solved_episode, trailing_means};
use crate::weights::write_atomic;

/// The contents of `summary.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Summary {
    /// Every hyperparameter.
    pub config: Config,
    /// The run's seed.
    pub seed: u64,
    /// The kernel the learner ran (results are bit-identical per kernel).
    pub kernel: Kernel,
    /// Parameters of the network.
    pub parameters: usize,
    /// Episodes actually run (fewer than configured after an early stop).
    pub episodes_run: usize,
    /// First episode whose trailing 100-episode mean return reached 195.
    pub solved_episode_195: Option<usize>,
    /// First episode whose trailing 100-episode mean return reached 475.
    pub solved_episode_475: Option<usize>,
    /// Mean return of the last 100 episodes (all of them, if fewer).
    pub final_mean100: f64,
    /// Best trailing 100-episode mean (the mean of all episodes, if fewer than 100).
    pub best_mean100: f64,
    /// Environment steps.
    pub env_steps: u64,
    /// Gradient steps.
    pub grad_steps: u64,
    /// Training wall time, s.
    pub wall_s: f64,
    /// Training wall time per environment step, microseconds.
    pub us_per_env_step: f64,
    /// Episode after which the exported policy was taken.
    pub policy_episode: usize,
    /// Periodic greedy evaluations that chose the policy.
    pub periodic_evals: Vec<PeriodicEval>,
    /// The exported policy, greedy, on fresh starts.
    pub final_eval: EvalResult,
}

/// One periodic evaluation.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PeriodicEval {
    /// After this episode.
    pub episode: usize,
    /// Mean return.
    pub mean: f64,
    /// Worst return.
    pub min: f64,
}

/// Derives the summary of a finished run.
pub fn summarize(cfg: &Config, seed: u64, r: &RunResult) -> Summary {
    let returns: Vec<f64> = r.episodes.iter().map(|e| e.ret).collect();
    let last = &returns[returns.len().saturating_sub(100)..];
    let final_mean100 = last.iter().sum::<f64>() / last.len().max(1) as f64;
    let best_mean100 =
        trailing_means(&returns, 100.min(returns.len()).max(1)).fold(f64::NEG_INFINITY, f64::max);
    Summary {
        config: cfg.clone(),
        seed,
        kernel: r.kernel,
        parameters: r.policy.tensors.iter().map(Vec::len).sum(),
        episodes_run: returns.len(),
        solved_episode_195: solved_episode(&returns, 195.0),
        solved_episode_475: solved_episode(&returns, 475.0),
        final_mean100,
        best_mean100,
        env_steps: r.env_steps,
        grad_steps: r.grad_steps,
        wall_s: r.wall_s,
        us_per_env_step: r.wall_s * 1e6 / r.env_steps.max(1) as f64,
        policy_episode: r.policy_episode,
        periodic_evals: r
            .evals
            .iter()
            .map(|(episode, e)| PeriodicEval {
                episode: *episode,
                mean: e.mean,
                min: e.min,
            })
            .collect(),
        final_eval: r.final_eval.clone(),
    }
}

/// One-line provenance of a run, for the headers of exported source.
pub fn provenance(s: &Summary) -> Vec<String> {
    let c = &s.config;
    vec![
        format!(
            "trained: {:?}, seed {}, {} episodes ({} env steps) of at most {} steps, kernel {:?}",
            c.algo, s.seed, s.episodes_run, s.env_steps, c.max_steps, s.kernel
        ),
        format!(
            "greedy evaluation: mean {:.1}, min {} over {} fresh {}-step episodes",
            s.final_eval.mean, s.final_eval.min, s.final_eval.episodes, s.final_eval.max_steps
        ),
    ]
}

/// Writes the whole run directory.
pub fn write_run(dir: &Path, cfg: &Config, seed: u64, r: &RunResult) -> Result<Summary> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let summary = summarize(cfg, seed, r);

    let mut csv = csv::Writer::from_writer(Vec::new());
    for e in &r.episodes {
        csv.serialize(e)?;
    }
    write_atomic(&dir.join("metrics.csv"), &csv.into_inner()?)?;
    write_atomic(
        &dir.join("summary.json"),
        &serde_json::to_vec_pretty(&summary)?,
    )?;

    let meta = HashMap::from([
        ("format".to_string(), "pt".to_string()),
        ("seed".to_string(), seed.to_string()),
        ("width".to_string(), r.policy.width.to_string()),
        ("config".to_string(), serde_json::to_string(cfg)?),
    ]);
    write_atomic(
        &dir.join("policy.safetensors"),
        &r.policy.to_safetensors(&meta)?,
    )?;
    let prov = provenance(&summary);
    write_atomic(
        &dir.join("policy.rs"),
        export::rust_module(&r.policy, &prov).as_bytes(),
    )?;
    Ok(summary)
}

/// Across-seed statistics of a `--seeds` run (`aggregate.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Aggregate {
    /// The seeds, in order.
    pub seeds: Vec<u64>,
    /// Each seed's final 100-episode training mean.
    pub final_mean100: Vec<f64>,
    /// Each seed's greedy evaluation mean.
    pub greedy_eval_mean: Vec<f64>,
    /// Each seed's first episode with a trailing mean >= 195 (null if never).
    pub solved_episode_195: Vec<Option<usize>>,
    /// Seeds whose greedy evaluation averaged at least 475.
    pub seeds_greedy_at_least_475: usize,
    /// Median of `final_mean100`.
    pub median_final_mean100: f64,
    /// Median wall seconds per run.
    pub median_wall_s: f64,
}

/// Summarises several seeds' summaries.
pub fn aggregate(summaries: &[Summary]) -> Aggregate {
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            f64::NAN
        } else {
            (v[(n - 1) / 2] + v[n / 2]) / 2.0
        }
    };
    Aggregate {
        seeds: summaries.iter().map(|s| s.seed).collect(),
        final_mean100: summaries.iter().map(|s| s.final_mean100).collect(),
        greedy_eval_mean: summaries.iter().map(|s| s.final_eval.mean).collect(),
        solved_episode_195: summaries.iter().map(|s| s.solved_episode_195).collect(),
        seeds_greedy_at_least_475: summaries
            .iter()
            .filter(|s| s.final_eval.mean >= 475.0)
            .count(),
        median_final_mean100: median(summaries.iter().map(|s| s.final_mean100).collect()),
        median_wall_s: median(summaries.iter().map(|s| s.wall_s).collect()),
    }
}
