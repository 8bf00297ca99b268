use super::*;
use crate::config::Init;
use crate::train::{Stream, init_weights, rng};
use rand_core::Rng;

fn kernels() -> Vec<Kernel> {
    [Kernel::Portable, Kernel::Avx2, Kernel::Avx512]
        .into_iter()
        .filter(|k| k.supported())
        .collect()
}

fn uniform(r: &mut impl Rng, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * ((r.next_u32() >> 8) as f32 / (1u32 << 24) as f32)
}

fn random_net<const H: usize>(seed: u64) -> Box<Mlp<H>> {
    let mut net = boxed_zero::<H>();
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
        let mut s = Scratch::<H>::new(6);
        let mut grad = boxed_zero::<H>();
        forward_batch(kernel, &net, &Packed::new(&net), &x, &mut s);
        let l = backward(
            kernel, &net, &x, &actions, &targets, loss, &mut s, &mut grad,
        );
        let want = reference_loss(&p64, H, &x, &actions, &targets, loss);
        assert!(
            (f64::from(l) - want).abs() <= 1e-5 * want.max(1.0),
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
            let mut s = Scratch::<64>::new(32);
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
        let mut p = boxed_zero::<8>();
        let (mut m, mut v, mut g) = (boxed_zero::<8>(), boxed_zero::<8>(), boxed_zero::<8>());
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
        boxed_zero::<8>(),
        boxed_zero::<8>(),
        boxed_zero::<8>(),
        boxed_zero::<8>(),
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
    let mut g = boxed_zero::<8>();
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
    let mut small = boxed_zero::<8>();
    small.fc2_bias[2] = 3.0;
    assert!(!clip_grad_norm(&mut small, 10.0));
    assert_eq!(small.fc2_bias[2], 3.0);
}

/// PyTorch's definition, written out: the norm always, summed in f64 in parameter order.
fn clip_reference<const H: usize>(grad: &mut Mlp<H>, max_norm: f32) {
    let mut sum = 0.0f64;
    for t in grad.tensors() {
        for &g in t {
            sum += f64::from(g) * f64::from(g);
        }
    }
    let norm = sum.sqrt() as f32;
    if norm > max_norm {
        let scale = max_norm / (norm + 1e-6);
        grad.tensors_mut()
            .into_iter()
            .for_each(|t| t.iter_mut().for_each(|g| *g *= scale));
    }
}

#[test]
fn the_screened_clip_equals_the_sequential_definition_bit_for_bit() {
    // Gradients scaled to norms straddling the threshold by a few f32 ulps, where a
    // wrong screen would skip a clip the definition makes (or make one it skips).
    let mut r = rng(11, Stream::Sample);
    let mut clipped = [0; 2];
    for case in 0..400 {
        let mut g = random_net::<64>(case);
        let norm = g
            .tensors()
            .iter()
            .flat_map(|t| t.iter())
            .map(|&v| f64::from(v) * f64::from(v))
            .sum::<f64>()
            .sqrt();
        let target = 10.0 * (1.0 + f64::from(uniform(&mut r, -4e-7, 4e-7)));
        let scale = (target / norm) as f32;
        g.tensors_mut()
            .into_iter()
            .for_each(|t| t.iter_mut().for_each(|v| *v *= scale));
        let mut want = g.clone();
        clip_reference(&mut want, 10.0);
        clipped[usize::from(clip_grad_norm(&mut g, 10.0))] += 1;
        assert_eq!(bits(&g), bits(&want), "case {case}");
    }
    assert!(clipped[0] > 50 && clipped[1] > 50, "{clipped:?}");
}

#[test]
fn soft_update_interpolates() {
    let (mut t, mut o) = (boxed_zero::<8>(), boxed_zero::<8>());
    t.fc2_weight[1][2] = 1.0;
    o.fc2_weight[1][2] = 3.0;
    soft_update(&mut t, &o, 0.25);
    assert_eq!(t.fc2_weight[1][2], 1.5);
}

/// `Kernel::Portable` runs in AVX2 registers where it can; the generic code called directly
/// here is the baseline build. Forward, backward and Adam must agree bit for bit, at the
/// narrowest width and at the firmware's.
#[test]
fn the_portable_kernel_gives_the_baseline_builds_bits() {
    fn check<const H: usize>() {
        let mut r = rng(21, Stream::Sample);
        let net = random_net::<H>(20);
        let packed = Packed::new(&net);
        let x = random_obs(&mut r, 13);
        let actions: Vec<u8> = (0..13).map(|i| (i % 2) as u8).collect();
        let targets: Vec<f32> = (0..13).map(|i| 0.3 * i as f32 - 1.0).collect();
        let (mut s1, mut s2) = (Scratch::<H>::new(13), Scratch::<H>::new(13));
        let (mut g1, mut g2) = (boxed_zero::<H>(), boxed_zero::<H>());
        forward_batch(Kernel::Portable, &net, &packed, &x, &mut s1);
        forward_impl::<H, Unfused, UNFUSED_ROWS>(&net, &packed, &x, &mut s2);
        let q =
            |s: &Scratch<H>| -> Vec<u32> { s.q.iter().flatten().map(|v| v.to_bits()).collect() };
        assert_eq!(q(&s1), q(&s2));
        let l1 = backward(
            Kernel::Portable,
            &net,
            &x,
            &actions,
            &targets,
            Loss::Huber,
            &mut s1,
            &mut g1,
        );
        let l2 = backward_impl::<H, Unfused, UNFUSED_ROWS>(
            &net,
            &x,
            &actions,
            &targets,
            Loss::Huber,
            &mut s2,
            &mut g2,
        );
        assert_eq!(l1.to_bits(), l2.to_bits());
        assert_eq!(bits(&g1), bits(&g2));
        let hp = AdamParams {
            lr: 1e-3,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        };
        let (mut p1, mut p2) = (net.clone(), net.clone());
        let (mut m1, mut v1, mut m2, mut v2) = (
            boxed_zero::<H>(),
            boxed_zero::<H>(),
            boxed_zero::<H>(),
            boxed_zero::<H>(),
        );
        for t in 1..4 {
            adam_step(Kernel::Portable, &hp, t, &mut p1, &g1, &mut m1, &mut v1);
            adam_impl::<H, Unfused, UNFUSED_ROWS>(&hp, t, &mut p2, &g2, &mut m2, &mut v2);
        }
        assert_eq!(bits(&p1), bits(&p2));
        assert_eq!(bits(&v1), bits(&v2));
    }
    check::<16>();
    check::<64>();
}

/// Acting must give the firmware's Q-values bit for bit with every kernel: on random
/// networks, at every width the ReLU and tree see differently, for ordinary observations and
/// for raw bit patterns (NaN, infinities, subnormals, signed zeros), and for weights that
/// are raw bit patterns too. A NaN's payload is not compared: which operand's payload an
/// add passes on depends on operand order, which the compiler may swap.
#[test]
fn acting_gives_the_firmwares_q_values_bit_for_bit() {
    fn nan_as_one(v: f32) -> u32 {
        if v.is_nan() {
            f32::NAN.to_bits()
        } else {
            v.to_bits()
        }
    }
    fn check<const H: usize>(seed: u64) {
        let mut r = rng(seed, Stream::Env);
        let mut nets = vec![random_net::<H>(seed)];
        let mut raw = random_net::<H>(seed + 1);
        for t in raw.tensors_mut() {
            for v in t.iter_mut().step_by(7) {
                *v = f32::from_bits(r.next_u32());
            }
        }
        nets.push(raw);
        let mut obs = random_obs(&mut r, 200);
        obs.extend((0..200).map(|_| [0; 4].map(|_| f32::from_bits(r.next_u32()))));
        obs.push([-0.0, 0.0, f32::NAN, f32::INFINITY]);
        for net in &nets {
            let packed = Packed::new(net);
            for kernel in kernels() {
                for o in &obs {
                    let (got, want) = (act(kernel, net, &packed, o), net.forward(o));
                    assert_eq!(
                        got.map(nan_as_one),
                        want.map(nan_as_one),
                        "{kernel:?}, width {H}, obs {o:?}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }
    check::<16>(30);
    check::<32>(31);
    check::<64>(32);
    check::<128>(33);
}

/// The AVX-512 build runs its 4-row blocks in `avx512::rows4`, eight accumulators wide; the
/// AVX2 build runs the generic kernel with the same fused multiply-adds. Both must give the
/// same bits, forward and backward, at every width the block divides and with a batch that
/// leaves rows over. (Skipped on CPUs without AVX-512.)
#[test]
fn the_avx512_blocks_give_the_generic_kernels_bits() {
    fn check<const H: usize>(seed: u64) {
        let mut r = rng(seed, Stream::Sample);
        let net = random_net::<H>(seed);
        let packed = Packed::new(&net);
        for n in [13, 32] {
            let x = random_obs(&mut r, n);
            let actions: Vec<u8> = (0..n).map(|i| (i % 3 % 2) as u8).collect();
            let targets: Vec<f32> = (0..n).map(|i| 0.7 * i as f32 - 3.0).collect();
            let run = |kernel| {
                let mut s = Scratch::<H>::new(n);
                let mut g = boxed_zero::<H>();
                forward_batch(kernel, &net, &packed, &x, &mut s);
                let q: Vec<u32> = s.q.iter().flatten().map(|v| v.to_bits()).collect();
                let l = backward(
                    kernel,
                    &net,
                    &x,
                    &actions,
                    &targets,
                    Loss::Mse,
                    &mut s,
                    &mut g,
                );
                (q, l.to_bits(), bits(&g))
            };
            assert!(
                run(Kernel::Avx2) == run(Kernel::Avx512),
                "width {H}, batch {n}"
            );
        }
    }
    if !Kernel::Avx512.supported() {
        eprintln!("no AVX-512 on this CPU: nothing to compare");
        return;
    }
    check::<32>(40);
    check::<64>(41);
    check::<128>(42);
}
