//! Gradients of the batch's mean TD loss, in two kinds of work: what each row needs alone
//! (its loss's gradient, and its error at each layer's units), and the sums over the
//! batch's rows that make the weight gradients. Rows may be split any way for the first;
//! each sum runs over every row in batch order, whoever computes it, so a gradient's bits
//! do not depend on how the work was shared.

use firmware::network::{Mlp, OBS_DIM};

use super::Loss;
use super::kernels::{Render, all_rows, rows_times};

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

/// `dq[b] = scale * dL/dQ` for each row, non-zero only at the taken action, and the row's
/// loss in `loss[b]`.
#[inline(always)]
fn loss_grad<const A: usize>(
    q: &[[f32; A]],
    actions: &[u8],
    targets: &[f32],
    (loss, scale): (Loss, f32),
    dq: &mut [[f32; A]],
    losses: &mut [f32],
) {
    for b in 0..q.len() {
        let a = usize::from(actions[b].min(A as u8 - 1));
        let d = q[b][a] - targets[b];
        let (l, g) = match loss {
            Loss::Mse => (d * d, 2.0 * d),
            Loss::Huber if d.abs() < 1.0 => (0.5 * d * d, d),
            Loss::Huber => (d.abs() - 0.5, d.signum()),
        };
        losses[b] = l;
        dq[b] = [0.0; A];
        dq[b][a] = g * scale;
    }
}

/// What the row work reads and writes, one entry per row: the forward pass's activations
/// `a1`, `a2` and Q-values `q` in; the loss's gradient `dq`, each hidden layer's errors
/// `d2`, `d1` and each row's loss out.
pub struct RowGrads<'a, const H: usize, const A: usize> {
    /// First hidden layer's activations.
    pub a1: &'a [[f32; H]],
    /// Second hidden layer's activations.
    pub a2: &'a [[f32; H]],
    /// Q-values.
    pub q: &'a [[f32; A]],
    /// Scaled `dL/dQ`.
    pub dq: &'a mut [[f32; A]],
    /// Errors at the second hidden layer's units.
    pub d2: &'a mut [[f32; H]],
    /// Errors at the first hidden layer's units.
    pub d1: &'a mut [[f32; H]],
    /// Each row's loss.
    pub loss: &'a mut [f32],
}

/// The row work of the backward pass: each row's loss gradient and its errors at the hidden
/// units, `d2 = (dq W3)` and `d1 = (d2 W2)`, each masked by its layer's ReLU'.
#[inline(always)]
pub(super) fn rows_impl<const H: usize, const A: usize, F: Render, const R: usize>(
    net: &Mlp<H, A>,
    actions: &[u8],
    targets: &[f32],
    loss: (Loss, f32),
    r: RowGrads<'_, H, A>,
) {
    let n = r.q.len();
    loss_grad(r.q, actions, targets, loss, r.dq, r.loss);
    all_rows::<H, A, F, R>(r.dq, &net.fc3_weight, None, false, r.d2);
    relu_backward(&mut r.d2[..n], r.a2);
    all_rows::<H, H, F, R>(r.d2, &net.fc2_weight, None, false, r.d1);
    relu_backward(&mut r.d1[..n], r.a1);
}

/// What the weight gradients are summed from: every row of the batch, in order.
#[derive(Clone, Copy)]
pub struct BatchGrads<'a, const H: usize, const A: usize> {
    /// Observations.
    pub x: &'a [[f32; OBS_DIM]],
    /// First hidden layer's activations.
    pub a1: &'a [[f32; H]],
    /// Second hidden layer's activations.
    pub a2: &'a [[f32; H]],
    /// Scaled `dL/dQ`.
    pub dq: &'a [[f32; A]],
    /// Errors at the second hidden layer's units.
    pub d2: &'a [[f32; H]],
    /// Errors at the first hidden layer's units.
    pub d1: &'a [[f32; H]],
}

/// A network's gradient in two shares of about equal work: the first half of the second
/// layer's weight rows, and everything else.
pub enum Share<'a, const H: usize, const A: usize> {
    /// Rows `0..H/2` of `fc2.weight`.
    First(&'a mut [[f32; H]]),
    /// Rows `H/2..H` of `fc2.weight`, and every other tensor.
    Second(SecondShare<'a, H, A>),
}

/// The tensors of [`Share::Second`].
pub struct SecondShare<'a, const H: usize, const A: usize> {
    /// Rows `H/2..H` of `fc2.weight`.
    pub fc2_weight: &'a mut [[f32; H]],
    /// `fc1.weight`.
    pub fc1_weight: &'a mut [[f32; OBS_DIM]; H],
    /// `fc1.bias`.
    pub fc1_bias: &'a mut [f32; H],
    /// `fc2.bias`.
    pub fc2_bias: &'a mut [f32; H],
    /// `fc3.weight`.
    pub fc3_weight: &'a mut [[f32; H]; A],
    /// `fc3.bias`.
    pub fc3_bias: &'a mut [f32; A],
}

