//! One training episode: the firmware's controller period, deciding through an epsilon-greedy
//! policy over the learner's online network ([`Explorer`]), closed around a world of the
//! training domain by the twin, as every evaluation and every board runs it. The policy is
//! trained on exactly the readings the controller accepts, advanced over the dead time as the
//! controller advances them.
//!
//! A transition reaches the replay buffer when the controller hands the policy the next
//! reading: the policy stores `(s, a, r, s')`, learns from the buffer if training is due, and
//! only then decides on `s'`, so each action is taken with the weights that learned from
//! every transition before it (CleanRL's order). A period whose reading the controller
//! rejects coasts: no action of the policy acted, so the transition into it is dropped.

use anyhow::Result;
use firmware::cartpole::{Action, unit_f64};
use firmware::controller::{Command, Policy};
use firmware::network::{N_ACTIONS, OBS_DIM, argmax};
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use twin::{Episode, Scenario};

use super::{EpisodeRecord, Learner, ReplayBuffer, Reward, epsilon, learn};
use crate::config::{Config, TargetUpdate, Unit};

/// The trainer's policy: epsilon-greedy over the learner's online network, learning from
/// each transition as the controller hands it the next reading.
pub(super) struct Explorer<'a, const H: usize> {
    pub learner: &'a mut Learner<H>,
    buf: &'a mut ReplayBuffer,
    cfg: &'a Config,
    explore: &'a mut Pcg64Mcg,
    sample: &'a mut Pcg64Mcg,
    /// Exploration rate of the next decision.
    eps: f64,
    /// The reading the policy last decided on and the action it took.
    seen: Option<([f32; OBS_DIM], Action)>,
    /// What followed the last decision, until its transition is stored.
    outcome: Option<Outcome>,
    /// Set before the episode's last reading: learn from it, decide nothing.
    finishing: bool,
    /// The episode, for a non-finite loss's message.
    episode: usize,
    stats: Stats,
    error: Option<anyhow::Error>,
}

/// The step after a decision, as the world took it.
#[derive(Clone, Copy)]
struct Outcome {
    /// The learning reward.
    reward: f32,
    terminated: bool,
    /// The run's environment steps after it.
    env_steps: u64,
    /// Its number within the episode, from 1.
    step: usize,
}

/// What one episode's decisions and updates added up to.
#[derive(Default)]
struct Stats {
    loss_sum: f64,
    losses: u32,
    maxq_sum: f64,
    /// The online net's max-Q of the last reading, before any end-of-episode training.
    final_q: Option<f64>,
}

impl<const H: usize> Policy for Explorer<'_, H> {
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> [f32; N_ACTIONS] {
        self.complete(Some(obs));
        let q = self.learner.q_values(obs);
        let best = f64::from(q[0].max(q[1]));
        if self.finishing || self.error.is_some() {
            self.stats.final_q = Some(best);
            return q;
        }
        self.stats.maxq_sum += best;
        let action = if unit_f64(self.explore) < self.eps {
            Action::from_index((self.explore.next_u32() & 1) as usize)
        } else {
            argmax(&q)
        };
        self.seen = Some((*obs, action));
        match (action == argmax(&q), action) {
            (true, _) => q,
            // Scores that make the controller take the explored action.
            (false, Action::Right) => [0.0, 1.0],
            (false, Action::Left) => [1.0, 0.0],
        }
    }
}

impl<const H: usize> Explorer<'_, H> {
    /// Ends the step of the last outcome: stores its transition into `next` (the reading the
    /// controller accepted; `None` if it rejected it), learns if training is due, and copies
    /// the target net if that is due.
    fn complete(&mut self, next: Option<&[f32; OBS_DIM]>) {
        let Some(Outcome {
            reward,
            terminated,
            env_steps,
            step,
        }) = self.outcome.take()
        else {
            return;
        };
        let cfg = self.cfg;
        // A terminal transition's next state is never bootstrapped from: when the controller
        // rejected the last reading (a cart past the end stop), the state before stands in.
        let next = next
            .copied()
            .or(self.seen.filter(|_| terminated).map(|(s, _)| s));
        if let (Some((s, a)), Some(next)) = (self.seen.take(), next) {
            self.buf.push(s, a, reward, next, terminated);
            if cfg.train_unit == Unit::Steps
                && self.buf.len() >= cfg.learning_starts.max(cfg.batch_size)
                && env_steps.is_multiple_of(cfg.train_every as u64)
                && self.error.is_none()
            {
                let at = (self.episode, Some(step), env_steps);
                match learn(self.learner, cfg, self.buf, self.sample, at) {
                    Ok((sum, n)) => {
                        self.stats.loss_sum += sum;
                        self.stats.losses += n;
                    }
                    Err(e) => self.error = Some(e),
                }
            }
        }
        self.seen = None;
        if cfg.target_update == TargetUpdate::Hard
            && cfg.target_period_unit == Unit::Steps
            && env_steps.is_multiple_of(cfg.target_period as u64)
        {
            self.learner.sync_target();
        }
    }
}

