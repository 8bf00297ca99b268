//! The training arithmetic's definition written as plain loops, sharing no code with the
//! kernels: every multiply-add fused and in the documented order, every sum started where the
//! kernels start it. Each kernel is tested against it bit for bit.

// Written as the formulas are, with explicit indices.
#![allow(clippy::needless_range_loop)]

use firmware::network::{Mlp, OBS_DIM, dot_portable};

use super::{AdamParams, Loss};

fn relu(v: f32) -> f32 {
    if v <= 0.0 { 0.0 } else { v }
}

/// `relu(b[o] + sum_i x[i] * w[o][i])` per output, each term fused, in increasing `i`.
fn layer<const I: usize, const O: usize>(
    x: &[f32; I],
    w: &[[f32; I]; O],
    b: &[f32; O],
) -> [f32; O] {
    core::array::from_fn(|o| relu((0..I).fold(b[o], |acc, i| x[i].mul_add(w[o][i], acc))))
}

/// The activations and Q-values of one observation.
pub(crate) fn forward<const H: usize, const A: usize>(
    net: &Mlp<H, A>,
    x: &[f32; OBS_DIM],
) -> ([f32; H], [f32; H], [f32; A]) {
    let a1 = layer(x, &net.fc1_weight, &net.fc1_bias);
    let a2 = layer(&a1, &net.fc2_weight, &net.fc2_bias);
    let q = core::array::from_fn(|a| dot_portable(&net.fc3_weight[a], &a2) + net.fc3_bias[a]);
    (a1, a2, q)
}

/// The gradient of `scale` times the rows' summed loss, and the summed loss.
pub(crate) fn backward<const H: usize, const A: usize>(
    net: &Mlp<H, A>,
    x: &[[f32; OBS_DIM]],
    actions: &[u8],
    targets: &[f32],
    (loss, scale): (Loss, f32),
) -> (Mlp<H, A>, f64) {
    let n = x.len();
    let acts: Vec<_> = x.iter().map(|x| forward(net, x)).collect();
    let mut total = 0.0f64;
    let mut dq = vec![[0.0f32; A]; n];
    for b in 0..n {
        let a = usize::from(actions[b].min(A as u8 - 1));
        let d = acts[b].2[a] - targets[b];
        let (l, g) = match loss {
            Loss::Mse => (d * d, 2.0 * d),
            Loss::Huber if d.abs() < 1.0 => (0.5 * d * d, d),
            Loss::Huber => (d.abs() - 0.5, d.signum()),
        };
        total += f64::from(l);
        dq[b][a] = g * scale;
    }
    let mut g = Mlp::<H, A>::zeroed();
    for b in 0..n {
        for o in 0..A {
            for i in 0..H {
                g.fc3_weight[o][i] = dq[b][o].mul_add(acts[b].1[i], g.fc3_weight[o][i]);
            }
            g.fc3_bias[o] += dq[b][o];
        }
    }
    // d2[b][h] = sum_a dq[b][a] W3[a][h], masked; d1[b][i] = sum_o d2[b][o] W2[o][i], masked.
    let mask = |v: f32, a: f32| if a <= 0.0 { 0.0 } else { v };
    let d2: Vec<[f32; H]> = (0..n)
        .map(|b| {
            core::array::from_fn(|h| {
                let v = (0..A).fold(0.0, |acc, a| dq[b][a].mul_add(net.fc3_weight[a][h], acc));
                mask(v, acts[b].1[h])
            })
        })
        .collect();
    let d1: Vec<[f32; H]> = (0..n)
        .map(|b| {
            core::array::from_fn(|i| {
                let v = (0..H).fold(0.0, |acc, o| d2[b][o].mul_add(net.fc2_weight[o][i], acc));
                mask(v, acts[b].0[i])
            })
        })
        .collect();
    for o in 0..H {
        for i in 0..H {
            g.fc2_weight[o][i] = (0..n).fold(0.0, |acc, b| d2[b][o].mul_add(acts[b].0[i], acc));
        }
        g.fc2_bias[o] = (0..n).fold(-0.0, |acc, b| acc + d2[b][o]);
        for i in 0..OBS_DIM {
            g.fc1_weight[o][i] = (0..n).fold(0.0, |acc, b| x[b][i].mul_add(d1[b][o], acc));
        }
        g.fc1_bias[o] = (0..n).fold(0.0, |acc, b| acc + d1[b][o]);
    }
    (g, total)
}

/// One Adam step, parameter by parameter.
pub(crate) fn adam<const H: usize, const A: usize>(
    hp: &AdamParams,
    t: u64,
    p: &mut Mlp<H, A>,
    g: &Mlp<H, A>,
    m: &mut Mlp<H, A>,
    v: &mut Mlp<H, A>,
) {
    let t = t.min(i32::MAX as u64) as i32;
    let step = (hp.lr / (1.0 - hp.beta1.powi(t))) as f32;
    let inv_sqrt_bc2 = (1.0 / (1.0 - hp.beta2.powi(t)).sqrt()) as f32;
    let (b1, b2, eps) = (hp.beta1 as f32, hp.beta2 as f32, hp.eps as f32);
    let (c1, c2) = ((1.0 - hp.beta1) as f32, (1.0 - hp.beta2) as f32);
    let [p, m, v] = [p, m, v].map(|n| n.tensors_mut());
    for (((p, g), m), v) in p.into_iter().zip(g.tensors()).zip(m).zip(v) {
        for k in 0..p.len() {
            let m1 = b1.mul_add(m[k], c1 * g[k]);
            let v1 = b2.mul_add(v[k], c2 * g[k] * g[k]);
            m[k] = if m1.abs() < 1e-30 { 0.0 } else { m1 };
            v[k] = if v1 < 1e-30 { 0.0 } else { v1 };
            p[k] -= step * m[k] / (v[k].sqrt() * inv_sqrt_bc2 + eps);
        }
    }
}

/// The sum of squares the gradient clip takes the norm of: element `j` of each tensor into
/// partial sum `j % 8`, tensor after tensor, the eight then added in order.
pub(crate) fn sum_of_squares<const H: usize, const A: usize>(g: &Mlp<H, A>) -> f64 {
    let mut lanes = [0.0f64; 8];
    for t in g.tensors() {
        for (j, &v) in t.iter().enumerate() {
            lanes[j % 8] += f64::from(v) * f64::from(v);
        }
    }
    lanes.iter().fold(-0.0, |a, l| a + l)
}