/// `grad` in its two [`Share`]s.
pub fn shares<const H: usize, const A: usize>(grad: &mut Mlp<H, A>) -> [Share<'_, H, A>; 2] {
    let (first, second) = grad.fc2_weight.split_at_mut(H / 2);
    [
        Share::First(first),
        Share::Second(SecondShare {
            fc2_weight: second,
            fc1_weight: &mut grad.fc1_weight,
            fc1_bias: &mut grad.fc1_bias,
            fc2_bias: &mut grad.fc2_bias,
            fc3_weight: &mut grad.fc3_weight,
            fc3_bias: &mut grad.fc3_bias,
        }),
    ]
}

/// One share of the weight gradients, each a sum over every row of `g` in order.
#[inline(always)]
pub(super) fn share_impl<const H: usize, const A: usize, F: Render, const R: usize>(
    g: BatchGrads<'_, H, A>,
    share: Share<'_, H, A>,
) {
    match share {
        Share::First(rows) => second_layer::<H, A, F, R>(g, rows, 0),
        Share::Second(s) => {
            second_layer::<H, A, F, R>(g, s.fc2_weight, H / 2);
            // Summed row after row, vectorised across units; each unit still adds its
            // column in batch order starting from -0.0, exactly as `Iterator::sum` over the
            // column would.
            *s.fc2_bias = [-0.0; H];
            for d in g.d2 {
                for (b, d) in s.fc2_bias.iter_mut().zip(d) {
                    *b += d;
                }
            }
            first_layer::<H, A, F>(g, s.fc1_weight, s.fc1_bias);
            output_layer(g, s.fc3_weight, s.fc3_bias);
        }
    }
}

/// Rows `first..` of the second layer's weight gradient: `dW2[o] = sum_b d2[b][o] *
/// a1[b]`, rows over `o`, terms over `b`, reading `d2` down its columns, `R` units at a time.
#[inline(always)]
fn second_layer<const H: usize, const A: usize, F: Render, const R: usize>(
    g: BatchGrads<'_, H, A>,
    rows: &mut [[f32; H]],
    first: usize,
) {
    for (k, out) in rows.as_chunks_mut::<R>().0.iter_mut().enumerate() {
        let k = first / R + k;
        rows_times::<H, R, F>(
            |b| g.d2[b].as_chunks::<R>().0[k],
            g.a1,
            None,
            false,
            out.each_mut(),
        );
    }
}

/// The first layer's gradients from its units' `d1` and the observations `x`.
#[inline(always)]
fn first_layer<const H: usize, const A: usize, F: Render>(
    g: BatchGrads<'_, H, A>,
    weight: &mut [[f32; OBS_DIM]; H],
    bias: &mut [f32; H],
) {
    // Accumulated transposed (contiguous over outputs), then stored [out][in].
    let mut gw1t = [[0.0f32; H]; OBS_DIM];
    rows_times::<H, OBS_DIM, F>(|b| g.x[b], g.d1, None, false, gw1t.each_mut());
    for (o, row) in weight.iter_mut().enumerate() {
        for (i, w) in row.iter_mut().enumerate() {
            *w = gw1t[i][o];
        }
    }
    *bias = [0.0; H];
    for row in g.d1 {
        for (b, d) in bias.iter_mut().zip(row) {
            *b += d;
        }
    }
}

/// The output layer's gradients (2 x H, small): direct sums over the rows.
#[inline(always)]
fn output_layer<const H: usize, const A: usize>(
    g: BatchGrads<'_, H, A>,
    weight: &mut [[f32; H]; A],
    bias: &mut [f32; A],
) {
    *weight = [[0.0; H]; A];
    *bias = [0.0; A];
    for (dq, a2) in g.dq.iter().zip(g.a2) {
        for o in 0..A {
            for (w, a) in weight[o].iter_mut().zip(a2) {
                *w = dq[o].mul_add(*a, *w);
            }
            bias[o] += dq[o];
        }
    }
}
