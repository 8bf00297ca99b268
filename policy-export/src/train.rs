//! The training loop: Double DQN (or DQN) on `firmware::cartpole`, acting through
//! `firmware::network` — the forward pass that ships — and learning with [`crate::nn`].
//!
//! Read top to bottom it is the whole algorithm: epsilon-greedy acting, a FIFO replay buffer
//! sampled without replacement, one TD regression step per `train_every` environment steps,
//! hard or soft target updates, and per-episode metrics. Every random draw comes from
//! streams derived from the run's seed, so the same seed and configuration give the same
//! weights and metrics, bit for bit, on the same machine and kernel.

use std::time::Instant;

use anyhow::{Result, bail};
use firmware::cartpole::{Action, CartPole, Params, unit_f64};
use firmware::network::{Mlp, N_ACTIONS, OBS_DIM, argmax};
use rand_core::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

use crate::config::{Algo, Config, Init, TargetUpdate, Unit};
use crate::nn::{self, AdamParams, Kernel, Packed, Scratch};
use crate::weights::Weights;

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
}

/// The generator of one stream of one seed.
pub fn rng(seed: u64, stream: Stream) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ stream as u64)
}

/// A FIFO experience buffer of fixed capacity; the oldest transition goes first.
pub struct ReplayBuffer {
    obs: Vec<[f32; OBS_DIM]>,
    next: Vec<[f32; OBS_DIM]>,
    action: Vec<u8>,
    reward: Vec<f32>,
    terminated: Vec<bool>,
    /// Per slot, which push filled it (1 = the first): tells a cache keyed by slot whether
    /// the slot still holds the transition it saw.
    write_ids: Vec<u64>,
    pushes: u64,
    capacity: usize,
    pos: usize,
}

impl ReplayBuffer {
    /// An empty buffer holding at most `capacity` transitions.
    pub fn new(capacity: usize) -> Self {
        ReplayBuffer {
            obs: Vec::with_capacity(capacity),
            next: Vec::with_capacity(capacity),
            action: Vec::with_capacity(capacity),
            reward: Vec::with_capacity(capacity),
            terminated: Vec::with_capacity(capacity),
            write_ids: Vec::with_capacity(capacity),
            pushes: 0,
            capacity,
            pos: 0,
        }
    }

    /// Transitions held.
    pub fn len(&self) -> usize {
        self.obs.len()
    }

    /// Whether nothing is stored yet.
    pub fn is_empty(&self) -> bool {
        self.obs.is_empty()
    }

    /// Stores a transition, overwriting the oldest once full.
    pub fn push(&mut self, obs: [f32; 4], action: Action, reward: f32, next: [f32; 4], term: bool) {
        let a = action.index() as u8;
        self.pushes += 1;
        if self.len() < self.capacity {
            self.obs.push(obs);
            self.next.push(next);
            self.action.push(a);
            self.reward.push(reward);
            self.terminated.push(term);
            self.write_ids.push(self.pushes);
        } else {
            self.obs[self.pos] = obs;
            self.next[self.pos] = next;
            self.action[self.pos] = a;
            self.reward[self.pos] = reward;
            self.terminated[self.pos] = term;
            self.write_ids[self.pos] = self.pushes;
        }
        self.pos = (self.pos + 1) % self.capacity;
    }

    /// `n` distinct indices, uniformly (as Python's `random.sample`); `n <= len()`.
    pub fn sample_indices<R: Rng>(&self, rng: &mut R, n: usize, out: &mut Vec<usize>) {
        out.clear();
        let len = self.len() as u64;
        while out.len() < n {
            // Lemire's multiply-shift: uniform enough for len << 2^32, no division.
            let i = ((u64::from(rng.next_u32()) * len) >> 32) as usize;
            if !out.contains(&i) {
                out.push(i);
            }
        }
    }

    /// The transition at index `i` (0 = oldest slot written first).
    pub fn get(&self, i: usize) -> ([f32; 4], u8, f32, [f32; 4], bool) {
        (
            self.obs[i],
            self.action[i],
            self.reward[i],
            self.next[i],
            self.terminated[i],
        )
    }

