//! The training loop: Double DQN (or DQN) on `firmware::cartpole`, acting through
//! `firmware::network` — the forward pass that ships — and learning with [`crate::nn`].
//!
//! Read top to bottom it is the whole algorithm: epsilon-greedy acting, a FIFO replay buffer
//! sampled without replacement, `updates_per_train` TD regression steps every `train_every`
//! environment steps or episodes, hard or soft target updates, an optional budget of
//! environment steps, and per-episode metrics. Every random draw comes from
//! streams derived from the run's seed, so the same seed and configuration give the same
//! weights and metrics, bit for bit, per kernel.
//!
//! - `replay`: the FIFO replay buffer.
//! - `learner`: the two networks, TD targets and one gradient step.
//! - `evaluate`: greedy evaluation and the solved-episode measures.

use std::time::Instant;

use anyhow::{Result, bail};
use firmware::cartpole::{Action, unit_f64};
use firmware::network::{Mlp, argmax};
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use twin::run::nominal_predictor;
use twin::{Domain, World};
use weights::Weights;

use crate::config::{Config, TargetUpdate, Unit};
use crate::nn::Kernel;

mod evaluate;
mod learner;
mod replay;
mod reward;

pub use evaluate::{EvalResult, EvalStreams, evaluate, solved_episode, trailing_means};
pub use learner::{Learner, init_weights, td_targets};
pub use replay::ReplayBuffer;
pub use reward::Reward;

/// Independent random streams of a run, so that changing how often one is drawn from (say,
/// the batch size) leaves the others' sequences alone.
#[derive(Clone, Copy)]
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

/// Which evaluation a set of streams serves.
#[derive(Clone, Copy)]
enum Eval {
    /// The periodic ones: the same streams every time within a run.
    Periodic,
    /// The finalists' trial: the same streams for every finalist.
    Trial,
    /// The final one, disjoint from everything the run trained or selected on.
    Final,
}

fn eval_streams(seed: u64, which: Eval) -> EvalStreams {
    let [a, b, c, d] = match which {
        Eval::Periodic => [
            Stream::Eval,
            Stream::EvalWorld,
            Stream::EvalNoise,
            Stream::EvalPushes,
        ],
        Eval::Trial => [
            Stream::Trial,
            Stream::TrialWorld,
            Stream::TrialNoise,
            Stream::TrialPushes,
        ],
        Eval::Final => [
            Stream::Final,
            Stream::FinalWorld,
            Stream::FinalNoise,
            Stream::FinalPushes,
        ],
    };
    EvalStreams {
        start: rng(seed, a),
        world: rng(seed, b),
        noise: rng(seed, c),
        pushes: rng(seed, d),
    }
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
    /// The finalists' trial, best periodic snapshot first: (episode, result); empty without
    /// finalists.
    pub trial: Vec<(usize, EvalResult)>,
    /// `policy` on fresh starts.
    pub final_eval: EvalResult,
    /// Total environment steps.
    pub env_steps: u64,
    /// Total gradient steps.
    pub grad_steps: u64,
    /// Training wall time, s (final evaluation excluded).
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
    by_width(cfg, seed, on_episode, true)
}

/// Trains one seed for its episode records alone, which is all a study reads: the policy
/// is neither chosen among snapshots nor evaluated on fresh starts (100 greedy episodes of
/// up to 500 steps for the paper preset). The records are [`train`]'s, bit for bit.
pub fn episodes(cfg: &Config, seed: u64) -> Result<Vec<EpisodeRecord>> {
    Ok(by_width(cfg, seed, &mut |_| {}, false)?.episodes)
}

fn by_width(
    cfg: &Config,
    seed: u64,
    on_episode: &mut dyn FnMut(&EpisodeRecord),
    evaluate_policy: bool,
) -> Result<RunResult> {
    cfg.validate()?;
    let kernel = cfg.kernel.resolve()?;
    macro_rules! by_width {
        ($($h:literal => $c:ident / $qc:ident,)*) => {
            match cfg.width {
                $($h => train_width::<$h>(cfg, seed, kernel, on_episode, evaluate_policy),)*
                w => unreachable!("validate() admits only supported widths, got {w}"),
            }
        };
    }
    firmware::for_each_width!(by_width)
}

