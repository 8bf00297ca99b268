//! One gradient step's state and work: the online and target networks, Adam's moments, the
//! TD targets of a sampled batch, and the target network's cached Q-values.
//!
//! A step is the definition `reference` writes in plain loops: the batch's TD targets, the
//! gradient of its mean loss summed over its rows in order, clipped, one Adam step. The
//! rows' own work (three forward passes, the backward pass to the hidden units) runs in two
//! parts of the batch and the weight gradients' sums in two shares of the parameters, each
//! over every row, without changing a bit: the split once fed a second core, which the
//! periodic evaluations now use instead (`super::periodic`). The target net's Q-values of a
//! replay slot are cached while neither changes. `tests` hold this learner to `reference`
//! bit for bit.

use firmware::network::{Mlp, OBS_DIM, argmax};
use rand_core::Rng;
use rand_distr::{Distribution, StandardNormal};

use super::replay::ReplayBuffer;
use super::{Stream, rng};
use crate::config::{Algo, Config, Init, TargetUpdate};
use crate::nn::{self, AdamParams, Kernel, Ops, Packed, Part};

mod batch;
#[cfg(test)]
pub(crate) mod reference;

use batch::{Batch, CachedQ, Nets};

/// TD targets for a batch: `r + gamma * (1 - terminated) * Q_target(s', a')`, where `a'` is
/// chosen by the online net (Double DQN) or by the target net itself (DQN). Truncated
/// episodes keep their bootstrap: only termination zeroes it.
pub fn td_targets<const A: usize>(
    algo: Algo,
    gamma: f32,
    rewards: &[f32],
    terminated: &[bool],
    q_target_next: &[[f32; A]],
    q_online_next: &[[f32; A]],
    out: &mut [f32],
) {
    for (b, y) in out.iter_mut().enumerate() {
        let qt = q_target_next[b];
        let next = match algo {
            Algo::Ddqn => qt[argmax(&q_online_next[b])],
            Algo::Dqn => qt[argmax(&qt)],
        };
        let bootstrap = if terminated[b] { 0.0 } else { gamma * next };
        *y = rewards[b] + bootstrap;
    }
}

/// One gradient step's state: the two networks, Adam's moments and the two halves' buffers.
pub struct Learner<const H: usize, const A: usize> {
    /// The network being trained; acting uses it. Private, as `target` is: each is
    /// repacked whenever it changes, and a caller's write would leave the packing stale.
    online: Box<Mlp<H, A>>,
    /// The slowly-following network that scores TD targets.
    target: Box<Mlp<H, A>>,
    online_packed: Box<Packed<H>>,
    target_packed: Box<Packed<H>>,
    m: Box<Mlp<H, A>>,
    v: Box<Mlp<H, A>>,
    grad: Box<Mlp<H, A>>,
    steps: u64,
    ops: &'static Ops<H, A>,
    adam: AdamParams,
    idx: Vec<usize>,
    batch: Batch<H, A>,
    /// Per replay slot, its target Q-values, where the target net is copied now and then
    /// (`TargetUpdate::Hard`): it then stays fixed for thousands of updates while each slot
    /// is drawn many times, so scoring a slot once per target version saves most of the
    /// target forward passes. A row's Q-values do not depend on the rows batched with it, so
    /// the result is the same bit for bit. Empty with soft updates, which change the target
    /// every step.
    target_q: Vec<CachedQ<A>>,
    /// Bumped whenever the target net changes; 0 marks a never-filled cache entry.
    target_version: u64,
}

impl<const H: usize, const A: usize> Learner<H, A> {
    /// Fresh networks initialised per `cfg.init` from the run's init stream, learning with
    /// `kernel`'s build of the arithmetic.
    pub fn new(cfg: &Config, kernel: Kernel, seed: u64) -> Self {
        let mut online = nn::boxed_zero::<H, A>();
        init_weights(&mut online, cfg.init, &mut rng(seed, Stream::Init));
        let cached = cfg.target_update == TargetUpdate::Hard;
        Learner {
            target: online.clone(),
            online_packed: Packed::new(&online),
            target_packed: Packed::new(&online),
            online,
            m: nn::boxed_zero(),
            v: nn::boxed_zero(),
            grad: nn::boxed_zero(),
            steps: 0,
            ops: Ops::new(kernel),
            adam: AdamParams {
                lr: cfg.lr,
                beta1: cfg.adam_beta1,
                beta2: cfg.adam_beta2,
                eps: cfg.adam_eps,
            },
            idx: Vec::with_capacity(cfg.batch_size),
            batch: Batch::new(cfg.batch_size),
            target_q: vec![CachedQ::EMPTY; if cached { cfg.buffer_size } else { 0 }],
            target_version: 1,
        }
    }

