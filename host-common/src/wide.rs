//! The firmware's forward pass, rearranged for host SIMD: same operations, same bits. The
//! host's renderings of it: the simulator balances and the trainer evaluates with
//! [`WideMlp`]; the trainer acts with [`forward_unpacked`], on weights that change every step.
//!
//! [`firmware::network::Mlp::forward`] computes one output at a time; compiled for a host, LLVM
//! vectorises it with 2-wide SSE code (see `docs/PERFORMANCE.md`). [`WideMlp`] computes a
//! block of 8 (AVX2) or 16 (AVX-512) outputs at once: register `k` holds partial sum `k` of
//! every output of the block, and input `i` adds `weight[block][i] * x[i]` to register
//! `i % 8`. Every output therefore gets exactly the multiplies, adds and tree of
//! [`firmware::network::dot`], in the same order, with no horizontal sums and partial-sum
//! chains only `H / 8` adds long. The output layer's dot products run with lane `k` of one
//! register as partial sum `k`. No multiply and add is fused: FMA would round differently
//! from the firmware. The Q-values are the firmware's bit for bit (tested below on random
//! networks and inputs, NaNs included).
//!
//! The hidden layers' weights are repacked block by block, so a block's weights are one
//! sequential stream (a plain transpose reads them with a stride of `4 H` bytes, measured
//! slower). Without AVX2 (chosen at run time) it runs the firmware's own forward pass.

use firmware::controller::{Duty, Levels, Policy};
#[cfg(target_arch = "x86_64")]
use firmware::network::LANES;
use firmware::network::{Mlp, N_ACTIONS, OBS_DIM};

use crate::kernel::Kernel;

/// A 4-H-H-A network laid out for one [`Kernel`], with the duty level of each output: the
/// greedy policy [`firmware::controller::Greedy`] is on the firmware. `H` must be a multiple
/// of 16.
#[derive(Clone, Debug)]
pub struct WideMlp<const H: usize, const A: usize = N_ACTIONS> {
    net: Mlp<H, A>,
    levels: Levels<A>,
    kernel: Kernel,
    /// `fc1.weight` in blocks of the kernel's width `W`: element `(b * 4 + i) * W + j` is
    /// `fc1_weight[b * W + j][i]`. Only the x86 kernels read it (elsewhere it is empty).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    fc1: Aligned,
    /// `fc2.weight` likewise: element `(b * H + i) * W + j` is `fc2_weight[b * W + j][i]`.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    fc2: Aligned,
}

/// Floats that start on a 64-byte boundary, so no 32- or 64-byte load of a block straddles
/// two cache lines (with `Vec`'s 4-byte alignment the AVX-512 kernel ran measurably slower).
#[derive(Debug)]
struct Aligned {
    buf: Vec<f32>,
    start: usize,
}

impl Aligned {
    const LINE: usize = 64 / size_of::<f32>();

    fn new(data: &[f32]) -> Aligned {
        let mut buf = vec![0.0; data.len() + Self::LINE - 1];
        // The buffer never grows, so its address, and this offset, stay valid.
        let start = (Self::LINE - buf.as_ptr().addr() / size_of::<f32>() % Self::LINE) % Self::LINE;
        buf[start..start + data.len()].copy_from_slice(data);
        Aligned { buf, start }
    }

    fn get(&self) -> &[f32] {
        &self.buf[self.start..self.start + self.buf.len() + 1 - Self::LINE]
    }
}

impl Clone for Aligned {
    fn clone(&self) -> Aligned {
        Aligned::new(self.get())
    }
}

impl<const H: usize, const A: usize> WideMlp<H, A> {
    const WIDTH_IS_BLOCKED: () =
        assert!(H.is_multiple_of(16) && H > 0, "H must be a multiple of 16");

    /// `net` on its `levels` for the fastest kernel this CPU runs.
    pub fn new(net: &Mlp<H, A>, levels: Levels<A>) -> Box<Self> {
        let kernel = Kernel::detect();
        Self::with_kernel(net, levels, kernel)
            .unwrap_or_else(|| unreachable!("{kernel:?} was detected"))
    }

    /// `net` on its `levels` for `kernel`, or `None` if this CPU cannot run it.
    pub fn with_kernel(net: &Mlp<H, A>, levels: Levels<A>, kernel: Kernel) -> Option<Box<Self>> {
        let () = Self::WIDTH_IS_BLOCKED;
        if !kernel.supported() {
            return None;
        }
        let width = block(kernel);
        Some(Box::new(WideMlp {
            net: net.clone(),
            levels,
            kernel,
            fc1: Aligned::new(&pack(&net.fc1_weight, width)),
            fc2: Aligned::new(&pack(&net.fc2_weight, width)),
        }))
    }

