//! Double DQN, top to bottom: the whole training loop of one run in CleanRL's order.
//!
//! Every period of every episode: the controller senses the world (the board's reading,
//! sanitised and advanced over the dead time), the learner chooses epsilon-greedily on it,
//! the controller acts with that choice, the world steps, the reward is scored, the next
//! reading is sensed, the transition `(s, a, r, s', terminated)` is stored, and, when due,
//! the learner takes its gradient steps and the target network is copied. The learner is
//! never the controller's policy: it only answers the controller's one question, "which
//! action on this reading?" ([`twin::Episode::act_with`]), so the periods it trains on are
//! the ones every evaluation and every board runs.
//!
//! A period whose reading the controller rejects coasts without asking the learner, so no
//! transition starts there, and the transition into it is dropped unless it terminated (a
//! terminal transition is never bootstrapped from, so the state before stands in for the
//! missing reading).

use std::time::Instant;

use anyhow::{Result, bail};
use firmware::cartpole::unit_f64;
use firmware::controller::Levels;
use firmware::network::{OBS_DIM, argmax};
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use twin::{Episode, Scenario};
use weights::Weights;

use super::evaluate::Judge;
use super::periodic::{Mark, Periodic};
use super::select::Selection;
use super::{
    Domains, EpisodeRecord, Learner, ReplayBuffer, Reward, RunResult, Stream, Training, domains,
    epsilon, rng,
};
use crate::config::{Config, TargetUpdate, Unit};
use crate::reward::Drive;

/// One run: episodes in worlds drawn from the training domain until the episode count or
/// the step budget is reached, the learner's weights evaluated every `eval_every` episodes,
/// and the policy chosen among those snapshots.
pub(super) fn run<const H: usize, const A: usize>(
    t: Training<'_>,
    levels: Levels<A>,
) -> Result<RunResult> {
    let (cfg, seed) = (t.cfg, t.seed);
    let start = Instant::now();
    let d = domains(cfg)?;
    let mut r = Trainer {
        cfg,
        levels,
        learner: Learner::<H, A>::new(cfg, t.kernel, seed),
        buf: ReplayBuffer::new(cfg.buffer_size),
        reward: Reward::parse(&cfg.reward).map_err(anyhow::Error::msg)?,
        explore: rng(seed, Stream::Explore),
        sample: rng(seed, Stream::Sample),
        env_steps: 0,
        cut_grad_steps: None,
        shown: 0,
    };
    let mut worlds = Worlds {
        domain: rng(seed, Stream::Domain),
        start: rng(seed, Stream::Env),
        noise: rng(seed, Stream::Noise),
        pushes: rng(seed, Stream::Pushes),
    };
    let judge = Judge {
        compensate: cfg.compensate,
        prices: r.reward.prices(),
    };
    let selection = Selection::new(cfg, seed, &d, levels, judge);
    let mut records = Vec::with_capacity(cfg.episodes);
    let beside = t.beside && cfg.eval_every > 0;
    let selection = std::thread::scope(|scope| {
        let mut periodic = Periodic::new(cfg, selection, beside.then_some(scope));
        let learnt = r.learn(
            &d,
            &mut worlds,
            &mut periodic,
            &mut records,
            t.on_episode,
            start,
        );
        match periodic.settle() {
            // An error in the episodes learnt beside the evaluation is in episodes it drops.
            Some(mark) => r.cut(mark, &mut records, t.on_episode),
            None => {
                learnt?;
                r.show(&records, t.on_episode);
            }
        }
        Ok::<_, anyhow::Error>(periodic.into_selection())
    })?;
    let wall_s = start.elapsed().as_secs_f64();
    let chosen = selection.choose(&r.learner, &records, t.evaluate_policy);
    Ok(RunResult {
        episodes: records,
        policy: Weights::from_mlp(&chosen.policy, &levels).map_err(|e| {
            anyhow::anyhow!("the trained weights are unusable ({e}); try a smaller lr or grad_clip")
        })?,
        policy_episode: chosen.episode,
        policy_env_steps: chosen.env_steps,
        selection_episodes: chosen.selection_episodes,
        selection_steps: chosen.selection_steps,
        evals: chosen.evals,
        trial: chosen.trial,
        final_eval: chosen.final_eval,
        env_steps: r.env_steps,
        grad_steps: r.grad_steps(),
        wall_s,
        kernel: t.kernel,
    })
}

/// A run's learning state, and the random streams the learner draws from ([`Stream`]).
struct Trainer<'a, const H: usize, const A: usize> {
    cfg: &'a Config,
    /// The duty level of each output: the policy the controller asks for an output.
    levels: Levels<A>,
    learner: Learner<H, A>,
    buf: ReplayBuffer,
    reward: Reward,
    explore: Pcg64Mcg,
    sample: Pcg64Mcg,
    env_steps: u64,
    /// The gradient steps of a run cut back by its selection ([`Trainer::cut`]).
    cut_grad_steps: Option<u64>,
    /// Records handed to the caller's `on_episode` so far.
    shown: usize,
}

