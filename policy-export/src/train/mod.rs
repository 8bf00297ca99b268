//! The training loop: Double DQN (or DQN) on `firmware::cartpole`, acting through
//! `firmware::network` — the forward pass that ships — and learning with [`crate::nn`].
//!
//! Read top to bottom it is the whole algorithm: epsilon-greedy acting, a FIFO replay buffer
//! sampled without replacement, one TD regression step per `train_every` environment steps,
//! hard or soft target updates, and per-episode metrics. Every random draw comes from
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
    /// them.
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
    cfg.validate()?;
    let kernel = cfg.kernel.resolve()?;
    macro_rules! by_width {
        ($($h:literal => $c:ident / $qc:ident,)*) => {
            match cfg.width {
                $($h => train_width::<$h>(cfg, seed, kernel, on_episode),)*
                w => unreachable!("validate() admits only supported widths, got {w}"),
            }
        };
    }
    firmware::for_each_width!(by_width)
}

fn train_width<const H: usize>(
    cfg: &Config,
    seed: u64,
    kernel: Kernel,
    on_episode: &mut dyn FnMut(&EpisodeRecord),
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
        loop {
            let t = match cfg.eps_unit {
                Unit::Steps => env_steps as f64,
                Unit::Episodes => ep as f64,
            };
            eps = epsilon(cfg, t);
            let q = learner.online.forward(&obs);
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

            if buf.len() >= learning_starts && env_steps.is_multiple_of(cfg.train_every as u64) {
                let loss = learner.update(cfg, &buf, &mut sample_rng);
                if !loss.is_finite() {
                    bail!(
                        "non-finite loss ({loss}) at episode {}, step {} (env step {env_steps}); \
                         try a smaller lr or grad_clip",
                        ep + 1,
                        rewards.len()
                    );
                }
                loss_sum += f64::from(loss);
                losses += 1;
            }
            if cfg.target_update == TargetUpdate::Hard
                && cfg.target_period_unit == Unit::Steps
                && env_steps.is_multiple_of(cfg.target_period as u64)
            {
                learner.sync_target();
            }
            obs = next;
            if tr.terminated || tr.truncated {
                break;
            }
        }
        if cfg.target_update == TargetUpdate::Hard
            && cfg.target_period_unit == Unit::Episodes
            && (ep + 1).is_multiple_of(cfg.target_period)
        {
            learner.sync_target();
        }

        let len = rewards.len();
        let mut g = 0.0f64;
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

        if cfg.eval_every > 0 && (ep + 1).is_multiple_of(cfg.eval_every) {
            let res = evaluate(
                &learner.online,
                cfg.eval_episodes,
                cfg.eval_max_steps,
                &eval_domain,
                cfg.compensate,
                &mut eval_streams(seed, Eval::Periodic),
            );
            let perfect = res.min >= f64::from(cfg.eval_max_steps);
            let rank = pool.partition_point(|(b, _, _)| !res.beats(b));
            if rank < pool_size {
                pool.insert(rank, (res.clone(), ep + 1, learner.online.clone()));
                pool.truncate(pool_size);
            }
            evals.push((ep + 1, res));
            if perfect && cfg.stop_when_perfect {
                break;
            }
        }
    }
    let wall_s = start.elapsed().as_secs_f64();
    let last = records.len();
    let mut trial = Vec::new();
    if cfg.finalists > 0 {
        let mut best: Option<(usize, EvalResult)> = None;
        for (i, (_, ep, net)) in pool.iter().enumerate() {
            let res = evaluate(
                net,
                cfg.finalist_episodes,
                cfg.finalist_max_steps,
                &trial_domain,
                cfg.compensate,
                &mut eval_streams(seed, Eval::Trial),
            );
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
        None => (last, learner.online.clone()),
    };
    let final_eval = evaluate(
        &policy,
        cfg.final_eval_episodes,
        cfg.eval_max_steps,
        &eval_domain,
        cfg.compensate,
        &mut eval_streams(seed, Eval::Final),
    );
    Ok(RunResult {
        episodes: records,
        policy: Weights::from_mlp(&policy).map_err(|e| {
            anyhow::anyhow!("the trained weights are unusable ({e}); try a smaller lr or grad_clip")
        })?,
        policy_episode,
        evals,
        trial,
        final_eval,
        env_steps,
        grad_steps: learner.steps(),
        wall_s,
        kernel,
    })
}

#[cfg(test)]
mod tests;