/// One run; with `evaluate_policy` false, the finalists' trial and the final evaluation
/// are left out.
fn train_width<const H: usize>(
    cfg: &Config,
    seed: u64,
    kernel: Kernel,
    on_episode: &mut dyn FnMut(&EpisodeRecord),
    evaluate_policy: bool,
) -> Result<RunResult> {
    let start = Instant::now();
    let mut learner = Learner::<H>::new(cfg, kernel, seed);
    let mut buf = ReplayBuffer::new(cfg.buffer_size);
    let (mut env_rng, mut explore_rng, mut sample_rng) = (
        rng(seed, Stream::Env),
        rng(seed, Stream::Explore),
        rng(seed, Stream::Sample),
    );
    let (mut domain_rng, mut noise_rng, mut push_rng) = (
        rng(seed, Stream::Domain),
        rng(seed, Stream::Noise),
        rng(seed, Stream::Pushes),
    );
    // validate() has parsed all three.
    let domain = Domain::parse(&cfg.domain).map_err(anyhow::Error::msg)?;
    let eval_domain = Domain::parse(&cfg.eval_domain).map_err(anyhow::Error::msg)?;
    let trial_domain = match cfg.finalist_domain.as_str() {
        "" => eval_domain.clone(),
        spec => Domain::parse(spec).map_err(anyhow::Error::msg)?,
    };
    let reward = Reward::parse(&cfg.reward).map_err(anyhow::Error::msg)?;
    let learning_starts = cfg.learning_starts.max(cfg.batch_size);
    let gamma = cfg.gamma;

    let mut records = Vec::with_capacity(cfg.episodes);
    let mut evals = Vec::new();
    // The best periodic snapshots, best first; among equals the earlier stays ahead.
    let mut pool: Vec<(EvalResult, usize, Box<Mlp<H>>)> = Vec::new();
    let pool_size = cfg.finalists.max(1);
    let mut env_steps: u64 = 0;
    let mut rewards: Vec<f32> = Vec::with_capacity(cfg.max_steps as usize);
    // Evaluation episodes and steps that chose the policy (each step scores 1).
    let (mut selection_episodes, mut selection_steps) = (0u64, 0u64);

    for ep in 0..cfg.episodes {
        let scenario = domain.sample(&mut domain_rng);
        let force = scenario.params.force_mag;
        let mut world = World::start(
            &scenario,
            cfg.max_steps,
            &mut env_rng,
            &mut noise_rng,
            &mut push_rng,
        );
        // The policy decides on the reading advanced over the known dead time, as it will
        // on the board; with none (or without `compensate`) that is the reading itself.
        let mut pred = nominal_predictor(if cfg.compensate { scenario.delay } else { 0 });
        let mut obs = pred.predict(&world.observe());
        let mut ret = 0.0f64;
        rewards.clear();
        let (mut loss_sum, mut losses, mut maxq_sum) = (0.0f64, 0u32, 0.0f64);
        let mut eps;
        let (mut spent, terminated);
        loop {
            let t = match cfg.eps_unit {
                Unit::Steps => env_steps as f64,
                Unit::Episodes => ep as f64,
            };
            eps = epsilon(cfg, t);
            let q = learner.q_values(&obs);
            maxq_sum += f64::from(q[0].max(q[1]));
            let action = if unit_f64(&mut explore_rng) < eps {
                Action::from_index((explore_rng.next_u32() & 1) as usize)
            } else {
                argmax(&q)
            };
            pred.record_push(action);
            let tr = world.apply(match action {
                Action::Right => force,
                Action::Left => -force,
            });
            let next = pred.predict(&world.observe());
            let r = reward.of(&scenario.params, &world.state(), tr.terminated);
            buf.push(obs, action, r, next, tr.terminated);
            rewards.push(r);
            ret += f64::from(tr.reward);
            env_steps += 1;

            if cfg.train_unit == Unit::Steps
                && buf.len() >= learning_starts
                && env_steps.is_multiple_of(cfg.train_every as u64)
            {
                let at = (ep, Some(rewards.len()), env_steps);
                let (sum, n) = learn(&mut learner, cfg, &buf, &mut sample_rng, at)?;
                loss_sum += sum;
                losses += n;
            }
            if cfg.target_update == TargetUpdate::Hard
                && cfg.target_period_unit == Unit::Steps
                && env_steps.is_multiple_of(cfg.target_period as u64)
            {
                learner.sync_target();
            }
            obs = next;
            spent = cfg.max_env_steps > 0 && env_steps >= cfg.max_env_steps;
            if tr.terminated || tr.truncated || spent {
                terminated = tr.terminated;
                break;
            }
        }
        // A cut episode's return goes on past the cut; without its tail every state near the
        // end would seem overestimated (by up to gamma^k / (1 - gamma) per step's reward).
        // The online net's own estimate stands in for it, so the gap measures how far Q
        // disagrees with what followed, not where the episode was cut.
        let mut g = if terminated {
            0.0
        } else {
            // The weights that acted, before any end-of-episode training.
            let q = learner.q_values(&obs);
            f64::from(q[0].max(q[1]))
        };
        if cfg.train_unit == Unit::Episodes
            && buf.len() >= learning_starts
            && (ep + 1).is_multiple_of(cfg.train_every)
        {
            let (sum, n) = learn(
                &mut learner,
                cfg,
                &buf,
                &mut sample_rng,
                (ep, None, env_steps),
            )?;
            loss_sum += sum;
            losses += n;
        }
        if cfg.target_update == TargetUpdate::Hard
            && cfg.target_period_unit == Unit::Episodes
            && (ep + 1).is_multiple_of(cfg.target_period)
        {
            learner.sync_target();
        }

        let len = rewards.len();
        let mut disc_sum = 0.0f64;
        for r in rewards.iter().rev() {
            g = f64::from(*r) + gamma * g;
            disc_sum += g;
        }
        let rec = EpisodeRecord {
            episode: ep + 1,
            ret,
            learning_return: rewards.iter().map(|&r| f64::from(r)).sum(),
            length: len as u32,
            epsilon: eps,
            mean_loss: (losses > 0).then(|| loss_sum / f64::from(losses)),
            mean_max_q: maxq_sum / len as f64,
            mean_discounted_return: disc_sum / len as f64,
            env_steps,
            wall_s: start.elapsed().as_secs_f64(),
        };
        on_episode(&rec);
        records.push(rec);

        // The weights the budget stops at are a candidate too.
        if cfg.eval_every > 0 && ((ep + 1).is_multiple_of(cfg.eval_every) || spent) {
            selection_episodes += cfg.eval_episodes as u64;
            let res = evaluate(
                learner.online(),
                cfg.eval_episodes,
                cfg.eval_max_steps,
                &eval_domain,
                cfg.compensate,
                &mut eval_streams(seed, Eval::Periodic),
            );
            selection_steps += steps_of(&res);
            let perfect = res.min >= f64::from(cfg.eval_max_steps);
            let rank = pool.partition_point(|(b, _, _)| !res.beats(b));
            if rank < pool_size {
                pool.insert(rank, (res.clone(), ep + 1, learner.snapshot()));
                pool.truncate(pool_size);
            }
            evals.push((ep + 1, res));
            if perfect && cfg.stop_when_perfect {
                break;
            }
        }
        if spent {
            break;
        }
    }
    let wall_s = start.elapsed().as_secs_f64();
    let last = records.len();
    let mut trial = Vec::new();
    if evaluate_policy && cfg.finalists > 0 {
        let mut best: Option<(usize, EvalResult)> = None;
        for (i, (_, ep, net)) in pool.iter().enumerate() {
            selection_episodes += cfg.finalist_episodes as u64;
            let res = evaluate(
                net,
                cfg.finalist_episodes,
                cfg.finalist_max_steps,
                &trial_domain,
                cfg.compensate,
                &mut eval_streams(seed, Eval::Trial),
            );
            selection_steps += steps_of(&res);
            // Survival decides; among equals the better periodic rank, since the periodic
            // cost (nominal-like worlds) measures precision better than the trial's pushes.
            if best.as_ref().is_none_or(|(_, b)| res.mean > b.mean) {
                best = Some((i, res.clone()));
            }
            trial.push((*ep, res));
        }
        if let Some((i, _)) = best {
            pool.swap(0, i);
        }
    }
    let (policy_episode, policy) = match pool.into_iter().next() {
        Some((_, ep, net)) => (ep, net),
        None => (last, learner.snapshot()),
    };
    let policy_env_steps = records[policy_episode - 1].env_steps;
    let final_eval = if evaluate_policy {
        evaluate(
            &policy,
            cfg.final_eval_episodes,
            cfg.eval_max_steps,
            &eval_domain,
            cfg.compensate,
            &mut eval_streams(seed, Eval::Final),
        )
    } else {
        // Never leaves this module: `episodes` keeps the records alone.
        EvalResult {
            episodes: 0,
            max_steps: cfg.eval_max_steps,
            mean: f64::NAN,
            min: f64::NAN,
            cost: f64::NAN,
        }
    };
    Ok(RunResult {
        episodes: records,
        policy: Weights::from_mlp(&policy).map_err(|e| {
            anyhow::anyhow!("the trained weights are unusable ({e}); try a smaller lr or grad_clip")
        })?,
        policy_episode,
        policy_env_steps,
        selection_episodes,
        selection_steps,
        evals,
        trial,
        final_eval,
        env_steps,
        grad_steps: learner.steps(),
        wall_s,
        kernel,
    })
}

/// The environment steps an evaluation ran: its return counts one per step.
fn steps_of(res: &EvalResult) -> u64 {
    (res.mean * res.episodes as f64).round() as u64
}

/// Takes `cfg.updates_per_train` gradient steps; returns the sum of their losses and their
/// number. `at` (episode index, step within it for per-step training, env steps) places a
/// non-finite loss in the error.
fn learn<const H: usize>(
    learner: &mut Learner<H>,
    cfg: &Config,
    buf: &ReplayBuffer,
    rng: &mut Pcg64Mcg,
    at: (usize, Option<usize>, u64),
) -> Result<(f64, u32)> {
    let mut sum = 0.0f64;
    for _ in 0..cfg.updates_per_train {
        let loss = learner.update(cfg, buf, rng);
        if !loss.is_finite() {
            let (ep, step, env) = at;
            let when = match step {
                Some(s) => format!("at episode {}, step {s}", ep + 1),
                None => format!("at the end of episode {}", ep + 1),
            };
            bail!(
                "non-finite loss ({loss}) {when} (env step {env}); try a smaller lr or grad_clip"
            );
        }
        sum += f64::from(loss);
    }
    Ok((sum, cfg.updates_per_train as u32))
}

#[cfg(test)]
mod tests;
