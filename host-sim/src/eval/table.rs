//! The table's rows: the statistics of a controller's episodes in a scenario at a horizon,
//! with 95% confidence intervals, and how the table and its failures are printed.

use host_common::stats::{Estimate, wilson};
use serde::Serialize;
use twin::EpisodeStats;

/// One line of the table: a controller on a scenario at a horizon.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Row {
    /// Controller name.
    pub controller: String,
    /// Scenario spec.
    pub scenario: String,
    /// Periods an episode may last.
    pub horizon: u32,
    /// The control period, s.
    pub period_s: f64,
    /// Episodes run.
    pub episodes: usize,
    /// Share that reached the horizon.
    pub success_rate: f64,
    /// Wilson 95% interval of the success rate.
    pub success_ci95: [f64; 2],
    /// Mean periods survived.
    pub mean_steps: f64,
    /// Its 95% half-width.
    pub mean_steps_ci95: f64,
    /// Shortest episode.
    pub min_steps: u32,
    /// 5th percentile of episode length (nearest rank).
    pub p5_steps: u32,
    /// Per-episode RMS of theta, degrees, averaged over episodes.
    pub rms_theta_deg: Estimate,
    /// Per-episode RMS of x, m.
    pub rms_x_m: Estimate,
    /// Per-episode mean |x|, m.
    pub mean_abs_x_m: Estimate,
    /// Command changes per second of balance.
    pub switches_per_s: Estimate,
    /// Reversals of the motor's direction per second of balance.
    pub reversals_per_s: Estimate,
    /// Per-episode mean |duty|, a fraction of the full push.
    pub mean_abs_duty: Estimate,
    /// Per-episode total variation of the duty per second (full pushes per second).
    pub duty_tv_per_s: Estimate,
    /// Per-episode mean squared motor current as a share of a full-duty stall's: the motor's
    /// heating.
    pub heat: Estimate,
    /// Periods that coasted on a rejected reading, over all episodes.
    pub faults: u64,
    /// Share of the periods a runtime monitor's fallback decided (0 without a monitor).
    pub fallback_share: f64,
    /// Episodes that fell or left the track before the horizon.
    pub failures: usize,
    /// The shortest failed episodes (at most [`WORST`]), to find out why.
    pub worst: Vec<Worst>,
}

/// Failed episodes a row lists.
pub const WORST: usize = 5;

/// A failed episode: which, how long it lasted, and where it started.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Worst {
    /// Episode number (with the row's seed, it replays: `render --seed S --episode N`).
    pub episode: u64,
    /// Periods it lasted.
    pub steps: u32,
    /// Its start `[x, x_dot, theta, theta_dot]`.
    pub start: [f64; 4],
}

impl Row {
    /// The statistics of a set of episodes of `period_s` periods, episode `i` of `seed` at
    /// `eps[i]`.
    pub fn from_episodes(
        controller: &str,
        scenario: &str,
        (horizon, period_s): (u32, f64),
        seed: u64,
        eps: &[EpisodeStats],
    ) -> Row {
        // Each figure is taken over the episodes as it is summed, none kept in a list of its
        // own: a row holds its episodes' statistics and little more (`EPISODE_BYTES`).
        let per = |f: &dyn Fn(&EpisodeStats) -> f64| Estimate::of_each(eps.len(), |i| f(&eps[i]));
        let steps = |e: &EpisodeStats| f64::from(e.steps.max(1));
        let successes = eps.iter().filter(|e| e.success).count();
        let steps_est = per(&|e| f64::from(e.steps));
        let p5_rank = (eps.len() * 5).div_ceil(100).max(1) - 1;
        Row {
            controller: controller.to_string(),
            scenario: scenario.to_string(),
            horizon,
            period_s,
            episodes: eps.len(),
            success_rate: successes as f64 / eps.len().max(1) as f64,
            success_ci95: wilson(successes, eps.len()),
            mean_steps: steps_est.mean,
            mean_steps_ci95: steps_est.ci95,
            min_steps: eps.iter().map(|e| e.steps).min().unwrap_or(0),
            p5_steps: smallest(eps.iter().map(|e| e.steps), p5_rank + 1)
                .last()
                .copied()
                .unwrap_or(0),
            rms_theta_deg: per(&|e| (e.sum_theta2 / steps(e)).sqrt().to_degrees()),
            rms_x_m: per(&|e| (e.sum_x2 / steps(e)).sqrt()),
            mean_abs_x_m: per(&|e| e.sum_abs_x / steps(e)),
            switches_per_s: per(&|e| f64::from(e.switches) / (steps(e) * period_s)),
            reversals_per_s: per(&|e| Motor::of(e, period_s).reversals_per_s),
            mean_abs_duty: per(&|e| Motor::of(e, period_s).mean_abs_duty),
            duty_tv_per_s: per(&|e| Motor::of(e, period_s).duty_tv_per_s),
            heat: per(&|e| Motor::of(e, period_s).heat),
            faults: eps.iter().map(|e| u64::from(e.faults)).sum(),
            fallback_share: eps.iter().map(|e| f64::from(e.fallback)).sum::<f64>()
                / eps.iter().map(|e| f64::from(e.steps)).sum::<f64>().max(1.0),
            failures: eps.len() - successes,
            worst: worst(seed, eps),
        }
    }
}

