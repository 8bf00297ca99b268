use super::*;
use crate::config::Init;
use crate::train::{Stream, init_weights, rng};
use rand_core::Rng;

/// [`Ops::forward_batch`] with `kernel`'s table.
fn forward_batch<const H: usize>(
    kernel: Kernel,
    net: &Mlp<H>,
    packed: &Packed<H>,
    x: &[[f32; OBS_DIM]],
    s: &mut Scratch<H, 2>,
) {
    Ops::<H, 2>::new(kernel).forward_batch(net, packed, x, s)
}

/// [`Ops::backward`] with `kernel`'s table.
#[allow(clippy::too_many_arguments)]
fn backward<const H: usize>(
    kernel: Kernel,
    net: &Mlp<H>,
    x: &[[f32; OBS_DIM]],
    actions: &[u8],
    targets: &[f32],
    loss: (Loss, f32),
    s: &mut Scratch<H, 2>,
    grad: &mut Mlp<H>,
) -> f64 {
    Ops::<H, 2>::new(kernel).backward(net, x, actions, targets, loss, s, grad)
}

/// [`Ops::adam`] with `kernel`'s table on every parameter of `p`.
fn adam_step<const H: usize>(
    kernel: Kernel,
    hp: &AdamParams,
    t: u64,
    p: &mut Mlp<H>,
    g: &Mlp<H>,
    m: &mut Mlp<H>,
    v: &mut Mlp<H>,
) {
    let (p, m, v) = (p.tensors_mut(), m.tensors_mut(), v.tensors_mut());
    let mut parts: Vec<Part<'_>> = p
        .into_iter()
        .zip(g.tensors())
        .zip(m.into_iter().zip(v))
        .map(|((p, g), (m, v))| (p, g, m, v))
        .collect();
    Ops::<H, 2>::new(kernel).adam(&hp.at(t), &mut parts);
}

fn kernels() -> Vec<Kernel> {
    Kernel::available()
}

fn uniform(r: &mut impl Rng, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * ((r.next_u32() >> 8) as f32 / (1u32 << 24) as f32)
}

fn random_net<const H: usize>(seed: u64) -> Box<Mlp<H>> {
    let mut net = boxed_zero::<H, 2>();
    init_weights(&mut net, Init::Xavier, &mut rng(seed, Stream::Init));
    // Non-trivial biases so that ReLU boundaries are exercised from both sides.
    let mut r = rng(seed, Stream::Sample);
    for b in [
        &mut net.fc1_bias[..],
        &mut net.fc2_bias[..],
        &mut net.fc3_bias[..],
    ] {
        b.iter_mut().for_each(|v| *v = uniform(&mut r, -0.3, 0.3));
    }
    net
}

/// Every parameter's bits, in tensor order.
fn bits<const H: usize>(m: &Mlp<H>) -> Vec<u32> {
    m.tensors()
        .iter()
        .flat_map(|t| t.iter().map(|v| v.to_bits()))
        .collect()
}

fn random_obs(r: &mut impl Rng, n: usize) -> Vec<[f32; 4]> {
    (0..n)
        .map(|_| [2.4, 2.0, 0.21, 2.0].map(|s| uniform(r, -s, s)))
        .collect()
}

/// The loss written out in f64 from the equations, sharing no code with the kernels.
fn reference_loss(
    p: &[Vec<f64>; 6],
    h: usize,
    x: &[[f32; 4]],
    a: &[u8],
    y: &[f32],
    loss: Loss,
) -> f64 {
    let mut total = 0.0;
    for b in 0..x.len() {
        let l1: Vec<f64> = (0..h)
            .map(|o| {
                (p[1][o]
                    + (0..4)
                        .map(|i| p[0][o * 4 + i] * f64::from(x[b][i]))
                        .sum::<f64>())
                .max(0.0)
            })
            .collect();
        let l2: Vec<f64> = (0..h)
            .map(|o| (p[3][o] + (0..h).map(|i| p[2][o * h + i] * l1[i]).sum::<f64>()).max(0.0))
            .collect();
        let act = usize::from(a[b]);
        let q = p[5][act] + (0..h).map(|i| p[4][act * h + i] * l2[i]).sum::<f64>();
        let d = q - f64::from(y[b]);
        total += match loss {
            Loss::Mse => d * d,
            Loss::Huber if d.abs() < 1.0 => 0.5 * d * d,
            Loss::Huber => d.abs() - 0.5,
        };
    }
    total / x.len() as f64
}

