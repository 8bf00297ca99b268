//! The training loop: Double DQN (or DQN) on the twin's worlds, acting through the
//! firmware's controller period and its forward pass (what ships), learning with
//! [`crate::nn`].
//!
//! Read top to bottom it is the whole algorithm: epsilon-greedy acting, a FIFO replay buffer
//! sampled without replacement, `updates_per_train` TD regression steps every `train_every`
//! environment steps or episodes, hard or soft target updates, an optional budget of
//! environment steps, and per-episode metrics. Every random draw comes from streams derived
//! from the run's seed, so the same seed and configuration give the same weights and
//! metrics, bit for bit, on every machine.
//!
//! - `dqn`: the training loop, top to bottom.
//! - `select`: the snapshots evaluated, the finalists' trial, the final evaluation.
//! - `periodic`: the periodic evaluations, beside the learning where a core is spare.
//! - `replay`: the FIFO replay buffer.
//! - `learner`: the two networks, TD targets and one gradient step.
//! - `evaluate`: greedy evaluation and the solved-episode measures.

use anyhow::Result;
use firmware::controller::Levels;
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use twin::Domain;
use weights::Weights;
use weights::shape::{ForShape, by_shape};

use crate::config::Config;
use crate::nn::Kernel;

mod dqn;
mod evaluate;
mod learner;
mod periodic;
mod replay;
mod select;

pub use crate::reward::{Prices, Reward};
pub use evaluate::{
    Eval, EvalResult, EvalStreams, Judge, evaluate, quantised, solved_episode, trailing_means,
};
pub use learner::{Learner, init_weights, td_targets};
pub use replay::ReplayBuffer;
pub use select::TrialRun;

/// Independent random streams of a run, so that changing how often one is drawn from (say,
/// the batch size) leaves the others' sequences alone.
#[derive(Clone, Copy, Debug)]
#[repr(u64)]
pub enum Stream {
    /// Initial weights.
    Init = 1,
    /// Training episode starts.
    Env = 2,
    /// Epsilon-greedy coin flips and random actions.
    Explore = 3,
    /// Minibatch indices.
    Sample = 4,
    /// Starts of the periodic evaluations (the same every time within a run).
    Eval = 5,
    /// Starts of the final evaluation, disjoint from everything the run trained or selected on.
    Final = 6,
    /// Worlds drawn from the training domain, one per episode.
    Domain = 7,
    /// Sensor noise of the training worlds.
    Noise = 8,
    /// Push sides of the training worlds.
    Pushes = 9,
    /// Worlds, noise and pushes of the periodic evaluations.
    EvalWorld = 10,
    /// See [`Stream::EvalWorld`].
    EvalNoise = 11,
    /// See [`Stream::EvalWorld`].
    EvalPushes = 12,
    /// Worlds, noise and pushes of the final evaluation.
    FinalWorld = 13,
    /// See [`Stream::FinalWorld`].
    FinalNoise = 14,
    /// See [`Stream::FinalWorld`].
    FinalPushes = 15,
    /// Starts of the finalists' trial.
    Trial = 16,
    /// Worlds, noise and pushes of the finalists' trial.
    TrialWorld = 17,
    /// See [`Stream::TrialWorld`].
    TrialNoise = 18,
    /// See [`Stream::TrialWorld`].
    TrialPushes = 19,
}

/// The generator of one stream of one seed (the project's one mixer, index 0).
pub fn rng(seed: u64, stream: Stream) -> Pcg64Mcg {
    host_common::seed::rng(seed, 0, stream as u64)
}

/// Exploration rate at `t` (steps or episodes, per the configuration).
pub fn epsilon(cfg: &Config, t: f64) -> f64 {
    cfg.eps_end + (cfg.eps_start - cfg.eps_end) * (-t / cfg.eps_decay).exp()
}

/// One row of `metrics.csv`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EpisodeRecord {
    /// 1-based episode number.
    pub episode: usize,
    /// Sum of the task's rewards (= steps survived).
    #[serde(rename = "return")]
    pub ret: f64,
    /// Sum of the learning rewards (the return itself unless the reward is shaped).
    pub learning_return: f64,
    /// Steps in the episode.
    pub length: u32,
    /// Exploration rate at the episode's last step.
    pub epsilon: f64,
    /// Mean TD loss over the episode's gradient steps (empty before learning starts).
    pub mean_loss: Option<f64>,
    /// Mean over visited states of `max_a Q(s, a)` predicted by the online net.
    pub mean_max_q: f64,
    /// Mean over visited states of the discounted learning return actually obtained from
    /// them; after a truncation (or the budget's cut) the online net's max-Q of the last
    /// state stands in for the rest.
    pub mean_discounted_return: f64,
    /// Environment steps so far.
    pub env_steps: u64,
    /// Seconds since training started (the one column that is not deterministic).
    pub wall_s: f64,
}

