//! Batched training math for the 4-H-H-2 network: forward with activations kept, backward,
//! global-norm clipping and Adam, written by hand for this one network shape.
//!
//! - `kernels`: the batched forward pass and the building block every matrix product uses.
//! - `backprop`: gradients of the TD loss: each row's own work, then the weight gradients'
//!   sums over every row in two shares of the parameters.
//! - `optim`: Adam, gradient clipping, soft target updates.
//! - `ops`: each build's operations in a table ([`Ops`]), chosen once per run.
//! - `reference` (tests): the definition in plain loops.
//!
//! The parameters live in the firmware's own [`Mlp`] type, so the policy the trainer acts
//! with is the policy that ships; acting goes through `host_common::wide`, the firmware's
//! forward pass bit for bit. The learning side's forward pass is laid out for batches
//! (`y += x_i * W^T[i]`, vectorised across outputs) instead of the firmware's per-output dot
//! products, so its outputs agree with `Mlp::forward` to rounding (tested to 1e-6 relative),
//! not bit for bit.
//!
//! # One arithmetic, several renderings
//!
//! Every multiply-add of the learning side is fused (`f32::mul_add`, rounded once), in the
//! order the kernels' sources give. That is the definition every run is trained with, and
//! fused multiply-adds are what fast hardware does: the same generic kernels are compiled
//! for AVX-512F + AVX-512VL + FMA (whose 4-row blocks run in intrinsics), for AVX2 + FMA,
//! and for the target's baseline, which on aarch64 is NEON's `fmla` and elsewhere a software
//! `fmaf`, picked at run time ([`Kernel::detect`]) and handed out as a table of operations
//! ([`Ops::new`]). All of them give the same bits (tested against a plain-loop rendering of
//! the definition), so a run's weights do not depend on the machine it ran on. Every sum
//! over a batch's rows runs over all of them in order, so how the work is shared between
//! cores is no part of the definition either.

use firmware::network::{Mlp, OBS_DIM};
pub use host_common::kernel::Kernel;

mod backprop;
mod kernels;
mod optim;

mod ops;

pub use backprop::{BatchGrads, RowGrads, SecondShare, Share, shares};
pub use kernels::Activations;
pub use ops::{Ops, Part};
pub use optim::{AdamParams, AdamStep, clip_grad_norm, soft_update};

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

/// A whole batch's activations and gradients, allocated once: what [`Ops::forward_batch`]
/// and [`Ops::backward`] work in.
pub struct Scratch<const H: usize, const A: usize> {
    a1: Vec<[f32; H]>,
    a2: Vec<[f32; H]>,
    d1: Vec<[f32; H]>,
    d2: Vec<[f32; H]>,
    dq: Vec<[f32; A]>,
    loss: Vec<f32>,
    /// Q-values of the last [`Ops::forward_batch`].
    pub q: Vec<[f32; A]>,
}

/// A network's first two weight matrices transposed (`[in][out]`), so that the batched
/// forward pass reads contiguous rows. Re-pack whenever the weights change.
pub struct Packed<const H: usize> {
    w1t: [[f32; H]; OBS_DIM],
    w2t: [[f32; H]; H],
}

impl<const H: usize> Packed<H> {
    /// The transposes of `net`'s weights, on the heap.
    pub fn new<const A: usize>(net: &Mlp<H, A>) -> Box<Self> {
        let mut p = Box::new(Packed {
            w1t: [[0.0; H]; OBS_DIM],
            w2t: [[0.0; H]; H],
        });
        p.pack(net);
        p
    }

    /// `self <- tau * online + (1 - tau) * self`, elementwise: the packing of
    /// [`soft_update`]'s result, bit for bit, without transposing.
    pub fn soft_update(&mut self, online: &Packed<H>, tau: f32) {
        for (t, o) in [
            (self.w1t.as_flattened_mut(), online.w1t.as_flattened()),
            (self.w2t.as_flattened_mut(), online.w2t.as_flattened()),
        ] {
            for (t, o) in t.iter_mut().zip(o) {
                *t = optim::interpolate(tau, *o, *t);
            }
        }
    }

    /// Both transposes, flattened, for tests.
    #[cfg(test)]
    pub(crate) fn transposes(&self) -> Vec<f32> {
        let mut v = self.w1t.as_flattened().to_vec();
        v.extend_from_slice(self.w2t.as_flattened());
        v
    }

    /// Refreshes the transposes from `net`. Called after every gradient step, so the
    /// square matrix moves in 4 x 4 tiles: element by element, the stores run down columns
    /// `4 H` bytes apart, which at width 128 land in a few L1 sets and took a seventh of
    /// the step.
    pub fn pack<const A: usize>(&mut self, net: &Mlp<H, A>) {
        for (o, w1) in net.fc1_weight.iter().enumerate() {
            for (i, w) in w1.iter().enumerate() {
                self.w1t[i][o] = *w;
            }
        }
        for (ob, rows) in net.fc2_weight.as_chunks::<4>().0.iter().enumerate() {
            for ib in 0..H / 4 {
                let tile = transpose4(rows.each_ref().map(|r| r.as_chunks::<4>().0[ib]));
                for (i, col) in tile.into_iter().enumerate() {
                    self.w2t[ib * 4 + i].as_chunks_mut::<4>().0[ob] = col;
                }
            }
        }
    }
}

/// The transpose of a 4 x 4 tile, in SSE registers: four loads, eight shuffles, four stores.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn transpose4(r: [[f32; 4]; 4]) -> [[f32; 4]; 4] {
    use core::arch::x86_64::*;
    // SAFETY: SSE is part of the x86-64 baseline; every pointer is to four floats.
    unsafe {
        let [r0, r1, r2, r3] = r.map(|r| _mm_loadu_ps(r.as_ptr()));
        let (t0, t1) = (_mm_unpacklo_ps(r0, r1), _mm_unpacklo_ps(r2, r3));
        let (t2, t3) = (_mm_unpackhi_ps(r0, r1), _mm_unpackhi_ps(r2, r3));
        let cols = [
            _mm_movelh_ps(t0, t1),
            _mm_movehl_ps(t1, t0),
            _mm_movelh_ps(t2, t3),
            _mm_movehl_ps(t3, t2),
        ];
        cols.map(|c| {
            let mut out = [0.0; 4];
            _mm_storeu_ps(out.as_mut_ptr(), c);
            out
        })
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn transpose4(r: [[f32; 4]; 4]) -> [[f32; 4]; 4] {
    core::array::from_fn(|i| r.map(|row| row[i]))
}

impl<const H: usize, const A: usize> Scratch<H, A> {
    /// Room for batches of up to `batch` samples.
    pub fn new(batch: usize) -> Self {
        Scratch {
            a1: vec![[0.0; H]; batch],
            a2: vec![[0.0; H]; batch],
            d1: vec![[0.0; H]; batch],
            d2: vec![[0.0; H]; batch],
            dq: vec![[0.0; A]; batch],
            loss: vec![0.0; batch],
            q: vec![[0.0; A]; batch],
        }
    }
}

/// A zeroed network on the heap (`Mlp<128>` is 70 KB: too big to move around on stacks).
pub fn boxed_zero<const H: usize, const A: usize>() -> Box<Mlp<H, A>> {
    Box::new(Mlp::zeroed())
}

#[cfg(test)]
pub(crate) mod reference;
#[cfg(test)]
mod tests;
