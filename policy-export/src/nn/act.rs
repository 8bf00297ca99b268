//! The acting forward pass: [`Mlp::forward`]'s Q-values, bit for bit, from the trainer's
//! packed transposes.
//!
//! The trainer acts once per environment step with the network that ships, so its Q-values
//! must be the firmware's own. `Mlp::forward` computes one output at a time, which a host
//! compiles to two-wide SSE code: a tenth of a `paper-fixed` run. Here the same operations
//! run across a block of `W` outputs at once: partial sum `k` of every output in the block
//! is one `W`-lane accumulator, input `i` adds `w[i] * x[i]` to accumulator `i % LANES`, and
//! the lanes meet in [`dot_portable`](firmware::network::dot_portable)'s tree before the
//! bias and the ReLU. Multiplies and adds are never fused, whatever the training kernel, so
//! every rendering gives the firmware's bits (tested against `Mlp::forward` on random
//! networks and raw bit patterns).

#[cfg(target_arch = "x86_64")]
use firmware::network::LANES;
use firmware::network::{Mlp, N_ACTIONS, OBS_DIM};

use super::{Kernel, Packed};

/// `[Q(obs, left), Q(obs, right)]` of `net`, whose transposes `packed` holds, as
/// [`Mlp::forward`] computes them. `kernel` picks the register width (AVX-512: 16 outputs a
/// block, AVX2 and the portable kernel where the CPU has AVX2: 8); without AVX2 it is
/// `Mlp::forward` itself.
pub fn act<const H: usize>(
    kernel: Kernel,
    net: &Mlp<H>,
    packed: &Packed<H>,
    obs: &[f32; OBS_DIM],
) -> [f32; N_ACTIONS] {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx512f,avx512vl,avx2")]
        fn avx512<const H: usize>(
            net: &Mlp<H>,
            packed: &Packed<H>,
            obs: &[f32; OBS_DIM],
        ) -> [f32; N_ACTIONS] {
            act_impl::<H, 16>(net, packed, obs)
        }
        #[target_feature(enable = "avx2")]
        fn avx2<const H: usize>(
            net: &Mlp<H>,
            packed: &Packed<H>,
            obs: &[f32; OBS_DIM],
        ) -> [f32; N_ACTIONS] {
            act_impl::<H, 8>(net, packed, obs)
        }
        match kernel {
            // SAFETY: the CPU was just checked for every feature the function enables.
            Kernel::Avx512 if Kernel::Avx512.supported() => {
                return unsafe { avx512(net, packed, obs) };
            }
            // SAFETY: as above (the AVX2 kernel's check covers AVX2).
            Kernel::Avx2 | Kernel::Portable if Kernel::Avx2.supported() => {
                return unsafe { avx2(net, packed, obs) };
            }
            _ => {}
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (kernel, packed);
    net.forward(obs)
}

#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn act_impl<const H: usize, const W: usize>(
    net: &Mlp<H>,
    packed: &Packed<H>,
    obs: &[f32; OBS_DIM],
) -> [f32; N_ACTIONS] {
    let mut h1 = [0.0; H];
    layer::<H, OBS_DIM, W>(&packed.w1t, &net.fc1_bias, obs, &mut h1);
    let mut h2 = [0.0; H];
    layer::<H, H, W>(&packed.w2t, &net.fc2_bias, &h1, &mut h2);
    core::array::from_fn(|a| {
        firmware::network::x86::dot_sse(&net.fc3_weight[a], &h2) + net.fc3_bias[a]
    })
}

/// `y = ReLU(W x + b)` with `wt` = `W` transposed, block by block of `W` outputs, each output
/// summed in `dot`'s lanes and tree.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn layer<const H: usize, const N: usize, const W: usize>(
    wt: &[[f32; H]; N],
    bias: &[f32; H],
    x: &[f32; N],
    y: &mut [f32; H],
) {
    const {
        assert!(
            H.is_multiple_of(W),
            "hidden width must be a multiple of the block"
        )
    };
    let bias = bias.as_chunks::<W>().0;
    for (c, (y, b)) in y.as_chunks_mut::<W>().0.iter_mut().zip(bias).enumerate() {
        // Term `i` into partial sum `k = i % LANES`. Written out lane by lane, with whole
        // arrays as values: loops over `k` were vectorised across the partial sums, into
        // gathers and scatters.
        let term = |a: [f32; W], i: usize| -> [f32; W] {
            let w = &wt[i].as_chunks::<W>().0[c];
            core::array::from_fn(|j| a[j] + w[j] * x[i])
        };
        let mut l = [[-0.0f32; W]; LANES];
        for g in (0..N).step_by(LANES) {
            let [l0, l1, l2, l3, l4, l5, l6, l7] = l;
            let t = |a, k: usize| if g + k < N { term(a, g + k) } else { a };
            l = [
                t(l0, 0),
                t(l1, 1),
                t(l2, 2),
                t(l3, 3),
                t(l4, 4),
                t(l5, 5),
                t(l6, 6),
                t(l7, 7),
            ];
        }
        let [l0, l1, l2, l3, l4, l5, l6, l7] = l;
        let v = add(add(add(l0, l4), add(l2, l6)), add(add(l1, l5), add(l3, l7)));
        *y = core::array::from_fn(|j| {
            let v = v[j] + b[j];
            if v > 0.0 { v } else { 0.0 }
        });
    }
}

#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn add<const W: usize>(a: [f32; W], b: [f32; W]) -> [f32; W] {
    core::array::from_fn(|j| a[j] + b[j])
}
