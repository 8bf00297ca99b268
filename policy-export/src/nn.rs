//! Batched training math for the 4-H-H-2 network: forward with activations kept, backward,
//! global-norm clipping and Adam, written by hand for this one network shape.
//!
//! The parameters live in the firmware's own [`Mlp`] type, so the policy the trainer acts
//! with is the policy that ships. Inference during training goes through
//! `firmware::network`; this module is only the learning side. Its forward pass is laid out
//! for batches (`y += x_i * W^T[i]`, vectorised across outputs) instead of the firmware's
//! per-output dot products, so its outputs agree with `Mlp::forward` to rounding (tested to
//! 1e-6 relative), not bit for bit.
//!
//! Speed comes from the layout and from compiling the same generic kernels three times:
//! with AVX-512F + FMA, with AVX2 + FMA, and for the baseline target, picked at run time
//! ([`Kernel::detect`]). Results are bit-identical for a given kernel; different kernels
//! round differently (FMA fuses), so a run records which one it used.

#[cfg(any(test, not(target_arch = "x86_64")))]
use firmware::network::dot;
use firmware::network::{Mlp, N_ACTIONS, OBS_DIM};

/// Which compilation of the kernels to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kernel {
    /// Baseline x86-64 (SSE2) or any other architecture; separate multiply and add.
    Portable,
    /// AVX2 with fused multiply-add.
    Avx2,
    /// AVX-512F with fused multiply-add.
    Avx512,
}

impl Kernel {
    /// The fastest kernel this CPU supports.
    pub fn detect() -> Kernel {
        #[cfg(target_arch = "x86_64")]
        {
            if is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("fma") {
                return Kernel::Avx512;
            }
            if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
                return Kernel::Avx2;
            }
        }
        Kernel::Portable
    }

    /// Whether this CPU can run `self`.
    pub fn supported(self) -> bool {
        match self {
            Kernel::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"),
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => {
                is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("fma")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }
}

/// The regression loss on the TD error `d = Q(s, a) - y`, averaged over the batch.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Loss {
    /// `d^2` (PyTorch `MSELoss`).
    Mse,
    /// `d^2 / 2` for `|d| < 1`, else `|d| - 1/2` (PyTorch `SmoothL1Loss`, beta 1).
    Huber,
}

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

/// Per-batch activations and gradients, allocated once.
pub struct Scratch<const H: usize> {
    a1: Vec<[f32; H]>,
    a2: Vec<[f32; H]>,
    d1: Vec<[f32; H]>,
    d2: Vec<[f32; H]>,
    dq: Vec<[f32; N_ACTIONS]>,
    /// Q-values of the last [`forward_batch`].
    pub q: Vec<[f32; N_ACTIONS]>,
}

/// A network's first two weight matrices transposed (`[in][out]`), so that the batched
/// forward pass reads contiguous rows. Re-pack whenever the weights change.
pub struct Packed<const H: usize> {
    w1t: [[f32; H]; OBS_DIM],
    w2t: [[f32; H]; H],
}

impl<const H: usize> Packed<H> {
    /// The transposes of `net`'s weights, on the heap.
    pub fn new(net: &Mlp<H>) -> Box<Self> {
        let mut p = Box::new(Packed {
            w1t: [[0.0; H]; OBS_DIM],
            w2t: [[0.0; H]; H],
        });
        p.pack(net);
        p
    }

    /// Refreshes the transposes from `net`.
    pub fn pack(&mut self, net: &Mlp<H>) {
        for (o, (w1, w2)) in net.fc1_weight.iter().zip(&net.fc2_weight).enumerate() {
            for (i, w) in w1.iter().enumerate() {
                self.w1t[i][o] = *w;
            }
            for (i, w) in w2.iter().enumerate() {
                self.w2t[i][o] = *w;
            }
        }
    }
}

impl<const H: usize> Scratch<H> {
    /// Room for batches of up to `batch` samples.
    pub fn new(batch: usize) -> Self {
        Scratch {
            a1: vec![[0.0; H]; batch],
            a2: vec![[0.0; H]; batch],
            d1: vec![[0.0; H]; batch],
            d2: vec![[0.0; H]; batch],
            dq: vec![[0.0; N_ACTIONS]; batch],
            q: vec![[0.0; N_ACTIONS]; batch],
        }
    }
}

