//! A linear state feedback as a Q-network of any supported shape: a policy whose behaviour
//! is known without training, to carry a network of many levels through the tools (export,
//! int8, C, a target over the link) and see that each runs it as the others do.

use firmware::network::{OBS_DIM, shapes};

use crate::{Result, Weights};

/// Q-values' common part: a trained network's are large beside their differences, and the
/// int8 export must keep the differences that decide.
const COMMON: f32 = 10.0;

/// The network of hidden width `width` whose output `i`, driving `levels[i]`, scores
/// `Q_i = l_i u - l_i^2 / 2 + 10` for the feedback `u = -gain . obs` (a fraction of the full
/// push): the largest is the level nearest `u`, so it drives the feedback rounded to the
/// levels and held at their ends. The first hidden layer carries the feedback's parts
/// `relu(-gain_k obs_k)` and `relu(gain_k obs_k)` in units 0 to 7 (every supported width
/// has them), the second passes them on, the other units are dead; so the output weights
/// are the levels, and the gain's range is the first layer's, whose units int8 scales one
/// by one. Refused as [`Weights::new`] refuses its shape or levels.
pub fn state_feedback(width: usize, levels: &[f32], gain: [f32; OBS_DIM]) -> Result<Weights> {
    let a = levels.len();
    crate::check_shape(width, a)?;
    let [mut w1, b1, mut w2, b2, mut w3, mut b3] = shapes(width, a).map(|s| vec![0.0f32; s.len()]);
    for (k, g) in gain.iter().enumerate() {
        // Units k and k + 4 carry the feedback's parts relu(-g s) and relu(g s).
        w1[k * OBS_DIM + k] = -g;
        w1[(k + OBS_DIM) * OBS_DIM + k] = *g;
        for unit in [k, k + OBS_DIM] {
            w2[unit * width + unit] = 1.0;
        }
        for (i, l) in levels.iter().enumerate() {
            w3[i * width + k] = *l;
            w3[i * width + k + OBS_DIM] = -l;
        }
    }
    for (b, l) in b3.iter_mut().zip(levels) {
        *b = COMMON - l * l / 2.0;
    }
    Weights::new(width, levels.to_vec(), [w1, b1, w2, b2, w3, b3])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_network_drives_the_level_nearest_the_feedback() {
        let levels = [-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0];
        let gain = [-0.5, -1.0, -20.0, -3.0];
        let w = state_feedback(64, &levels, gain).unwrap();
        let net = w.to_mlp::<64, 7>().unwrap();
        for (obs, want) in [
            ([0.0, 0.0, 0.0, 0.0], 3),
            ([0.0, 0.0, 0.012, 0.0], 4),
            ([0.0, 0.0, 0.02, 0.0], 5),
            ([0.0, 0.0, -0.02, 0.0], 1),
            ([0.2, 0.0, 0.3, 0.0], 6),
            ([-0.2, 0.0, -0.3, 0.0], 0),
        ] {
            let u: f32 = obs.iter().zip(gain).map(|(s, k)| -k * s).sum();
            let q = net.forward(&obs);
            assert_eq!(firmware::network::argmax(&q), want, "{obs:?}: u {u}, {q:?}");
            // Q_i - Q_j = (l_i - l_j)(u - (l_i + l_j) / 2), to f32 rounding.
            let d = (levels[6] - levels[0]) * (u - (levels[6] + levels[0]) / 2.0);
            assert!((q[6] - q[0] - d).abs() < 1e-4, "{obs:?}: {q:?}");
        }
        assert!(state_feedback(48, &levels, gain).is_err());
    }
}
