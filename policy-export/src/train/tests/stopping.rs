//! When a run stops before its episode count: the selection's two rules, each replayed
//! from the run's recorded evaluations.

use super::small;
use crate::config::{Config, KernelChoice};
use crate::train::{EvalResult, train};

#[test]
fn patience_stops_the_run_when_the_evaluations_stop_finding_better() {
    let cfg = Config {
        eval_every: 1,
        eval_episodes: 2,
        eval_max_steps: 60,
        patience: 3,
        episodes: 200,
        ..small(KernelChoice::Auto)
    };
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
    let cfg = Config {
        eval_every: 1,
        eval_episodes: 2,
        eval_max_steps: 60,
        settle: 3,
        episodes: 400,
        ..small(KernelChoice::Auto)
    };
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