/// The random streams training episodes draw from (see `Stream`).
pub(super) struct Streams {
    pub env: Pcg64Mcg,
    pub explore: Pcg64Mcg,
    pub sample: Pcg64Mcg,
    pub noise: Pcg64Mcg,
    pub pushes: Pcg64Mcg,
}

/// The run's state one training episode works on.
pub(super) struct Run<'a, const H: usize> {
    pub cfg: &'a Config,
    pub learner: &'a mut Learner<H>,
    pub buf: &'a mut ReplayBuffer,
    pub reward: &'a Reward,
    pub streams: &'a mut Streams,
    pub env_steps: &'a mut u64,
    pub rewards: &'a mut Vec<f32>,
}

impl<const H: usize> Run<'_, H> {
    /// Episode `ep` (0-based) in `scenario`: its record (the wall time left for the caller),
    /// and whether the step budget is spent.
    pub fn episode(&mut self, ep: usize, scenario: &Scenario) -> Result<(EpisodeRecord, bool)> {
        let cfg = self.cfg;
        self.rewards.clear();
        let Streams {
            env,
            explore,
            sample,
            noise,
            pushes,
        } = &mut *self.streams;
        let explorer = Explorer {
            learner: &mut *self.learner,
            buf: &mut *self.buf,
            cfg,
            explore,
            sample,
            eps: 0.0,
            seen: None,
            outcome: None,
            finishing: false,
            episode: ep,
            stats: Stats::default(),
            error: None,
        };
        let streams = (&mut *noise, &mut *pushes);
        let mut episode = Episode::start(
            explorer,
            scenario,
            cfg.max_steps,
            env,
            streams,
            cfg.compensate,
        );
        let (terminated, spent, eps) = loop {
            let eps = epsilon(
                cfg,
                match cfg.eps_unit {
                    Unit::Steps => *self.env_steps as f64,
                    Unit::Episodes => ep as f64,
                },
            );
            episode.policy_mut().eps = eps;
            if episode.decide() == Command::Coast {
                episode.policy_mut().complete(None);
            }
            let tr = episode.apply();
            *self.env_steps += 1;
            let r = self
                .reward
                .of(&scenario.params, &episode.world().state(), tr.terminated);
            self.rewards.push(r);
            episode.policy_mut().outcome = Some(Outcome {
                reward: r,
                terminated: tr.terminated,
                env_steps: *self.env_steps,
                step: self.rewards.len(),
            });
            let spent = cfg.max_env_steps > 0 && *self.env_steps >= cfg.max_env_steps;
            if tr.terminated || tr.truncated || spent {
                episode.policy_mut().finishing = true;
                if episode.decide() == Command::Coast {
                    episode.policy_mut().complete(None);
                }
                break (tr.terminated, spent, eps);
            }
        };
        let p = episode.policy_mut();
        if let Some(e) = p.error.take() {
            return Err(e);
        }
        let stats = std::mem::take(&mut p.stats);
        drop(episode);
        let rec = self.end_of_episode(ep, stats, terminated, eps)?;
        Ok((rec, spent))
    }

    /// The episode's end: training and a target copy if due per episode, and its record.
    fn end_of_episode(
        &mut self,
        ep: usize,
        stats: Stats,
        terminated: bool,
        eps: f64,
    ) -> Result<EpisodeRecord> {
        let cfg = self.cfg;
        let (mut loss_sum, mut losses) = (stats.loss_sum, stats.losses);
        if cfg.train_unit == Unit::Episodes
            && self.buf.len() >= cfg.learning_starts.max(cfg.batch_size)
            && (ep + 1).is_multiple_of(cfg.train_every)
        {
            let at = (ep, None, *self.env_steps);
            let (sum, n) = learn(self.learner, cfg, self.buf, &mut self.streams.sample, at)?;
            loss_sum += sum;
            losses += n;
        }
        if cfg.target_update == TargetUpdate::Hard
            && cfg.target_period_unit == Unit::Episodes
            && (ep + 1).is_multiple_of(cfg.target_period)
        {
            self.learner.sync_target();
        }
        // A cut episode's return goes on past the cut; without its tail every state near
        // the end would seem overestimated (by up to gamma^k / (1 - gamma) per step's
        // reward). The online net's own estimate stands in for it, so the gap measures how
        // far Q disagrees with what followed, not where the episode was cut.
        let mut g = if terminated {
            0.0
        } else {
            stats.final_q.unwrap_or(0.0)
        };
        let len = self.rewards.len();
        let mut disc_sum = 0.0f64;
        for r in self.rewards.iter().rev() {
            g = f64::from(*r) + cfg.gamma * g;
            disc_sum += g;
        }
        Ok(EpisodeRecord {
            episode: ep + 1,
            ret: len as f64,
            learning_return: self.rewards.iter().map(|&r| f64::from(r)).sum(),
            length: len as u32,
            epsilon: eps,
            mean_loss: (losses > 0).then(|| loss_sum / f64::from(losses)),
            mean_max_q: stats.maxq_sum / len as f64,
            mean_discounted_return: disc_sum / len as f64,
            env_steps: *self.env_steps,
            wall_s: 0.0,
        })
    }
}
