//! The batched forward pass, and the one building block every matrix product of the
//! trainer is made of: `y = init + sum_i x_i * w_i`, each term a fused multiply-add
//! (`f32::mul_add`, one rounding), in increasing `i`. That is the training arithmetic's
//! definition; every build renders exactly it (software `fmaf` where the CPU has no FMA).

use firmware::network::{Mlp, OBS_DIM};

use super::Packed;

/// Which rendering of the one arithmetic a build runs: [`rows_times`]'s generic code, or
/// its 4-row blocks in AVX-512 intrinsics ([`avx512::rows4`]). Both compute the same fused
/// multiply-adds in the same order, so the same bits.
pub(super) trait Render {
    /// Whether [`rows_times`] should run its 4-row blocks in [`avx512::rows4`] (it checks
    /// the CPU itself).
    #[cfg(target_arch = "x86_64")]
    const AVX512: bool = false;
}
/// The generic code, compiled for the build's target features.
pub(super) struct Generic;
impl Render for Generic {}
/// The AVX-512 build's 4-row blocks.
#[cfg(target_arch = "x86_64")]
pub(super) struct Avx512;
#[cfg(target_arch = "x86_64")]
impl Render for Avx512 {
    const AVX512: bool = true;
}
/// Batch rows a kernel computes together: each weight chunk is then loaded once for all of
/// them, and their accumulators form independent chains that hide the multiply-add latency.
pub(super) const ROWS: usize = 4;

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
pub(super) fn rows_times<const H: usize, const R2: usize, F: Render>(
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
    #[cfg(target_arch = "x86_64")]
    // The check costs a cached load per block of 4 rows, and makes soundness local: only
    // the AVX-512 entry point uses `Avx512`, but nothing else would stop another caller.
    if F::AVX512
        && R2 == 4
        && H.is_multiple_of(avx512::BLOCK)
        && std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("fma")
    {
        let mut rows = y.into_iter();
        let y = core::array::from_fn(|_| rows.next().expect("R2 is 4"));
        // SAFETY: the CPU was just checked for the features `rows4` enables.
        unsafe {
            avx512::rows4(
                |i| {
                    let x = x(i);
                    [x[0], x[1], x[2], x[3]]
                },
                w,
                init,
                relu,
                y,
            )
        };
        return;
    }
    let mut y = y.map(|r| r.as_chunks_mut::<L>().0);
    for c in 0..H / L {
        let start = init.map_or([0.0; L], |b| b.as_chunks::<L>().0[c]);
        let mut acc = [start; R2];
        for (i, wi) in w.iter().enumerate() {
            let wc = &wi.as_chunks::<L>().0[c];
            for (acc, xi) in acc.iter_mut().zip(x(i)) {
                for (a, w) in acc.iter_mut().zip(wc) {
                    *a = xi.mul_add(*w, *a);
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

/// [`rows_times`] for 4 rows in AVX-512 registers, 32 outputs at a time: eight
/// accumulators, two per row, so that eight independent multiply-add chains hide the
/// latency. LLVM keeps the generic kernel's four 16-lane accumulators in registers but
/// spills eight (or any `[f32; 32]` ones): measured 5x slower. Four chains keep a core that
/// issues two 512-bit multiply-adds a cycle (Zen 5) half idle.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
pub(super) mod avx512 {
    use core::arch::x86_64::*;

    /// Outputs per pass; a width must be a multiple of it.
    pub(crate) const BLOCK: usize = 32;

    /// `y[r] = init + sum_i x(i)[r] * w[i]` (fused, in increasing `i`), then ReLU if asked:
    /// [`rows_times`](super::rows_times)'s operations, so its bits.
    #[inline]
    #[target_feature(enable = "avx512f,fma")]
    pub(crate) fn rows4<const H: usize>(
        x: impl Fn(usize) -> [f32; 4],
        w: &[[f32; H]],
        init: Option<&[f32; H]>,
        relu: bool,
        y: [&mut [f32; H]; 4],
    ) {
        // SAFETY: `p` points to 16 readable (writable) floats; `loadu`/`storeu` need no
        // alignment.
        let load = |p: &[f32; 16]| unsafe { _mm512_loadu_ps(p.as_ptr()) };
        let store = |p: &mut [f32; 16], v| unsafe { _mm512_storeu_ps(p.as_mut_ptr(), v) };
        let zero = _mm512_setzero_ps();
        let [y0, y1, y2, y3] = y.map(|r| r.as_chunks_mut::<16>().0);
        let mut y = [y0, y1, y2, y3];
        for c in (0..H / 16).step_by(2) {
            let start = |k: usize| init.map_or(zero, |b| load(&b.as_chunks::<16>().0[c + k]));
            let (s0, s1) = (start(0), start(1));
            let (mut a00, mut a01, mut a10, mut a11) = (s0, s1, s0, s1);
            let (mut a20, mut a21, mut a30, mut a31) = (s0, s1, s0, s1);
            for (i, wi) in w.iter().enumerate() {
                let wc = wi.as_chunks::<16>().0;
                let (w0, w1) = (load(&wc[c]), load(&wc[c + 1]));
                let [x0, x1, x2, x3] = x(i).map(|v| _mm512_set1_ps(v));
                a00 = _mm512_fmadd_ps(x0, w0, a00);
                a01 = _mm512_fmadd_ps(x0, w1, a01);
                a10 = _mm512_fmadd_ps(x1, w0, a10);
                a11 = _mm512_fmadd_ps(x1, w1, a11);
                a20 = _mm512_fmadd_ps(x2, w0, a20);
                a21 = _mm512_fmadd_ps(x2, w1, a21);
                a30 = _mm512_fmadd_ps(x3, w0, a30);
                a31 = _mm512_fmadd_ps(x3, w1, a31);
            }
            let out = [[a00, a01], [a10, a11], [a20, a21], [a30, a31]];
            for (y, acc) in y.iter_mut().zip(out) {
                for (k, a) in acc.into_iter().enumerate() {
                    // `a <= 0` is false for NaN, which passes through, as in the generic
                    // kernel; `-0.0` becomes `+0.0`.
                    let a = if relu {
                        _mm512_mask_mov_ps(a, _mm512_cmp_ps_mask::<_CMP_LE_OQ>(a, zero), zero)
                    } else {
                        a
                    };
                    store(&mut y[c + k], a);
                }
            }
        }
    }
}

/// [`rows_times`] over every row of `xs`/`ys`, `R` at a time, the remainder one by one.
#[inline(always)]
pub(super) fn all_rows<const H: usize, const N: usize, F: Render, const R: usize>(
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

/// A forward pass's activations and Q-values, one entry per row of its input.
pub struct Activations<'a, const H: usize, const A: usize> {
    /// First hidden layer.
    pub a1: &'a mut [[f32; H]],
    /// Second hidden layer.
    pub a2: &'a mut [[f32; H]],
    /// Q-values.
    pub q: &'a mut [[f32; A]],
}

#[inline(always)]
pub(super) fn forward_impl<const H: usize, const A: usize, F: Render, const R: usize>(
    net: &Mlp<H, A>,
    packed: &Packed<H>,
    x: &[[f32; OBS_DIM]],
    out: Activations<'_, H, A>,
) {
    let n = x.len();
    all_rows::<H, OBS_DIM, F, R>(x, &packed.w1t, Some(&net.fc1_bias), true, out.a1);
    all_rows::<H, H, F, R>(&out.a1[..n], &packed.w2t, Some(&net.fc2_bias), true, out.a2);
    for (a2, q) in out.a2[..n].iter().zip(out.q[..n].iter_mut()) {
        for ((q, w), bias) in q.iter_mut().zip(&net.fc3_weight).zip(&net.fc3_bias) {
            // `dot`'s order in SSE registers: inlined here, LLVM compiles `dot` itself to
            // scalar code, which cost 8% of a training step.
            #[cfg(target_arch = "x86_64")]
            let d = host_common::dot_x86::dot_sse(w, a2);
            #[cfg(not(target_arch = "x86_64"))]
            let d = firmware::network::dot(w, a2);
            *q = d + bias;
        }
    }
}
