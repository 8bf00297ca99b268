//! A run directory: what `policy-export train --out DIR` leaves behind.
//!
//! `metrics.csv` (one row per episode), `summary.json` (the full configuration, the seed,
//! the headline numbers), `policy.safetensors` (PyTorch names) and `policy.rs` (the const-
//! array module `firmware` compiles); with `--seeds`, one such directory per seed under
//! `seed-N/` and `aggregate.json`.
//!
//! A run directory is written as a unit and replaced only when it is provably this tool's:
//! [`crate::outdir`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use host_common::stats::mean;
use serde::{Deserialize, Serialize};
use weights::checkpoint::{Import, to_safetensors};
use weights::files::{MAX_POLICY_BYTES, read_capped, write_atomic};
use weights::source::{DEFAULT_RUST_NAME, rust_module};

use crate::config::Config;
use crate::nn::Kernel;
use crate::train::{EvalResult, RunResult, TrialRun, solved_episode, trailing_means};

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
    /// The same of the learning returns (equal to `final_mean100` unless the reward is
    /// shaped).
    #[serde(default)]
    pub final_learning_mean100: f64,
    /// Best trailing 100-episode mean (the mean of all episodes, if fewer than 100).
    pub best_mean100: f64,
    /// Environment steps.
    pub env_steps: u64,
    /// Gradient steps.
    pub grad_steps: u64,
    /// Training wall time, s ([`crate::train::RunResult::wall_s`]).
    pub wall_s: f64,
    /// Training wall time per environment step, microseconds.
    pub us_per_env_step: f64,
    /// Episode after which the exported policy was taken.
    pub policy_episode: usize,
    /// Environment steps trained when it was taken.
    #[serde(default)]
    pub policy_env_steps: u64,
    /// Evaluation episodes run to choose it (not counted as environment steps).
    #[serde(default)]
    pub selection_episodes: u64,
    /// Environment steps of those episodes.
    #[serde(default)]
    pub selection_steps: u64,
    /// Periodic greedy evaluations that chose the policy.
    pub periodic_evals: Vec<PeriodicEval>,
    /// The finalists' longer trial that chose among the best periodic snapshots (empty
    /// without `finalists`).
    #[serde(default)]
    pub finalist_trial: Vec<TrialRun>,
    /// The exported policy's trial as each board runs it; `null` when the trial did not
    /// run its int8 network (`board_int8`) or there was none.
    #[serde(default)]
    pub board_trial: Option<BoardTrial>,
    /// The exported policy, greedy, on fresh starts.
    pub final_eval: EvalResult,
}

/// The shipped snapshot's finalists' trial on both boards, on the same episodes.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BoardTrial {
    /// The snapshot taken after this episode.
    pub episode: usize,
    /// The float network's.
    pub f32: EvalResult,
    /// The int8 network's.
    pub int8: EvalResult,
}

impl BoardTrial {
    /// The chosen snapshot's, if its trial ran both boards.
    fn of(trial: &[TrialRun], episode: usize) -> Option<BoardTrial> {
        let t = trial.iter().find(|t| t.episode == episode)?;
        Some(BoardTrial {
            episode,
            f32: t.f32.clone(),
            int8: t.int8.clone()?,
        })
    }
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
    let tail = returns.len().saturating_sub(100);
    let final_mean100 = mean(&returns[tail..]);
    let learning: Vec<f64> = r.episodes[tail..]
        .iter()
        .map(|e| e.learning_return)
        .collect();
    let best_mean100 =
        trailing_means(&returns, 100.min(returns.len()).max(1)).fold(f64::NEG_INFINITY, f64::max);
    Summary {
        config: cfg.clone(),
        seed,
        kernel: r.kernel,
        parameters: r.policy.params(),
        episodes_run: returns.len(),
        solved_episode_195: solved_episode(&returns, 195.0),
        solved_episode_475: solved_episode(&returns, 475.0),
        final_mean100,
        final_learning_mean100: mean(&learning),
        best_mean100,
        env_steps: r.env_steps,
        grad_steps: r.grad_steps,
        wall_s: r.wall_s,
        us_per_env_step: r.wall_s * 1e6 / r.env_steps.max(1) as f64,
        policy_episode: r.policy_episode,
        policy_env_steps: r.policy_env_steps,
        selection_episodes: r.selection_episodes,
        selection_steps: r.selection_steps,
        periodic_evals: r
            .evals
            .iter()
            .map(|(episode, e)| PeriodicEval {
                episode: *episode,
                mean: e.mean,
                min: e.min,
            })
            .collect(),
        finalist_trial: r.trial.clone(),
        board_trial: BoardTrial::of(&r.trial, r.policy_episode),
        final_eval: r.final_eval.clone(),
    }
}