/// A zeroed network on the heap (`Mlp<128>` is 70 KB: too big to move around on stacks).
pub fn boxed_zero<const H: usize>() -> Box<Mlp<H>> {
    Box::new(Mlp::zeroed())
}

/// Generates a public entry point per kernel implementation: it runs `$imp` compiled for the
/// chosen kernel, with fused multiply-add where that kernel has it. A kernel this CPU lacks
/// falls back to the portable build (the command line refuses such a choice up front).
macro_rules! kernel_entry {
    ($(#[$doc:meta])* fn $name:ident($($arg:ident: $ty:ty),*) -> $ret:ty => $imp:ident) => {
        $(#[$doc])*
        #[allow(clippy::too_many_arguments)]
        pub fn $name<const H: usize>(kernel: Kernel, $($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                fn avx512<const H: usize>($($arg: $ty),*) -> $ret {
                    $imp::<H, Fused, FUSED_ROWS>($($arg),*)
                }
                #[target_feature(enable = "avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                fn avx2<const H: usize>($($arg: $ty),*) -> $ret {
                    $imp::<H, Fused, FUSED_ROWS>($($arg),*)
                }
                match kernel {
                    // SAFETY: the CPU was just checked for every feature the function enables.
                    Kernel::Avx512 if Kernel::Avx512.supported() => {
                        return unsafe { avx512::<H>($($arg),*) };
                    }
                    // SAFETY: as above.
                    Kernel::Avx2 if Kernel::Avx2.supported() => {
                        return unsafe { avx2::<H>($($arg),*) };
                    }
                    _ => {}
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = kernel;
            $imp::<H, Unfused, UNFUSED_ROWS>($($arg),*)
        }
    };
}

kernel_entry! {
    /// Forward pass of `x` (one row per sample) through `net` (with `packed` its current
    /// transposes), keeping the activations for [`backward`]; Q-values land in
    /// `s.q[..x.len()]`.
    fn forward_batch(
        net: &Mlp<H>,
        packed: &Packed<H>,
        x: &[[f32; OBS_DIM]],
        s: &mut Scratch<H>
    ) -> ()
        => forward_impl
}

kernel_entry! {
    /// Gradients of the mean loss over the batch of the last [`forward_batch`] of `net` on
    /// `x`, where sample `b` regresses `Q(x_b, actions[b])` towards `targets[b]`. Overwrites
    /// `grad`; returns the loss.
    fn backward(
        net: &Mlp<H>,
        x: &[[f32; OBS_DIM]],
        actions: &[u8],
        targets: &[f32],
        loss: Loss,
        s: &mut Scratch<H>,
        grad: &mut Mlp<H>
    ) -> f32 => backward_impl
}

kernel_entry! {
    /// One Adam step (`t` counts from 1) of `params` along `grad`, updating the moments.
    fn adam_step(
        hp: &AdamParams,
        t: u64,
        params: &mut Mlp<H>,
        grad: &Mlp<H>,
        m: &mut Mlp<H>,
        v: &mut Mlp<H>
    ) -> () => adam_impl
}

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

/// Multiply-add as a type, so one generic kernel compiles with and without fusion, and
/// how many batch rows a kernel computes together: each weight chunk is then loaded once for
/// all of them, and their accumulators form independent chains that hide the multiply-add
/// latency, as many as the register file holds (16 SSE registers hold 2 rows of 4).
trait MulAdd {
    fn mul_add(a: f32, b: f32, c: f32) -> f32;
}
const FUSED_ROWS: usize = 4;
const UNFUSED_ROWS: usize = 2;
struct Fused;
struct Unfused;
impl MulAdd for Fused {
    #[inline(always)]
    fn mul_add(a: f32, b: f32, c: f32) -> f32 {
        a.mul_add(b, c)
    }
}
impl MulAdd for Unfused {
    #[inline(always)]
    fn mul_add(a: f32, b: f32, c: f32) -> f32 {
        a * b + c
    }
}

/// Output lanes per accumulator: one AVX-512 register, two AVX2 ones, four SSE ones.
/// Every supported width is a multiple of it.
const L: usize = 16;

/// The kernels' one building block, for `R2` rows at once:
/// `y[r] = init + sum_i x(i)[r] * w[i]` over the `w.len()` terms, then ReLU if asked.
/// Accumulators are `[f32; L]` values the compiler keeps in registers; a whole `[f32; H]`
/// accumulator would live in memory and turn every term into a load-add-store chain.
/// `x(i)` gathers term `i`'s coefficient for each row, so a matrix can be read along either
/// axis without first being transposed.
#[inline(always)]
fn rows_times<const H: usize, const R2: usize, F: MulAdd>(
    x: impl Fn(usize) -> [f32; R2],
    w: &[[f32; H]],
    init: Option<&[f32; H]>,
    relu: bool,
    y: [&mut [f32; H]; R2],
) {
    const {
        assert!(
            H.is_multiple_of(L),
            "hidden width must be a multiple of the lane block"
        )
    };
    let mut y = y.map(|r| r.as_chunks_mut::<L>().0);
    for c in 0..H / L {
        let start = init.map_or([0.0; L], |b| b.as_chunks::<L>().0[c]);
        let mut acc = [start; R2];
        for (i, wi) in w.iter().enumerate() {
            let wc = &wi.as_chunks::<L>().0[c];
            for (acc, xi) in acc.iter_mut().zip(x(i)) {
                for (a, w) in acc.iter_mut().zip(wc) {
                    *a = F::mul_add(xi, *w, *a);
                }
            }
        }
        for (acc, y) in acc.iter().zip(y.iter_mut()) {
            for (o, a) in y[c].iter_mut().zip(acc) {
                *o = if relu && *a <= 0.0 { 0.0 } else { *a };
            }
        }
    }
}

/// [`rows_times`] over every row of `xs`/`ys`, `R` at a time, the remainder one by one.
#[inline(always)]
fn all_rows<const H: usize, const N: usize, F: MulAdd, const R: usize>(
    xs: &[[f32; N]],
    w: &[[f32; H]],
    init: Option<&[f32; H]>,
    relu: bool,
    ys: &mut [[f32; H]],
) {
    let n = w.len();
    let (xb, xr) = xs.as_chunks::<R>();
    let (yb, yr) = ys[..xs.len()].as_chunks_mut::<R>();
    for (x, y) in xb.iter().zip(yb) {
        let x = x.each_ref().map(|r| &r[..n]);
        rows_times::<H, R, F>(|i| x.map(|r| r[i]), w, init, relu, y.each_mut());
    }
    for (x, y) in xr.iter().zip(yr) {
        let x = &x[..n];
        rows_times::<H, 1, F>(|i| [x[i]], w, init, relu, [y]);
    }
}

#[inline(always)]
fn forward_impl<const H: usize, F: MulAdd, const R: usize>(
    net: &Mlp<H>,
    packed: &Packed<H>,
    x: &[[f32; OBS_DIM]],
    s: &mut Scratch<H>,
) {
    let n = x.len();
    all_rows::<H, OBS_DIM, F, R>(x, &packed.w1t, Some(&net.fc1_bias), true, &mut s.a1);
    all_rows::<H, H, F, R>(
        &s.a1[..n],
        &packed.w2t,
        Some(&net.fc2_bias),
        true,
        &mut s.a2,
    );
    for (a2, q) in s.a2[..n].iter().zip(s.q[..n].iter_mut()) {
        for ((q, w), bias) in q.iter_mut().zip(&net.fc3_weight).zip(&net.fc3_bias) {
            #[cfg(target_arch = "x86_64")]
            let d = dot_x86(w, a2);
            #[cfg(not(target_arch = "x86_64"))]
            let d = dot(w, a2);
            *q = d + bias;
        }
    }
}

/// `firmware::network::dot` in SSE registers, operation for operation: lane `k` of the
/// register pair is the dot product's partial sum `k` (eight products at a time, multiplied
/// then added, never fused), then the lanes meet in `dot`'s tree. Bit-identical to `dot`
/// (tested). SSE2 is part of x86-64 itself, so every x86-64 CPU runs it.
///
/// LLVM does not find this form by itself: inlined into the kernels it compiled the output
/// layer's dot products to scalar code, 8% of a training step. Every kernel uses this one;
/// [`dot_avx`] would save the AVX-512 kernel only 0.2 us of 16.
#[cfg(target_arch = "x86_64")]
#[inline]
pub fn dot_x86<const N: usize>(w: &[f32; N], x: &[f32; N]) -> f32 {
    use firmware::network::LANES;
    use std::arch::x86_64::*;
    const {
        assert!(
            N.is_multiple_of(LANES),
            "dot_x86 takes whole chunks of eight"
        )
    };
    fn pairs<const N: usize>(v: &[f32; N]) -> &[[[f32; 4]; 2]] {
        v.as_chunks::<4>().0.as_chunks::<2>().0
    }
    // SAFETY: SSE and SSE2 are part of x86-64, so every CPU this runs on has them; each
    // load reads four floats of a `[f32; 4]`, and `loadu` needs no alignment.
    unsafe {
        let (mut lo, mut hi) = (_mm_set1_ps(-0.0), _mm_set1_ps(-0.0));
        for (w, x) in pairs(w).iter().zip(pairs(x)) {
            lo = _mm_add_ps(
                lo,
                _mm_mul_ps(_mm_loadu_ps(w[0].as_ptr()), _mm_loadu_ps(x[0].as_ptr())),
            );
            hi = _mm_add_ps(
                hi,
                _mm_mul_ps(_mm_loadu_ps(w[1].as_ptr()), _mm_loadu_ps(x[1].as_ptr())),
            );
        }
        // [l0 + l4, l1 + l5, l2 + l6, l3 + l7]
        let quad = _mm_add_ps(lo, hi);
        // [(l0 + l4) + (l2 + l6), (l1 + l5) + (l3 + l7), ..]
        let pair = _mm_add_ps(quad, _mm_movehl_ps(quad, quad));
        _mm_cvtss_f32(_mm_add_ss(pair, _mm_shuffle_ps::<0b01>(pair, pair)))
    }
}

/// [`dot_x86`] in one AVX register, for code already compiled with AVX: host-sim's
/// one-observation forward pass, where its shorter chain is 5 ns of 127.
///
/// # Safety
///
/// Outside code compiled with AVX enabled, call it only on a CPU that has AVX
/// (`is_x86_feature_detected!("avx")`).
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx")]
pub fn dot_avx<const N: usize>(w: &[f32; N], x: &[f32; N]) -> f32 {
    use firmware::network::LANES;
    use std::arch::x86_64::*;
    const {
        assert!(
            N.is_multiple_of(LANES),
            "dot_avx takes whole chunks of eight"
        )
    };
    // SAFETY: `v` is eight readable floats; `loadu` needs no alignment.
    let load = |v: &[f32; LANES]| unsafe { _mm256_loadu_ps(v.as_ptr()) };
    let mut acc = _mm256_set1_ps(-0.0);
    for (w, x) in w.as_chunks::<LANES>().0.iter().zip(x.as_chunks().0) {
        acc = _mm256_add_ps(acc, _mm256_mul_ps(load(w), load(x)));
    }
    let quad = _mm_add_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps::<1>(acc));
    let pair = _mm_add_ps(quad, _mm_movehl_ps(quad, quad));
    _mm_cvtss_f32(_mm_add_ss(pair, _mm_shuffle_ps::<0b01>(pair, pair)))
}

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

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn backward_impl<const H: usize, F: MulAdd, const R: usize>(
    net: &Mlp<H>,
    x: &[[f32; OBS_DIM]],
    actions: &[u8],
    targets: &[f32],
    loss: Loss,
    s: &mut Scratch<H>,
    grad: &mut Mlp<H>,
) -> f32 {
    const {
        assert!(
            H.is_multiple_of(R),
            "hidden width must be a multiple of the rows per block"
        )
    };
    let n = x.len();
    let inv_n = 1.0 / n as f32;
    let mut total = 0.0f64;
    // dL/dQ is non-zero only at the taken action.
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
        s.dq[b][a] = g * inv_n;
    }

    // Output layer (2 x H, small): direct sums.
    grad.fc3_weight = [[0.0; H]; N_ACTIONS];
    grad.fc3_bias = [0.0; N_ACTIONS];
    for b in 0..n {
        for o in 0..N_ACTIONS {
            let g = s.dq[b][o];
            for (gw, a) in grad.fc3_weight[o].iter_mut().zip(&s.a2[b]) {
                *gw = F::mul_add(g, *a, *gw);
            }
            grad.fc3_bias[o] += g;
        }
    }
    // Into the second hidden layer: d2 = (dq W3) masked by ReLU'.
    all_rows::<H, N_ACTIONS, F, R>(&s.dq[..n], &net.fc3_weight, None, false, &mut s.d2);
    relu_backward(&mut s.d2[..n], &s.a2[..n]);
    // Second layer weights: dW2[o] = sum_b d2[b][o] * a1[b], rows over o, terms over b,
    // reading d2 down its columns, R units at a time.
    let d2 = &s.d2[..n];
    let a1 = &s.a1[..n];
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
    // Into the first hidden layer: d1 = (d2 W2) masked by ReLU'.
    all_rows::<H, H, F, R>(d2, &net.fc2_weight, None, false, &mut s.d1);
    relu_backward(&mut s.d1[..n], a1);
    // First layer, accumulated transposed (contiguous over outputs), then stored [out][in].
    let mut gw1t = [[0.0f32; H]; OBS_DIM];
    rows_times::<H, OBS_DIM, F>(|b| x[b], &s.d1[..n], None, false, gw1t.each_mut());
    for (o, row) in grad.fc1_weight.iter_mut().enumerate() {
        for (i, w) in row.iter_mut().enumerate() {
            *w = gw1t[i][o];
        }
    }
    grad.fc1_bias = [0.0; H];
    for d1 in &s.d1[..n] {
        for (g, d) in grad.fc1_bias.iter_mut().zip(d1) {
            *g += d;
        }
    }
    (total / n as f64) as f32
}

#[inline(always)]
fn adam_impl<const H: usize, F: MulAdd, const R: usize>(
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
            let m1 = F::mul_add(b1, *m, c1 * g);
            let v1 = F::mul_add(b2, *v, c2 * g * g);
            *m = if m1.abs() < FLUSH { 0.0 } else { m1 };
            *v = if v1 < FLUSH { 0.0 } else { v1 };
            *p -= step * *m / (v.sqrt() / sqrt_bc2 + eps);
        }
    }
}

