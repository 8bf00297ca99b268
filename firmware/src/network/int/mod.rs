//! The Q-network in integers only, for cores without an FPU (Cortex-M0/M0+, most RISC-V
//! microcontrollers), where every f32 operation is a library call of dozens of instructions.
//!
//! [`QMlp::forward`] executes no floating-point operation: int8 weights, int32 accumulation,
//! and between layers a requantisation by an integer multiplier and shifts ([`Requant`]).
//! It follows the scheme of TFLite's int8 kernels (symmetric weights, int32 biases in the
//! accumulator's scale), with two choices of its own, made for FPU-less cores:
//!
//! - **Hidden activations are `u8` with zero point 0.** They follow a ReLU, so they are never
//!   negative; unsigned bytes give them all 8 bits (int8 with zero point 0 would waste one,
//!   and an offset zero point would cost a correction term per output).
//! - **The multiplier is 16 bits, not Q31.** A Q31 multiply needs the 64-bit product, which a
//!   Cortex-M0 (32 x 32 -> 32 `muls` only) computes in a library call. Here the accumulator is
//!   first shifted down to 15 bits (`pre_shift`, chosen so that the largest accumulator that
//!   does not saturate the output still fits), then multiplied by a 16-bit multiplier in 32
//!   bits, then rounded and shifted (`post_shift`). An activation has 8 bits, so 15 bits of
//!   accumulator and 16 of multiplier lose nothing that it could show.
//!
//! # The observation's format
//!
//! The input is `[x, x_dot, theta, theta_dot]` in the fixed-point format of
//! [`crate::fixed`] (Q3.12: 1/4096 of a unit, range +-8 units).
//! [`crate::fixed::from_state`] converts a float reading, the encoder observer's included
//! ([`crate::estimator::Observer::fixed_state`]); [`crate::estimator::AlphaBeta::fixed_state`]
//! produces it from encoder counts in integers alone.
//!
//! # The output
//!
//! `q` is the output layer's two `i32` accumulators, in one scale, so the controller pushes
//! right iff `q[1] > q[0]`, as with the float network. A network exported by
//! `policy-export export --quant int8` outputs the advantages `Q - mean(Q)` (so
//! `q[0] == -q[1]`) rather than the Q-values: their common part decides nothing and would
//! take the int8 weights' precision from the difference that does (`weights::quant` has the
//! measurement). The scale, Q-value per unit, is in the exported module's documentation.
//!
//! The arithmetic wraps instead of panicking, so any weights and any input give a defined
//! result; weights written by `policy-export export --quant int8` never wrap (their bounds
//! are checked when they are made).
//!
//! ```
//! use firmware::network::int::QMlp;
//! let net = QMlp::<64>::zeroed();
//! assert_eq!(net.forward(&[0; 4]), [0, 0]);
//! ```

use super::{N_ACTIONS, OBS_DIM, argmax};

#[cfg(cartpole_dsp)]
pub mod dsp;
#[cfg(all(target_arch = "arm", not(cartpole_dsp)))]
pub mod thumb;

/// The bytes of flash a 4-H-H-A [`QMlp`] occupies, as `size_of` gives it:
/// int8 weights, int32 biases and one [`Requant`] per hidden unit.
pub const fn flash_bytes(h: usize, a: usize) -> usize {
    (OBS_DIM * h + h * h + a * h) + 4 * (2 * h + a) + 4 * 2 * h
}

/// How one hidden unit's int32 accumulator becomes its `u8` activation (ReLU included):
///
/// ```text
/// t = min(max(acc, 0) >> pre_shift, 32767)
/// y = min((t * multiplier + 2^(post_shift - 1)) >> post_shift, 255)   (no rounding term if post_shift = 0)
/// ```
///
/// computed in `u32`, where it cannot overflow (`t < 2^15`, `multiplier < 2^16`). Shifts are
/// taken modulo 32. The real factor it applies is `multiplier / 2^(pre_shift + post_shift)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(C)]
pub struct Requant {
    /// The 16-bit integer multiplier.
    pub multiplier: u16,
    /// Right shift of the accumulator before the multiply.
    pub pre_shift: u8,
    /// Rounding right shift after it.
    pub post_shift: u8,
}