/// One-line provenance of a run, for the headers of exported source.
pub fn provenance(s: &Summary) -> Vec<String> {
    let c = &s.config;
    vec![
        format!(
            "trained: {:?}, seed {}, {} episodes ({} env steps) of at most {} steps",
            c.algo, s.seed, s.episodes_run, s.env_steps, c.max_steps
        ),
        format!(
            "greedy evaluation: mean {:?}, min {:?} over {} fresh {}-step episodes",
            s.final_eval.mean, s.final_eval.min, s.final_eval.episodes, s.final_eval.max_steps
        ),
    ]
}

/// Where an exported policy came from: its run's summary, or the file and its layout.
pub fn source_provenance(src: &Path, import: &Import) -> Result<Vec<String>> {
    let Some(summary_path) = src.is_dir().then(|| summary_of(src)).flatten() else {
        return Ok(vec![format!(
            "source: {} ({})",
            src.file_name().unwrap_or_default().to_string_lossy(),
            import.describe()
        )]);
    };
    // The summary's figures describe the policy its run wrote beside it, and no other.
    crate::outdir::unchanged(&[&weights::checkpoint::policy_file(src), &summary_path])?;
    let bytes = read_capped(&summary_path, MAX_POLICY_BYTES)?;
    // The parser reads `1e-400` as 0, which went into the module as a measured minimum.
    if let Some(why) = std::str::from_utf8(&bytes)
        .ok()
        .and_then(weights::hidden_zero_in_numbers)
    {
        return Err(weights::Error::Input(format!(
            "{}: not a run summary: {why}",
            weights::shown(&summary_path)
        ))
        .into());
    }
    let s: Summary = weights::json::parse_bytes(&bytes).map_err(|e| {
        weights::Error::Input(format!(
            "{}: not a run summary: {e}",
            weights::shown(&summary_path)
        ))
    })?;
    check_figures(&s)
        .and_then(|()| same_run(&s, &import.metadata))
        .map_err(|e| {
            weights::Error::Input(format!(
                "{}: not a run summary: {e}",
                weights::shown(&summary_path)
            ))
        })?;
    Ok(provenance(&s))
}

/// Why a summary cannot be the run of the policy file whose `metadata` the trainer wrote:
/// another seed or configuration (a file beside another run's summary, with no marker to
/// tell, was exported as that run's), naming the first key that differs. Keys are compared
/// where both record them: an older version's file lacks the keys added since, or holds
/// some removed since; a file that records neither seed nor configuration (not the
/// trainer's) says nothing either way.
fn same_run(s: &Summary, metadata: &BTreeMap<String, String>) -> std::result::Result<(), String> {
    if let Some(seed) = metadata.get(SEED_KEY).filter(|&m| *m != s.seed.to_string()) {
        return Err(format!(
            "seed: the policy file records seed {}, the summary {}",
            weights::quote(seed),
            s.seed
        ));
    }
    let Some(text) = metadata.get(CONFIG_KEY) else {
        return Ok(());
    };
    let Ok(serde_json::Value::Object(file)) = serde_json::from_str(text) else {
        return Err(format!(
            "config: the policy file records {}, not a configuration",
            weights::quote(text)
        ));
    };
    let summary = weights_config(&s.config).map_err(|e| e.to_string())?;
    let differs = summary
        .as_object()
        .into_iter()
        .flatten()
        .find(|(key, v)| file.get(*key).is_some_and(|f| f != *v));
    match differs {
        Some((key, v)) => Err(format!(
            "config.{key}: the policy file records {}, the summary {v}",
            file[key]
        )),
        None => Ok(()),
    }
}

