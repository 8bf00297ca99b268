use firmware::fixed::from_state as fixed_obs;
use firmware::rig::Rig;
use shipped::policy::POLICY;

use super::quantiser::{adaptive_round, quantise_bias, quantise_weights, requant, symmetric};
use super::*;
use crate::Weights;

#[test]
fn a_requantisation_applies_its_factor_to_16_bits_and_saturates_late() {
    // From the smallest factor whose saturating accumulator fits in an i32.
    let mut factor = 2e-7;
    while factor < 10.0 {
        let r = requant(factor);
        let applied =
            f64::from(r.multiplier) / 2f64.powi(i32::from(r.pre_shift) + i32::from(r.post_shift));
        assert!((applied / factor - 1.0).abs() < 2e-5, "{factor}: {r:?}");
        // The largest accumulator below saturation keeps 14 bits after the pre-shift.
        let t = (255.0 / factor) / 2f64.powi(i32::from(r.pre_shift));
        assert!(
            (16_383.0..32_767.0).contains(&t) || r.pre_shift == 0,
            "{factor}: {t}"
        );
        // And the output saturates where the real product reaches 255.5.
        let acc = (255.5 / factor).ceil() as i32;
        assert_eq!(r.apply(acc), 255, "{factor}");
        factor *= 1.37;
    }
}

/// `e^T M e` for the rounding of `w` to `q` at scale `s`.
fn output_error(w: &[f32], q: &[i8], s: f64, m: &[f64]) -> f64 {
    let e: Vec<f64> = w
        .iter()
        .zip(q)
        .map(|(w, q)| f64::from(*w) - s * f64::from(*q))
        .collect();
    m.chunks(e.len())
        .zip(&e)
        .map(|(row, ei)| ei * row.iter().zip(&e).map(|(m, e)| m * e).sum::<f64>())
        .sum()
}

#[test]
fn adaptive_rounding_lowers_the_output_error_and_stays_beside_nearest() {
    let mut seed = 7u64;
    let mut next = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for n in [4usize, 16, 64] {
        // Correlated inputs: M = A A^T / k for random A, as activations give.
        let k = 3 * n;
        let a: Vec<f64> = (0..n * k).map(|_| next()).collect();
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                m[i * n + j] = (0..k).map(|c| a[i * k + c] * a[j * k + c]).sum::<f64>() / k as f64;
            }
        }
        let w: Vec<f32> = (0..n).map(|_| (next() * 2.0 - 1.0) as f32).collect();
        let s = symmetric(&w);
        let nearest: Vec<i8> = quantise_weights(&w, s).collect();
        let adaptive = adaptive_round(&w, s, &m);
        assert!(output_error(&w, &adaptive, s, &m) <= output_error(&w, &nearest, s, &m));
        assert!(
            adaptive
                .iter()
                .zip(&nearest)
                .all(|(a, b)| (i16::from(*a) - i16::from(*b)).abs() <= 1)
        );
        // Uncorrelated inputs: each weight's own error is all there is, and nearest is best.
        let diagonal: Vec<f64> = (0..n * n)
            .map(|i| if i % (n + 1) == 0 { 1.0 } else { 0.0 })
            .collect();
        assert_eq!(adaptive_round(&w, s, &diagonal), nearest);
    }
}

/// A calibration set of the tests' own: states along a swinging, drifting trajectory.
fn trajectory() -> Vec<[f32; 4]> {
    (0..4000)
        .map(|i| {
            let t = i as f32 * 0.01;
            [
                0.8 * (0.3 * t).sin(),
                0.5 * (0.7 * t).cos(),
                0.05 * (2.1 * t).sin(),
                0.4 * (1.3 * t).cos(),
            ]
        })
        .collect()
}

#[test]
fn the_shipped_policy_keeps_its_decisions_where_they_matter() {
    let w = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    let states = trajectory();
    for g in [Granularity::PerChannel, Granularity::PerTensor] {
        let q = quantise(&w, &states, g).unwrap();
        let net = q.to_qmlp::<64, 2>().unwrap();
        let (mut big, mut kept, mut err, mut size) = (0, 0, 0.0f64, 0.0f64);
        for s in &states {
            let f = POLICY.forward(s);
            let a = f64::from(f[1] - f[0]) / 2.0;
            let qi = net.forward(&fixed_obs(s));
            err += (f64::from(qi[1]) * q.q_scale() - a).abs();
            size += a.abs();
            // A clear preference (a margin of 0.3 and more) must survive, but for a few
            // states away from where the policy goes (`host-sim agree` counts the flips on
            // visited states: docs/QUANTISATION.md).
            if a.abs() >= 0.15 {
                big += 1;
                kept += u32::from((qi[1] > qi[0]) == (f[1] > f[0]));
            }
        }
        assert!(
            big > 500 && kept * 100 >= big * 98,
            "{g:?}: {kept} of {big}"
        );
        assert!(
            err < 0.2 * size,
            "{g:?}: advantage error {err} against {size}"
        );
    }
}