impl Requant {
    /// A requantisation (for generated code: `Requant::new(40_000, 3, 21)`).
    pub const fn new(multiplier: u16, pre_shift: u8, post_shift: u8) -> Requant {
        Requant {
            multiplier,
            pre_shift,
            post_shift,
        }
    }

    /// The activation of a unit whose accumulator is `acc`.
    #[inline(always)]
    pub fn apply(self, acc: i32) -> u8 {
        if acc <= 0 {
            return 0;
        }
        let t = (acc as u32 >> (self.pre_shift & 31)).min(0x7fff);
        let post = self.post_shift & 31;
        let y = (t * u32::from(self.multiplier) + ((1u32 << post) >> 1)) >> post;
        y.min(255) as u8
    }
}

/// A 4-H-H-A Q-network with integer weights, the integer counterpart of
/// [`Mlp`](super::Mlp): `weight[o][i]` connects input `i` to output `o`, as in PyTorch. The
/// layout is C's (`repr(C)`), field for field the C API's `struct cartpole_qmlpH`; the
/// 32-bit fields come first so that it has no padding.
#[derive(Clone, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct QMlp<const H: usize, const A: usize = N_ACTIONS> {
    /// First layer biases, in the scale of its accumulator (weight scale / 4096).
    pub fc1_bias: [i32; H],
    /// Second layer biases, in the scale of its accumulator.
    pub fc2_bias: [i32; H],
    /// Output biases, in the scale of the output.
    pub fc3_bias: [i32; A],
    /// First layer requantisation, per unit.
    pub fc1_requant: [Requant; H],
    /// Second layer requantisation, per unit.
    pub fc2_requant: [Requant; H],
    /// First layer weights, `[H][4]`.
    pub fc1_weight: [[i8; OBS_DIM]; H],
    /// Second layer weights, `[H][H]`.
    pub fc2_weight: [[i8; H]; H],
    /// Output weights, `[A][H]`, one scale for every row.
    pub fc3_weight: [[i8; H]; A],
}

impl<const H: usize, const A: usize> QMlp<H, A> {
    /// Everything zero; usable in `const` and `static` items.
    pub const fn zeroed() -> Self {
        QMlp {
            fc1_bias: [0; H],
            fc2_bias: [0; H],
            fc3_bias: [0; A],
            fc1_requant: [Requant::new(0, 0, 0); H],
            fc2_requant: [Requant::new(0, 0, 0); H],
            fc1_weight: [[0; OBS_DIM]; H],
            fc2_weight: [[0; H]; H],
            fc3_weight: [[0; H]; A],
        }
    }

