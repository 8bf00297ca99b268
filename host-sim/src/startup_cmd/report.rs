//! What `host-sim startup` reports: one row per arithmetic, summed over its episodes, as
//! JSON and as a table.

use serde::Serialize;
use twin::startup::{Begin, Outcome};

/// One arithmetic's episodes, summed up.
#[derive(Serialize)]
pub(super) struct Row {
    arithmetic: &'static str,
    episodes: u32,
    /// Balanced within `within_s` of power-on and held `hold_s` after.
    success: f64,
    /// Seconds from power-on to the balance that held, median, 90th and 99th percentile and
    /// largest, over the successful episodes.
    time_to_balance_s: [f64; 4],
    /// The cart's largest distance from the centre, m: the 99th percentile and the largest.
    track_used_m: [f64; 2],
    /// Episodes in which the cart passed into the end-stop margin, and touched a stop.
    into_margin: u32,
    end_stop_contacts: u32,
    /// The largest error of the hanging zero, pole counts, and of the cart's centre, cart
    /// counts, over the episodes that took them; none (`null`, `-`) where none did.
    zero_error_counts: Option<i64>,
    centre_error_counts: Option<i64>,
    /// At steady balance (an episode's second half): the cart's RMS distance from the
    /// centre, m, median and 99th percentile over the episodes; the mean |duty|.
    steady_rms_x_m: [f64; 2],
    steady_mean_abs_duty: f64,
    catches: u64,
    misses: u64,
    falls: u64,
}

/// The run's rows and what they ran.
#[derive(Serialize)]
pub(super) struct Report {
    pub(super) start: Begin,
    /// The push `--knock` gave: its force, N, and when, s after power-on.
    pub(super) knock: Option<[f64; 2]>,
    pub(super) seed: u64,
    pub(super) within_s: f64,
    pub(super) hold_s: f64,
    /// `--cart-start`, m, and `--zero-error`, degrees: what the episodes began from.
    pub(super) cart_start_m: f64,
    pub(super) zero_error_deg: f64,
    pub(super) startup: String,
    pub(super) rows: Vec<Row>,
}

/// The row of one arithmetic's `outcomes`: success is a balance begun by period `within`
/// that lasted to the end, its time counted from period `from` (power-on, or a knock: a
/// balance the knock did not break counts as back at once); the margin is the track's
/// accepted half-length `margin`.
pub(super) fn summarise(
    arithmetic: &'static str,
    outcomes: &[Outcome],
    (from, within): (u32, u32),
    tau: f64,
    margin: f64,
) -> Row {
    let mut times: Vec<f64> = outcomes
        .iter()
        .filter_map(|o| o.balanced_from.filter(|&b| b <= within))
        .map(|b| f64::from(b.saturating_sub(from)) * tau)
        .collect();
    times.sort_by(f64::total_cmp);
    let mut track: Vec<f64> = outcomes.iter().map(|o| o.max_abs_x).collect();
    track.sort_by(f64::total_cmp);
    let steady: Vec<_> = outcomes.iter().filter_map(|o| o.steady).collect();
    let mut rms_x: Vec<f64> = steady.iter().map(|s| s.rms_x).collect();
    rms_x.sort_by(f64::total_cmp);
    let duty = steady.iter().map(|s| s.mean_abs_duty).sum::<f64>() / steady.len() as f64;
    let count = |f: &dyn Fn(&Outcome) -> bool| outcomes.iter().filter(|o| f(o)).count() as u32;
    let total = |f: &dyn Fn(&Outcome) -> u32| outcomes.iter().map(|o| u64::from(f(o))).sum();
    Row {
        arithmetic,
        episodes: outcomes.len() as u32,
        success: times.len() as f64 / outcomes.len().max(1) as f64,
        time_to_balance_s: [0.5, 0.9, 0.99, 1.0].map(|q| quantile(&times, q)),
        track_used_m: [0.99, 1.0].map(|q| quantile(&track, q)),
        into_margin: count(&|o| o.max_abs_x > margin),
        end_stop_contacts: count(&|o| o.end_stop_periods > 0),
        zero_error_counts: worst(outcomes, |o| o.zero_error),
        centre_error_counts: worst(outcomes, |o| o.centre_error),
        steady_rms_x_m: [0.5, 0.99].map(|q| quantile(&rms_x, q)),
        steady_mean_abs_duty: duty,
        catches: total(&|o| o.transitions.caught),
        misses: total(&|o| o.transitions.missed),
        falls: total(&|o| o.transitions.fell),
    }
}

/// The largest |error| `of` the outcomes that took their zero; none where none did (it was
/// shown as i64's largest, 9223372036854775807 counts, as if measured, where one did not).
fn worst(outcomes: &[Outcome], of: impl Fn(&Outcome) -> Option<i64>) -> Option<i64> {
    outcomes.iter().filter_map(|o| of(o).map(i64::abs)).max()
}

/// A count for the table, `-` for none.
fn shown(count: Option<i64>) -> String {
    count.map_or_else(|| "-".into(), |c| c.to_string())
}

/// The `q` quantile of `sorted` (the nearest rank below); NaN for none.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    match sorted.len() {
        0 => f64::NAN,
        n => sorted[((n - 1) as f64 * q).floor() as usize],
    }
}

/// The report as a table.
pub(super) fn table(r: &Report) -> String {
    let since = match r.knock {
        Some([force, at]) => format!("of a {force} N knock at {at} s"),
        None => "of power-on".into(),
    };
    let mut out = format!(
        "start-up from {:?}, seed {}: balanced within {} s {since} and held {} s\n  {}\n\n  \
         {:<6} {:>8} {:>8} {:>25} {:>15} {:>7} {:>6} {:>5} {:>6} {:>18} {:>7} {:>16}\n",
        r.start,
        r.seed,
        r.within_s,
        r.hold_s,
        r.startup,
        "",
        "episodes",
        "success",
        "time to balance s p50/p90/p99/max",
        "track m p99/max",
        "margin",
        "stops",
        "zero",
        "centre",
        "steady x m p50/p99",
        "|duty|",
        "catch/miss/fall"
    );
    for w in &r.rows {
        let t = w.time_to_balance_s;
        out += &format!(
            "  {:<6} {:>8} {:>7.1}% {:>25} {:>15} {:>7} {:>6} {:>5} {:>6} {:>18} {:>6.1}% {:>16}\n",
            w.arithmetic,
            w.episodes,
            100.0 * w.success,
            format!("{:.1}/{:.1}/{:.1}/{:.1}", t[0], t[1], t[2], t[3]),
            format!("{:.3}/{:.3}", w.track_used_m[0], w.track_used_m[1]),
            w.into_margin,
            w.end_stop_contacts,
            shown(w.zero_error_counts),
            shown(w.centre_error_counts),
            format!("{:.3}/{:.3}", w.steady_rms_x_m[0], w.steady_rms_x_m[1]),
            100.0 * w.steady_mean_abs_duty,
            format!("{}/{}/{}", w.catches, w.misses, w.falls),
        );
    }
    out
}
