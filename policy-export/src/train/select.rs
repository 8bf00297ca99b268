//! Which weights a run ships: the best periodically evaluated snapshots, tried again in the
//! finalists' longer trial (with `board_int8`, each as its float and its int8 board runs
//! it), and the winner evaluated once more on fresh episodes.

use firmware::controller::Levels;
use firmware::network::Mlp;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::evaluate::{Judge, evaluate_int, quantised};
use super::{Domains, EpisodeRecord, Eval, EvalResult, EvalStreams, Learner, evaluate};
use crate::config::Config;

/// One finalist's trial: its float network's result, and with `board_int8` its integer
/// network's on the same episodes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrialRun {
    /// The snapshot taken after this episode.
    pub episode: usize,
    /// The float network (f32 board).
    #[serde(rename = "result")]
    pub f32: EvalResult,
    /// The integer network (int8 board), quantised as `export --quant int8` quantises it;
    /// a network the quantiser refuses holds no episode on such a board and scores 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub int8: Option<EvalResult>,
}

impl TrialRun {
    /// What the trial ranks by: the mean survival of the worse of its boards, since either
    /// may run it.
    pub fn survival(&self) -> f64 {
        self.int8
            .as_ref()
            .map_or(self.f32.mean, |q| self.f32.mean.min(q.mean))
    }

    /// Its cost on the worse of its boards.
    pub fn cost(&self) -> f64 {
        self.int8
            .as_ref()
            .map_or(self.f32.cost, |q| self.f32.cost.max(q.cost))
    }
}

/// The finalist a trial picks. With no `margin`, the best survival; among equals the
/// earlier, which had the better periodic rank, since the periodic cost (nominal-like
/// worlds) measures precision better than pushes every finalist falls to. With a margin
/// (a fraction of the best survival), the lowest cost among those surviving within it: a
/// trial its finalists survive says in its cost which holds the pole more gently.
pub(super) fn pick(trial: &[TrialRun], margin: f64) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (i, t) in trial.iter().enumerate() {
        let s = t.survival();
        if best.is_none_or(|(_, b)| s > b) {
            best = Some((i, s));
        }
    }
    let (longest, b) = best?;
    if margin == 0.0 {
        return Some(longest);
    }
    let within = |t: &&TrialRun| t.survival() >= b * (1.0 - margin);
    let costs = trial.iter().enumerate().filter(|(_, t)| within(t));
    costs
        .min_by(|(_, x), (_, y)| x.cost().total_cmp(&y.cost()))
        .map(|(i, _)| i)
}

/// The environment steps an evaluation ran: its return counts one per step.
fn steps_of(res: &EvalResult) -> u64 {
    (res.mean * res.episodes as f64).round() as u64
}

/// The snapshots of a run and their evaluations so far.
pub(super) struct Selection<'a, const H: usize, const A: usize> {
    levels: Levels<A>,
    judge: Judge,
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
    pub trial: Vec<TrialRun>,
    pub final_eval: EvalResult,
}

