//! Where the fit starts: estimates read off the logs directly, so that the simulation-error
//! minimisation starts near its minimum whatever the rig file guessed. A pendulum's
//! simulated swing drifts out of phase with the measured one within a few cycles of a
//! wrong length, and the sum of squares then has a minimum at every cycle slipped; started
//! from the length its measured period gives, the fit is in the right one.

use firmware::cartpole::Params;

use super::lm::solve_spd;
use super::model::{CartData, SwingData};

/// The pendulum's length and pivot friction from a free swing: its period, corrected for
/// the amplitude, gives the length of the uniform rod that swings at it
/// (`T0 = 2 pi sqrt(4 l / (3 g))`), and the decay of its successive amplitudes the
/// friction (`A ~ exp(-3 mu_p t / (8 m l^2))`, the swing's damping linearised about
/// hanging). `None` without two full swings.
pub fn swing(s: &SwingData, p: &Params) -> Option<(f64, f64)> {
    let c = &s.counts;
    // Passes through hanging, by linear interpolation, in periods.
    let passes: Vec<f64> = (1..c.len())
        .filter(|&k| c[k - 1].signum() != c[k].signum())
        .map(|k| (k - 1) as f64 + c[k - 1] / (c[k - 1] - c[k]))
        .collect();
    if passes.len() < 3 {
        return None;
    }
    let half = (passes[passes.len() - 1] - passes[0]) / (passes.len() - 1) as f64 * p.tau;
    // The amplitude of each half swing, rad, and when it peaked, s.
    let peaks: Vec<(f64, f64)> = passes
        .windows(2)
        .filter_map(|w| {
            let range = (w[0].ceil() as usize)..=(w[1].floor() as usize).min(c.len() - 1);
            let k = range.max_by(|&a, &b| c[a].abs().total_cmp(&c[b].abs()))?;
            Some((k as f64 * p.tau, c[k].abs() / s.per_rad))
        })
        .collect();
    let mean =
        |f: &dyn Fn(f64) -> f64| peaks.iter().map(|&(_, a)| f(a)).sum::<f64>() / peaks.len() as f64;
    let (a2, a4) = (mean(&|a| a * a), mean(&|a| a.powi(4)));
    // The large-amplitude pendulum's period series, T = T0 (1 + A^2/16 + 11 A^4/3072).
    let t0 = 2.0 * half / (1.0 + a2 / 16.0 + 11.0 * a4 / 3072.0);
    let length = 3.0 * p.gravity * t0 * t0 / (16.0 * core::f64::consts::PI.powi(2));
    let decay = -slope(
        &peaks
            .iter()
            .map(|&(t, a)| (t, a.max(1e-9).ln()))
            .collect::<Vec<_>>(),
    );
    let friction = (8.0 / 3.0 * p.masspole * length * length * decay).clamp(0.0, 0.1);
    length.is_finite().then_some((length, friction))
}

/// The least-squares slope of `points`.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p.0 / n, y + p.1 / n));
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx > 0.0 { sxy / sxx } else { 0.0 }
}

/// The motor's stall force, damping and the cart's Coulomb friction by linear least squares
/// on the cart's equation of motion, at dead time `dead`: the cart's and pole's
/// accelerations from second differences of the counts, the pole's reaction
/// (`m l (w^2 sin - theta_acc cos)`, with `p`'s length) taken off the cart's `M x_acc`, and
/// what is left regressed on the duty over the two periods the difference spans, the
/// velocity, and the friction's direction times the weight. An equation-error estimate,
/// biased by the differences' noise, good enough to start from; `None` where it gives no
/// positive force.
pub fn cart(c: &CartData, p: &Params, dead: usize) -> Option<(f64, f64, f64)> {
    let (tau, m, ml) = (p.tau, p.total_mass(), p.polemass_length());
    let x: Vec<f64> = c.counts.iter().map(|v| v / c.per_m).collect();
    let phi: Vec<f64> = c.pole.iter().map(|v| v / c.per_rad).collect();
    let mut a = [0.0; 9];
    let mut b = [0.0; 3];
    for k in 1..x.len().saturating_sub(1) {
        let acc = (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (tau * tau);
        let vel = (x[k + 1] - x[k - 1]) / (2.0 * tau);
        let w = (phi[k + 1] - phi[k - 1]) / (2.0 * tau);
        let alpha = (phi[k + 1] - 2.0 * phi[k] + phi[k - 1]) / (tau * tau);
        let theta = core::f64::consts::PI + phi[k];
        let y = m * acc - ml * (w * w * theta.sin() - alpha * theta.cos());
        let duty = 0.5 * (c.acting(k - 1, dead) + c.acting(k, dead));
        let row = [duty, -vel, -vel.signum() * m * p.gravity];
        for i in 0..3 {
            b[i] += row[i] * y;
            for j in 0..3 {
                a[i * 3 + j] += row[i] * row[j];
            }
        }
    }
    let f = solve_spd(&a, &b, 3)?;
    (f[0] > 0.0 && f[0].is_finite()).then(|| (f[0], f[1].max(0.0), f[2].clamp(0.0, 1.0)))
}
