//! One half of a minibatch: its rows of the replay buffer, their TD targets, and the gradient
//! of their share of the loss.

use firmware::network::{Mlp, N_ACTIONS, OBS_DIM};

use super::td_targets;
use crate::config::{Algo, Config};
use crate::nn::{self, Kernel, Packed, Scratch};
use crate::train::ReplayBuffer;

/// `Q_target(s')` of one replay slot, valid while the target net and the slot are the ones
/// it was computed for.
#[derive(Clone, Copy, Default)]
pub(super) struct CachedQ {
    q: [f32; N_ACTIONS],
    target_version: u64,
    write_id: u64,
}

/// What both halves read: the networks, their packings, and the loss's scale (one over the
/// whole batch's size).
pub(super) struct Nets<'a, const H: usize> {
    pub kernel: Kernel,
    pub online: &'a Mlp<H>,
    pub online_packed: &'a Packed<H>,
    pub target: &'a Mlp<H>,
    pub target_packed: &'a Packed<H>,
    pub scale: f32,
}

/// One half's rows and everything computed from them.
pub(super) struct Half<const H: usize> {
    idx: Vec<usize>,
    x: Vec<[f32; OBS_DIM]>,
    x_next: Vec<[f32; OBS_DIM]>,
    actions: Vec<u8>,
    rewards: Vec<f32>,
    terminated: Vec<bool>,
    q_target: Vec<[f32; N_ACTIONS]>,
    q_online: Vec<[f32; N_ACTIONS]>,
    targets: Vec<f32>,
    /// Rows whose target Q-values were not cached, and their next states.
    miss_rows: Vec<usize>,
    x_miss: Vec<[f32; OBS_DIM]>,
    scratch: Scratch<H>,
    grad: Box<Mlp<H>>,
}

impl<const H: usize> Half<H> {
    /// Room for `rows` rows.
    pub fn new(rows: usize) -> Self {
        Half {
            idx: Vec::with_capacity(rows),
            x: Vec::with_capacity(rows),
            x_next: Vec::with_capacity(rows),
            actions: Vec::with_capacity(rows),
            rewards: Vec::with_capacity(rows),
            terminated: Vec::with_capacity(rows),
            q_target: vec![[0.0; N_ACTIONS]; rows],
            q_online: vec![[0.0; N_ACTIONS]; rows],
            targets: vec![0.0; rows],
            miss_rows: Vec::with_capacity(rows),
            x_miss: Vec::with_capacity(rows),
            scratch: Scratch::new(rows),
            grad: nn::boxed_zero(),
        }
    }

    /// Takes slots `idx` of `buf`, and the target Q-values the cache holds for them.
    fn gather(&mut self, buf: &ReplayBuffer, idx: &[usize], cache: &[CachedQ], version: u64) {
        self.idx.clear();
        self.idx.extend_from_slice(idx);
        self.x.clear();
        self.x_next.clear();
        self.actions.clear();
        self.rewards.clear();
        self.terminated.clear();
        self.miss_rows.clear();
        self.x_miss.clear();
        for (b, &i) in idx.iter().enumerate() {
            let (s, a, r, s2, t) = buf.get(i);
            self.x.push(s);
            self.actions.push(a);
            self.rewards.push(r);
            self.x_next.push(s2);
            self.terminated.push(t);
            match cache.get(i) {
                Some(c) if c.target_version == version && c.write_id == buf.write_id(i) => {
                    self.q_target[b] = c.q;
                }
                _ => {
                    self.miss_rows.push(b);
                    self.x_miss.push(s2);
                }
            }
        }
    }

    /// The half's rows (`idx` of `buf`, with the target Q-values `cache` holds for them at
    /// target version `version`), their TD targets, forward and backward pass: its gradient
    /// (kept) and its summed loss.
    pub fn learn(
        &mut self,
        cfg: &Config,
        nets: &Nets<'_, H>,
        buf: &ReplayBuffer,
        idx: &[usize],
        (cache, version): (&[CachedQ], u64),
    ) -> f64 {
        self.gather(buf, idx, cache, version);
        let (k, s) = (nets.kernel, &mut self.scratch);
        if !self.miss_rows.is_empty() {
            nn::forward_batch(k, nets.target, nets.target_packed, &self.x_miss, s);
            for (&b, q) in self.miss_rows.iter().zip(&s.q) {
                self.q_target[b] = *q;
            }
        }
        let n = self.x.len();
        if cfg.algo == Algo::Ddqn {
            nn::forward_batch(k, nets.online, nets.online_packed, &self.x_next, s);
            self.q_online[..n].copy_from_slice(&s.q[..n]);
        }
        td_targets(
            cfg.algo,
            cfg.gamma as f32,
            &self.rewards,
            &self.terminated,
            &self.q_target[..n],
            &self.q_online[..n],
            &mut self.targets[..n],
        );
        nn::forward_batch(k, nets.online, nets.online_packed, &self.x, s);
        let loss = (cfg.loss, nets.scale);
        let (x, a, y) = (&self.x, &self.actions, &self.targets[..n]);
        nn::backward(k, nets.online, x, a, y, loss, s, &mut self.grad)
    }

    /// Writes the target Q-values this half computed into the cache (where there is one).
    pub fn cache(&self, cache: &mut [CachedQ], version: u64, buf: &ReplayBuffer) {
        if cache.is_empty() {
            return;
        }
        for &b in &self.miss_rows {
            let i = self.idx[b];
            cache[i] = CachedQ {
                q: self.q_target[b],
                target_version: version,
                write_id: buf.write_id(i),
            };
        }
    }

    /// This half's gradient plus `other`'s, in place: the batch's gradient.
    pub fn add_gradient(&mut self, other: &Half<H>) -> &mut Mlp<H> {
        for (g, o) in self
            .grad
            .tensors_mut()
            .into_iter()
            .zip(other.grad.tensors())
        {
            for (g, o) in g.iter_mut().zip(o) {
                *g += o;
            }
        }
        &mut self.grad
    }

    /// The half's rows' target Q-values, for tests.
    #[cfg(test)]
    pub fn q_target(&self) -> &[[f32; N_ACTIONS]] {
        &self.q_target[..self.x.len()]
    }

    /// The half's rows' next states, for tests.
    #[cfg(test)]
    pub fn x_next(&self) -> &[[f32; OBS_DIM]] {
        &self.x_next
    }

    /// How many of the half's rows missed the cache.
    #[cfg(test)]
    pub fn misses(&self) -> usize {
        self.miss_rows.len()
    }
}
