//! The learner's definition in plain loops, for the fast [`Learner`](super::Learner) to be
//! held to bit for bit: every row of the batch through the networks one at a time (no
//! cache of target Q-values), the gradient of the whole batch at once (no parts, no shares,
//! no threads), clipped, one Adam step, the target followed. It shares with the fast learner
//! only the sampling of the batch and the TD targets' formula; its arithmetic is
//! `crate::nn::reference`'s, which shares no code with the kernels.

use firmware::network::{Mlp, OBS_DIM};
use rand_core::Rng;

use super::td_targets;
use crate::config::{Algo, Config, TargetUpdate};
use crate::nn::{AdamParams, reference};
use crate::train::ReplayBuffer;

/// The two networks and Adam's moments, each step computed from the definition.
pub(crate) struct ReferenceLearner<const H: usize, const A: usize> {
    pub online: Box<Mlp<H, A>>,
    pub target: Box<Mlp<H, A>>,
    m: Box<Mlp<H, A>>,
    v: Box<Mlp<H, A>>,
    steps: u64,
    adam: AdamParams,
}

impl<const H: usize, const A: usize> ReferenceLearner<H, A> {
    /// Starts from `online` (the target a copy of it), with fresh moments.
    pub fn new(cfg: &Config, online: &Mlp<H, A>) -> Self {
        ReferenceLearner {
            online: Box::new(online.clone()),
            target: Box::new(online.clone()),
            m: Box::new(Mlp::zeroed()),
            v: Box::new(Mlp::zeroed()),
            steps: 0,
            adam: AdamParams {
                lr: cfg.lr,
                beta1: cfg.adam_beta1,
                beta2: cfg.adam_beta2,
                eps: cfg.adam_eps,
            },
        }
    }

    /// One step on a batch sampled as the fast learner samples it; returns the mean loss.
    pub fn update<R: Rng>(&mut self, cfg: &Config, buf: &ReplayBuffer, rng: &mut R) -> f32 {
        let mut idx = Vec::new();
        buf.sample_indices(rng, cfg.batch_size, &mut idx);
        let rows: Vec<_> = idx.iter().map(|&i| buf.get(i)).collect();
        let x: Vec<[f32; OBS_DIM]> = rows.iter().map(|r| r.0).collect();
        let actions: Vec<u8> = rows.iter().map(|r| r.1).collect();
        let rewards: Vec<f32> = rows.iter().map(|r| r.2).collect();
        let terminated: Vec<bool> = rows.iter().map(|r| r.4).collect();
        let q = |net: &Mlp<H, A>| -> Vec<[f32; A]> {
            rows.iter()
                .map(|r| reference::forward(net, &r.3).2)
                .collect()
        };
        let q_target = q(&self.target);
        let q_online = match cfg.algo {
            Algo::Ddqn => q(&self.online),
            Algo::Dqn => q_target.clone(),
        };
        let mut y = vec![0.0; rows.len()];
        let (algo, gamma) = (cfg.algo, cfg.gamma as f32);
        td_targets(
            algo,
            gamma,
            &rewards,
            &terminated,
            &q_target,
            &q_online,
            &mut y,
        );
        let scale = 1.0 / rows.len() as f32;
        let (mut g, loss) = reference::backward(&self.online, &x, &actions, &y, (cfg.loss, scale));
        if cfg.grad_clip > 0.0 {
            clip(&mut g, cfg.grad_clip as f32);
        }
        self.steps += 1;
        let (p, m, v) = (&mut *self.online, &mut *self.m, &mut *self.v);
        reference::adam(&self.adam, self.steps, p, &g, m, v);
        if cfg.target_update == TargetUpdate::Soft {
            let tau = cfg.tau as f32;
            let target = self.target.tensors_mut();
            for (t, o) in target.into_iter().zip(self.online.tensors()) {
                for (t, o) in t.iter_mut().zip(o) {
                    *t = tau * o + (1.0 - tau) * *t;
                }
            }
        }
        (loss / rows.len() as f64) as f32
    }

    /// The hard target update.
    pub fn sync_target(&mut self) {
        self.target.clone_from(&self.online);
    }
}

/// PyTorch's `clip_grad_norm_`: scaled by `max / (norm + 1e-6)` where the norm exceeds
/// `max`, the norm taken in the definition's order.
fn clip<const H: usize, const A: usize>(g: &mut Mlp<H, A>, max: f32) {
    let norm = reference::sum_of_squares(g).sqrt() as f32;
    if norm > max {
        let scale = max / (norm + 1e-6);
        for t in g.tensors_mut() {
            t.iter_mut().for_each(|v| *v *= scale);
        }
    }
}
