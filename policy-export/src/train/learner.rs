//! One gradient step's state and work: the online and target networks, Adam's moments, the
//! TD targets of a sampled batch, and the target network's cached Q-values.

use firmware::network::{Mlp, N_ACTIONS, OBS_DIM, argmax};
use host_common::wide::WideMlp;
use rand_core::Rng;
use rand_distr::{Distribution, StandardNormal};

use super::replay::ReplayBuffer;
use super::{Stream, rng};
use crate::config::{Algo, Config, Init, TargetUpdate};
use crate::nn::{self, AdamParams, Kernel, Packed, Scratch};

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
    /// The network being trained; acting uses it. Private, as `target` is: each is
    /// repacked whenever it changes, and a caller's write would leave the packing stale.
    online: Box<Mlp<H>>,
    /// The slowly-following network that scores TD targets.
    target: Box<Mlp<H>>,
    online_packed: Box<Packed<H>>,
    target_packed: Box<Packed<H>>,
    /// The online net laid out for acting: the firmware's forward pass, bit for bit.
    acting: Box<WideMlp<H>>,
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
            acting: WideMlp::with_kernel(&online, kernel).unwrap_or_else(|| WideMlp::new(&online)),
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
        self.online_packed.pack(&self.online);
        self.acting.refresh(&self.online);
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

    /// The online net's Q-values of `obs`, bit for bit those of `firmware`'s forward pass.
    pub fn q_values(&self, obs: &[f32; OBS_DIM]) -> [f32; N_ACTIONS] {
        self.acting.forward(obs)
    }

    /// The network being trained.
    pub fn online(&self) -> &Mlp<H> {
        &self.online
    }

    /// A copy of the network being trained, boxed like the learner's own: at width 256 a
    /// network is 270 KB, a large share of a worker thread's stack.
    pub fn snapshot(&self) -> Box<Mlp<H>> {
        self.online.clone()
    }

    /// Gradient steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
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
    for (t, shape) in net.tensors_mut().into_iter().zip(Mlp::<H>::SHAPES) {
        let Some((fan_out, fan_in)) = shape.matrix() else {
            t.fill(0.01);
            continue;
        };
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::unit_f64;
    use firmware::cartpole::Action;

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
}
