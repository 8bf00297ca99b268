//! The optimiser side of a gradient step: PyTorch's Adam, global-norm clipping and the
//! soft target update.

use firmware::network::Mlp;

/// Adam's constants (PyTorch's form: `eps` added to `sqrt(v_hat)`). Kept in f64 because
/// PyTorch derives `1 - beta` and the bias corrections in double precision and rounds each
/// to f32 once; `1.0f32 - 0.999f32` would be 5e-5 off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdamParams {
    /// Learning rate.
    pub lr: f64,
    /// First-moment decay.
    pub beta1: f64,
    /// Second-moment decay.
    pub beta2: f64,
    /// Added to the denominator.
    pub eps: f64,
}

/// Moments below this are flushed to zero. Dead-ReLU parameters get zero gradients and their
/// first moments decay geometrically into subnormal floats, which x86 processes about 100x
/// slower; at 1e-30 a moment is irrelevant to any update (lr * 1e-30 / sqrt(v)).
const FLUSH: f32 = 1e-30;

/// Scales `grad` so that its global L2 norm is at most `max_norm` (PyTorch's
/// `clip_grad_norm_`, which scales by `max_norm / (norm + 1e-6)`, with the norm summed in
/// f64, parameter by parameter); returns whether it scaled.
///
/// That sequential f64 sum is one chain of 4,610 dependent additions, about 4 us per update
/// at width 64, and every run's bits depend on its roundings. So a vectorised sum screens
/// first: summed in any order, n non-negative terms (each square of an f32 is exact in f64)
/// come within `(n - 1) * 2^-53` relative of their exact sum, under 1e-11 for any width the
/// trainer supports. A screen below `max_norm^2 * (1 - 1e-9)` therefore proves that the
/// sequential sum is below `max_norm^2` too, its square root at most `max_norm`, and that
/// nothing is scaled. Only otherwise is the sequential norm computed, and the result is the
/// same, bit for bit, as computing it always.
pub fn clip_grad_norm<const H: usize>(grad: &mut Mlp<H>, max_norm: f32) -> bool {
    let limit = f64::from(max_norm) * f64::from(max_norm);
    if sum_of_squares_any_order(grad) < limit * (1.0 - 1e-9) {
        return false;
    }
    let norm = grad
        .tensors()
        .iter()
        .flat_map(|t| t.iter())
        .map(|&g| f64::from(g) * f64::from(g))
        .sum::<f64>()
        .sqrt() as f32;
    if norm > max_norm {
        let scale = max_norm / (norm + 1e-6);
        for t in grad.tensors_mut() {
            t.iter_mut().for_each(|g| *g *= scale);
        }
        return true;
    }
    false
}

/// The sum of squares of every parameter, in f64, in eight interleaved partial sums per
/// tensor (so it vectorises); NaN if any parameter is NaN.
fn sum_of_squares_any_order<const H: usize>(grad: &Mlp<H>) -> f64 {
    let mut acc = [0.0f64; 8];
    for t in grad.tensors() {
        let (chunks, rest) = t.as_chunks::<8>();
        for c in chunks {
            for (a, &g) in acc.iter_mut().zip(c) {
                *a += f64::from(g) * f64::from(g);
            }
        }
        for (a, &g) in acc.iter_mut().zip(rest) {
            *a += f64::from(g) * f64::from(g);
        }
    }
    acc.iter().sum()
}

/// `target <- tau * online + (1 - tau) * target`, elementwise.
pub fn soft_update<const H: usize>(target: &mut Mlp<H>, online: &Mlp<H>, tau: f32) {
    for (t, o) in target.tensors_mut().into_iter().zip(online.tensors()) {
        for (t, o) in t.iter_mut().zip(o) {
            *t = tau * o + (1.0 - tau) * *t;
        }
    }
}
#[inline(always)]
pub(super) fn adam_impl<const H: usize>(
    hp: &AdamParams,
    t: u64,
    params: &mut Mlp<H>,
    grad: &Mlp<H>,
    m: &mut Mlp<H>,
    v: &mut Mlp<H>,
) {
    let t = t.min(i32::MAX as u64) as i32;
    let bc1 = 1.0 - hp.beta1.powi(t);
    let bc2 = 1.0 - hp.beta2.powi(t);
    let step = (hp.lr / bc1) as f32;
    let sqrt_bc2 = bc2.sqrt() as f32;
    let (b1, b2, eps) = (hp.beta1 as f32, hp.beta2 as f32, hp.eps as f32);
    let (c1, c2) = ((1.0 - hp.beta1) as f32, (1.0 - hp.beta2) as f32);
    let moments = m.tensors_mut().into_iter().zip(v.tensors_mut());
    for ((p, g), (m, v)) in params
        .tensors_mut()
        .into_iter()
        .zip(grad.tensors())
        .zip(moments)
    {
        for (((p, g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
            let m1 = b1.mul_add(*m, c1 * g);
            let v1 = b2.mul_add(*v, c2 * g * g);
            *m = if m1.abs() < FLUSH { 0.0 } else { m1 };
            *v = if v1 < FLUSH { 0.0 } else { v1 };
            *p -= step * *m / (v.sqrt() / sqrt_bc2 + eps);
        }
    }
}
