use firmware::fixed::from_state as fixed_obs;
use firmware::policy::POLICY;
use firmware::rig::Rig;

use super::quantiser::{adaptive_round, quantise_weights, requant, symmetric};
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

#[test]
fn the_shipped_policy_keeps_its_decisions_where_they_matter() {
    let w = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    // A calibration set of its own: states along a swinging, drifting trajectory.
    let states: Vec<[f32; 4]> = (0..4000)
        .map(|i| {
            let t = i as f32 * 0.01;
            [
                0.8 * (0.3 * t).sin(),
                0.5 * (0.7 * t).cos(),
                0.05 * (2.1 * t).sin(),
                0.4 * (1.3 * t).cos(),
            ]
        })
        .collect();
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
    let c = c_header(&q, "p_int", &[], &Rig::GYMNASIUM).unwrap();
    assert!(c.contains("static const struct cartpole_qmlp64 p_int = {"));
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
