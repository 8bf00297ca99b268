//! The training arithmetic's operations as one build renders them, in a table chosen once
//! per run ([`Ops::new`]): the learner calls through the table and never names a kernel.
//!
//! Every build runs the same generic code (`kernels`, `backprop`, `optim`), compiled for
//! its instruction set by a `#[target_feature]` function, so the table of each build is
//! its own monomorphised copy of one source. The unsafe calls into those functions are
//! sound because a table is handed out only after the CPU was checked for every feature
//! its build enables.

use firmware::network::{Mlp, OBS_DIM};
use host_common::kernel::Kernel;
use host_common::wide;

use super::backprop::{BatchGrads, RowGrads, Share, rows_impl, share_impl, shares};
#[cfg(target_arch = "x86_64")]
use super::kernels::Avx512;
use super::kernels::{Activations, Generic, ROWS, forward_impl};
use super::optim::adam_elements;
use super::{AdamStep, Loss, Packed, Scratch};

/// One run of parameters with its gradients and moments: `(p, g, m, v)`.
pub type Part<'a> = (&'a mut [f32], &'a [f32], &'a mut [f32], &'a mut [f32]);

/// The row work's signature: the net, actions, targets, the loss and its scale, the rows.
type RowsFn<const H: usize, const A: usize> =
    fn(&Mlp<H, A>, &[u8], &[f32], (Loss, f32), RowGrads<'_, H, A>);

/// One build's operations.
pub struct Ops<const H: usize, const A: usize> {
    kernel: Kernel,
    forward: fn(&Mlp<H, A>, &Packed<H>, &[[f32; OBS_DIM]], Activations<'_, H, A>),
    rows: RowsFn<H, A>,
    share: fn(BatchGrads<'_, H, A>, Share<'_, H, A>),
    adam: fn(&AdamStep, &mut [Part<'_>]),
    act: fn(&Mlp<H, A>, &[f32; OBS_DIM]) -> [f32; A],
}

/// Each operation's generic code, for one build: `$render` the 4-row blocks' rendering,
/// `$enable` the features its `#[target_feature]` functions enable (none for the baseline).
macro_rules! build {
    ($build:ident, $render:ty, $kernel:expr $(, $enable:literal)?) => {
        mod $build {
            use super::*;

            $(#[target_feature(enable = $enable)])?
            fn forward<const H: usize, const A: usize>(
                net: &Mlp<H, A>,
                packed: &Packed<H>,
                x: &[[f32; OBS_DIM]],
                out: Activations<'_, H, A>,
            ) {
                forward_impl::<H, A, $render, ROWS>(net, packed, x, out)
            }

            $(#[target_feature(enable = $enable)])?
            fn rows<const H: usize, const A: usize>(
                net: &Mlp<H, A>,
                actions: &[u8],
                targets: &[f32],
                loss: (Loss, f32),
                r: RowGrads<'_, H, A>,
            ) {
                rows_impl::<H, A, $render, ROWS>(net, actions, targets, loss, r)
            }

            $(#[target_feature(enable = $enable)])?
            fn share<const H: usize, const A: usize>(g: BatchGrads<'_, H, A>, s: Share<'_, H, A>) {
                share_impl::<H, A, $render, ROWS>(g, s)
            }

            $(#[target_feature(enable = $enable)])?
            fn adam(a: &AdamStep, parts: &mut [Part<'_>]) {
                for (p, g, m, v) in parts.iter_mut() {
                    adam_elements(a, p, g, m, v);
                }
            }

            fn act<const H: usize, const A: usize>(net: &Mlp<H, A>, obs: &[f32; OBS_DIM]) -> [f32; A] {
                wide::forward_unpacked(net, obs, $kernel)
            }

            // The allow covers the baseline, whose functions need no `unsafe` to call.
            #[allow(unused_unsafe)]
            pub(super) const fn ops<const H: usize, const A: usize>() -> Ops<H, A> {
                // SAFETY: each function is called only through the table [`Ops::new`] hands
                // out after checking that the CPU has every feature the build enables.
                Ops {
                    kernel: $kernel,
                    forward: |n, p, x, o| unsafe { forward::<H, A>(n, p, x, o) },
                    rows: |n, a, t, l, r| unsafe { rows::<H, A>(n, a, t, l, r) },
                    share: |g, s| unsafe { share::<H, A>(g, s) },
                    adam: |a, p| unsafe { adam(a, p) },
                    act: act::<H, A>,
                }
            }
        }
    };
}

build!(portable, Generic, Kernel::Portable);
#[cfg(target_arch = "x86_64")]
build!(avx2, Generic, Kernel::Avx2, "avx2,fma");
#[cfg(target_arch = "x86_64")]
build!(avx512, Avx512, Kernel::Avx512, "avx512f,avx512vl,avx2,fma");

impl<const H: usize, const A: usize> Ops<H, A> {
    const PORTABLE: Ops<H, A> = portable::ops();
    #[cfg(target_arch = "x86_64")]
    const AVX2: Ops<H, A> = avx2::ops();
    #[cfg(target_arch = "x86_64")]
    const AVX512: Ops<H, A> = avx512::ops();

    /// `kernel`'s table; a kernel this CPU lacks gets the baseline's (the command line
    /// refuses such a choice up front). Every table computes the same bits.
    pub fn new(kernel: Kernel) -> &'static Ops<H, A> {
        match kernel {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 if kernel.supported() => &Self::AVX512,
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 if kernel.supported() => &Self::AVX2,
            _ => &Self::PORTABLE,
        }
    }

    /// The kernel this table renders.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// The forward pass of `x` (one row per sample) through `net` (`packed` its current
    /// transposes), its activations kept for the backward pass. Rows are independent: any
    /// split of them gives the same bits.
    pub fn forward(
        &self,
        net: &Mlp<H, A>,
        packed: &Packed<H>,
        x: &[[f32; OBS_DIM]],
        out: Activations<'_, H, A>,
    ) {
        (self.forward)(net, packed, x, out)
    }

    /// The backward pass's row work ([`RowGrads`]): row `b` regresses `Q(x_b, actions[b])`
    /// towards `targets[b]`, its gradient scaled by `loss.1`. Rows are independent.
    pub fn rows(
        &self,
        net: &Mlp<H, A>,
        actions: &[u8],
        targets: &[f32],
        loss: (Loss, f32),
        r: RowGrads<'_, H, A>,
    ) {
        (self.rows)(net, actions, targets, loss, r)
    }

    /// One [`Share`] of the weight gradients, each a sum over every row of `g` in order.
    pub fn share(&self, g: BatchGrads<'_, H, A>, share: Share<'_, H, A>) {
        (self.share)(g, share)
    }

    /// One Adam step on runs of parameters, gradients and moments: elementwise, so any
    /// split of a network's parameters gives the same bits.
    pub fn adam(&self, a: &AdamStep, parts: &mut [Part<'_>]) {
        (self.adam)(a, parts)
    }

    /// The firmware's forward pass of one observation, bit for bit (`host_common::wide`):
    /// what acting uses.
    pub fn q_values(&self, net: &Mlp<H, A>, obs: &[f32; OBS_DIM]) -> [f32; A] {
        (self.act)(net, obs)
    }

    /// [`Ops::forward`] of a whole batch into `s`; Q-values land in `s.q[..x.len()]`.
    pub fn forward_batch(
        &self,
        net: &Mlp<H, A>,
        packed: &Packed<H>,
        x: &[[f32; OBS_DIM]],
        s: &mut Scratch<H, A>,
    ) {
        let out = Activations {
            a1: &mut s.a1,
            a2: &mut s.a2,
            q: &mut s.q,
        };
        self.forward(net, packed, x, out);
    }

    /// The gradient of `loss.1` times the summed loss over the rows of the last
    /// [`Ops::forward_batch`] of `net` on `x` into `grad` (overwritten), both shares on this
    /// thread; returns the summed loss, in f64, row after row.
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &self,
        net: &Mlp<H, A>,
        x: &[[f32; OBS_DIM]],
        actions: &[u8],
        targets: &[f32],
        loss: (Loss, f32),
        s: &mut Scratch<H, A>,
        grad: &mut Mlp<H, A>,
    ) -> f64 {
        let n = x.len();
        let rows = RowGrads {
            a1: &s.a1[..n],
            a2: &s.a2[..n],
            q: &s.q[..n],
            dq: &mut s.dq[..n],
            d2: &mut s.d2[..n],
            d1: &mut s.d1[..n],
            loss: &mut s.loss[..n],
        };
        self.rows(net, actions, targets, loss, rows);
        let g = BatchGrads {
            x,
            a1: &s.a1[..n],
            a2: &s.a2[..n],
            dq: &s.dq[..n],
            d2: &s.d2[..n],
            d1: &s.d1[..n],
        };
        for share in shares(grad) {
            self.share(g, share);
        }
        s.loss[..n].iter().fold(0.0, |t, &l| t + f64::from(l))
    }
}