    /// Which push wrote slot `i`: unique over the buffer's life.
    pub fn write_id(&self, i: usize) -> u64 {
        self.write_ids[i]
    }
}

/// Exploration rate at `t` (steps or episodes, per the configuration).
pub fn epsilon(cfg: &Config, t: f64) -> f64 {
    cfg.eps_end + (cfg.eps_start - cfg.eps_end) * (-t / cfg.eps_decay).exp()
}

/// TD targets for a batch: `r + gamma * (1 - terminated) * Q_target(s', a')`, where `a'` is
/// chosen by the online net (Double DQN) or by the target net itself (DQN). Truncated
/// episodes keep their bootstrap: only termination zeroes it.
pub fn td_targets(
    algo: Algo,
    gamma: f32,
    rewards: &[f32],
    terminated: &[bool],
    q_target_next: &[[f32; N_ACTIONS]],
    q_online_next: &[[f32; N_ACTIONS]],
    out: &mut [f32],
) {
    for (b, y) in out.iter_mut().enumerate() {
        let qt = q_target_next[b];
        let next = match algo {
            Algo::Ddqn => qt[argmax(&q_online_next[b]).index()],
            Algo::Dqn => qt[argmax(&qt).index()],
        };
        let bootstrap = if terminated[b] { 0.0 } else { gamma * next };
        *y = rewards[b] + bootstrap;
    }
}

/// `Q_target(s')` of one replay slot, valid while the target net and the slot are the ones
/// it was computed for.
#[derive(Clone, Copy, Default)]
struct CachedQ {
    q: [f32; N_ACTIONS],
    target_version: u64,
    write_id: u64,
}

/// One gradient step's state: the two networks, Adam's moments and the batch buffers.
pub struct Learner<const H: usize> {
    /// The network being trained; acting uses it.
    pub online: Box<Mlp<H>>,
    /// The slowly-following network that scores TD targets.
    pub target: Box<Mlp<H>>,
    online_packed: Box<Packed<H>>,
    target_packed: Box<Packed<H>>,
    grad: Box<Mlp<H>>,
    m: Box<Mlp<H>>,
    v: Box<Mlp<H>>,
    steps: u64,
    kernel: Kernel,
    adam: AdamParams,
    scratch: Scratch<H>,
    idx: Vec<usize>,
    x: Vec<[f32; OBS_DIM]>,
    x_next: Vec<[f32; OBS_DIM]>,
    actions: Vec<u8>,
    rewards: Vec<f32>,
    terminated: Vec<bool>,
    q_target: Vec<[f32; N_ACTIONS]>,
    q_online: Vec<[f32; N_ACTIONS]>,
    targets: Vec<f32>,
    /// Per replay slot, its target Q-values. A hard-updated target net stays fixed for
    /// thousands of updates while each slot is drawn many times, so scoring a slot once
    /// per target version saves most of the target forward passes. A row's Q-values do
    /// not depend on the rows batched with it, so the result is the same bit for bit.
    target_q: Vec<CachedQ>,
    /// Bumped whenever the target net changes; 0 marks a never-filled cache entry.
    target_version: u64,
    /// Batch rows whose target Q-values were not cached, and their next states.
    miss_rows: Vec<usize>,
    x_miss: Vec<[f32; OBS_DIM]>,
}