/// Why the figures a summary gives for the provenance cannot be a run's, if they cannot:
/// an export copies them into generated code as fact, where a worst return above the mean,
/// an evaluation of no episodes or a subnormal mean went unread.
fn check_figures(s: &Summary) -> std::result::Result<(), String> {
    let (e, c) = (&s.final_eval, &s.config);
    c.within_limits().map_err(|e| format!("config: {}", e.0))?;
    let count = |field: &str, n: u64, most: u64, what: &str| {
        if (1..=most).contains(&n) {
            Ok(())
        } else {
            Err(format!("{field}: expected 1 to {most} ({what}), found {n}"))
        }
    };
    count(
        "final_eval.episodes",
        e.episodes as u64,
        u64::MAX,
        "episodes run",
    )?;
    count(
        "final_eval.max_steps",
        u64::from(e.max_steps),
        u64::MAX,
        "a step limit",
    )?;
    count(
        "episodes_run",
        s.episodes_run as u64,
        c.episodes as u64,
        "at most the configured episodes",
    )?;
    let most_steps = (s.episodes_run as u64).saturating_mul(u64::from(c.max_steps));
    let least_steps = s.episodes_run as u64;
    if !(least_steps..=most_steps).contains(&s.env_steps) {
        return Err(format!(
            "env_steps: expected {least_steps} to {most_steps} ({} episodes of 1 to {} steps), \
             found {}",
            s.episodes_run, c.max_steps, s.env_steps
        ));
    }
    let returns = [("final_eval.min", e.min), ("final_eval.mean", e.mean)];
    if let Some((field, x)) = returns.iter().find(|(_, x)| !weights::plain(*x)) {
        return Err(format!("{field}: expected a normal number, found {x:?}"));
    }
    // An episode's return is its steps, one reward each; a fraction is no episode's.
    if e.min.fract() != 0.0 {
        return Err(format!(
            "final_eval.min: expected a whole number of steps, found {:?}",
            e.min
        ));
    }
    let order = [
        ("final_eval.min", 1.0, e.min, e.mean),
        ("final_eval.mean", e.min, e.mean, f64::from(e.max_steps)),
    ];
    match order
        .iter()
        .find(|(_, low, x, high)| !(low <= x && x <= high))
    {
        Some((field, low, x, high)) => Err(format!(
            "{field}: expected a return from {low:?} to {high:?} (1 <= min <= mean <= \
             max_steps: an episode takes a step at least), found {x:?}"
        )),
        None => Ok(()),
    }
}

/// The files `export` reads of the policy at `src`: its policy file, and its run's summary
/// for the provenance, if it has one. An output may be neither (`--out RUN/summary.json`
/// replaced the summary with the module).
pub fn export_inputs(src: &Path) -> Vec<PathBuf> {
    let file = weights::checkpoint::policy_file(src);
    std::iter::once(file).chain(summary_of(src)).collect()
}

/// The `summary.json` of the policy at `src`: in a run directory, or beside a policy file.
/// Whatever has that name is the summary, read as inputs are (a directory, a FIFO or a link
/// to a device refused, naming what it is); only a name that does not exist is no summary.
/// Taken as absent when not a regular file, a summary that was a directory lost the run's
/// provenance from the module without a word.
fn summary_of(src: &Path) -> Option<PathBuf> {
    let dir = if src.is_dir() { src } else { src.parent()? };
    let path = dir.join("summary.json");
    match std::fs::symlink_metadata(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        _ => Some(path),
    }
}

/// What the run's summary says against putting the policy at `src` on a board, a line each:
/// no board-level trial figures, or an int8 board that held the finalists' trial more than
/// [`INT8_SHORTFALL`] shorter than the float board. Neither board is held to the trial's
/// full length: its pushes are chosen to part the finalists, and no snapshot outlasts all of
/// them. Nothing when no summary describes the policy.
pub fn board_warnings(src: &Path) -> Vec<String> {
    let Some(path) = summary_of(src) else {
        return Vec::new();
    };
    let shown = weights::shown(&path);
    let summary = read_capped(&path, MAX_POLICY_BYTES)
        .ok()
        .and_then(|b| weights::json::parse_bytes::<Summary>(&b).ok());
    let Some(summary) = summary else {
        return vec![format!(
            "warning: {shown} is not a run summary, so the policy has no board-level trial \
             figures"
        )];
    };
    let Some(b) = summary.board_trial else {
        return vec![format!(
            "warning: {shown} has no board-level trial figures (board_trial): the policy was \
             not tried as an int8 board runs it (train with board_int8 = true)"
        )];
    };
    if b.int8.mean >= b.f32.mean * (1.0 - INT8_SHORTFALL) {
        return Vec::new();
    }
    vec![format!(
        "warning: {shown}: board_trial.int8.mean is {:?} periods against board_trial.f32.mean \
         {:?} (of {}): the int8 board falls sooner than the float one in the finalists' trial; \
         prefer the f32 export on a core with an FPU",
        b.int8.mean, b.f32.mean, b.int8.max_steps
    )]
}

