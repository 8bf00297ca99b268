//! The firmware's [`dot`](firmware::network::dot) in x86-64 vector registers, operation for
//! operation, for host code that runs the forward pass often: the trainer's output layer and
//! the wide forward pass ([`crate::wide`]).
//!
//! Lane `k` of the vector is the dot product's partial sum `k`: eight products at a time are
//! multiplied, then added (never fused), and the lanes meet in `dot`'s tree, so both
//! renderings return `dot_portable`'s bits (tested below on random and raw-bit inputs, NaNs,
//! infinities and subnormals included). LLVM does not find this form by itself: inlined into a
//! batched kernel it compiles `dot` to scalar code.
//!
//! The `unsafe` is the unaligned loads, which take raw pointers, and the call into the SSE
//! function, whose feature every x86-64 CPU has: the arithmetic intrinsics are safe
//! wherever their target feature is enabled.
#![allow(unsafe_code)]

use core::arch::x86_64::*;

use firmware::network::LANES;

/// [`dot`](firmware::network::dot) in a pair of SSE registers. SSE2 is part of x86-64 itself, so every
/// x86-64 CPU runs it and the function is safe. `N` must be a multiple of [`LANES`].
#[inline]
pub fn dot_sse<const N: usize>(w: &[f32; N], x: &[f32; N]) -> f32 {
    const {
        assert!(
            N.is_multiple_of(LANES),
            "dot_sse takes whole chunks of eight"
        )
    };
    // SAFETY: SSE is part of the x86-64 baseline: every CPU this code runs on has it.
    unsafe { sse(w, x) }
}

#[inline]
#[target_feature(enable = "sse")]
fn sse<const N: usize>(w: &[f32; N], x: &[f32; N]) -> f32 {
    // SAFETY: `v` is four readable floats and this function runs only with SSE.
    let load = |v: &[f32; 4]| unsafe { _mm_loadu_ps(v.as_ptr()) };
    let (mut lo, mut hi) = (_mm_set1_ps(-0.0), _mm_set1_ps(-0.0));
    for (w, x) in w
        .as_chunks::<LANES>()
        .0
        .iter()
        .zip(x.as_chunks::<LANES>().0)
    {
        let (w, x) = (w.as_chunks::<4>().0, x.as_chunks::<4>().0);
        lo = _mm_add_ps(lo, _mm_mul_ps(load(&w[0]), load(&x[0])));
        hi = _mm_add_ps(hi, _mm_mul_ps(load(&w[1]), load(&x[1])));
    }
    tree(_mm_add_ps(lo, hi))
}

/// [`dot_sse`] in one AVX register, for code compiled with AVX enabled (the simulator's wide
/// kernels); its chain of additions is half as long. `N` must be a multiple of [`LANES`].
///
/// # Safety
///
/// Outside code compiled with AVX enabled, call it only on a CPU that has AVX
/// (`is_x86_feature_detected!("avx")`).
#[inline]
#[target_feature(enable = "avx")]
pub fn dot_avx<const N: usize>(w: &[f32; N], x: &[f32; N]) -> f32 {
    const {
        assert!(
            N.is_multiple_of(LANES),
            "dot_avx takes whole chunks of eight"
        )
    };
    // SAFETY: `v` is eight readable floats and this function runs only with AVX.
    let load = |v: &[f32; LANES]| unsafe { _mm256_loadu_ps(v.as_ptr()) };
    let mut acc = _mm256_set1_ps(-0.0);
    for (w, x) in w
        .as_chunks::<LANES>()
        .0
        .iter()
        .zip(x.as_chunks::<LANES>().0)
    {
        acc = _mm256_add_ps(acc, _mm256_mul_ps(load(w), load(x)));
    }
    tree(_mm_add_ps(
        _mm256_castps256_ps128(acc),
        _mm256_extractf128_ps::<1>(acc),
    ))
}

/// `dot`'s tree from `[l0 + l4, l1 + l5, l2 + l6, l3 + l7]`:
/// `((l0 + l4) + (l2 + l6)) + ((l1 + l5) + (l3 + l7))`.
#[inline]
#[target_feature(enable = "sse")]
fn tree(quad: __m128) -> f32 {
    let pair = _mm_add_ps(quad, _mm_movehl_ps(quad, quad));
    _mm_cvtss_f32(_mm_add_ss(pair, _mm_shuffle_ps::<0b01>(pair, pair)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::network::dot_portable;
    use rand_core::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// How many of 500 random pairs `dot_sse` and (where the CPU has AVX) `dot_avx` get other
    /// bits than `dot_portable` for; two NaNs count as equal.
    fn differ<const N: usize>(r: &mut Pcg64Mcg) -> [usize; 2] {
        let avx = std::is_x86_feature_detected!("avx");
        let differs = |a: f32, b: f32| a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan());
        let mut n = [0; 2];
        for case in 0..500 {
            // Half moderate values whose sums cancel, half raw bit patterns.
            let mut draw = || {
                let bits = r.next_u32();
                if case % 2 == 0 {
                    (bits >> 8) as f32 / (1 << 24) as f32 * 6.0 - 3.0
                } else {
                    f32::from_bits(bits)
                }
            };
            let w: [f32; N] = core::array::from_fn(|_| draw());
            let x: [f32; N] = core::array::from_fn(|_| draw());
            let want = dot_portable(&w, &x);
            n[0] += usize::from(differs(dot_sse(&w, &x), want));
            if avx {
                // SAFETY: the CPU was just checked for AVX.
                n[1] += usize::from(differs(unsafe { dot_avx(&w, &x) }, want));
            }
        }
        n
    }

    #[test]
    fn the_x86_renderings_equal_dot_portable_bit_for_bit() {
        let mut r = Pcg64Mcg::seed_from_u64(21);
        let n = [
            differ::<8>(&mut r),
            differ::<16>(&mut r),
            differ::<64>(&mut r),
            differ::<256>(&mut r),
        ];
        assert_eq!(n, [[0; 2]; 4]);
    }

    #[test]
    fn they_keep_the_tree_where_other_associations_round_differently() {
        // Lane sums chosen so that each of the usual alternative trees gives another f32
        // (the firmware's `the_tree_is_the_documented_one` shows it).
        let lanes = [-3.0, 3e7, -6e7, 3e7, -1e8, 3.0, 1e8, 3.0];
        let x = [1.0f32; 16];
        let mut w = [0.0f32; 16];
        w[..8].copy_from_slice(&lanes);
        let want = dot_portable(&w, &x);
        assert_eq!(want, 8.0);
        assert_eq!(dot_sse(&w, &x).to_bits(), want.to_bits());
        if std::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU was just checked for AVX.
            assert_eq!(unsafe { dot_avx(&w, &x) }.to_bits(), want.to_bits());
        }
    }
}