#[cfg(test)]
mod tests {
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

    /// How many of 500 random pairs `dot_x86` and (where the CPU has AVX) `dot_avx` get
    /// other bits than `dot` for.
    #[cfg(target_arch = "x86_64")]
    fn check_dot_x86<const N: usize>(r: &mut impl Rng) -> [usize; 2] {
        let avx = is_x86_feature_detected!("avx");
        let differs = |a: f32, b: f32| a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan());
        let mut differ = [0; 2];
        for case in 0..500 {
            // Half ordinary values, half raw bit patterns: NaNs, infinities, subnormals and
            // signed zeros, where a wrong order or a fused step would show.
            let mut draw = || {
                if case % 2 == 0 {
                    uniform(r, -3.0, 3.0)
                } else {
                    f32::from_bits(r.next_u32())
                }
            };
            let w: [f32; N] = std::array::from_fn(|_| draw());
            let x: [f32; N] = std::array::from_fn(|_| draw());
            let want = dot(&w, &x);
            differ[0] += usize::from(differs(dot_x86(&w, &x), want));
            if avx {
                // SAFETY: the CPU was just checked for AVX.
                differ[1] += usize::from(differs(unsafe { dot_avx(&w, &x) }, want));
            }
        }
        differ
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn the_x86_dot_products_equal_the_firmwares_bit_for_bit() {
        let mut r = rng(21, Stream::Sample);
        let differ = [
            check_dot_x86::<8>(&mut r),
            check_dot_x86::<16>(&mut r),
            check_dot_x86::<64>(&mut r),
            check_dot_x86::<256>(&mut r),
        ];
        assert_eq!(differ, [[0; 2]; 4]);
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
            let p2 =
                p1 - (0.1 / (1.0 - 0.81)) * m2 / (v2.sqrt() / (1.0 - 0.998001f64).sqrt() + 1e-8);
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
            let bits = |m: &Mlp<64>| -> Vec<u32> {
                m.tensors()
                    .iter()
                    .flat_map(|t| t.iter().map(|v| v.to_bits()))
                    .collect()
            };
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
}
