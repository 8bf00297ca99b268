//! A sampled minibatch and the work of each of its rows: the three forward passes (the
//! target and online nets on the next state, the online net on the state), the TD target,
//! the loss's gradient and the errors at the hidden units. A row's work does not depend on
//! the rows beside it, so the batch is worked in two parts on two cores with the same bits
//! as in one; the sums over rows that make the weight gradients come after, over the whole
//! batch in order (`crate::nn::Share`).

use firmware::network::{Mlp, OBS_DIM};

use super::td_targets;
use crate::config::{Algo, Config};
use crate::nn::{Activations, BatchGrads, Ops, Packed, RowGrads};
use crate::train::ReplayBuffer;

/// `Q_target(s')` of one replay slot, valid while the target net and the slot are the ones
/// it was computed for.
#[derive(Clone, Copy)]
pub(super) struct CachedQ<const A: usize> {
    q: [f32; A],
    target_version: u64,
    write_id: u64,
}

impl<const A: usize> CachedQ<A> {
    /// A never-filled entry: target version 0 is never current.
    pub const EMPTY: CachedQ<A> = CachedQ {
        q: [0.0; A],
        target_version: 0,
        write_id: 0,
    };
}

/// The networks the rows read, and the loss's scale (one over the batch's size).
pub(super) struct Nets<'a, const H: usize, const A: usize> {
    pub ops: &'static Ops<H, A>,
    pub online: &'a Mlp<H, A>,
    pub online_packed: &'a Packed<H>,
    pub target: &'a Mlp<H, A>,
    pub target_packed: &'a Packed<H>,
    pub scale: f32,
}

/// Every per-row array of a batch, allocated once for the largest batch.
pub(super) struct Batch<const H: usize, const A: usize> {
    x: Vec<[f32; OBS_DIM]>,
    x_next: Vec<[f32; OBS_DIM]>,
    actions: Vec<u8>,
    rewards: Vec<f32>,
    terminated: Vec<bool>,
    /// Whether the row's target Q-values must be computed (the cache had none).
    miss: Vec<bool>,
    q_target: Vec<[f32; A]>,
    q_online: Vec<[f32; A]>,
    targets: Vec<f32>,
    a1: Vec<[f32; H]>,
    a2: Vec<[f32; H]>,
    q: Vec<[f32; A]>,
    dq: Vec<[f32; A]>,
    d2: Vec<[f32; H]>,
    d1: Vec<[f32; H]>,
    loss: Vec<f32>,
    /// Each part's room for the next states' forward passes.
    spare: [Spare<H, A>; 2],
}

/// One part's buffers for the forward passes whose activations are not kept.
struct Spare<const H: usize, const A: usize> {
    a1: Vec<[f32; H]>,
    a2: Vec<[f32; H]>,
    q: Vec<[f32; A]>,
    x_miss: Vec<[f32; OBS_DIM]>,
}

impl<const H: usize, const A: usize> Spare<H, A> {
    fn new(rows: usize) -> Self {
        Spare {
            a1: vec![[0.0; H]; rows],
            a2: vec![[0.0; H]; rows],
            q: vec![[0.0; A]; rows],
            x_miss: Vec::with_capacity(rows),
        }
    }
}

/// One part's rows of a [`Batch`].
pub(super) struct Rows<'a, const H: usize, const A: usize> {
    x: &'a [[f32; OBS_DIM]],
    x_next: &'a [[f32; OBS_DIM]],
    actions: &'a [u8],
    rewards: &'a [f32],
    terminated: &'a [bool],
    miss: &'a [bool],
    q_target: &'a mut [[f32; A]],
    q_online: &'a mut [[f32; A]],
    targets: &'a mut [f32],
    a1: &'a mut [[f32; H]],
    a2: &'a mut [[f32; H]],
    q: &'a mut [[f32; A]],
    dq: &'a mut [[f32; A]],
    d2: &'a mut [[f32; H]],
    d1: &'a mut [[f32; H]],
    loss: &'a mut [f32],
    spare: &'a mut Spare<H, A>,
}

