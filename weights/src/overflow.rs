//! The readings a network can take in f32: past a bound computed from its weights, a sum of
//! its forward pass can leave f32's range, infinities meet (`inf - inf` is NaN, which the
//! ReLU turns off), and the answer is no state's: the last layer's biases alone, or no
//! number at all.

use crate::Weights;

/// The largest magnitude any sum may reach: f32's largest finite value over 34, room for
/// the rounding of every partial sum.
const MOST: f64 = 1e37;

impl Weights {
    /// The largest reading (every channel within plus or minus it) for which no sum of the
    /// forward pass, partial sums included, passes [`MOST`]. Each unit's sum is bounded by
    /// its weights' magnitudes times its inputs' bounds plus its bias's: affine in the
    /// reading's bound, a slope and an offset per unit, layer after layer.
    pub fn reading_bound(&self) -> f32 {
        let mut units = vec![(1.0, 0.0); 4];
        let mut bound = f64::INFINITY;
        for layer in self.tensors.chunks(2) {
            let (w, b) = (&layer[0], &layer[1]);
            units = b
                .iter()
                .zip(w.chunks(units.len()))
                .map(|(&bias, row)| {
                    let start = (0.0, f64::from(bias.abs()));
                    row.iter()
                        .zip(&units)
                        .fold(start, |(s, c), (&w, &(us, uc))| {
                            let w = f64::from(w.abs());
                            (s + w * us, c + w * uc)
                        })
                })
                .collect();
            for &(slope, offset) in &units {
                bound = bound.min((MOST - offset) / slope);
            }
        }
        bound.clamp(0.0, f64::from(f32::MAX)) as f32
    }
}

#[cfg(test)]
mod tests {
    use crate::{BANG_BANG, Weights};

    /// Every weight `w`, every bias `b`, hidden width 16: the sums' bounds by hand.
    fn uniform(w: f32, b: f32) -> Weights {
        let sizes = [16 * 4, 16, 16 * 16, 16, 2 * 16, 2];
        let tensors = sizes.map(|n| vec![0.0; n]);
        let tensors = tensors.map(|mut t| {
            let v = if t.len() == 16 || t.len() == 2 { b } else { w };
            t.fill(v);
            t
        });
        Weights::new(16, BANG_BANG.to_vec(), tensors).unwrap()
    }

    #[test]
    fn the_bound_is_the_largest_sums_by_hand() {
        // Layer 1: 4 w B + b; layer 2: 16 w (4 w B + b) + b; layer 3: 16 w of that + b.
        // With w = 1, b = 0: 1024 B, so B = 1e37 / 1024.
        assert_eq!(uniform(1.0, 0.0).reading_bound(), (1e37f64 / 1024.0) as f32);
        // With w = 0.5, b = 1: 2 B + 1, then 16 B + 9, then 128 B + 73, the largest.
        let expected = ((1e37f64 - 73.0) / 128.0) as f32;
        assert_eq!(uniform(0.5, 1.0).reading_bound(), expected);
        // Weights of zero leave the readings unbounded in f32.
        assert_eq!(uniform(0.0, 1.0).reading_bound(), f32::MAX);
    }

    /// Weights of every sign and size, and each unit's bound summed another way: over the
    /// typed network's rows, slopes and offsets apart.
    #[test]
    fn the_bound_is_the_smallest_over_every_units_sum() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut draw = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32 * 8.0 - 4.0
        };
        let sizes = [16 * 4, 16, 16 * 16, 16, 2 * 16, 2];
        let tensors = sizes.map(|n| (0..n).map(|_| draw()).collect());
        let w = Weights::new(16, BANG_BANG.to_vec(), tensors).unwrap();
        let m = w.to_mlp::<16, 2>().unwrap();
        let abs = |x: f32| f64::from(x.abs());
        let layer = |rows: Vec<Vec<f32>>, b: &[f32], below: &[(f64, f64)]| -> Vec<(f64, f64)> {
            rows.iter()
                .zip(b)
                .map(|(row, &b)| {
                    let slope: f64 = row.iter().zip(below).map(|(&w, u)| abs(w) * u.0).sum();
                    let offset: f64 = row.iter().zip(below).map(|(&w, u)| abs(w) * u.1).sum();
                    (slope, offset + abs(b))
                })
                .collect()
        };
        let l1 = layer(
            m.fc1_weight.iter().map(|r| r.to_vec()).collect(),
            &m.fc1_bias,
            &[(1.0, 0.0); 4],
        );
        let l2 = layer(
            m.fc2_weight.iter().map(|r| r.to_vec()).collect(),
            &m.fc2_bias,
            &l1,
        );
        let l3 = layer(
            m.fc3_weight.iter().map(|r| r.to_vec()).collect(),
            &m.fc3_bias,
            &l2,
        );
        let want = [l1, l2, l3]
            .concat()
            .iter()
            .map(|(s, c)| (1e37 - c) / s)
            .fold(f64::INFINITY, f64::min) as f32;
        let got = w.reading_bound();
        assert!((got / want - 1.0).abs() < 1e-6, "{got} against {want}");
    }

    /// At the bound the f32 forward pass is finite; past f32's range for the sums, it is
    /// not: the bound is what separates them for a network whose sums all grow together.
    #[test]
    fn the_forward_pass_is_finite_at_the_bound_and_not_far_past_it() {
        let w = uniform(1.0, 0.0);
        let net = w.to_mlp::<16, 2>().unwrap();
        let b = w.reading_bound();
        assert!(net.forward(&[b; 4]).iter().all(|q| q.is_finite()));
        assert!(!net.forward(&[b * 1000.0; 4]).iter().all(|q| q.is_finite()));
    }
}