    /// The kernel [`WideMlp::forward`] runs.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// Q-values, one per output, bit-identical to [`Mlp::forward`].
    #[inline]
    pub fn forward(&self, obs: &[f32; OBS_DIM]) -> [f32; A] {
        match self.kernel {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => x86::avx2(self, obs),
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => x86::avx512(self, obs),
            _ => self.net.forward(obs),
        }
    }
}

/// `w[o][i]` in blocks of `width` outputs, block after block (empty for width 0).
fn pack<const I: usize, const O: usize>(w: &[[f32; I]; O], width: usize) -> Vec<f32> {
    let mut out = vec![0.0; if width == 0 { 0 } else { I * O }];
    pack_into(w, width, &mut out);
    out
}

/// [`pack`] into `out`, which holds `I * O` floats (none for width 0).
fn pack_into<const I: usize, const O: usize>(w: &[[f32; I]; O], width: usize, out: &mut [f32]) {
    match width {
        8 => pack_blocks::<I, O, 8>(w, out),
        16 => pack_blocks::<I, O, 16>(w, out),
        _ => {}
    }
}

/// Block `b` of `W` rows of `w` becomes `I` rows of `W` floats, `out[b * I + i][j] =
/// w[b * W + j][i]`: reading each row of `w` once, writing into a block that stays in cache.
fn pack_blocks<const I: usize, const O: usize, const W: usize>(w: &[[f32; I]; O], out: &mut [f32]) {
    let out = out.as_chunks_mut::<W>().0;
    for (block, dst) in w.chunks_exact(W).zip(out.chunks_exact_mut(I)) {
        let block: &[[f32; I]; W] = block.try_into().expect("chunks of W rows");
        for (i, d) in dst.iter_mut().enumerate() {
            *d = core::array::from_fn(|j| block[j][i]);
        }
    }
}

/// The firmware's forward pass on `net` as it lies, each hidden and output unit's dot product
/// in one AVX register ([`crate::dot_x86::dot_avx`], the lanes meeting in `dot`'s tree): for
/// a network that changes between calls, as the trainer's does after every gradient step,
/// where [`WideMlp`]'s repacking costs more than its wider blocks save. `kernel` says which
/// instructions the CPU has (the firmware's own pass without AVX); the same bits as
/// [`Mlp::forward`] either way. `H` must be a multiple of 8.
pub fn forward_unpacked<const H: usize, const A: usize>(
    net: &Mlp<H, A>,
    obs: &[f32; OBS_DIM],
    kernel: Kernel,
) -> [f32; A] {
    match kernel {
        // SAFETY: both kernels are chosen only on CPUs with AVX2, hence AVX
        // (`Kernel::supported`).
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        Kernel::Avx2 | Kernel::Avx512 => unsafe { x86::unpacked(net, obs) },
        _ => net.forward(obs),
    }
}