/// The random streams the training worlds draw from: the worlds themselves (one per
/// episode), starts, sensor noise, push sides.
struct Worlds {
    domain: Pcg64Mcg,
    start: Pcg64Mcg,
    noise: Pcg64Mcg,
    pushes: Pcg64Mcg,
}

/// The largest Q-value, in f64 (`max` folds NaN away as `f32::max` does).
fn max_of<const A: usize>(q: &[f32; A]) -> f64 {
    f64::from(q.iter().copied().fold(f32::NEG_INFINITY, f32::max))
}

/// What one episode's periods add up to, for its record.
#[derive(Default)]
struct Tally {
    rewards: Vec<f32>,
    loss_sum: f64,
    losses: u32,
    maxq_sum: f64,
    /// The online net's max-Q of the last reading, after the last period's training.
    final_q: Option<f64>,
}

impl<const H: usize, const A: usize> Trainer<'_, H, A> {
    /// Episodes in worlds drawn from `d`'s training domain until the episode count, the
    /// step budget or a periodic evaluation stops the run; each record shown once no
    /// evaluation under way can drop it.
    fn learn<'s, 'c: 's>(
        &mut self,
        d: &Domains,
        w: &mut Worlds,
        periodic: &mut Periodic<'s, '_, 'c, H, A>,
        records: &mut Vec<EpisodeRecord>,
        on_episode: &mut dyn FnMut(&EpisodeRecord),
        start: Instant,
    ) -> Result<()> {
        let cfg = self.cfg;
        for ep in 0..cfg.episodes {
            let scenario = d.train.sample(&mut w.domain);
            let (mut rec, spent) = self.episode(w, ep, &scenario)?;
            rec.wall_s = start.elapsed().as_secs_f64();
            records.push(rec);
            // The weights the budget stops at are a candidate too.
            let due = cfg.eval_every > 0 && ((ep + 1).is_multiple_of(cfg.eval_every) || spent);
            if due {
                let mark = Mark {
                    episodes: ep + 1,
                    env_steps: self.env_steps,
                    grad_steps: self.learner.steps(),
                };
                if let Some(stop) = periodic.submit(self.learner.snapshot(), mark) {
                    self.cut(stop, records, on_episode);
                    return Ok(());
                }
            }
            self.show(&records[..periodic.kept(records.len())], on_episode);
            if spent {
                break;
            }
        }
        Ok(())
    }

    /// Cuts the run back to `mark`: the episodes after it dropped, its counts restored.
    fn cut(
        &mut self,
        mark: Mark,
        records: &mut Vec<EpisodeRecord>,
        on_episode: &mut dyn FnMut(&EpisodeRecord),
    ) {
        records.truncate(mark.episodes);
        self.env_steps = mark.env_steps;
        self.cut_grad_steps = Some(mark.grad_steps);
        self.show(records, on_episode);
    }

    /// Hands the records not yet shown to `on_episode`.
    fn show(&mut self, records: &[EpisodeRecord], on_episode: &mut dyn FnMut(&EpisodeRecord)) {
        for rec in &records[self.shown.min(records.len())..] {
            on_episode(rec);
        }
        self.shown = records.len();
    }

    /// Gradient steps taken, up to the cut if the run was cut back.
    fn grad_steps(&self) -> u64 {
        self.cut_grad_steps.unwrap_or(self.learner.steps())
    }

    /// Episode `ep` (0-based) in `scenario`: its record (the wall time left for the caller),
    /// and whether the step budget is spent.
    fn episode(
        &mut self,
        w: &mut Worlds,
        ep: usize,
        scenario: &Scenario,
    ) -> Result<(EpisodeRecord, bool)> {
        let cfg = self.cfg;
        let streams = (&mut w.noise, &mut w.pushes);
        let horizon = cfg.max_steps;
        let (levels, start) = (self.levels, &mut w.start);
        let mut world = Episode::start(levels, scenario, horizon, start, streams, cfg.compensate);
        let mut tally = Tally::default();
        let mut sensed = world.sense();
        let mut previous = 0.0;
        loop {
            let t = match cfg.eps_unit {
                Unit::Steps => self.env_steps as f64,
                Unit::Episodes => ep as f64,
            };
            let eps = epsilon(cfg, t);
            let mut taken = None;
            world.act_with(sensed, |s| {
                let a = self.choose(s, eps, &mut tally);
                taken = Some((*s, a));
                a
            });
            let duty = taken
                .and_then(|(_, a)| levels.duty(a))
                .map_or(0.0, |d| f64::from(d.fraction()));
            let x_dot = world.world().state().x_dot;
            let tr = world.apply();
            self.env_steps += 1;
            let state = world.world().state();
            let drive = Drive {
                duty,
                previous,
                x_dot,
            };
            previous = duty;
            let reward = self
                .reward
                .of(&scenario.params, &drive, &state, tr.terminated);
            tally.rewards.push(reward);
            sensed = world.sense();
            let next = sensed.shown();
            if let Some((s, a)) = taken
                && let Some(next) = next.or(tr.terminated.then_some(s))
            {
                self.buf.push(s, a, reward, next, tr.terminated);
                let at = (ep, Some(tally.rewards.len()));
                self.train_if_due(Unit::Steps, self.env_steps, at, &mut tally)?;
            }
            self.sync_if_due(Unit::Steps, self.env_steps);
            let spent = cfg.max_env_steps > 0 && self.env_steps >= cfg.max_env_steps;
            if tr.terminated || tr.truncated || spent {
                tally.final_q = next.map(|s| self.max_q(&s));
                let (ep1, at) = ((ep + 1) as u64, (ep, None));
                self.train_if_due(Unit::Episodes, ep1, at, &mut tally)?;
                self.sync_if_due(Unit::Episodes, ep1);
                return Ok((self.record(ep, &tally, tr.terminated, eps), spent));
            }
        }
    }

    /// Epsilon-greedy on the online network (a random output uniformly, `next_u32() % A`);
    /// its max-Q tallied.
    fn choose(&mut self, s: &[f32; OBS_DIM], eps: f64, tally: &mut Tally) -> usize {
        let q = self.learner.q_values(s);
        tally.maxq_sum += max_of(&q);
        if unit_f64(&mut self.explore) < eps {
            self.explore.next_u32() as usize % A
        } else {
            argmax(&q)
        }
    }

    fn max_q(&self, s: &[f32; OBS_DIM]) -> f64 {
        max_of(&self.learner.q_values(s))
    }

    /// `updates_per_train` gradient steps when training counts in `unit` and `count` of
    /// them (environment steps, or episodes ended) is a multiple of `train_every`, once the
    /// buffer holds enough. `at` (episode, step within it) places a non-finite loss.
    fn train_if_due(
        &mut self,
        unit: Unit,
        count: u64,
        at: (usize, Option<usize>),
        tally: &mut Tally,
    ) -> Result<()> {
        let cfg = self.cfg;
        if cfg.train_unit != unit
            || self.buf.len() < cfg.learning_starts.max(cfg.batch_size)
            || !count.is_multiple_of(cfg.train_every as u64)
        {
            return Ok(());
        }
        for _ in 0..cfg.updates_per_train {
            let loss = self.learner.update(cfg, &self.buf, &mut self.sample);
            if !loss.is_finite() {
                let when = match at {
                    (ep, Some(s)) => format!("at episode {}, step {s}", ep + 1),
                    (ep, None) => format!("at the end of episode {}", ep + 1),
                };
                let env = self.env_steps;
                bail!(
                    "non-finite loss ({loss}) {when} (env step {env}); try a smaller lr or grad_clip"
                );
            }
            tally.loss_sum += f64::from(loss);
            tally.losses += 1;
        }
        Ok(())
    }

    /// The hard target update, when its period counts in `unit` and `count` is a multiple of
    /// it (soft updates follow every gradient step inside the learner).
    fn sync_if_due(&mut self, unit: Unit, count: u64) {
        let cfg = self.cfg;
        if cfg.target_update == TargetUpdate::Hard
            && cfg.target_period_unit == unit
            && count.is_multiple_of(cfg.target_period as u64)
        {
            self.learner.sync_target();
        }
    }

    /// The episode's record. A cut episode's return goes on past the cut; without its tail
    /// every state near the end would seem overestimated (by up to gamma^k / (1 - gamma) per
    /// step's reward). The online net's own estimate stands in for it, so the gap measures
    /// how far Q disagrees with what followed, not where the episode was cut.
    fn record(&self, ep: usize, tally: &Tally, terminated: bool, eps: f64) -> EpisodeRecord {
        let cfg = self.cfg;
        let mut g = if terminated {
            0.0
        } else {
            tally.final_q.unwrap_or(0.0)
        };
        let len = tally.rewards.len();
        let mut disc_sum = 0.0f64;
        for r in tally.rewards.iter().rev() {
            g = f64::from(*r) + cfg.gamma * g;
            disc_sum += g;
        }
        EpisodeRecord {
            episode: ep + 1,
            ret: len as f64,
            learning_return: tally.rewards.iter().map(|&r| f64::from(r)).sum(),
            length: len as u32,
            epsilon: eps,
            mean_loss: (tally.losses > 0).then(|| tally.loss_sum / f64::from(tally.losses)),
            mean_max_q: tally.maxq_sum / len as f64,
            mean_discounted_return: disc_sum / len as f64,
            env_steps: self.env_steps,
            wall_s: 0.0,
        }
    }
}