    /// The outputs `q` in the output's integer scale for a fixed-point observation (see [the
    /// module](self)); the greedy output is their [`argmax`]. By the target's fastest kernels: the DSP extension's on ARMv7E-M cores
    /// (Cortex-M4, M7: `dsp`), hand-written ARMv6-M code on other Arm cores (`thumb`),
    /// [`QMlp::forward_portable`] elsewhere. All give the same bits.
    ///
    /// Only `q` leaves: returning the hidden activations too would put them in every
    /// caller's frame, beside this pass's own.
    #[inline]
    pub fn forward(&self, obs: &[i16; OBS_DIM]) -> [i32; A] {
        #[cfg(cartpole_dsp)]
        if H > 0 && H.is_multiple_of(8) {
            let h1 = dsp::input(&self.fc1_weight, &self.fc1_bias, &self.fc1_requant, obs);
            let h2 = dsp::hidden(&self.fc2_weight, &self.fc2_bias, &self.fc2_requant, &h1);
            return dsp::output(&self.fc3_weight, &self.fc3_bias, &h2);
        }
        #[cfg(all(target_arch = "arm", not(cartpole_dsp)))]
        if H > 0 && H.is_multiple_of(8) {
            let h1 = input(&self.fc1_weight, &self.fc1_bias, &self.fc1_requant, obs);
            let mut h2 = [0u8; H];
            let units = h2
                .chunks_exact_mut(2)
                .zip(self.fc2_weight.as_chunks::<2>().0);
            let params = self
                .fc2_bias
                .chunks_exact(2)
                .zip(self.fc2_requant.chunks_exact(2));
            for ((y, [wa, wb]), (b, r)) in units.zip(params) {
                for (((y, acc), b), r) in y.iter_mut().zip(thumb::dot2(wa, wb, &h1)).zip(b).zip(r) {
                    *y = r.apply(acc.wrapping_add(*b));
                }
            }
            let mut q = self.fc3_bias;
            let (pairs, odd) = self.fc3_weight.as_chunks::<2>();
            for (q, [wa, wb]) in q.chunks_exact_mut(2).zip(pairs) {
                for (q, acc) in q.iter_mut().zip(thumb::dot2(wa, wb, &h2)) {
                    *q = q.wrapping_add(acc);
                }
            }
            // An odd last row alone: paired with itself, it would be summed twice.
            if let ([w], Some(q)) = (odd, q.last_mut()) {
                *q = q.wrapping_add(thumb::dot1(w, &h2));
            }
            return q;
        }
        self.forward_portable(obs)
    }

    /// [`QMlp::forward`] in plain Rust: the definition of the integer forward pass, which the
    /// kernels are tested against (on the device, by the self-test).
    #[inline]
    pub fn forward_portable(&self, obs: &[i16; OBS_DIM]) -> [i32; A] {
        let h1 = input(&self.fc1_weight, &self.fc1_bias, &self.fc1_requant, obs);
        let mut h2 = [0u8; H];
        for (((y, w), b), r) in h2
            .iter_mut()
            .zip(&self.fc2_weight)
            .zip(&self.fc2_bias)
            .zip(&self.fc2_requant)
        {
            *y = r.apply(dot_u8(w, &h1).wrapping_add(*b));
        }
        let mut q = [0i32; A];
        for ((q, w), b) in q.iter_mut().zip(&self.fc3_weight).zip(&self.fc3_bias) {
            *q = dot_u8(w, &h2).wrapping_add(*b);
        }
        q
    }

    /// The output with the largest value; a tie picks the lower index, as the float
    /// network's [`argmax`].
    #[inline]
    pub fn greedy(&self, obs: &[i16; OBS_DIM]) -> usize {
        argmax(&self.forward(obs))
    }
}

/// The first hidden layer in plain Rust: `requant(w . obs + b)` per unit.
#[inline(always)]
fn input<const H: usize>(
    w: &[[i8; OBS_DIM]; H],
    b: &[i32; H],
    r: &[Requant; H],
    obs: &[i16; OBS_DIM],
) -> [u8; H] {
    // Built in place: a zeroed array filled afterwards costs the M0 a memset and a copy.
    core::array::from_fn(|k| {
        let mut acc = 0i32;
        for (w, x) in w[k].iter().zip(obs) {
            acc += i32::from(*w) * i32::from(*x);
        }
        r[k].apply(acc.wrapping_add(b[k]))
    })
}

/// `sum w[i] * x[i]` of int8 weights and u8 activations. It cannot overflow for `N` up to
/// 65,000 (each product is at most 32,640 in magnitude), and integer addition is associative, so
/// any order (and any vector rendering) gives these bits.
#[inline(always)]
fn dot_u8<const N: usize>(w: &[i8; N], x: &[u8; N]) -> i32 {
    let mut acc = 0i32;
    for (w, x) in w.iter().zip(x) {
        acc += i32::from(*w) * i32::from(*x);
    }
    acc
}

#[cfg(test)]
mod tests;
