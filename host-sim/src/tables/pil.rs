//! The processor-in-the-loop columns of a results table, from `eval --pil --json`'s `pil`
//! array.

use serde::Deserialize;

use crate::eval::group;

/// One row's check, as `eval --pil` writes it.
#[derive(Deserialize)]
pub struct Check {
    controller: String,
    scenario: String,
    horizon: u32,
    periods: u64,
    mismatches: u64,
    time_ns: [u64; 3],
    overruns: u64,
}

impl Check {
    /// Its controller, scenario and horizon.
    pub fn key(&self) -> (&str, &str, u32) {
        (&self.controller, &self.scenario, self.horizon)
    }
}

/// The columns' names, after the controller's.
pub const COLUMNS: [&str; 5] = [
    "periods",
    "mismatches",
    "time us median / p99 / worst",
    "worst of period",
    "overruns",
];

/// The check of `controller` on `scenario` at `horizon`.
pub fn find<'a>(
    checks: &'a [Check],
    controller: &str,
    scenario: &str,
    horizon: u32,
) -> Option<&'a Check> {
    checks
        .iter()
        .find(|c| c.controller == controller && c.scenario == scenario && c.horizon == horizon)
}

/// The cells of [`COLUMNS`] for `check`, its period `period_s` long.
pub fn cells(check: &Check, period_s: f64) -> [String; 5] {
    let us = check.time_ns.map(|t| t as f64 / 1e3);
    let worst = check.time_ns[2] as f64 / (period_s * 1e9);
    [
        group(check.periods as usize),
        group(check.mismatches as usize),
        format!("{:.0} / {:.0} / {:.0}", us[0], us[1], us[2]),
        format!("{:.1}%", 100.0 * worst),
        group(check.overruns as usize),
    ]
}