    /// Samples a minibatch and takes one clipped Adam step on the TD loss; returns the loss.
    pub fn update<R: Rng>(&mut self, cfg: &Config, buf: &ReplayBuffer, rng: &mut R) -> f32 {
        buf.sample_indices(rng, cfg.batch_size, &mut self.idx);
        let n = self.idx.len();
        let (cache, version) = (&mut self.target_q, self.target_version);
        self.batch.gather(buf, &self.idx, cache, version);
        let nets = Nets {
            ops: self.ops,
            online: &self.online,
            online_packed: &self.online_packed,
            target: &self.target,
            target_packed: &self.target_packed,
            scale: 1.0 / n as f32,
        };
        let [r0, r1] = self.batch.halves();
        r0.work(cfg, &nets);
        r1.work(cfg, &nets);
        self.batch.cache(&self.idx, cache, version, buf);
        let [s0, s1] = nn::shares(&mut self.grad);
        let g = self.batch.grads();
        self.ops.share(g, s0);
        self.ops.share(g, s1);
        if cfg.grad_clip > 0.0 {
            nn::clip_grad_norm(&mut self.grad, cfg.grad_clip as f32);
        }
        self.steps += 1;
        let step = self.adam.at(self.steps);
        let mut parts = parameters(&mut self.online, &self.grad, &mut self.m, &mut self.v);
        self.ops.adam(&step, &mut parts);
        self.online_packed.pack(&self.online);
        if cfg.target_update == TargetUpdate::Soft {
            let tau = cfg.tau as f32;
            nn::soft_update(&mut self.target, &self.online, tau);
            // Elementwise, so the packing follows by the same formula: no transposing.
            self.target_packed.soft_update(&self.online_packed, tau);
            self.target_version += 1;
        }
        (self.batch.loss() / n as f64) as f32
    }

    /// The online net's Q-values of `obs`, bit for bit those of `firmware`'s forward pass.
    pub fn q_values(&self, obs: &[f32; OBS_DIM]) -> [f32; A] {
        self.ops.q_values(&self.online, obs)
    }

    /// The network being trained.
    pub fn online(&self) -> &Mlp<H, A> {
        &self.online
    }

    /// A copy of the network being trained, boxed like the learner's own: at width 256 a
    /// network is 270 KB, a large share of a worker thread's stack.
    pub fn snapshot(&self) -> Box<Mlp<H, A>> {
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

/// A network's parameters, each tensor beside its gradient and its two moments.
fn parameters<'a, const H: usize, const A: usize>(
    p: &'a mut Mlp<H, A>,
    g: &'a Mlp<H, A>,
    m: &'a mut Mlp<H, A>,
    v: &'a mut Mlp<H, A>,
) -> Vec<Part<'a>> {
    p.tensors_mut()
        .into_iter()
        .zip(g.tensors())
        .zip(m.tensors_mut().into_iter().zip(v.tensors_mut()))
        .map(|((p, g), (m, v))| (p, g, m, v))
        .collect()
}

/// Whether a run may have a second core for its periodic evaluations: the thread pool has
/// one (the machine's cores, or `RAYON_NUM_THREADS`, `train --threads`), and the run is not
/// one of several the pool runs side by side (seeds, a study), each of which keeps a core
/// busy.
pub(super) fn spare_core() -> bool {
    rayon::current_thread_index().is_none() && rayon::current_num_threads() >= 2
}

/// Xavier-normal or N(0, 0.1^2) weights, biases 0.01, drawn tensor by tensor in PyTorch's
/// parameter order.
pub fn init_weights<const H: usize, const A: usize, R: Rng>(
    net: &mut Mlp<H, A>,
    init: Init,
    rng: &mut R,
) {
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
mod tests;
