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
/// `clip_grad_norm_`, which scales by `max_norm / (norm + 1e-6)`); returns whether it
/// scaled.
///
/// The norm is summed in f64 (each square of an f32 is exact in f64) in eight interleaved
/// partial sums, tensor after tensor, then the partial sums in order ([`sum_of_squares`]):
/// PyTorch's one sequential sum is a chain of 4,610 dependent additions, which this order
/// breaks into eight that a vector unit runs side by side.
pub fn clip_grad_norm<const H: usize, const A: usize>(grad: &mut Mlp<H, A>, max_norm: f32) -> bool {
    let norm = sum_of_squares(grad).sqrt() as f32;
    if norm > max_norm {
        let scale = max_norm / (norm + 1e-6);
        for t in grad.tensors_mut() {
            t.iter_mut().for_each(|g| *g *= scale);
        }
        return true;
    }
    false
}

/// The sum of squares of every parameter, in f64, in eight interleaved partial sums over
/// each tensor in turn, the partial sums then added in order; NaN if any parameter is NaN.
pub fn sum_of_squares<const H: usize, const A: usize>(grad: &Mlp<H, A>) -> f64 {
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
pub fn soft_update<const H: usize, const A: usize>(
    target: &mut Mlp<H, A>,
    online: &Mlp<H, A>,
    tau: f32,
) {
    for (t, o) in target.tensors_mut().into_iter().zip(online.tensors()) {
        for (t, o) in t.iter_mut().zip(o) {
            *t = interpolate(tau, *o, *t);
        }
    }
}

/// One soft update's element: `tau * online + (1 - tau) * target`.
#[inline(always)]
pub(super) fn interpolate(tau: f32, online: f32, target: f32) -> f32 {
    tau * online + (1.0 - tau) * target
}
/// One Adam step's constants, derived from [`AdamParams`] at step `t` (from 1).
#[derive(Clone, Copy, Debug)]
pub struct AdamStep {
    step: f32,
    inv_sqrt_bc2: f32,
    b1: f32,
    b2: f32,
    eps: f32,
    c1: f32,
    c2: f32,
}

impl AdamParams {
    /// The constants of step `t` (counted from 1).
    pub fn at(&self, t: u64) -> AdamStep {
        let t = t.min(i32::MAX as u64) as i32;
        let bc1 = 1.0 - self.beta1.powi(t);
        let bc2 = 1.0 - self.beta2.powi(t);
        AdamStep {
            step: (self.lr / bc1) as f32,
            // PyTorch divides by `sqrt(bc2)`; multiplying by its reciprocal saves a division
            // per parameter, and the bits are this arithmetic's own either way.
            inv_sqrt_bc2: (1.0 / bc2.sqrt()) as f32,
            b1: self.beta1 as f32,
            b2: self.beta2 as f32,
            eps: self.eps as f32,
            c1: (1.0 - self.beta1) as f32,
            c2: (1.0 - self.beta2) as f32,
        }
    }
}

/// Adam on a run of parameters `p` with gradients `g` and moments `m`, `v`, elementwise, so
/// that any split of the parameters gives the same bits.
#[inline(always)]
pub(super) fn adam_elements(a: &AdamStep, p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32]) {
    for (((p, g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
        let m1 = a.b1.mul_add(*m, a.c1 * g);
        let v1 = a.b2.mul_add(*v, a.c2 * g * g);
        *m = if m1.abs() < FLUSH { 0.0 } else { m1 };
        *v = if v1 < FLUSH { 0.0 } else { v1 };
        *p -= a.step * *m / (v.sqrt() * a.inv_sqrt_bc2 + a.eps);
    }
}