impl<const H: usize> Learner<H> {
    /// Fresh networks initialised per `cfg.init` from the run's init stream.
    pub fn new(cfg: &Config, kernel: Kernel, seed: u64) -> Self {
        let mut online = nn::boxed_zero::<H>();
        init_weights(&mut online, cfg.init, &mut rng(seed, Stream::Init));
        let b = cfg.batch_size;
        Learner {
            target: online.clone(),
            online_packed: Packed::new(&online),
            target_packed: Packed::new(&online),
            online,
            grad: nn::boxed_zero(),
            m: nn::boxed_zero(),
            v: nn::boxed_zero(),
            steps: 0,
            kernel,
            adam: AdamParams {
                lr: cfg.lr,
                beta1: cfg.adam_beta1,
                beta2: cfg.adam_beta2,
                eps: cfg.adam_eps,
            },
            scratch: Scratch::new(b),
            idx: Vec::with_capacity(b),
            x: vec![[0.0; OBS_DIM]; b],
            x_next: vec![[0.0; OBS_DIM]; b],
            actions: vec![0; b],
            rewards: vec![0.0; b],
            terminated: vec![false; b],
            q_target: vec![[0.0; N_ACTIONS]; b],
            q_online: vec![[0.0; N_ACTIONS]; b],
            targets: vec![0.0; b],
            target_q: vec![CachedQ::default(); cfg.buffer_size],
            target_version: 1,
            miss_rows: Vec::with_capacity(b),
            x_miss: Vec::with_capacity(b),
        }
    }

    /// Samples a minibatch and takes one clipped Adam step on the TD loss; returns the loss.
    pub fn update<R: Rng>(&mut self, cfg: &Config, buf: &ReplayBuffer, rng: &mut R) -> f32 {
        buf.sample_indices(rng, cfg.batch_size, &mut self.idx);
        for (b, &i) in self.idx.iter().enumerate() {
            let (s, a, r, s2, t) = buf.get(i);
            (
                self.x[b],
                self.actions[b],
                self.rewards[b],
                self.x_next[b],
                self.terminated[b],
            ) = (s, a, r, s2, t);
        }
        let k = self.kernel;
        self.score_targets(k, buf);
        // The online weights changed in the previous step; the target's only when synced.
        self.online_packed.pack(&self.online);
        if cfg.algo == Algo::Ddqn {
            nn::forward_batch(
                k,
                &self.online,
                &self.online_packed,
                &self.x_next,
                &mut self.scratch,
            );
            self.q_online.copy_from_slice(&self.scratch.q);
        }
        td_targets(
            cfg.algo,
            cfg.gamma as f32,
            &self.rewards,
            &self.terminated,
            &self.q_target,
            &self.q_online,
            &mut self.targets,
        );
        nn::forward_batch(
            k,
            &self.online,
            &self.online_packed,
            &self.x,
            &mut self.scratch,
        );
        let loss = nn::backward(
            k,
            &self.online,
            &self.x,
            &self.actions,
            &self.targets,
            cfg.loss,
            &mut self.scratch,
            &mut self.grad,
        );
        if cfg.grad_clip > 0.0 {
            nn::clip_grad_norm(&mut self.grad, cfg.grad_clip as f32);
        }
        self.steps += 1;
        nn::adam_step(
            k,
            &self.adam,
            self.steps,
            &mut self.online,
            &self.grad,
            &mut self.m,
            &mut self.v,
        );
        if cfg.target_update == TargetUpdate::Soft {
            nn::soft_update(&mut self.target, &self.online, cfg.tau as f32);
            self.target_packed.pack(&self.target);
            self.target_version += 1;
        }
        loss
    }

    /// Fills `q_target` with the target net's Q-values of the batch's next states, from the
    /// cache where it is current, with one batched forward pass for the rest.
    fn score_targets(&mut self, k: Kernel, buf: &ReplayBuffer) {
        self.miss_rows.clear();
        self.x_miss.clear();
        for (b, &i) in self.idx.iter().enumerate() {
            let c = &self.target_q[i];
            if c.target_version == self.target_version && c.write_id == buf.write_id(i) {
                self.q_target[b] = c.q;
            } else {
                self.miss_rows.push(b);
                self.x_miss.push(self.x_next[b]);
            }
        }
        if self.miss_rows.is_empty() {
            return;
        }
        nn::forward_batch(
            k,
            &self.target,
            &self.target_packed,
            &self.x_miss,
            &mut self.scratch,
        );
        for (&b, q) in self.miss_rows.iter().zip(&self.scratch.q) {
            self.q_target[b] = *q;
            self.target_q[self.idx[b]] = CachedQ {
                q: *q,
                target_version: self.target_version,
                write_id: buf.write_id(self.idx[b]),
            };
        }
    }

