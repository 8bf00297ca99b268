//! How good a policy is: greedy episodes on fresh starts, and the paper's "solved" measure
//! on a run's returns.

use firmware::cartpole::{CartPole, Params};
use firmware::network::Mlp;
use rand_core::Rng;
use serde::{Deserialize, Serialize};

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
}

/// Runs `episodes` greedy episodes of at most `max_steps` with starts from `rng`.
pub fn evaluate<const H: usize, R: Rng>(
    net: &Mlp<H>,
    episodes: usize,
    max_steps: u32,
    rng: &mut R,
) -> EvalResult {
    let mut env = CartPole::new(Params::default(), max_steps);
    let (mut sum, mut min) = (0.0, f64::INFINITY);
    for _ in 0..episodes {
        let mut obs = env.reset(rng);
        let mut ret = 0.0;
        loop {
            let t = env.step(net.greedy_action(&obs));
            ret += f64::from(t.reward);
            obs = t.obs;
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