#[test]
fn what_cannot_be_represented_is_refused() {
    let w = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    let e = quantise(&w, &[], Granularity::PerChannel).unwrap_err();
    assert!(e.is_input() && e.to_string().contains("calibration"), "{e}");
    // A unit with tiny weights and a large bias: its bias does not fit its accumulator.
    let mut t = w.tensors().clone();
    for v in &mut t[0][..4] {
        *v = 1e-30;
    }
    t[1][0] = 5.0;
    let odd = Weights::new(64, crate::BANG_BANG.to_vec(), t).unwrap();
    let e = quantise(&odd, &[[0.0; 4]], Granularity::PerChannel).unwrap_err();
    assert!(e.to_string().contains("`fc1.bias`"), "{e}");
}

#[test]
fn sources_name_their_scale_and_size() {
    let w = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    let q = quantise(&w, &[[0.01, 0.0, 0.02, 0.0]], Granularity::PerTensor).unwrap();
    let rust = rust_module(&q, "P_INT", &["source: a test".into()], &Rig::GYMNASIUM).unwrap();
    assert!(rust.contains("pub static P_INT: ::firmware::network::int::QMlp<64>"));
    assert!(rust.contains("5512 bytes of flash") && rust.contains("per-tensor"));
    assert!(
        !rust.contains("LEVELS"),
        "the paper's levels go without saying"
    );
    let c = c_header(&q, "p_int", &[], &Rig::GYMNASIUM).unwrap();
    assert!(c.contains("static const struct cartpole_qmlp64 p_int = {"));
    assert!(c.contains("cartpole_controller_init_qmlp64(&ctl, &p_int, &p_int_rig)"));
    // Seven levels: the shape in every name, and the levels beside the weights.
    let q = quantise(
        &seven_levels(),
        &[[0.01, 0.0, 0.02, 0.0]],
        Granularity::PerChannel,
    )
    .unwrap();
    let rust = rust_module(&q, "P_INT", &[], &Rig::GYMNASIUM).unwrap();
    assert!(rust.contains("pub static P_INT: ::firmware::network::int::QMlp<64, 7>"));
    assert!(rust.contains("pub const LEVELS: ::firmware::controller::Levels<7>"));
    assert!(rust.contains("Levels::new([-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0])"));
    // 4,800 bytes of weights, 540 of biases, 512 of requantisations.
    assert!(rust.contains("5852 bytes of flash"));
    let c = c_header(&q, "p_int", &[], &Rig::GYMNASIUM).unwrap();
    assert!(c.contains("static const struct cartpole_qmlp64x7 p_int = {"));
    assert!(c.contains(
        "static const int16_t p_int_levels[7] = {-1000, -500, -200, 0, 200, 500, 1000};"
    ));
    assert!(c.contains("static inline int16_t p_int_duty(const int32_t q[7]) {"));
    assert!(c.contains(
        "void cartpole_qmlp64x7_forward(const struct cartpole_qmlp64x7 *w, const int16_t obs[4], int32_t q[7]);"
    ));
    assert!(
        c.contains("cartpole_controller_init_qmlp64x7(&ctl, &p_int, p_int_levels, 7, &p_int_rig)")
    );
    // Two outputs on other levels than the full pushes: Rust says so, C cannot run them.
    let gentle = crate::feedback::state_feedback(64, &[-0.5, 0.5], [-0.5, -1.0, -20.0, -3.0]);
    let q = quantise(
        &gentle.unwrap(),
        &[[0.01, 0.0, 0.02, 0.0]],
        Granularity::PerChannel,
    )
    .unwrap();
    let rust = rust_module(&q, "P_INT", &[], &Rig::GYMNASIUM).unwrap();
    assert!(rust.contains("QMlp<64> =") && rust.contains("Levels::new([-0.5, 0.5])"));
    let e = c_header(&q, "p_int", &[], &Rig::GYMNASIUM).unwrap_err();
    assert!(e.is_input() && e.to_string().contains("[-0.5, 0.5]"), "{e}");
    assert!(
        rust_module(&q, "lower", &[], &Rig::GYMNASIUM)
            .unwrap_err()
            .is_input()
    );
    assert!(
        c_header(&q, "int", &[], &Rig::GYMNASIUM)
            .unwrap_err()
            .is_input()
    );
}

/// The paper's output layer as the quantiser made it before it took more outputs: the one
/// advantage row `(right - left) / 2` rounded, its negation for the left row, and the
/// biases alike. Written out here as a second implementation of the two-output case.
fn two_output_rows(w: &Weights, moments: &[f64], s_x: f64) -> (Vec<i8>, Vec<i32>) {
    let (w3, b3) = (&w.tensors()[4], &w.tensors()[5]);
    let h = w.width();
    let row: Vec<f32> = (0..h)
        .map(|k| ((f64::from(w3[h + k]) - f64::from(w3[k])) / 2.0) as f32)
        .collect();
    let s = symmetric(&row);
    let right = adaptive_round(&row, s, moments);
    let bias = ((f64::from(b3[1]) - f64::from(b3[0])) / 2.0) as f32;
    let b = (f64::from(bias) / (s * s_x)).round() as i32;
    let left = right.iter().map(|v| -v);
    (left.chain(right.iter().copied()).collect(), vec![-b, b])
}

