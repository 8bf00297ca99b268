//! How good a policy is: greedy episodes on fresh starts, and the paper's "solved" measure
//! on a run's returns.

use firmware::cartpole::Action;
use firmware::network::Mlp;
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use twin::run::nominal_predictor;
use twin::{Domain, World};

/// A greedy evaluation's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalResult {
    /// Episodes run.
    pub episodes: usize,
    /// Their step limit.
    pub max_steps: u32,
    /// Mean return.
    pub mean: f64,
    /// Worst return.
    pub min: f64,
    /// How far from upright and centred it held the plant: the mean over every step of
    /// `(theta / theta_max)^2 + (x / x_max)^2`. Between snapshots of equal returns, the lower
    /// is the better controller.
    #[serde(default)]
    pub cost: f64,
}

impl EvalResult {
    /// Whether `self` beats `other`: a higher mean return, or an equal one held closer to
    /// upright and centre.
    pub fn beats(&self, other: &EvalResult) -> bool {
        self.mean > other.mean || (self.mean == other.mean && self.cost < other.cost)
    }
}

/// The random streams of one evaluation: starts, the worlds drawn from its domain, and
/// those worlds' sensor noise and pushes (drawn from only where the world has them, so a
/// nominal evaluation draws only starts).
pub struct EvalStreams {
    /// Start states.
    pub start: Pcg64Mcg,
    /// Worlds from the domain.
    pub world: Pcg64Mcg,
    /// Sensor noise.
    pub noise: Pcg64Mcg,
    /// Push sides.
    pub pushes: Pcg64Mcg,
}

/// Runs `episodes` greedy episodes of at most `max_steps`, each in a world of `domain`;
/// with `compensate`, deciding on readings advanced over the world's dead time.
pub fn evaluate<const H: usize>(
    net: &Mlp<H>,
    episodes: usize,
    max_steps: u32,
    domain: &Domain,
    compensate: bool,
    rng: &mut EvalStreams,
) -> EvalResult {
    let (mut sum, mut min) = (0.0, f64::INFINITY);
    let (mut cost, mut steps) = (0.0f64, 0u64);
    for _ in 0..episodes {
        let scenario = domain.sample(&mut rng.world);
        let mut world = World::start(
            &scenario,
            max_steps,
            &mut rng.start,
            &mut rng.noise,
            &mut rng.pushes,
        );
        let force = scenario.params.force_mag;
        let mut pred = nominal_predictor(if compensate { scenario.delay } else { 0 });
        let mut ret = 0.0;
        loop {
            let action = net.greedy_action(&pred.predict(&world.observe()));
            let sign = if action == Action::Right { 1.0 } else { -1.0 };
            pred.record_push(action);
            let t = world.apply(sign * force);
            ret += f64::from(t.reward);
            let (s, p) = (world.state(), &scenario.params);
            cost += (s.theta / p.theta_threshold_radians).powi(2) + (s.x / p.x_threshold).powi(2);
            steps += 1;
            if t.terminated || t.truncated {
                break;
            }
        }
        sum += ret;
        min = f64::min(min, ret);
    }
    EvalResult {
        episodes,
        max_steps,
        mean: sum / episodes as f64,
        min,
        cost: cost / steps.max(1) as f64,
    }
}

/// First episode (1-based) whose trailing 100-episode mean return reaches `threshold`.
pub fn solved_episode(returns: &[f64], threshold: f64) -> Option<usize> {
    trailing_means(returns, 100)
        .position(|m| m >= threshold)
        .map(|i| i + 100)
}

/// Means of every full window of `w` consecutive values, in order.
pub fn trailing_means(values: &[f64], w: usize) -> impl Iterator<Item = f64> + '_ {
    values
        .windows(w)
        .map(move |win| win.iter().sum::<f64>() / w as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solved_episode_is_the_first_full_window_reaching_the_threshold() {
        let mut r = vec![100.0; 150];
        r.extend(vec![200.0; 100]);
        // Window ending at episode e has (e - 150) returns of 200: mean 100 + (e - 150).
        assert_eq!(solved_episode(&r, 195.0), Some(245));
        assert_eq!(solved_episode(&r[..99], 0.0), None);
    }
}