impl<const H: usize, const A: usize> Policy for &WideMlp<H, A> {
    type Scores = [f32; A];
    #[inline]
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> [f32; A] {
        self.forward(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.levels.duty(i)
    }
}

/// Outputs per register of `kernel`'s build (0: no repacking, the firmware's own pass).
fn block(kernel: Kernel) -> usize {
    match kernel {
        Kernel::Portable => 0,
        Kernel::Avx2 => 8,
        Kernel::Avx512 => 16,
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod x86 {
    use std::arch::x86_64::*;

    use super::*;

    /// `fn $entry(net, obs)`, the forward pass, and `fn $name(y, w, b, x)`:
    /// `y = relu(W x + b)` for `W` packed in blocks of `$width` outputs (see [`WideMlp`]).
    /// Register `k` holds partial sum `k` of a block's outputs, so each output follows `dot`'s
    /// order exactly. `$group` blocks run together and share each input's broadcast: two with
    /// AVX-512's 32 registers (16 partial sums, 8 broadcasts), one with AVX2's 16. One
    /// definition for both vector widths.
    macro_rules! layer {
        ($entry:ident, $name:ident, $feature:literal, $width:literal, $group:literal,
         $vec:ty, $load:ident, $store:ident, $set1:ident, $add:ident, $mul:ident, $max:ident,
         $zero:ident) => {
            /// The forward pass with `$width` outputs per register.
            pub(super) fn $entry<const H: usize, const A: usize>(
                net: &WideMlp<H, A>,
                obs: &[f32; OBS_DIM],
            ) -> [f32; A] {
                #[target_feature(enable = $feature)]
                fn imp<const H: usize, const A: usize>(
                    net: &WideMlp<H, A>,
                    obs: &[f32; OBS_DIM],
                ) -> [f32; A] {
                    let mut h1 = [0.0; H];
                    $name(&mut h1, net.fc1.get().as_chunks().0, &net.net.fc1_bias, obs);
                    let mut h2 = [0.0; H];
                    $name(&mut h2, net.fc2.get().as_chunks().0, &net.net.fc2_bias, &h1);
                    output(net, &h2)
                }
                // SAFETY: a `WideMlp` gets this kernel only from `with_kernel`, after
                // checking that the CPU has `$feature`.
                unsafe { imp(net, obs) }
            }

            #[inline]
            #[target_feature(enable = $feature)]
            fn $name<const I: usize, const O: usize>(
                y: &mut [f32; O],
                w: &[[f32; $width]],
                b: &[f32; O],
                x: &[f32; I],
            ) {
                #[inline]
                #[target_feature(enable = $feature)]
                fn group<const I: usize, const G: usize>(
                    y: &mut [[f32; $width]; G],
                    b: &[[f32; $width]; G],
                    w: &[[[f32; $width]; I]; G],
                    x: &[f32; I],
                ) {
                    // SAFETY: `v` is `$width` readable floats; `loadu` needs no alignment.
                    let load = |v: &[f32; $width]| -> $vec { unsafe { $load(v.as_ptr()) } };
                    // Read `x` afresh for each group: otherwise LLVM hoists all `I` broadcasts out
                    // of the loop over groups, spills them to the stack as whole vectors and
                    // reloads 64 bytes where 4 would do, which measured slower.
                    let (xs, rest) = std::hint::black_box(x).as_chunks::<LANES>();
                    let mut acc = [[$set1(-0.0); LANES]; G];
                    for (c, xs) in xs.iter().enumerate() {
                        let xs = xs.map(|x| $set1(x));
                        for (k, &x) in xs.iter().enumerate() {
                            for (acc, w) in acc.iter_mut().zip(w) {
                                acc[k] = $add(acc[k], $mul(load(&w[c * LANES + k]), x));
                            }
                        }
                    }
                    for (k, &x) in rest.iter().enumerate() {
                        for (acc, w) in acc.iter_mut().zip(w) {
                            let i = I - rest.len() + k;
                            acc[k] = $add(acc[k], $mul(load(&w[i]), $set1(x)));
                        }
                    }
                    for ((acc, y), b) in acc.iter().zip(y).zip(b) {
                        let [a0, a1, a2, a3, a4, a5, a6, a7] = *acc;
                        let even = $add($add(a0, a4), $add(a2, a6));
                        let odd = $add($add(a1, a5), $add(a3, a7));
                        let v = $add($add(even, odd), load(b));
                        // max returns its second operand unless the first is greater: NaN and
                        // -0.0 give +0.0, as the firmware's ReLU does.
                        let v = $max(v, $zero());
                        // SAFETY: `y` is `$width` writable floats; `storeu` needs no alignment.
                        unsafe { $store(y.as_mut_ptr(), v) };
                    }
                }

                let (y, y1) = y.as_chunks_mut::<$width>().0.as_chunks_mut::<$group>();
                let (b, b1) = b.as_chunks::<$width>().0.as_chunks::<$group>();
                let (w, w1) = w.as_chunks::<I>().0.as_chunks::<$group>();
                for ((y, b), w) in y.iter_mut().zip(b).zip(w) {
                    group(y, b, w, x);
                }
                for ((y, b), w) in y1.iter_mut().zip(b1).zip(w1) {
                    group::<I, 1>(
                        core::array::from_mut(y),
                        core::array::from_ref(b),
                        core::array::from_ref(w),
                        x,
                    );
                }
            }
        };
    }

    layer!(
        avx2,
        layer8,
        "avx2",
        8,
        1,
        __m256,
        _mm256_loadu_ps,
        _mm256_storeu_ps,
        _mm256_set1_ps,
        _mm256_add_ps,
        _mm256_mul_ps,
        _mm256_max_ps,
        _mm256_setzero_ps
    );
    layer!(
        avx512,
        layer16,
        "avx512f",
        16,
        2,
        __m512,
        _mm512_loadu_ps,
        _mm512_storeu_ps,
        _mm512_set1_ps,
        _mm512_add_ps,
        _mm512_mul_ps,
        _mm512_max_ps,
        _mm512_setzero_ps
    );

    /// [`super::forward_unpacked`] on a CPU with AVX: the first layer's four-term dot
    /// products in plain Rust, the others in one AVX register each.
    #[target_feature(enable = "avx")]
    pub(super) fn unpacked<const H: usize, const A: usize>(
        net: &Mlp<H, A>,
        obs: &[f32; OBS_DIM],
    ) -> [f32; A] {
        const { assert!(H.is_multiple_of(LANES), "whole chunks of eight") };
        let relu = |v: f32| if v > 0.0 { v } else { 0.0 };
        let h1: [f32; H] = core::array::from_fn(|o| {
            relu(firmware::network::dot_portable(&net.fc1_weight[o], obs) + net.fc1_bias[o])
        });
        let h2: [f32; H] = core::array::from_fn(|o| {
            relu(crate::dot_x86::dot_avx(&net.fc2_weight[o], &h1) + net.fc2_bias[o])
        });
        core::array::from_fn(|a| crate::dot_x86::dot_avx(&net.fc3_weight[a], &h2) + net.fc3_bias[a])
    }

    /// The output layer: per action, `dot` in one AVX register (the trainer's rendering,
    /// tested bit-identical to `dot`), then the bias.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn output<const H: usize, const A: usize>(net: &WideMlp<H, A>, h: &[f32; H]) -> [f32; A] {
        let (w, b) = (&net.net.fc3_weight, &net.net.fc3_bias);
        core::array::from_fn(|a| crate::dot_x86::dot_avx(&w[a], h) + b[a])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;
    use shipped::policy::POLICY;

    fn uniform(rng: &mut Pcg64Mcg, scale: f32) -> f32 {
        ((rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0) * scale
    }

    fn same<const A: usize>(a: [f32; A], b: [f32; A]) -> bool {
        a.iter()
            .zip(&b)
            .all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()))
    }

    /// Observations from the failure box and well beyond it, plus raw bit patterns.
    fn observations(rng: &mut Pcg64Mcg, n: usize) -> Vec<[f32; 4]> {
        (0..n)
            .map(|k| match k % 3 {
                0 => [2.4, 3.0, 0.21, 3.0].map(|s| uniform(rng, s)),
                1 => [1e3; 4].map(|s| uniform(rng, s)),
                _ => [0; 4].map(|_| f32::from_bits(rng.next_u32())),
            })
            .collect()
    }

    /// Every kernel this CPU runs against the firmware's forward pass, packed and unpacked;
    /// not the packed portable kernel, whose forward pass is the firmware's own.
    fn check<const H: usize, const A: usize>(net: &Mlp<H, A>, rng: &mut Pcg64Mcg) {
        let levels: [f32; A] = core::array::from_fn(|i| i as f32 / A as f32);
        let levels = Levels::new(levels).unwrap();
        let wides: Vec<_> = Kernel::ALL
            .iter()
            .filter(|&&k| k != Kernel::Portable)
            .filter_map(|&k| WideMlp::with_kernel(net, levels, k))
            .collect();
        for obs in observations(rng, 600) {
            let want = net.forward(&obs);
            for kernel in Kernel::available() {
                let got = forward_unpacked(net, &obs, kernel);
                assert!(
                    same(got, want),
                    "unpacked {kernel:?} H={H} {obs:?}: {got:?} {want:?}"
                );
            }
            for wide in &wides {
                let got = wide.forward(&obs);
                let kernel = wide.kernel();
                assert!(
                    same(got, want),
                    "{kernel:?} H={H} {obs:?}: {got:?} {want:?}"
                );
            }
        }
    }

    fn random_net<const H: usize, const A: usize>(rng: &mut Pcg64Mcg) -> Box<Mlp<H, A>> {
        let mut net = Box::new(Mlp::<H, A>::zeroed());
        for t in net.tensors_mut() {
            for v in t {
                *v = uniform(rng, 0.5);
            }
        }
        net
    }

    #[test]
    fn bit_identical_to_the_firmware_forward_pass() {
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        check(&POLICY, &mut rng);
        for _ in 0..5 {
            check(&*random_net::<16, 2>(&mut rng), &mut rng);
            check(&*random_net::<32, 2>(&mut rng), &mut rng);
            check(&*random_net::<64, 2>(&mut rng), &mut rng);
            check(&*random_net::<128, 2>(&mut rng), &mut rng);
            check(&*random_net::<64, 5>(&mut rng), &mut rng);
            check(&*random_net::<16, 9>(&mut rng), &mut rng);
        }
    }

    #[test]
    fn the_order_is_the_firmware_one_not_a_sequential_sum() {
        // One output whose inputs cancel: 1e8 and -1e8 sit in lane 0, the small terms in
        // other lanes, so only the documented order keeps them (as in firmware's own test).
        let mut net = Box::new(Mlp::<16>::zeroed());
        net.fc1_bias = [1.0; 16];
        let w = &mut net.fc2_weight[3];
        w[0] = 1e8;
        w[8] = -1e8;
        w[1] = 1.0;
        w[4] = 0.5;
        w[12] = 0.25;
        net.fc3_weight[1][3] = 1.0;
        for kernel in Kernel::ALL {
            if let Some(wide) = WideMlp::with_kernel(&net, Levels::BANG_BANG, kernel) {
                assert_eq!(wide.forward(&[0.0; 4]), [0.0, 1.75], "{kernel:?}");
                assert_eq!(forward_unpacked(&net, &[0.0; 4], kernel), [0.0, 1.75]);
            }
        }
        assert_eq!(net.forward(&[0.0; 4]), [0.0, 1.75]);
    }
}
