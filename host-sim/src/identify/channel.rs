//! One encoder's residuals in a fitted log: its measured and simulated counts, and the
//! figures of their differences that say whether the fit holds (`misfit` judges them).

use std::ops::Range;

/// The standard deviation of an encoder's rounding to a count, counts: `1/sqrt(12)`.
pub const ROUNDING_SD: f64 = 0.288_675_134_594_812_9;
/// How long the window is whose residuals are reported as the largest, s.
pub const WINDOW_S: f64 = 1.0;

/// One encoder's measured and simulated counts in a log, and what their differences say.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Which encoder: `cart` or `pole`.
    pub name: &'static str,
    /// The measured counts (each count's midpoint; the pole's from hanging).
    pub measured: Vec<f64>,
    /// The simulated counts.
    pub simulated: Vec<f64>,
    /// The RMS of their difference, counts.
    pub rms: f64,
    /// The lag-1 autocorrelation of their difference.
    pub autocorrelation: f64,
    /// The window of [`WINDOW_S`] (periods from the trace's first) whose RMS difference is
    /// the largest, and that RMS.
    pub worst: (Range<usize>, f64),
}

/// The RMS of `e`, 0 for none.
fn rms(e: &[f64]) -> f64 {
    (e.iter().map(|v| v * v).sum::<f64>() / e.len().max(1) as f64).sqrt()
}

/// The lag-1 autocorrelation of `e` about its mean, 0 where it does not vary.
fn autocorrelation(e: &[f64]) -> f64 {
    let mean = e.iter().sum::<f64>() / e.len().max(1) as f64;
    let d: Vec<f64> = e.iter().map(|v| v - mean).collect();
    let var: f64 = d.iter().map(|v| v * v).sum();
    let lag: f64 = d.windows(2).map(|w| w[0] * w[1]).sum();
    if var > 0.0 { lag / var } else { 0.0 }
}

impl Channel {
    /// The channel `name` of `measured` and `simulated` counts, at `window` periods a window.
    pub fn new(
        name: &'static str,
        measured: Vec<f64>,
        simulated: Vec<f64>,
        window: usize,
    ) -> Channel {
        let e: Vec<f64> = measured
            .iter()
            .zip(&simulated)
            .map(|(a, b)| a - b)
            .collect();
        let window = window.clamp(1, e.len().max(1));
        let worst = (0..e.len().div_ceil(window))
            .map(|i| {
                let r = i * window..((i + 1) * window).min(e.len());
                let v = rms(&e[r.clone()]);
                (r, v)
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0..0, 0.0));
        Channel {
            name,
            rms: rms(&e),
            autocorrelation: autocorrelation(&e),
            worst,
            measured,
            simulated,
        }
    }
}
