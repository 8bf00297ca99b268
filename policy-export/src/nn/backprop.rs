//! Gradients of the batch's mean TD loss, layer by layer from the output back.

use firmware::network::{Mlp, N_ACTIONS, OBS_DIM};

use super::kernels::{Render, all_rows, rows_times};
use super::{Loss, Scratch};

/// Zeroes the gradient of every unit whose ReLU output was 0 (its derivative there).
#[inline(always)]
fn relu_backward<const H: usize>(grad: &mut [[f32; H]], activation: &[[f32; H]]) {
    for (g, a) in grad.iter_mut().zip(activation) {
        for (g, a) in g.iter_mut().zip(a) {
            if *a <= 0.0 {
                *g = 0.0;
            }
        }
    }
}

/// `s.dq[b] = scale * dL/dQ` for the first `n` rows, non-zero only at the taken action;
/// returns the summed loss.
#[inline(always)]
fn loss_grad<const H: usize>(
    s: &mut Scratch<H>,
    n: usize,
    actions: &[u8],
    targets: &[f32],
    (loss, scale): (Loss, f32),
) -> f64 {
    let mut total = 0.0f64;
    for b in 0..n {
        let a = usize::from(actions[b].min(1));
        let d = s.q[b][a] - targets[b];
        let (l, g) = match loss {
            Loss::Mse => (d * d, 2.0 * d),
            Loss::Huber if d.abs() < 1.0 => (0.5 * d * d, d),
            Loss::Huber => (d.abs() - 0.5, d.signum()),
        };
        total += f64::from(l);
        s.dq[b] = [0.0; N_ACTIONS];
        s.dq[b][a] = g * scale;
    }
    total
}

/// The output layer's gradients (2 x H, small): direct sums over the first `n` rows.
#[inline(always)]
fn output_layer<const H: usize>(s: &Scratch<H>, n: usize, grad: &mut Mlp<H>) {
    grad.fc3_weight = [[0.0; H]; N_ACTIONS];
    grad.fc3_bias = [0.0; N_ACTIONS];
    for b in 0..n {
        for o in 0..N_ACTIONS {
            let g = s.dq[b][o];
            for (gw, a) in grad.fc3_weight[o].iter_mut().zip(&s.a2[b]) {
                *gw = g.mul_add(*a, *gw);
            }
            grad.fc3_bias[o] += g;
        }
    }
}

/// The second layer's gradients from its units' `d2` and its inputs `a1`.
#[inline(always)]
fn second_layer<const H: usize, F: Render, const R: usize>(
    d2: &[[f32; H]],
    a1: &[[f32; H]],
    grad: &mut Mlp<H>,
) {
    // dW2[o] = sum_b d2[b][o] * a1[b], rows over o, terms over b, reading d2 down its
    // columns, R units at a time.
    for (k, g) in grad
        .fc2_weight
        .as_chunks_mut::<R>()
        .0
        .iter_mut()
        .enumerate()
    {
        rows_times::<H, R, F>(
            |b| d2[b].as_chunks::<R>().0[k],
            a1,
            None,
            false,
            g.each_mut(),
        );
    }
    // Summed row after row, vectorised across units; each unit still adds its column in
    // batch order starting from -0.0, exactly as `Iterator::sum` over the column would.
    grad.fc2_bias = [-0.0; H];
    for d in d2 {
        for (g, d) in grad.fc2_bias.iter_mut().zip(d) {
            *g += d;
        }
    }
}

/// The first layer's gradients from its units' `d1` and the observations `x`.
#[inline(always)]
fn first_layer<const H: usize, F: Render>(
    x: &[[f32; OBS_DIM]],
    d1: &[[f32; H]],
    grad: &mut Mlp<H>,
) {
    // Accumulated transposed (contiguous over outputs), then stored [out][in].
    let mut gw1t = [[0.0f32; H]; OBS_DIM];
    rows_times::<H, OBS_DIM, F>(|b| x[b], d1, None, false, gw1t.each_mut());
    for (o, row) in grad.fc1_weight.iter_mut().enumerate() {
        for (i, w) in row.iter_mut().enumerate() {
            *w = gw1t[i][o];
        }
    }
    grad.fc1_bias = [0.0; H];
    for row in d1 {
        for (g, d) in grad.fc1_bias.iter_mut().zip(row) {
            *g += d;
        }
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn backward_impl<const H: usize, F: Render, const R: usize>(
    net: &Mlp<H>,
    x: &[[f32; OBS_DIM]],
    actions: &[u8],
    targets: &[f32],
    loss: (Loss, f32),
    s: &mut Scratch<H>,
    grad: &mut Mlp<H>,
) -> f64 {
    const {
        assert!(
            H.is_multiple_of(R),
            "hidden width must be a multiple of the rows per block"
        )
    };
    let n = x.len();
    let total = loss_grad(s, n, actions, targets, loss);
    output_layer(s, n, grad);
    // Into the second hidden layer: d2 = (dq W3) masked by ReLU'.
    all_rows::<H, N_ACTIONS, F, R>(&s.dq[..n], &net.fc3_weight, None, false, &mut s.d2);
    relu_backward(&mut s.d2[..n], &s.a2[..n]);
    let d2 = &s.d2[..n];
    let a1 = &s.a1[..n];
    second_layer::<H, F, R>(d2, a1, grad);
    // Into the first hidden layer: d1 = (d2 W2) masked by ReLU'.
    all_rows::<H, H, F, R>(d2, &net.fc2_weight, None, false, &mut s.d1);
    relu_backward(&mut s.d1[..n], a1);
    first_layer::<H, F>(x, &s.d1[..n], grad);
    total
}