/// Everything a finished run hands to its writer.
pub struct RunResult {
    /// Per-episode metrics.
    pub episodes: Vec<EpisodeRecord>,
    /// The run's policy: the best periodically evaluated snapshot, or the last weights.
    pub policy: Weights,
    /// Episode after which `policy` was taken.
    pub policy_episode: usize,
    /// Environment steps trained when `policy` was taken.
    pub policy_env_steps: u64,
    /// Evaluation episodes run to choose `policy` (periodic and finalists'; not training
    /// steps, and not counted in `env_steps`).
    pub selection_episodes: u64,
    /// Environment steps of those episodes.
    pub selection_steps: u64,
    /// Periodic evaluations: (episode, result).
    pub evals: Vec<(usize, EvalResult)>,
    /// The finalists' trial, best periodic snapshot first; empty without finalists.
    pub trial: Vec<TrialRun>,
    /// `policy` on fresh starts.
    pub final_eval: EvalResult,
    /// Total environment steps.
    pub env_steps: u64,
    /// Total gradient steps.
    pub grad_steps: u64,
    /// Training wall time, s: the learning and its periodic evaluations, up to the last
    /// episode (the finalists' trial and the final evaluation, which choose and judge the
    /// policy after it, excluded).
    pub wall_s: f64,
    /// The kernel that ran.
    pub kernel: Kernel,
}

/// Trains one seed. `on_episode` sees each episode's record as it completes.
pub fn train(
    cfg: &Config,
    seed: u64,
    on_episode: &mut dyn FnMut(&EpisodeRecord),
) -> Result<RunResult> {
    run(cfg, seed, on_episode, true, learner::spare_core())
}

/// Trains one seed for its episode records alone, which is all a study reads: the policy
/// is neither chosen among snapshots nor evaluated on fresh starts (100 greedy episodes of
/// up to 500 steps for the paper preset). The records are [`train`]'s, bit for bit.
pub fn episodes(cfg: &Config, seed: u64) -> Result<Vec<EpisodeRecord>> {
    Ok(run(cfg, seed, &mut |_| {}, false, learner::spare_core())?.episodes)
}

/// One run at the configured shape; with `evaluate_policy` false, the finalists' trial and
/// the final evaluation are left out; with `beside`, the periodic evaluations run beside
/// the learning (`periodic`), which gives the same bits.
struct Training<'a> {
    cfg: &'a Config,
    levels: Vec<f32>,
    seed: u64,
    kernel: Kernel,
    on_episode: &'a mut dyn FnMut(&EpisodeRecord),
    evaluate_policy: bool,
    beside: bool,
}

fn run(
    cfg: &Config,
    seed: u64,
    on_episode: &mut dyn FnMut(&EpisodeRecord),
    evaluate_policy: bool,
    beside: bool,
) -> Result<RunResult> {
    cfg.validate()?;
    let kernel = cfg.kernel.resolve()?;
    let levels = cfg.levels()?;
    let outputs = levels.len();
    let training = Training {
        cfg,
        levels,
        seed,
        kernel,
        on_episode,
        evaluate_policy,
        beside,
    };
    by_shape(cfg.width, outputs, training)?
}

impl ForShape for Training<'_> {
    type Output = Result<RunResult>;
    fn run<const H: usize, const A: usize>(self) -> Result<RunResult> {
        let fractions: [f32; A] = core::array::from_fn(|i| self.levels[i]);
        let levels = Levels::new(fractions).map_err(|e| anyhow::anyhow!("levels: {e}"))?;
        dqn::run::<H, A>(self, levels)
    }
}

/// The domains of a run, parsed (`validate` has checked them).
struct Domains {
    /// The machine they are drawn around: the one an int8 board's network is quantised on.
    machine: twin::Machine,
    train: Domain,
    eval: Domain,
    trial: Domain,
}

fn domains(cfg: &Config) -> Result<Domains> {
    let machine = cfg.machine()?;
    let parse = |spec: &str| Domain::parse_on(spec, &machine).map_err(anyhow::Error::msg);
    let eval = parse(&cfg.eval_domain)?;
    Ok(Domains {
        train: parse(&cfg.domain)?,
        trial: match cfg.finalist_domain.as_str() {
            "" => eval.clone(),
            spec => parse(spec)?,
        },
        eval,
        machine,
    })
}

#[cfg(test)]
mod tests;