/// The second hidden layer's activations of `w` on `states` as the quantiser sees them
/// (through the Q3.12 input): their second moments, and the scale of their largest.
fn h2_moments(w: &Weights, states: &[[f32; 4]]) -> (Vec<f64>, f64) {
    let h = w.width();
    let t = w.tensors();
    let layer = |wt: &[f32], b: &[f32], x: &[f64]| -> Vec<f64> {
        wt.chunks(x.len())
            .zip(b)
            .map(|(row, b)| {
                let v: f64 = row.iter().zip(x).map(|(w, x)| f64::from(*w) * x).sum();
                (v + f64::from(*b)).max(0.0)
            })
            .collect()
    };
    let (mut m, mut max) = (vec![0.0; h * h], 0.0f64);
    for s in states {
        let x = fixed_obs(s).map(|v| f64::from(v) / 4096.0);
        let h2 = layer(&t[2], &t[3], &layer(&t[0], &t[1], &x));
        max = h2.iter().fold(max, |m, v| m.max(*v));
        for (i, a) in h2.iter().enumerate() {
            for (j, b) in h2.iter().enumerate() {
                m[i * h + j] += a * b;
            }
        }
    }
    for m in &mut m {
        *m /= states.len() as f64;
    }
    (m, max / 255.0)
}

#[test]
fn two_outputs_are_quantised_as_the_paper_s_advantage_row_was() {
    let states = trajectory();
    let shipped = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    let levels = [-0.6, 0.9];
    let other = crate::feedback::state_feedback(16, &levels, [-0.5, -1.0, -20.0, -3.0]).unwrap();
    for w in [shipped, other] {
        let (moments, s_x) = h2_moments(&w, &states);
        let want = two_output_rows(&w, &moments, s_x);
        for g in [Granularity::PerChannel, Granularity::PerTensor] {
            let q = quantise(&w, &states, g).unwrap();
            assert_eq!((q.fc3_weight.clone(), q.fc3_bias.clone()), want, "{g:?}");
            assert_eq!(q.activation_scales()[1], s_x);
        }
    }
}

/// The feedback network of seven levels with every weight moved a little, so that no row
/// is exact in int8 and every unit counts.
fn seven_levels() -> Weights {
    let levels = [-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0];
    let w = crate::feedback::state_feedback(64, &levels, [-0.5, -1.0, -20.0, -3.0]).unwrap();
    let mut seed = 3u64;
    let mut noise = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        ((seed >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.04
    };
    let tensors = w
        .tensors()
        .clone()
        .map(|t| t.iter().map(|v| v + noise()).collect());
    Weights::new(64, levels.to_vec(), tensors).unwrap()
}

#[test]
fn a_policy_of_seven_levels_keeps_its_decisions_and_its_advantages() {
    let w = seven_levels();
    let net = w.to_mlp::<64, 7>().unwrap();
    let states = trajectory();
    for g in [Granularity::PerChannel, Granularity::PerTensor] {
        let q = quantise(&w, &states, g).unwrap();
        assert_eq!((q.outputs(), q.levels()), (7, w.levels()));
        let int = q.to_qmlp::<64, 7>().unwrap();
        assert!(q.to_qmlp::<64, 2>().is_err() && q.to_qmlp::<16, 7>().is_err());
        let (mut clear, mut kept, mut err, mut size) = (0, 0, 0.0f64, 0.0f64);
        for s in &states {
            let f = net.forward(s).map(f64::from);
            let mean = f.iter().sum::<f64>() / 7.0;
            let qi = int.forward(&fixed_obs(s));
            for (qi, f) in qi.iter().zip(f) {
                err += (f64::from(*qi) * q.q_scale() - (f - mean)).abs();
                size += (f - mean).abs();
            }
            // The margin of the float choice over the runner-up.
            let best = firmware::network::argmax(&f);
            let margin = f
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != best)
                .fold(f64::INFINITY, |m, (_, v)| m.min(f[best] - v));
            if margin >= 0.02 {
                clear += 1;
                kept += u32::from(firmware::network::argmax(&qi) == best);
            }
        }
        assert!(
            clear > 2000 && kept * 100 >= clear * 99,
            "{g:?}: {kept} of {clear}"
        );
        // One scale per tensor resolves the first layer's small gains more coarsely.
        let bound = match g {
            Granularity::PerChannel => 0.01,
            Granularity::PerTensor => 0.03,
        };
        assert!(
            err < bound * size,
            "{g:?}: advantage error {err} against {size}"
        );
    }
}

/// A bias too large for the accumulator is named shortest: `{}` wrote -3e38 with its 39
/// digits.
#[test]
fn a_bias_past_the_accumulator_is_named_shortest() {
    let e = quantise_bias("fc1.bias", -3e38, 1.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("tensor `fc1.bias`: bias -3e38 is -3.0000000054977558e38 units"),
        "{e}"
    );
}