    /// Hard target update: copy the online weights.
    pub fn sync_target(&mut self) {
        self.target.clone_from(&self.online);
        self.target_packed.pack(&self.target);
        self.target_version += 1;
    }
}

/// Xavier-normal or N(0, 0.1^2) weights, biases 0.01, drawn tensor by tensor in PyTorch's
/// parameter order.
pub fn init_weights<const H: usize, R: Rng>(net: &mut Mlp<H>, init: Init, rng: &mut R) {
    let shapes = Mlp::<H>::SHAPES;
    for (t, shape) in net.tensors_mut().into_iter().zip(shapes) {
        if shape.len() == 1 {
            t.fill(0.01);
            continue;
        }
        let (fan_out, fan_in) = (shape[0], shape[1]);
        let std = match init {
            Init::Xavier => (2.0 / (fan_in + fan_out) as f64).sqrt(),
            Init::Normal01 => 0.1,
        };
        for w in t {
            let z: f64 = StandardNormal.sample(rng);
            *w = (std * z) as f32;
        }
    }
}

/// One row of `metrics.csv`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EpisodeRecord {
    /// 1-based episode number.
    pub episode: usize,
    /// Sum of rewards (= steps survived).
    #[serde(rename = "return")]
    pub ret: f64,
    /// Steps in the episode.
    pub length: u32,
    /// Exploration rate at the episode's last step.
    pub epsilon: f64,
    /// Mean TD loss over the episode's gradient steps (empty before learning starts).
    pub mean_loss: Option<f64>,
    /// Mean over visited states of `max_a Q(s, a)` predicted by the online net.
    pub mean_max_q: f64,
    /// Mean over visited states of the discounted return actually obtained from them.
    pub mean_discounted_return: f64,
    /// Environment steps so far.
    pub env_steps: u64,
    /// Seconds since training started (the one column that is not deterministic).
    pub wall_s: f64,
}

/// A greedy evaluation's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalResult {
    /// Episodes run.
    pub episodes: usize,
    /// Their step limit.
    pub max_steps: u32,
    /// Mean return.
    pub mean: f64,
    /// Worst return.
    pub min: f64,
}

/// Runs `episodes` greedy episodes of at most `max_steps` with starts from `rng`.
pub fn evaluate<const H: usize, R: Rng>(
    net: &Mlp<H>,
    episodes: usize,
    max_steps: u32,
    rng: &mut R,
) -> EvalResult {
    let mut env = CartPole::new(Params::default(), max_steps);
    let (mut sum, mut min) = (0.0, f64::INFINITY);
    for _ in 0..episodes {
        let mut obs = env.reset(rng);
        let mut ret = 0.0;
        loop {
            let t = env.step(net.greedy_action(&obs));
            ret += f64::from(t.reward);
            obs = t.obs;
            if t.terminated || t.truncated {
                break;
            }
        }
        sum += ret;
        min = f64::min(min, ret);
    }
    EvalResult {
        episodes,
        max_steps,
        mean: sum / episodes as f64,
        min,
    }
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
    match cfg.width {
        16 => train_width::<16>(cfg, seed, kernel, on_episode),
        32 => train_width::<32>(cfg, seed, kernel, on_episode),
        64 => train_width::<64>(cfg, seed, kernel, on_episode),
        128 => train_width::<128>(cfg, seed, kernel, on_episode),
        256 => train_width::<256>(cfg, seed, kernel, on_episode),
        w => unreachable!("validate() admits only supported widths, got {w}"),
    }
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
    let mut env = CartPole::new(Params::default(), cfg.max_steps);
    let learning_starts = cfg.learning_starts.max(cfg.batch_size);
    let gamma = cfg.gamma;

    let mut records = Vec::with_capacity(cfg.episodes);
    let mut evals = Vec::new();
    let mut best: Option<(f64, usize, Box<Mlp<H>>)> = None;
    let mut env_steps: u64 = 0;
    let mut rewards: Vec<f32> = Vec::with_capacity(cfg.max_steps as usize);

    for ep in 0..cfg.episodes {
        let mut obs = env.reset(&mut env_rng);
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
            let tr = env.step(action);
            buf.push(obs, action, tr.reward, tr.obs, tr.terminated);
            rewards.push(tr.reward);
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
            obs = tr.obs;
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
            ret: rewards.iter().map(|&r| f64::from(r)).sum(),
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
                &mut rng(seed, Stream::Eval),
            );
            let perfect = res.min >= f64::from(cfg.eval_max_steps);
            if best.as_ref().is_none_or(|(m, _, _)| res.mean > *m) {
                best = Some((res.mean, ep + 1, learner.online.clone()));
            }
            evals.push((ep + 1, res));
            if perfect && cfg.stop_when_perfect {
                break;
            }
        }
    }
    let wall_s = start.elapsed().as_secs_f64();
    let last = records.len();
    let (policy_episode, policy) = match best {
        Some((_, ep, net)) => (ep, net),
        None => (last, learner.online.clone()),
    };
    let final_eval = evaluate(
        &policy,
        cfg.final_eval_episodes,
        cfg.eval_max_steps,
        &mut rng(seed, Stream::Final),
    );
    Ok(RunResult {
        episodes: records,
        policy: Weights::from_mlp(&policy),
        policy_episode,
        evals,
        final_eval,
        env_steps,
        grad_steps: learner.steps,
        wall_s,
        kernel,
    })
}

