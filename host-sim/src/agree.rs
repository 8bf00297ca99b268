//! How often the integer network (`firmware::network::int`) takes the float network's action,
//! on states the float policy visits, and where the two part.
//!
//! The states are every observation the float policy's network is asked about in episodes
//! of the default robustness set (500 steps, the dead time predicted, as in `eval`), row
//! after row until the requested count; the episodes' seed is not the calibration's
//! (`twin::calibrate`), so the quantiser has not seen them. A disagreement is binned by the
//! float network's own margin `|Q_right - Q_left|`: where it is tiny, either action is about
//! as good, and a flip costs little.

use anyhow::{Result, bail};
use firmware::fixed::from_state as fixed_obs;
use firmware::network::argmax;
use rayon::prelude::*;
use serde::Serialize;
use twin::Scenario;
use twin::calibrate::visited;

use crate::eval::Net;

/// Upper bounds of the margin bins (the last is open).
pub const MARGIN_BINS: [f64; 5] = [0.01, 0.03, 0.1, 0.3, f64::INFINITY];

/// One margin bin.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Bin {
    /// States whose float margin is below this (and at or above the previous bin's).
    pub margin_below: f64,
    /// States in the bin.
    pub states: u64,
    /// Of them, where the integer network pushed the other way.
    pub disagree: u64,
}

/// One scenario's count.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ScenarioCount {
    /// Scenario spec.
    pub scenario: String,
    /// States visited.
    pub states: u64,
    /// Disagreements among them.
    pub disagree: u64,
}

/// The agreement report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// States compared.
    pub states: u64,
    /// Where both networks chose the same action.
    pub agree: u64,
    /// Disagreements by the float network's margin.
    pub by_margin: Vec<Bin>,
    /// By scenario.
    pub by_scenario: Vec<ScenarioCount>,
    /// The largest float margin at which the two disagreed, and its observation.
    pub worst: Option<(f64, [f32; 4])>,
}

/// One row's counts, before they are summed.
struct RowCount {
    count: ScenarioCount,
    bins: Vec<Bin>,
    worst: Option<(f64, [f32; 4])>,
}

/// The margin bins, empty.
fn empty_bins() -> Vec<Bin> {
    MARGIN_BINS
        .iter()
        .map(|&m| Bin {
            margin_below: m,
            states: 0,
            disagree: 0,
        })
        .collect()
}

/// The float network's margin (its best Q-value less the next best: `|Q[1] - Q[0]|` with
/// two outputs) and whether the two networks choose differently. A non-finite Q-value
/// decides nothing: a disagreement, in the widest bin.
fn compare(q: &[f32], qi: &[i32]) -> (f64, bool) {
    let Some(best) = q.iter().all(|v| v.is_finite()).then(|| argmax(q)) else {
        return (f64::MAX, true);
    };
    let next = (0..q.len())
        .filter(|&i| i != best)
        .map(|i| f64::from(q[i]))
        .fold(f64::NEG_INFINITY, f64::max);
    let margin = f64::from(q[best]) - next;
    (margin, best != argmax(qi))
}

/// Compares the two networks on `per_row` states of scenario `s`, from episodes of `seed`.
/// Episodes end early when the policy fails, so they run one at a time until the row has
/// its share.
fn count_row(net: &Net, s: &Scenario, per_row: u64, seed: u64) -> RowCount {
    let mut bins = empty_bins();
    let mut count = ScenarioCount {
        scenario: s.name.clone(),
        states: 0,
        disagree: 0,
    };
    let mut worst: Option<(f64, [f32; 4])> = None;
    let mut episode = 0;
    while count.states < per_row {
        let one = visited(
            net,
            std::slice::from_ref(s),
            episode..episode + 1,
            500,
            seed,
        );
        episode += 1;
        for obs in one.iter().take((per_row - count.states) as usize) {
            let q = net.forward(obs);
            let qi = net
                .forward_int(&fixed_obs(obs))
                .expect("checked by the caller");
            let (margin, differ) = compare(q.values(), qi.values());
            count.states += 1;
            let bin = bins.iter_mut().find(|b| margin < b.margin_below);
            if let Some(b) = bin {
                b.states += 1;
                b.disagree += u64::from(differ);
            }
            if differ {
                count.disagree += 1;
                if worst.is_none_or(|(m, _)| margin > m) {
                    worst = Some((margin, *obs));
                }
            }
        }
    }
    RowCount { count, bins, worst }
}

