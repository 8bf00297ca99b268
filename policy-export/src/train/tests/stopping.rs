//! When a run stops before its episode count: the selection's two rules, each replayed
//! from the run's recorded evaluations.

use super::{bits, small, strip};
use crate::config::{Config, KernelChoice};
use crate::train::{EvalResult, RunResult, run, train};

/// A run evaluated after every episode, stopped by three evaluations without a better one.
fn patient() -> Config {
    Config {
        eval_every: 1,
        eval_episodes: 2,
        eval_max_steps: 60,
        patience: 3,
        episodes: 200,
        ..small(KernelChoice::Auto)
    }
}

/// A run evaluated after every episode, stopped by three perfect evaluations in a row.
fn settling() -> Config {
    Config {
        patience: 0,
        settle: 3,
        episodes: 400,
        ..patient()
    }
}

#[test]
fn patience_stops_the_run_when_the_evaluations_stop_finding_better() {
    let cfg = patient();
    let run = train(&cfg, 5, &mut |_| {}).unwrap();
    // Replayed from the recorded evaluations: the first one three after the last best.
    let mut best: Option<&EvalResult> = None;
    let mut stale = 0;
    let mut stop = None;
    for (i, (_, res)) in run.evals.iter().enumerate() {
        if best.is_none_or(|b| res.beats(b)) {
            (best, stale) = (Some(res), 0);
        } else {
            stale += 1;
        }
        if stale == 3 {
            stop = Some(i);
            break;
        }
    }
    let stop = stop.expect("the evaluations went stale within the run");
    assert_eq!(run.evals.len(), stop + 1);
    assert_eq!(run.episodes.len(), run.evals[stop].0);
    assert!(run.episodes.len() < 200);
}

#[test]
fn settling_stops_the_run_once_its_evaluations_hold_every_episode_in_a_row() {
    let cfg = settling();
    let run = train(&cfg, 5, &mut |_| {}).unwrap();
    // Replayed: the third perfect evaluation of a run of them, and none before it.
    let perfect = |res: &EvalResult| res.min >= 60.0;
    let mut in_a_row = 0;
    let stop = run.evals.iter().position(|(_, res)| {
        in_a_row = if perfect(res) { in_a_row + 1 } else { 0 };
        in_a_row == 3
    });
    let stop = stop.expect("the evaluations settled within the run");
    assert_eq!(run.evals.len(), stop + 1);
    assert_eq!(run.episodes.len(), run.evals[stop].0);
    assert!(run.episodes.len() < 400);
}

/// A run whose evaluations ran beside its learning is the run that waited for each: the
/// episodes learnt past a stopping evaluation are dropped, with their steps.
#[test]
fn evaluating_beside_the_learning_gives_the_waiting_runs_bits() {
    let budget = Config {
        eval_every: 7,
        max_env_steps: 3_000,
        ..settling()
    };
    for (cfg, seed) in [(patient(), 5), (settling(), 5), (budget, 3)] {
        let [waited, beside]: [RunResult; 2] =
            [false, true].map(|beside| run(&cfg, seed, &mut |_| {}, true, beside).unwrap());
        assert!(
            waited.episodes.len() < cfg.episodes,
            "the run stopped early"
        );
        assert_eq!(strip(&beside), strip(&waited));
        assert_eq!(bits(&beside), bits(&waited));
        assert_eq!(beside.evals, waited.evals);
        assert_eq!(beside.trial, waited.trial);
        assert_eq!(beside.final_eval, waited.final_eval);
        let counts = |r: &RunResult| (r.env_steps, r.grad_steps, r.policy_episode);
        assert_eq!(counts(&beside), counts(&waited));
        let selection = |r: &RunResult| (r.selection_episodes, r.selection_steps);
        assert_eq!(selection(&beside), selection(&waited));
    }
}

/// What the caller is shown is what the run kept: each record once, in order, none that
/// a stopping evaluation dropped.
#[test]
fn a_run_cut_back_shows_only_the_records_it_keeps() {
    let cfg = patient();
    let mut shown = Vec::new();
    let r = run(&cfg, 5, &mut |e| shown.push(e.episode), true, true).unwrap();
    let kept: Vec<usize> = r.episodes.iter().map(|e| e.episode).collect();
    assert_eq!(shown, kept);
    assert_eq!(kept, (1..=kept.len()).collect::<Vec<_>>());
}