fn check_gradients<const H: usize>(loss: Loss) {
    let net = random_net::<H>(11);
    let mut r = rng(12, Stream::Sample);
    let x = random_obs(&mut r, 6);
    let actions: Vec<u8> = (0..6).map(|i| (i % 2) as u8).collect();
    // Targets far and near, so Huber's both branches are taken.
    let targets: Vec<f32> = (0..6).map(|i| if i < 3 { 3.0 } else { 0.1 }).collect();
    let p64: [Vec<f64>; 6] = net
        .tensors()
        .map(|t| t.iter().map(|&v| f64::from(v)).collect());
    for kernel in kernels() {
        let mut s = Scratch::<H, 2>::new(6);
        let mut grad = boxed_zero::<H, 2>();
        forward_batch(kernel, &net, &Packed::new(&net), &x, &mut s);
        let scaled = (loss, 1.0 / x.len() as f32);
        let l = backward(
            kernel, &net, &x, &actions, &targets, scaled, &mut s, &mut grad,
        );
        let l = l / x.len() as f64;
        let want = reference_loss(&p64, H, &x, &actions, &targets, loss);
        assert!(
            (l - want).abs() <= 1e-5 * want.max(1.0),
            "{kernel:?}: {l} vs {want}"
        );
        for (ti, g) in grad.tensors().iter().enumerate() {
            for (j, &g) in g.iter().enumerate() {
                let eps = 1e-6;
                let mut plus = p64.clone();
                plus[ti][j] += eps;
                let mut minus = p64.clone();
                minus[ti][j] -= eps;
                let fd = (reference_loss(&plus, H, &x, &actions, &targets, loss)
                    - reference_loss(&minus, H, &x, &actions, &targets, loss))
                    / (2.0 * eps);
                let err = (f64::from(g) - fd).abs();
                assert!(
                    err <= 1e-4 * fd.abs().max(1.0),
                    "{kernel:?} {loss:?} tensor {ti} element {j}: analytic {g} vs finite difference {fd}"
                );
            }
        }
    }
}

#[test]
fn gradients_match_central_finite_differences() {
    check_gradients::<16>(Loss::Mse);
    check_gradients::<16>(Loss::Huber);
    check_gradients::<32>(Loss::Mse);
}