/// Compares the two networks of `net` on at least `states` visited states (see [the
/// module](self)), from episodes of `seed` on `machine`'s default set; `net` must have been built with its integer
/// version.
pub fn agreement(net: &Net, machine: &twin::Machine, states: u64, seed: u64) -> Result<Report> {
    if net.forward_int(&[0; 4]).is_none() {
        bail!("the policy was loaded without its integer version");
    }
    let rows = Scenario::default_set_on(machine);
    let per_row = states.div_ceil(rows.len() as u64);
    let counts: Vec<RowCount> = rows
        .par_iter()
        .map(|s| count_row(net, s, per_row, seed))
        .collect();
    let mut report = Report {
        states: 0,
        agree: 0,
        by_margin: empty_bins(),
        by_scenario: Vec::new(),
        worst: None,
    };
    for RowCount { count, bins, worst } in counts {
        report.states += count.states;
        report.agree += count.states - count.disagree;
        for (total, b) in report.by_margin.iter_mut().zip(bins) {
            total.states += b.states;
            total.disagree += b.disagree;
        }
        if let Some(w) = worst
            && report.worst.is_none_or(|(m, _)| w.0 > m)
        {
            report.worst = Some(w);
        }
        report.by_scenario.push(count);
    }
    Ok(report)
}

/// The report as a table.
pub fn format_report(r: &Report) -> String {
    use std::fmt::Write;
    let pct = |a: u64, n: u64| {
        if n == 0 {
            0.0
        } else {
            100.0 * a as f64 / n as f64
        }
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "int8 against f32: the same action in {} of {} visited states ({:.3}%)",
        r.agree,
        r.states,
        pct(r.agree, r.states)
    );
    let _ = writeln!(s, "\nfloat margin |Q_right - Q_left|     states  disagree");
    let mut lower = 0.0;
    for b in &r.by_margin {
        let range = if b.margin_below.is_finite() {
            format!("[{lower}, {})", b.margin_below)
        } else {
            format!(">= {lower}")
        };
        let _ = writeln!(
            s,
            "{range:<34} {:>7} {:>9} ({:.2}%)",
            b.states,
            b.disagree,
            pct(b.disagree, b.states)
        );
        lower = b.margin_below;
    }
    let width = r
        .by_scenario
        .iter()
        .map(|c| c.scenario.len())
        .max()
        .unwrap_or(8)
        .max(8);
    let _ = writeln!(s, "\n{:<width$}  states  disagree", "scenario");
    for c in &r.by_scenario {
        let _ = writeln!(
            s,
            "{:<width$} {:>7} {:>9} ({:.2}%)",
            c.scenario,
            c.states,
            c.disagree,
            pct(c.disagree, c.states)
        );
    }
    if let Some((m, obs)) = r.worst {
        let _ = writeln!(s, "\nlargest margin of a disagreement: {m:.4} at {obs:?}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_nan_or_infinite_q_value_is_a_disagreement_not_a_zero_margin() {
        assert_eq!(compare(&[1.0, 3.0], &[0, 5]), (2.0, false));
        assert_eq!(compare(&[1.0, 3.0], &[5, 0]), (2.0, true));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(compare(&[bad, 0.0], &[0, 5]), (f64::MAX, true));
            assert_eq!(compare(&[0.0, bad], &[5, 0]), (f64::MAX, true));
        }
        // The widest bin takes it.
        assert!(f64::MAX < *MARGIN_BINS.last().unwrap());
    }
}