/// How much shorter than the float board's the int8 board's mean survival in the
/// finalists' trial may be before `export` warns: one point, the bound the project holds
/// int8 to beside f32.
pub const INT8_SHORTFALL: f64 = 0.01;

/// The configuration a policy file records: everything its weights depend on. The kernel
/// is left out: every kernel trains the same bits, so a file must not differ by the machine
/// that made it (`summary.json` says which ran). Otherwise as files record it
/// ([`Config::recorded`]).
fn weights_config(cfg: &Config) -> serde_json::Result<serde_json::Value> {
    let mut v = cfg.recorded()?;
    if let Some(map) = v.as_object_mut() {
        map.remove("kernel");
    }
    Ok(v)
}

/// The policy file's metadata keys for its run's seed and configuration.
const SEED_KEY: &str = "seed";
const CONFIG_KEY: &str = "config";

/// Writes one run's files into `dir` (a [`crate::outdir::Staging`] path or one of its
/// `seed-N`).
pub fn write_run(dir: &Path, cfg: &Config, seed: u64, r: &RunResult) -> Result<Summary> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", weights::shown(dir)))?;
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
    let meta = BTreeMap::from([
        ("format".to_string(), "pt".to_string()),
        (SEED_KEY.to_string(), seed.to_string()),
        (
            weights::checkpoint::WIDTH_KEY.to_string(),
            r.policy.width().to_string(),
        ),
        (CONFIG_KEY.to_string(), weights_config(cfg)?.to_string()),
        (
            twin::rigfile::METADATA_KEY.to_string(),
            twin::rigfile::to_toml(&cfg.machine()?),
        ),
    ]);
    write_atomic(
        &dir.join("policy.safetensors"),
        &to_safetensors(&r.policy, &meta)?,
    )?;
    let prov = provenance(&summary);
    write_atomic(
        &dir.join("policy.rs"),
        rust_module(&r.policy, DEFAULT_RUST_NAME, &prov, &cfg.machine()?.rig)?.as_bytes(),
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
    /// Each seed's environment steps trained when its policy was taken.
    pub policy_env_steps: Vec<u64>,
    /// Median and largest of `policy_env_steps` over the seeds that reached 475.
    pub policy_env_steps_at_475: Option<(f64, u64)>,
    /// Evaluation episodes and their environment steps that chose the policies, summed over
    /// all seeds.
    pub selection_episodes: u64,
    /// See `selection_episodes`.
    pub selection_steps: u64,
    /// Median of `final_mean100`.
    pub median_final_mean100: f64,
    /// Median wall seconds per run.
    pub median_wall_s: f64,
}

/// Summarises several seeds' summaries.
pub fn aggregate(summaries: &[Summary]) -> Aggregate {
    let median = |v: Vec<f64>| host_common::stats::median(&v);
    Aggregate {
        seeds: summaries.iter().map(|s| s.seed).collect(),
        final_mean100: summaries.iter().map(|s| s.final_mean100).collect(),
        greedy_eval_mean: summaries.iter().map(|s| s.final_eval.mean).collect(),
        solved_episode_195: summaries.iter().map(|s| s.solved_episode_195).collect(),
        seeds_greedy_at_least_475: summaries
            .iter()
            .filter(|s| s.final_eval.mean >= 475.0)
            .count(),
        policy_env_steps: summaries.iter().map(|s| s.policy_env_steps).collect(),
        policy_env_steps_at_475: {
            let at: Vec<u64> = summaries
                .iter()
                .filter(|s| s.final_eval.mean >= 475.0)
                .map(|s| s.policy_env_steps)
                .collect();
            at.iter().max().map(|&max| {
                let m = median(at.iter().map(|&s| s as f64).collect());
                (m, max)
            })
        },
        selection_episodes: summaries.iter().map(|s| s.selection_episodes).sum(),
        selection_steps: summaries.iter().map(|s| s.selection_steps).sum(),
        median_final_mean100: median(summaries.iter().map(|s| s.final_mean100).collect()),
        median_wall_s: median(summaries.iter().map(|s| s.wall_s).collect()),
    }
}