#[test]
fn batched_forward_matches_the_firmware_forward() {
    let mut r = rng(5, Stream::Env);
    for seed in 0..5 {
        let net = random_net::<64>(seed);
        let x = random_obs(&mut r, 32);
        for kernel in kernels() {
            let mut s = Scratch::<64, 2>::new(32);
            forward_batch(kernel, &net, &Packed::new(&net), &x, &mut s);
            for (xb, q) in x.iter().zip(&s.q) {
                let want = net.forward(xb);
                assert_eq!(
                    firmware::network::argmax(q),
                    firmware::network::argmax(&want)
                );
                for (g, w) in q.iter().zip(&want) {
                    assert!(
                        (g - w).abs() <= 1e-6 * w.abs().max(1.0),
                        "{kernel:?}: {q:?} vs {want:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn adam_steps_match_hand_computed_values() {
    let hp = AdamParams {
        lr: 0.1,
        beta1: 0.9,
        beta2: 0.999,
        eps: 1e-8,
    };
    for kernel in kernels() {
        let mut p = boxed_zero::<16, 2>();
        let (mut m, mut v, mut g) = (
            boxed_zero::<16, 2>(),
            boxed_zero::<16, 2>(),
            boxed_zero::<16, 2>(),
        );
        p.fc2_weight[3][4] = 1.0;
        g.fc2_weight[3][4] = 0.5;
        adam_step(kernel, &hp, 1, &mut p, &g, &mut m, &mut v);
        // m = 0.05, v = 0.00025; m_hat = 0.5, v_hat = 0.25: p = 1 - 0.1 * 0.5 / (0.5 + 1e-8).
        let p1 = 1.0 - 0.1 * 0.5 / (0.5 + 1e-8);
        assert!(
            (f64::from(p.fc2_weight[3][4]) - p1).abs() < 1e-7,
            "{kernel:?}"
        );
        assert!(
            (m.fc2_weight[3][4] - 0.05).abs() < 1e-9
                && (v.fc2_weight[3][4] - 0.00025).abs() < 1e-11
        );
        g.fc2_weight[3][4] = -0.25;
        adam_step(kernel, &hp, 2, &mut p, &g, &mut m, &mut v);
        // m = 0.9 * 0.05 - 0.1 * 0.25 = 0.02; v = 0.999 * 0.00025 + 0.001 * 0.0625 = 0.00031225.
        let (m2, v2) = (0.02f64, 0.00031225f64);
        let p2 = p1 - (0.1 / (1.0 - 0.81)) * m2 / (v2.sqrt() / (1.0 - 0.998001f64).sqrt() + 1e-8);
        assert!(
            (f64::from(p.fc2_weight[3][4]) - p2).abs() < 1e-6,
            "{kernel:?}: {} vs {p2}",
            p.fc2_weight[3][4]
        );
        // Untouched parameters (zero gradient) stay exactly where they were.
        assert_eq!(p.fc2_weight[0][0], 0.0);
    }
}

#[test]
fn dead_units_moments_are_flushed_not_subnormal() {
    let hp = AdamParams {
        lr: 1e-3,
        beta1: 0.9,
        beta2: 0.999,
        eps: 1e-8,
    };
    let (mut p, mut m, mut v, mut g) = (
        boxed_zero::<16, 2>(),
        boxed_zero::<16, 2>(),
        boxed_zero::<16, 2>(),
        boxed_zero::<16, 2>(),
    );
    g.fc1_bias[0] = 1e-3;
    adam_step(Kernel::Portable, &hp, 1, &mut p, &g, &mut m, &mut v);
    g.fc1_bias[0] = 0.0;
    for t in 2..2000 {
        adam_step(Kernel::Portable, &hp, t, &mut p, &g, &mut m, &mut v);
        assert!(m.fc1_bias[0] == 0.0 || m.fc1_bias[0].is_normal());
        assert!(v.fc1_bias[0] == 0.0 || v.fc1_bias[0].is_normal());
    }
    assert_eq!(m.fc1_bias[0], 0.0);
}

#[test]
fn clipping_rescales_to_the_threshold() {
    let mut g = boxed_zero::<16, 2>();
    g.fc1_weight[0][0] = 12.0;
    g.fc3_bias[1] = -16.0; // norm 20
    assert!(clip_grad_norm(&mut g, 10.0));
    let after = g
        .tensors()
        .iter()
        .flat_map(|t| t.iter())
        .map(|v| v * v)
        .sum::<f32>()
        .sqrt();
    assert!((after - 10.0).abs() < 1e-5, "{after}");
    assert!(
        (g.fc1_weight[0][0] / g.fc3_bias[1] + 0.75).abs() < 1e-7,
        "direction kept"
    );
    let mut small = boxed_zero::<16, 2>();
    small.fc2_bias[2] = 3.0;
    assert!(!clip_grad_norm(&mut small, 10.0));
    assert_eq!(small.fc2_bias[2], 3.0);
}

#[test]
fn the_clip_follows_the_definition_on_both_sides_of_the_threshold() {
    // Gradients scaled to norms straddling the threshold by a few f32 ulps, where a wrong
    // sum would clip where the definition does not (or the other way round).
    let mut r = rng(11, Stream::Sample);
    let mut clipped = [0; 2];
    for case in 0..400 {
        let mut g = random_net::<64>(case);
        let norm = reference::sum_of_squares(&g).sqrt();
        let target = 10.0 * (1.0 + f64::from(uniform(&mut r, -4e-7, 4e-7)));
        let scale = (target / norm) as f32;
        g.tensors_mut()
            .into_iter()
            .for_each(|t| t.iter_mut().for_each(|v| *v *= scale));
        let mut want = g.clone();
        let n = reference::sum_of_squares(&want).sqrt() as f32;
        if n > 10.0 {
            let k = 10.0 / (n + 1e-6);
            want.tensors_mut()
                .into_iter()
                .for_each(|t| t.iter_mut().for_each(|v| *v *= k));
        }
        clipped[usize::from(clip_grad_norm(&mut g, 10.0))] += 1;
        assert_eq!(bits(&g), bits(&want), "case {case}");
    }
    assert!(clipped[0] > 50 && clipped[1] > 50, "{clipped:?}");
}

#[test]
fn soft_update_interpolates() {
    let (mut t, mut o) = (boxed_zero::<16, 2>(), boxed_zero::<16, 2>());
    t.fc2_weight[1][2] = 1.0;
    o.fc2_weight[1][2] = 3.0;
    soft_update(&mut t, &o, 0.25);
    assert_eq!(t.fc2_weight[1][2], 1.5);
}

/// Every kernel this CPU runs renders the definition (`reference`) bit for bit: forward,
/// backward and Adam, at widths the AVX-512 blocks divide and one they leave a remainder of,
/// with batches that leave rows over, on weights and inputs that cross every ReLU.
#[test]
fn every_kernel_renders_the_definition_bit_for_bit() {
    fn check<const H: usize>(seed: u64) {
        let mut r = rng(seed, Stream::Sample);
        let net = random_net::<H>(seed);
        let packed = Packed::new(&net);
        for n in [13, 32] {
            let x = random_obs(&mut r, n);
            let actions: Vec<u8> = (0..n).map(|i| (i % 3 % 2) as u8).collect();
            let targets: Vec<f32> = (0..n).map(|i| 0.7 * i as f32 - 3.0).collect();
            let loss = (Loss::Huber, 1.0 / n as f32);
            let (want_g, want_l) = reference::backward(&net, &x, &actions, &targets, loss);
            let want_q: Vec<u32> = x
                .iter()
                .flat_map(|o| reference::forward(&net, o).2)
                .map(f32::to_bits)
                .collect();
            for kernel in kernels() {
                let mut s = Scratch::<H, 2>::new(n);
                let mut g = boxed_zero::<H, 2>();
                forward_batch(kernel, &net, &packed, &x, &mut s);
                let q: Vec<u32> = s.q.iter().flatten().map(|v| v.to_bits()).collect();
                assert_eq!(q, want_q, "{kernel:?}: forward, width {H}, batch {n}");
                let l = backward(kernel, &net, &x, &actions, &targets, loss, &mut s, &mut g);
                assert_eq!(l.to_bits(), want_l.to_bits(), "{kernel:?}: loss");
                assert_eq!(
                    bits(&g),
                    bits(&want_g),
                    "{kernel:?}: gradient, width {H}, batch {n}"
                );
                let hp = AdamParams {
                    lr: 1e-3,
                    beta1: 0.9,
                    beta2: 0.999,
                    eps: 1e-8,
                };
                let (mut p1, mut p2) = (net.clone(), net.clone());
                let [mut m1, mut v1, mut m2, mut v2] = [0; 4].map(|_| boxed_zero::<H, 2>());
                for t in 1..4 {
                    adam_step(kernel, &hp, t, &mut p1, &g, &mut m1, &mut v1);
                    reference::adam(&hp, t, &mut p2, &want_g, &mut m2, &mut v2);
                }
                assert_eq!(bits(&p1), bits(&p2), "{kernel:?}: Adam");
                assert_eq!(bits(&v1), bits(&v2), "{kernel:?}: Adam's moments");
            }
        }
    }
    check::<16>(40);
    check::<32>(41);
    check::<64>(42);
    check::<128>(43);
}

/// The learner acts with the firmware's Q-values, bit for bit, before and after it learns.
#[test]
fn the_learner_acts_with_the_firmwares_forward_pass() {
    use crate::config::Config;
    use crate::train::{Learner, ReplayBuffer};
    let cfg = Config {
        batch_size: 8,
        ..Config::paper()
    };
    for kernel in kernels() {
        let mut learner = Learner::<64, 2>::new(&cfg, kernel, 3);
        let mut buf = ReplayBuffer::new(64);
        let mut r = rng(4, Stream::Sample);
        let obs = random_obs(&mut r, 40);
        for (k, o) in obs.iter().enumerate() {
            buf.push(*o, k % 2, 1.0, obs[(k + 1) % 40], k % 9 == 0);
        }
        for round in 0..3 {
            for o in &obs {
                let (got, want) = (learner.q_values(o), learner.online().forward(o));
                assert_eq!(
                    got.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "{kernel:?} {round}"
                );
            }
            learner.update(&cfg, &buf, &mut r);
        }
    }
}