impl<'a, const H: usize, const A: usize> Selection<'a, H, A> {
    pub fn new(
        cfg: &'a Config,
        seed: u64,
        domains: &'a Domains,
        levels: Levels<A>,
        judge: Judge,
    ) -> Self {
        Selection {
            levels,
            judge,
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

    /// The episodes, their length and worlds of `which`.
    fn plan(&self, which: Eval) -> (usize, u32, &'a twin::Domain) {
        let (cfg, d) = (self.cfg, self.domains);
        match which {
            Eval::Periodic => (cfg.eval_episodes, cfg.eval_max_steps, &d.eval),
            Eval::Final => (cfg.final_eval_episodes, cfg.eval_max_steps, &d.eval),
            Eval::Trial => (cfg.finalist_episodes, cfg.finalist_max_steps, &d.trial),
        }
    }

    /// Counts an evaluation that chose the policy.
    fn count(&mut self, which: Eval, res: &EvalResult) {
        if !matches!(which, Eval::Final) {
            self.episodes += res.episodes as u64;
            self.steps += steps_of(res);
        }
    }

    fn evaluate(&mut self, net: &Mlp<H, A>, which: Eval) -> EvalResult {
        let res = self.run(net, which);
        self.count(which, &res);
        res
    }

    /// `net`'s evaluation `which`, not yet counted.
    fn run(&self, net: &Mlp<H, A>, which: Eval) -> EvalResult {
        let (episodes, steps, domain) = self.plan(which);
        let (policy, streams) = ((net, self.levels), EvalStreams::of(self.seed, which));
        evaluate(policy, episodes, steps, domain, self.judge, streams)
    }

    /// `net`'s trial as its int8 board runs it, on the float network's episodes, not yet
    /// counted; `None` if the quantiser refuses the network.
    fn trial_int8(&self, net: &Mlp<H, A>) -> Option<EvalResult> {
        let (episodes, steps, domain) = self.plan(Eval::Trial);
        let q = quantised((net, self.levels), &self.domains.machine).ok()?;
        let streams = EvalStreams::of(self.seed, Eval::Trial);
        let policy = (&*q, self.levels);
        Some(evaluate_int(
            policy, episodes, steps, domain, self.judge, streams,
        ))
    }

    /// Every finalist's trial, f32 and (if asked) int8 boards, the finalists side by side on
    /// all cores: each trial is a pure function of its network, so the order they run in
    /// changes nothing. The episodes that ran are counted; an int8 board the quantiser
    /// refused ran none and scores 0.
    fn trials(&mut self, pool: &[(EvalResult, usize, Box<Mlp<H, A>>)]) -> Vec<TrialRun> {
        let this = &*self;
        let runs: Vec<_> = pool
            .par_iter()
            .map(|(_, episode, net)| {
                let (f32, int8) = rayon::join(
                    || this.run(net, Eval::Trial),
                    || this.cfg.board_int8.then(|| this.trial_int8(net)),
                );
                (*episode, f32, int8)
            })
            .collect();
        let (episodes, max_steps, _) = self.plan(Eval::Trial);
        let refused = EvalResult {
            episodes,
            max_steps,
            mean: 0.0,
            min: 0.0,
            cost: 0.0,
        };
        let mut trial = Vec::with_capacity(runs.len());
        for (episode, f32, int8) in runs {
            self.count(Eval::Trial, &f32);
            if let Some(Some(ran)) = &int8 {
                self.count(Eval::Trial, ran);
            }
            let int8 = int8.map(|r| r.unwrap_or_else(|| refused.clone()));
            trial.push(TrialRun { episode, f32, int8 });
        }
        trial
    }

    /// Evaluates `net`, the learner's weights after episode `episode` (1-based), and keeps
    /// it if it is among the best; whether every episode reached the limit.
    pub fn periodic(&mut self, net: Box<Mlp<H, A>>, episode: usize) -> bool {
        let res = self.evaluate(&net, Eval::Periodic);
        let perfect = res.min >= f64::from(self.cfg.eval_max_steps);
        let rank = self.pool.partition_point(|(b, _, _)| !res.beats(b));
        self.stale = if rank == 0 { 0 } else { self.stale + 1 };
        if rank < self.cfg.finalists.max(1) {
            self.pool.insert(rank, (res.clone(), episode, net));
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
            trial = self.trials(&pool);
            self.pool = pool;
            if let Some(i) = pick(&trial, self.cfg.trial_margin) {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn result(mean: f64) -> EvalResult {
        EvalResult {
            episodes: 50,
            max_steps: 10_000,
            mean,
            min: mean - 100.0,
            cost: 0.01,
        }
    }

    fn run(episode: usize, f32: f64, int8: Option<f64>) -> TrialRun {
        TrialRun {
            episode,
            f32: result(f32),
            int8: int8.map(result),
        }
    }

    #[test]
    fn a_finalist_whose_int8_board_falls_loses() {
        // The first holds best as a float board and falls at once as an int8 one.
        let trial = [
            run(10, 10_000.0, Some(120.0)),
            run(20, 9_500.0, Some(9_400.0)),
            run(30, 9_400.0, Some(10_000.0)),
        ];
        assert_eq!(
            trial.each_ref().map(TrialRun::survival),
            [120.0, 9_400.0, 9_400.0]
        );
        // Equal survival: the earlier, of the better periodic rank.
        assert_eq!(pick(&trial, 0.0), Some(1));
        // Without int8 figures the float board alone ranks them.
        let float = trial.map(|t| TrialRun { int8: None, ..t });
        assert_eq!(pick(&float, 0.0), Some(0));
        assert_eq!(pick(&[], 0.0), None);
        assert_eq!(pick(&[], 0.05), None);
    }

    #[test]
    fn with_a_margin_the_cheapest_of_the_survivors_within_it_wins() {
        let priced = |episode, f32: f64, f32_cost, int8: f64, int8_cost| TrialRun {
            episode,
            f32: EvalResult {
                cost: f32_cost,
                ..result(f32)
            },
            int8: Some(EvalResult {
                cost: int8_cost,
                ..result(int8)
            }),
        };
        let trial = [
            // The longest survivor, the dearest.
            priced(10, 10_000.0, 0.9, 10_000.0, 0.8),
            // Within 5% of it (9,500 of 10,000) and the cheapest on its worse board.
            priced(20, 9_600.0, 0.2, 9_500.0, 0.3),
            // Cheaper still on its float board, but its int8 board is the dearest of all.
            priced(30, 10_000.0, 0.1, 10_000.0, 1.0),
            // The cheapest, but its int8 board survives 9,499: outside the margin.
            priced(40, 10_000.0, 0.05, 9_499.0, 0.05),
        ];
        assert_eq!(trial.each_ref().map(TrialRun::cost), [0.9, 0.3, 1.0, 0.05]);
        assert_eq!(pick(&trial, 0.05), Some(1));
        // No margin: the longest survivor, the earlier among equals.
        assert_eq!(pick(&trial, 0.0), Some(0));
        // A margin too narrow for any but the longest survivors.
        assert_eq!(pick(&trial, 0.001), Some(0));
    }
}
