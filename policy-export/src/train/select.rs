//! Which weights a run ships: the best periodically evaluated snapshots, tried again in the
//! finalists' longer trial, and the winner evaluated once more on fresh episodes.

use firmware::controller::Levels;
use firmware::network::Mlp;

use super::{Domains, EpisodeRecord, EvalResult, EvalStreams, Learner, Stream, evaluate};
use crate::config::Config;

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
    let streams = match which {
        Eval::Periodic => [
            Stream::EvalWorld,
            Stream::Eval,
            Stream::EvalNoise,
            Stream::EvalPushes,
        ],
        Eval::Trial => [
            Stream::TrialWorld,
            Stream::Trial,
            Stream::TrialNoise,
            Stream::TrialPushes,
        ],
        Eval::Final => [
            Stream::FinalWorld,
            Stream::Final,
            Stream::FinalNoise,
            Stream::FinalPushes,
        ],
    };
    EvalStreams { seed, streams }
}

/// The environment steps an evaluation ran: its return counts one per step.
fn steps_of(res: &EvalResult) -> u64 {
    (res.mean * res.episodes as f64).round() as u64
}

/// The snapshots of a run and their evaluations so far.
pub(super) struct Selection<'a, const H: usize, const A: usize> {
    levels: Levels<A>,
    cfg: &'a Config,
    seed: u64,
    domains: &'a Domains,
    /// The best periodic snapshots, best first; among equals the earlier stays ahead.
    pool: Vec<(EvalResult, usize, Box<Mlp<H, A>>)>,
    evals: Vec<(usize, EvalResult)>,
    episodes: u64,
    steps: u64,
    /// Periodic evaluations since the best snapshot was last replaced.
    stale: usize,
}

/// What a run ships, and how it was chosen.
pub(super) struct Chosen<const H: usize, const A: usize> {
    pub policy: Box<Mlp<H, A>>,
    /// The episode after which it was taken.
    pub episode: usize,
    pub env_steps: u64,
    pub selection_episodes: u64,
    pub selection_steps: u64,
    pub evals: Vec<(usize, EvalResult)>,
    pub trial: Vec<(usize, EvalResult)>,
    pub final_eval: EvalResult,
}

impl<'a, const H: usize, const A: usize> Selection<'a, H, A> {
    pub fn new(cfg: &'a Config, seed: u64, domains: &'a Domains, levels: Levels<A>) -> Self {
        Selection {
            levels,
            cfg,
            seed,
            domains,
            pool: Vec::new(),
            evals: Vec::new(),
            episodes: 0,
            steps: 0,
            stale: 0,
        }
    }

    fn evaluate(&mut self, net: &Mlp<H, A>, which: Eval) -> EvalResult {
        let cfg = self.cfg;
        let (episodes, steps, domain) = match which {
            Eval::Periodic | Eval::Final => {
                (cfg.eval_episodes, cfg.eval_max_steps, &self.domains.eval)
            }
            Eval::Trial => (
                cfg.finalist_episodes,
                cfg.finalist_max_steps,
                &self.domains.trial,
            ),
        };
        let episodes = match which {
            Eval::Final => cfg.final_eval_episodes,
            _ => episodes,
        };
        let streams = eval_streams(self.seed, which);
        let policy = (net, self.levels);
        let res = evaluate(policy, episodes, steps, domain, cfg.compensate, streams);
        if !matches!(which, Eval::Final) {
            self.episodes += episodes as u64;
            self.steps += steps_of(&res);
        }
        res
    }

    /// Evaluates the learner's weights after episode `episode` (1-based) and keeps them if
    /// they are among the best; whether every episode reached the limit.
    pub fn periodic(&mut self, learner: &Learner<H, A>, episode: usize) -> bool {
        let res = self.evaluate(learner.online(), Eval::Periodic);
        let perfect = res.min >= f64::from(self.cfg.eval_max_steps);
        let rank = self.pool.partition_point(|(b, _, _)| !res.beats(b));
        self.stale = if rank == 0 { 0 } else { self.stale + 1 };
        if rank < self.cfg.finalists.max(1) {
            self.pool
                .insert(rank, (res.clone(), episode, learner.snapshot()));
            self.pool.truncate(self.cfg.finalists.max(1));
        }
        self.evals.push((episode, res));
        perfect
    }

    /// Periodic evaluations in a row that found no better snapshot than the best.
    pub fn stale(&self) -> usize {
        self.stale
    }

    /// Tries the finalists, if any, and picks the run's policy (the learner's last weights
    /// when nothing was evaluated); with `evaluate_policy`, scores it on fresh episodes.
    pub fn choose(
        mut self,
        learner: &Learner<H, A>,
        records: &[EpisodeRecord],
        evaluate_policy: bool,
    ) -> Chosen<H, A> {
        let mut trial = Vec::new();
        if evaluate_policy && self.cfg.finalists > 0 {
            let pool = std::mem::take(&mut self.pool);
            let mut best: Option<(usize, f64)> = None;
            for (i, (_, ep, net)) in pool.iter().enumerate() {
                let res = self.evaluate(net, Eval::Trial);
                // Survival decides; among equals the better periodic rank, since the periodic
                // cost (nominal-like worlds) measures precision better than the trial's
                // pushes.
                if best.is_none_or(|(_, b)| res.mean > b) {
                    best = Some((i, res.mean));
                }
                trial.push((*ep, res));
            }
            self.pool = pool;
            if let Some((i, _)) = best {
                self.pool.swap(0, i);
            }
        }
        let (episode, policy) = match std::mem::take(&mut self.pool).into_iter().next() {
            Some((_, ep, net)) => (ep, net),
            None => (records.len(), learner.snapshot()),
        };
        let final_eval = if evaluate_policy {
            self.evaluate(&policy, Eval::Final)
        } else {
            // Never leaves the trainer: `episodes` keeps the records alone.
            EvalResult {
                episodes: 0,
                max_steps: self.cfg.eval_max_steps,
                mean: f64::NAN,
                min: f64::NAN,
                cost: f64::NAN,
            }
        };
        Chosen {
            policy,
            episode,
            env_steps: records[episode - 1].env_steps,
            selection_episodes: self.episodes,
            selection_steps: self.steps,
            evals: self.evals,
            trial,
            final_eval,
        }
    }
}