/// First episode (1-based) whose trailing 100-episode mean return reaches `threshold`.
pub fn solved_episode(returns: &[f64], threshold: f64) -> Option<usize> {
    trailing_means(returns, 100)
        .position(|m| m >= threshold)
        .map(|i| i + 100)
}

/// Means of every full window of `w` consecutive values, in order.
pub fn trailing_means(values: &[f64], w: usize) -> impl Iterator<Item = f64> + '_ {
    values
        .windows(w)
        .map(move |win| win.iter().sum::<f64>() / w as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ddqn_and_dqn_targets_differ_where_they_should() {
        // Online net prefers action 0, target net rates action 1 higher.
        let qt = [[1.0, 3.0], [1.0, 3.0]];
        let qo = [[5.0, 2.0], [5.0, 2.0]];
        let r = [1.0, 1.0];
        let term = [false, true];
        let mut y = [0.0; 2];
        td_targets(Algo::Ddqn, 0.5, &r, &term, &qt, &qo, &mut y);
        assert_eq!(y, [1.0 + 0.5 * 1.0, 1.0]);
        td_targets(Algo::Dqn, 0.5, &r, &term, &qt, &qo, &mut y);
        assert_eq!(y, [1.0 + 0.5 * 3.0, 1.0]);
    }

    #[test]
    fn epsilon_follows_the_papers_schedule() {
        let c = Config::paper();
        assert_eq!(epsilon(&c, 0.0), 0.9);
        assert!((epsilon(&c, 200.0) - (0.01 + 0.89 * (-1.0f64).exp())).abs() < 1e-15);
        assert!((epsilon(&c, 200.0) - 0.337_413).abs() < 1e-6);
        assert!((epsilon(&c, 1e5) - 0.01).abs() < 1e-15);
    }

    #[test]
    fn replay_buffer_wraps_around_oldest_first() {
        let mut b = ReplayBuffer::new(3);
        for i in 0..5 {
            b.push(
                [i as f32; 4],
                Action::from_index(i % 2),
                i as f32,
                [0.0; 4],
                i == 4,
            );
        }
        assert_eq!(b.len(), 3);
        let rewards: Vec<f32> = (0..3).map(|i| b.get(i).2).collect();
        assert_eq!(
            rewards,
            [3.0, 4.0, 2.0],
            "slots 0 and 1 overwritten by the 4th and 5th"
        );
        assert!(b.get(1).4 && !b.get(0).4);
        let mut idx = Vec::new();
        let mut r = rng(1, Stream::Sample);
        for _ in 0..100 {
            b.sample_indices(&mut r, 3, &mut idx);
            let mut s = idx.clone();
            s.sort();
            assert_eq!(s, [0, 1, 2], "without replacement");
        }
    }

    #[test]
    fn solved_episode_is_the_first_full_window_reaching_the_threshold() {
        let mut r = vec![100.0; 150];
        r.extend(vec![200.0; 100]);
        // Window ending at episode e has (e - 150) returns of 200: mean 100 + (e - 150).
        assert_eq!(solved_episode(&r, 195.0), Some(245));
        assert_eq!(solved_episode(&r[..99], 0.0), None);
    }

    #[test]
    fn cached_target_q_values_equal_a_fresh_forward_pass() {
        let kernel = Kernel::detect();
        for target_update in [TargetUpdate::Hard, TargetUpdate::Soft] {
            // A small buffer, so slots are overwritten many times over.
            let cfg = Config {
                buffer_size: 48,
                target_update,
                ..Config::paper()
            };
            let mut learner = Learner::<64>::new(&cfg, kernel, 7);
            let mut buf = ReplayBuffer::new(cfg.buffer_size);
            let (mut r, mut sample) = (rng(7, Stream::Env), rng(7, Stream::Sample));
            let mut state = || [0; OBS_DIM].map(|_| (unit_f64(&mut r) as f32 - 0.5) * 4.0);
            let mut fresh = Scratch::<64>::new(cfg.batch_size);
            let (mut rows, mut misses) = (0, 0);
            for step in 0..400 {
                let (s, s2) = (state(), state());
                buf.push(s, Action::from_index(step % 2), 1.0, s2, step % 7 == 0);
                if buf.len() < cfg.batch_size {
                    continue;
                }
                let target = learner.target.clone();
                learner.update(&cfg, &buf, &mut sample);
                nn::forward_batch(
                    kernel,
                    &target,
                    &Packed::new(&target),
                    &learner.x_next,
                    &mut fresh,
                );
                let bits =
                    |q: &[[f32; 2]]| q.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&learner.q_target),
                    bits(&fresh.q),
                    "{target_update:?} step {step}"
                );
                rows += cfg.batch_size;
                misses += learner.miss_rows.len();
                if step % 100 == 99 {
                    learner.sync_target();
                }
            }
            match target_update {
                // Most rows come from the cache, but new and overwritten slots do not.
                TargetUpdate::Hard => {
                    assert!(misses > 0 && misses * 4 < rows, "{misses} of {rows}")
                }
                // The target changes every step: nothing can be reused.
                TargetUpdate::Soft => assert_eq!(misses, rows),
            }
        }
    }

    fn small() -> Config {
        Config {
            episodes: 40,
            ..Config::paper()
        }
    }

    #[test]
    fn the_same_seed_gives_bit_identical_weights_and_metrics() {
        let run = |seed| train(&small(), seed, &mut |_| {}).unwrap();
        let (a, b, c) = (run(3), run(3), run(4));
        let bits = |r: &RunResult| {
            r.policy
                .tensors
                .iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&a), bits(&b));
        let strip = |r: &RunResult| {
            r.episodes
                .iter()
                .map(|e| EpisodeRecord {
                    wall_s: 0.0,
                    ..e.clone()
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(strip(&a), strip(&b));
        assert_eq!(a.final_eval, b.final_eval);
        assert_ne!(bits(&a), bits(&c));
        assert!(a.grad_steps > 0 && a.env_steps > 100);
    }

    #[test]
    fn a_diverging_run_stops_with_the_episode_and_step() {
        let cfg = Config {
            lr: 1e30,
            grad_clip: 0.0,
            episodes: 50,
            ..Config::paper()
        };
        let e = train(&cfg, 0, &mut |_| {})
            .err()
            .expect("lr 1e30 must blow up");
        let msg = e.to_string();
        assert!(
            msg.contains("non-finite loss") && msg.contains("at episode"),
            "{msg}"
        );
    }
}