/// What one episode asked of its motor, the figures a row averages over its episodes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motor {
    /// Reversals of the motor's direction per second of balance.
    pub reversals_per_s: f64,
    /// Mean |duty|, a fraction of the full push.
    pub mean_abs_duty: f64,
    /// Total variation of the duty per second (full pushes per second).
    pub duty_tv_per_s: f64,
    /// Mean squared motor current as a share of a full-duty stall's.
    pub heat: f64,
}

impl Motor {
    /// Episode `e`'s figures, its periods `period_s` long.
    pub fn of(e: &EpisodeStats, period_s: f64) -> Motor {
        let steps = f64::from(e.steps.max(1));
        Motor {
            reversals_per_s: f64::from(e.reversals) / (steps * period_s),
            mean_abs_duty: e.sum_abs_duty / steps,
            duty_tv_per_s: e.sum_duty_change / (steps * period_s),
            heat: e.sum_heat / steps,
        }
    }

    /// The figures' names: those of the row's fields that average them.
    pub const NAMES: [&'static str; 4] =
        ["reversals_per_s", "mean_abs_duty", "duty_tv_per_s", "heat"];

    /// The figures in the order of [`Motor::NAMES`].
    pub fn values(&self) -> [f64; 4] {
        [
            self.reversals_per_s,
            self.mean_abs_duty,
            self.duty_tv_per_s,
            self.heat,
        ]
    }
}

/// The `k` smallest of `items`, in ascending order, keeping no more than `k` of them at a
/// time (the 5th percentile of ten million episodes sorted a copy of all of them).
fn smallest<T: Ord>(items: impl Iterator<Item = T>, k: usize) -> Vec<T> {
    let mut kept = std::collections::BinaryHeap::with_capacity(k + 1);
    for x in items {
        kept.push(x);
        if kept.len() > k {
            kept.pop();
        }
    }
    kept.into_sorted_vec()
}

fn worst(seed: u64, eps: &[EpisodeStats]) -> Vec<Worst> {
    let failed = eps.iter().enumerate().filter(|(_, e)| !e.success);
    smallest(failed.map(|(i, e)| (e.steps, i as u64)), WORST)
        .into_iter()
        .map(|(steps, episode)| Worst {
            episode,
            steps,
            start: twin::run::start_state(seed, episode).to_array(),
        })
        .collect()
}

/// The table, grouped by horizon and scenario, one line per controller.
pub fn format_table(rows: &[Row]) -> String {
    let mut out = String::new();
    let mut last: Option<u32> = None;
    let sw = rows.iter().map(|r| r.scenario.len()).fold(18, usize::max);
    let cw = rows.iter().map(|r| r.controller.len()).fold(7, usize::max);
    for r in rows {
        if last != Some(r.horizon) {
            if last.is_some() {
                out.push('\n');
            }
            out += &format!(
                "horizon {} ({} s), {} episodes per row, 95% CI\n",
                r.horizon,
                f64::from(r.horizon) * r.period_s,
                r.episodes
            );
            out += &format!(
                "{:<sw$} {:<cw$} {:>22} {:>9} {:>17} {:>6} {:>6} {:>13} {:>15} {:>15} {:>12} {:>12} {:>8} {:>8} {:>7}\n",
                "scenario",
                "ctrl",
                "success",
                "failed",
                "mean steps",
                "min",
                "p5",
                "RMS theta deg",
                "RMS x m",
                "mean |x| m",
                "switch/s",
                "reverse/s",
                "|duty|",
                "heat",
                "faults"
            );
            last = Some(r.horizon);
        }
        let pm = |e: &Estimate, p: usize| format!("{:.p$} ± {:.p$}", e.mean, e.ci95);
        out += &format!(
            "{:<sw$} {:<cw$} {:>6.1}% [{:>5.1}, {:>5.1}] {:>9} {:>17} {:>6} {:>6} {:>13} {:>15} {:>15} {:>12} {:>12} {:>8.3} {:>8.4} {:>7}\n",
            r.scenario,
            r.controller,
            100.0 * r.success_rate,
            100.0 * r.success_ci95[0],
            100.0 * r.success_ci95[1],
            group(r.failures),
            pm(
                &Estimate {
                    mean: r.mean_steps,
                    ci95: r.mean_steps_ci95
                },
                1
            ),
            r.min_steps,
            r.p5_steps,
            pm(&r.rms_theta_deg, 2),
            pm(&r.rms_x_m, 3),
            pm(&r.mean_abs_x_m, 3),
            pm(&r.switches_per_s, 1),
            pm(&r.reversals_per_s, 1),
            r.mean_abs_duty.mean,
            r.heat.mean,
            r.faults
        );
    }
    out
}

/// For each row with failures: how many of how many, then the shortest episodes, one a line,
/// with the start that `host-sim eval --seed` reproduces.
pub fn format_failures(rows: &[Row], seed: u64) -> String {
    let mut out = String::new();
    for r in rows.iter().filter(|r| r.failures > 0) {
        out += &format!(
            "{} on {} at {} steps: {} of {} failed (seed {seed}); the shortest:\n",
            r.controller,
            r.scenario,
            r.horizon,
            group(r.failures),
            group(r.episodes)
        );
        for w in &r.worst {
            let [x, xd, t, td] = w.start;
            out += &format!(
                "  episode {:>7}: {:>6} steps from [{x:.4}, {xd:.4}, {t:.4}, {td:.4}]\n",
                w.episode, w.steps
            );
        }
    }
    out
}

/// `1234567` as `1,234,567`.
pub(crate) fn group(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An episode's motor figures are the means of its one-episode row, by the row's names.
    #[test]
    fn motor_figures_are_a_rows_by_name() {
        let e = EpisodeStats {
            steps: 50,
            reversals: 4,
            sum_abs_duty: 30.0,
            sum_duty_change: 12.0,
            sum_heat: 20.0,
            ..EpisodeStats::default()
        };
        let m = Motor::of(&e, 0.02);
        // 4 reversals in 50 periods of 0.02 s: one second. 12 full pushes of change a second.
        assert_eq!(
            m,
            Motor {
                reversals_per_s: 4.0,
                mean_abs_duty: 0.6,
                duty_tv_per_s: 12.0,
                heat: 0.4
            }
        );
        let row = serde_json::to_value(Row::from_episodes("c", "s", (50, 0.02), 0, &[e])).unwrap();
        for (name, value) in Motor::NAMES.into_iter().zip(m.values()) {
            assert_eq!(row[name]["mean"].as_f64(), Some(value), "{name}");
        }
    }

    #[test]
    fn row_statistics() {
        let eps: Vec<EpisodeStats> = (1..=40u32)
            .map(|s| EpisodeStats {
                steps: s * 10,
                success: s == 40,
                sum_theta2: f64::from(s * 10) * 0.01,
                sum_x2: f64::from(s * 10) * 4.0,
                sum_abs_x: f64::from(s * 10) * 2.0,
                switches: s * 5,
                reversals: s * 2,
                sum_abs_duty: f64::from(s * 10) * 0.25,
                sum_duty_change: f64::from(s * 10) * 0.1,
                sum_heat: f64::from(s * 10) * 0.04,
                faults: 1,
                fallback: s,
            })
            .collect();
        let r = Row::from_episodes("c", "s", (400, 0.02), 9, &eps);
        assert_eq!((r.min_steps, r.p5_steps, r.faults), (10, 20, 40));
        // A tenth of every episode's periods: 820 of 8,200.
        assert_eq!(r.fallback_share, 0.1);
        assert_eq!(r.failures, 39);
        assert_eq!(
            r.worst.iter().map(|w| w.episode).collect::<Vec<_>>(),
            [0, 1, 2, 3, 4]
        );
        assert_eq!(r.worst[2].steps, 30);
        assert_eq!(r.worst[1].start, twin::run::start_state(9, 1).to_array());
        let text = format_failures(std::slice::from_ref(&r), 9);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "c on s at 400 steps: 39 of 40 failed (seed 9); the shortest:"
        );
        assert!(
            lines[1].starts_with("  episode       0:     10 steps from ["),
            "{text}"
        );
        assert_eq!(lines.len(), 6);
        assert_eq!(group(1_234_567), "1,234,567");
        assert_eq!(group(47), "47");
        assert_eq!(r.success_rate, 1.0 / 40.0);
        assert!((r.rms_theta_deg.mean - 0.1f64.to_degrees()).abs() < 1e-12);
        assert!((r.rms_x_m.mean - 2.0).abs() < 1e-12 && r.rms_x_m.ci95 < 1e-12);
        assert!((r.mean_abs_x_m.mean - 2.0).abs() < 1e-12);
        assert!((r.switches_per_s.mean - 25.0).abs() < 1e-9);
        // 2 s reversals in 10 s periods of 0.02 s: 10 a second; 0.1 per period is 5 a second.
        assert!((r.reversals_per_s.mean - 10.0).abs() < 1e-9);
        assert!((r.duty_tv_per_s.mean - 5.0).abs() < 1e-9);
        assert!((r.mean_abs_duty.mean - 0.25).abs() < 1e-12);
        assert!((r.heat.mean - 0.04).abs() < 1e-12);
    }
}
