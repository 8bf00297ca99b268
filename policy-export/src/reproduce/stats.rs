//! The numbers of one run, and of one configuration over its seeds, with the project's
//! interval convention (`host_common::stats`).

use host_common::stats::{Estimate, mean, median, sd};
use serde::Serialize;

use super::variants::Variant;
use crate::train::{EpisodeRecord, solved_episode, trailing_means};

/// Per-run numbers.
#[derive(Clone, Debug, Serialize)]
pub struct RunStats {
    /// Seed.
    pub seed: u64,
    /// First episode whose trailing 100-episode mean reaches 195.
    pub solved_195: Option<usize>,
    /// Mean return of the last 100 episodes.
    pub final_mean100: f64,
    /// Standard deviation of the returns of episodes 101 to 200.
    pub sd_101_200: f64,
    /// Largest fall of the trailing 10-episode mean from its running peak, after that mean
    /// first reaches 150 (0 if it never does).
    pub max_drop_after_150: f64,
    /// Per-episode returns.
    pub returns: Vec<f64>,
    /// Per-episode mean of max-Q over visited states.
    pub mean_max_q: Vec<f64>,
    /// Per-episode mean discounted learning return actually obtained from those states
    /// (what the Q-values estimate, so the overestimation is measured against it).
    pub mean_discounted_return: Vec<f64>,
}

impl RunStats {
    /// The numbers of one finished run.
    pub fn of(seed: u64, episodes: &[EpisodeRecord]) -> RunStats {
        let returns: Vec<f64> = episodes.iter().map(|e| e.ret).collect();
        let tail = &returns[returns.len().saturating_sub(100)..];
        let mid = &returns[returns.len().min(100)..returns.len().min(200)];
        RunStats {
            seed,
            solved_195: solved_episode(&returns, 195.0),
            final_mean100: mean(tail),
            sd_101_200: sd(mid),
            max_drop_after_150: max_drop(&returns, 150.0),
            mean_max_q: episodes.iter().map(|e| e.mean_max_q).collect(),
            mean_discounted_return: episodes.iter().map(|e| e.mean_discounted_return).collect(),
            returns,
        }
    }
}

/// The largest fall of the 10-episode trailing mean below its running peak, counted from
/// the first time that mean reaches `gate`.
pub fn max_drop(returns: &[f64], gate: f64) -> f64 {
    let m10: Vec<f64> = trailing_means(returns, 10).collect();
    let Some(start) = m10.iter().position(|&m| m >= gate) else {
        return 0.0;
    };
    let mut peak = f64::NEG_INFINITY;
    let mut drop: f64 = 0.0;
    for &m in &m10[start..] {
        peak = peak.max(m);
        drop = drop.max(peak - m);
    }
    drop
}

/// One row of a results table.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Study.
    pub study: String,
    /// Row label.
    pub label: String,
    /// Trainable parameters.
    pub params: usize,
    /// Seeds run.
    pub seeds: usize,
    /// Seeds whose trailing 100-episode mean ever reached 195.
    pub solved_seeds: usize,
    /// Median first episode of those that did.
    pub median_solved_episode: Option<f64>,
    /// Seeds that reached it by episode 160 (the paper's headline for its preset).
    pub solved_by_160: usize,
    /// Mean of the last 100 episodes, averaged over seeds.
    pub final_mean100: Estimate,
    /// SD of returns over episodes 101-200, averaged over seeds.
    pub sd_101_200: Estimate,
    /// Largest 10-episode-mean drop after 150, averaged over seeds.
    pub max_drop_after_150: Estimate,
    /// Mean over episodes 101 to the end of (max-Q minus discounted return), averaged over
    /// seeds: the overestimation.
    pub overestimation: Estimate,
    /// The paper's convergence and final reward for this row.
    pub paper: Option<(String, String)>,
}

/// Aggregates the runs of one variant: means over seeds with their 95% intervals.
pub fn row(v: &Variant, runs: &[RunStats]) -> Row {
    let solved: Vec<f64> = runs
        .iter()
        .filter_map(|r| r.solved_195)
        .map(|e| e as f64)
        .collect();
    let per = |f: &dyn Fn(&RunStats) -> f64| -> Vec<f64> { runs.iter().map(f).collect() };
    let over = per(&|r| {
        let gaps: Vec<f64> = r
            .mean_max_q
            .iter()
            .zip(&r.mean_discounted_return)
            .skip(100)
            .map(|(q, g)| q - g)
            .collect();
        mean(&gaps)
    });
    Row {
        study: v.study.to_string(),
        label: v.label.clone(),
        params: firmware::network::params(v.cfg.width, 2),
        seeds: runs.len(),
        solved_seeds: solved.len(),
        median_solved_episode: (!solved.is_empty()).then(|| median(&solved)),
        solved_by_160: solved.iter().filter(|&&e| e <= 160.0).count(),
        final_mean100: Estimate::of(&per(&|r| r.final_mean100)),
        sd_101_200: Estimate::of(&per(&|r| r.sd_101_200)),
        max_drop_after_150: Estimate::of(&per(&|r| r.max_drop_after_150)),
        overestimation: Estimate::of(&over),
        paper: v.paper.map(|(a, b)| (a.to_string(), b.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::reproduce::variants;

    #[test]
    fn drop_is_measured_from_the_running_peak_after_the_gate() {
        // 10-episode means: 100 x10, then 200 x10, then 120 x10.
        let returns: Vec<f64> = [100.0; 10]
            .into_iter()
            .chain([200.0; 10])
            .chain([120.0; 10])
            .collect();
        assert_eq!(max_drop(&returns, 150.0), 80.0);
        assert_eq!(max_drop(&returns, 250.0), 0.0);
    }

    #[test]
    fn run_stats_and_rows() {
        let eps: Vec<EpisodeRecord> = (1..=300)
            .map(|i| EpisodeRecord {
                episode: i,
                ret: if i > 150 { 200.0 } else { 10.0 },
                learning_return: 0.0,
                length: 0,
                epsilon: 0.0,
                mean_loss: None,
                mean_max_q: 30.0,
                mean_discounted_return: 20.0,
                env_steps: 0,
                wall_s: 0.0,
            })
            .collect();
        let r = RunStats::of(1, &eps);
        assert_eq!(r.final_mean100, 200.0);
        // Trailing mean of 100 reaches 195 once at most 2 of them are 10: episode 248.
        assert_eq!(r.solved_195, Some(248));
        let v = &variants(&Config::paper())[1];
        let row = row(v, &[r.clone(), r]);
        assert_eq!((row.params, row.solved_seeds), (4_610, 2));
        assert_eq!(row.median_solved_episode, Some(248.0));
        assert_eq!(row.solved_by_160, 0);
        assert_eq!(row.overestimation.mean, 10.0);
    }
}