/// `v[..n]` as its rows `..k` and `k..n`.
fn parts<T>(v: &mut [T], n: usize, k: usize) -> (&mut [T], &mut [T]) {
    v[..n].split_at_mut(k)
}

impl<const H: usize, const A: usize> Batch<H, A> {
    /// Room for `rows` rows.
    pub fn new(rows: usize) -> Self {
        Batch {
            x: Vec::with_capacity(rows),
            x_next: Vec::with_capacity(rows),
            actions: Vec::with_capacity(rows),
            rewards: Vec::with_capacity(rows),
            terminated: Vec::with_capacity(rows),
            miss: Vec::with_capacity(rows),
            q_target: vec![[0.0; A]; rows],
            q_online: vec![[0.0; A]; rows],
            targets: vec![0.0; rows],
            a1: vec![[0.0; H]; rows],
            a2: vec![[0.0; H]; rows],
            q: vec![[0.0; A]; rows],
            dq: vec![[0.0; A]; rows],
            d2: vec![[0.0; H]; rows],
            d1: vec![[0.0; H]; rows],
            loss: vec![0.0; rows],
            spare: [Spare::new(rows.div_ceil(2)), Spare::new(rows.div_ceil(2))],
        }
    }

    /// Takes slots `idx` of `buf`, and the target Q-values `cache` holds for them at target
    /// version `version` (an empty cache holds none).
    pub fn gather(
        &mut self,
        buf: &ReplayBuffer,
        idx: &[usize],
        cache: &[CachedQ<A>],
        version: u64,
    ) {
        self.x.clear();
        self.x_next.clear();
        self.actions.clear();
        self.rewards.clear();
        self.terminated.clear();
        self.miss.clear();
        for (b, &i) in idx.iter().enumerate() {
            let (s, a, r, s2, t) = buf.get(i);
            self.x.push(s);
            self.actions.push(a);
            self.rewards.push(r);
            self.x_next.push(s2);
            self.terminated.push(t);
            let hit = cache
                .get(i)
                .filter(|c| c.target_version == version && c.write_id == buf.write_id(i));
            if let Some(c) = hit {
                self.q_target[b] = c.q;
            }
            self.miss.push(hit.is_none());
        }
    }

    /// The gathered rows in two parts: the first `ceil(n / 2)` and the rest.
    pub fn halves(&mut self) -> [Rows<'_, H, A>; 2] {
        let n = self.x.len();
        let k = n.div_ceil(2);
        let [s0, s1] = &mut self.spare;
        let (x, x_next) = (self.x.split_at(k), self.x_next.split_at(k));
        let (actions, rewards) = (self.actions.split_at(k), self.rewards.split_at(k));
        let (terminated, miss) = (self.terminated.split_at(k), self.miss.split_at(k));
        let (q_target, q_online) = (
            parts(&mut self.q_target, n, k),
            parts(&mut self.q_online, n, k),
        );
        let (targets, loss) = (parts(&mut self.targets, n, k), parts(&mut self.loss, n, k));
        let (a1, a2, q) = (
            parts(&mut self.a1, n, k),
            parts(&mut self.a2, n, k),
            parts(&mut self.q, n, k),
        );
        let (dq, d2, d1) = (
            parts(&mut self.dq, n, k),
            parts(&mut self.d2, n, k),
            parts(&mut self.d1, n, k),
        );
        [
            Rows {
                x: x.0,
                x_next: x_next.0,
                actions: actions.0,
                rewards: rewards.0,
                terminated: terminated.0,
                miss: miss.0,
                q_target: q_target.0,
                q_online: q_online.0,
                targets: targets.0,
                a1: a1.0,
                a2: a2.0,
                q: q.0,
                dq: dq.0,
                d2: d2.0,
                d1: d1.0,
                loss: loss.0,
                spare: s0,
            },
            Rows {
                x: x.1,
                x_next: x_next.1,
                actions: actions.1,
                rewards: rewards.1,
                terminated: terminated.1,
                miss: miss.1,
                q_target: q_target.1,
                q_online: q_online.1,
                targets: targets.1,
                a1: a1.1,
                a2: a2.1,
                q: q.1,
                dq: dq.1,
                d2: d2.1,
                d1: d1.1,
                loss: loss.1,
                spare: s1,
            },
        ]
    }

    /// What the weight gradients are summed from, every gathered row in order.
    pub fn grads(&self) -> BatchGrads<'_, H, A> {
        let n = self.x.len();
        BatchGrads {
            x: &self.x,
            a1: &self.a1[..n],
            a2: &self.a2[..n],
            dq: &self.dq[..n],
            d2: &self.d2[..n],
            d1: &self.d1[..n],
        }
    }

    /// The batch's summed loss, in f64, row after row.
    pub fn loss(&self) -> f64 {
        let n = self.x.len();
        self.loss[..n].iter().fold(0.0, |t, &l| t + f64::from(l))
    }

    /// Writes the target Q-values computed for the rows of slots `idx` into the cache
    /// (where there is one).
    pub fn cache(&self, idx: &[usize], cache: &mut [CachedQ<A>], version: u64, buf: &ReplayBuffer) {
        if cache.is_empty() {
            return;
        }
        for (b, &i) in idx.iter().enumerate().filter(|(b, _)| self.miss[*b]) {
            cache[i] = CachedQ {
                q: self.q_target[b],
                target_version: version,
                write_id: buf.write_id(i),
            };
        }
    }

    /// The rows' target Q-values and next states, and how many missed the cache, for tests.
    #[cfg(test)]
    pub fn targets_seen(&self) -> (&[[f32; A]], &[[f32; OBS_DIM]], usize) {
        let n = self.x.len();
        let misses = self.miss.iter().filter(|m| **m).count();
        (&self.q_target[..n], &self.x_next, misses)
    }
}

impl<const H: usize, const A: usize> Rows<'_, H, A> {
    /// The rows' work: the target net on the next states the cache lacks, the online net
    /// on the next states (Double DQN), the TD targets, the online net on the states, and
    /// the backward pass's row work.
    pub fn work(self, cfg: &Config, nets: &Nets<'_, H, A>) {
        let ops = nets.ops;
        let s = self.spare;
        s.x_miss.clear();
        s.x_miss.extend(
            self.x_next
                .iter()
                .zip(self.miss)
                .filter(|(_, m)| **m)
                .map(|(x, _)| *x),
        );
        if !s.x_miss.is_empty() {
            let out = Activations {
                a1: &mut s.a1,
                a2: &mut s.a2,
                q: &mut s.q,
            };
            ops.forward(nets.target, nets.target_packed, &s.x_miss, out);
            let missed = self.q_target.iter_mut().zip(self.miss).filter(|(_, m)| **m);
            for ((q, _), computed) in missed.zip(&s.q) {
                *q = *computed;
            }
        }
        if cfg.algo == Algo::Ddqn {
            let out = Activations {
                a1: &mut s.a1,
                a2: &mut s.a2,
                q: &mut *self.q_online,
            };
            ops.forward(nets.online, nets.online_packed, self.x_next, out);
        }
        let (rewards, terminated) = (self.rewards, self.terminated);
        let (qt, qo) = (&*self.q_target, &*self.q_online);
        td_targets(
            cfg.algo,
            cfg.gamma as f32,
            rewards,
            terminated,
            qt,
            qo,
            &mut *self.targets,
        );
        let out = Activations {
            a1: &mut *self.a1,
            a2: &mut *self.a2,
            q: &mut *self.q,
        };
        ops.forward(nets.online, nets.online_packed, self.x, out);
        let rows = RowGrads {
            a1: &*self.a1,
            a2: &*self.a2,
            q: &*self.q,
            dq: self.dq,
            d2: self.d2,
            d1: self.d1,
            loss: self.loss,
        };
        ops.rows(
            nets.online,
            self.actions,
            &*self.targets,
            (cfg.loss, nets.scale),
            rows,
        );
    }
}
