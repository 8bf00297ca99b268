//! The Q-network: 4 inputs, two hidden ReLU layers of width `H`, 2 linear outputs.
//!
//! This is the one definition of the inference forward pass. The trainer acts with it, the
//! simulator balances with it and the microcontroller runs it, so a policy behaves the same
//! everywhere, bit for bit.
//!
//! Weights are plain fixed-size arrays in PyTorch's `nn.Linear` layout (`weight[out][in]`),
//! so a policy is a `static` in flash and [`Mlp::forward`] needs about `2 * H` floats of stack
//! and nothing else: no heap, no panics.
//!
//! # Summation order
//!
//! Floating-point addition is not associative, so "the" forward pass needs a defined order.
//! Every dot product of length `n` is computed by [`dot`] in [`LANES`] partial sums: lane `k`
//! (starting at `-0.0`, the identity of addition, so its first sum is its first product)
//! adds `w[i] * x[i]` for `i = k, k + LANES, k + 2 * LANES, ...` in increasing `i`; the lanes are then added as a tree, `(l0 + l4) + (l2 + l6)` and
//! `(l1 + l5) + (l3 + l7)`, and those two summed; the bias is added last. Independent partial
//! sums break the chain of `n` dependent additions that a single accumulator would form: a
//! host CPU runs the lanes in one SIMD register and a Cortex-M4 overlaps them in its FPU
//! pipeline, while both compute exactly the same IEEE-754 operations (multiplies and adds are
//! never fused), hence the same bits.
//!
//! ```
//! use firmware::network::{Mlp, dot};
//! let w = [1.0, 2.0, 3.0, 4.0];
//! let x = [0.5, 0.25, -1.0, 2.0];
//! assert_eq!(dot(&w, &x), 6.0);
//! assert_eq!(Mlp::<64>::PARAMS, 4_610);
//! ```

use crate::cartpole::Action;

/// Inputs: the plant's observation `[x, x_dot, theta, theta_dot]`.
pub const OBS_DIM: usize = 4;
/// Outputs: one Q-value per action (left, right).
pub const N_ACTIONS: usize = 2;
/// Partial sums per dot product (see the module docs).
pub const LANES: usize = 8;
/// Hidden width of the paper's network and of the shipped policy.
pub const PAPER_WIDTH: usize = 64;

/// The paper's network: 4-64-64-2.
pub type PolicyNet = Mlp<PAPER_WIDTH>;

/// A 4-H-H-2 multilayer perceptron with ReLU hidden layers. Field names follow the PyTorch
/// module `fc1`, `fc2`, `fc3` (as in its safetensors export); `weight[o][i]` connects input
/// `i` to output `o`.
#[derive(Clone, Debug, PartialEq)]
pub struct Mlp<const H: usize> {
    /// First layer weights, `[H][4]`.
    pub fc1_weight: [[f32; OBS_DIM]; H],
    /// First layer biases, `[H]`.
    pub fc1_bias: [f32; H],
    /// Second layer weights, `[H][H]`.
    pub fc2_weight: [[f32; H]; H],
    /// Second layer biases, `[H]`.
    pub fc2_bias: [f32; H],
    /// Output layer weights, `[2][H]`.
    pub fc3_weight: [[f32; H]; N_ACTIONS],
    /// Output layer biases, `[2]`.
    pub fc3_bias: [f32; N_ACTIONS],
}

/// The six tensors' PyTorch names, in the order [`Mlp::tensors`] returns them.
pub const TENSOR_NAMES: [&str; 6] = [
    "fc1.weight",
    "fc1.bias",
    "fc2.weight",
    "fc2.bias",
    "fc3.weight",
    "fc3.bias",
];

impl<const H: usize> Mlp<H> {
    /// Number of parameters: `4H + H + H*H + H + 2H + 2` (4,610 for `H = 64`).
    pub const PARAMS: usize = OBS_DIM * H + H + H * H + H + N_ACTIONS * H + N_ACTIONS;

    /// Shapes of the six tensors, in [`TENSOR_NAMES`] order, as PyTorch prints them.
    pub const SHAPES: [&'static [usize]; 6] = [
        &[H, OBS_DIM],
        &[H],
        &[H, H],
        &[H],
        &[N_ACTIONS, H],
        &[N_ACTIONS],
    ];

    /// All parameters zero; usable in `const` and `static` items.
    pub const fn zeroed() -> Self {
        Mlp {
            fc1_weight: [[0.0; OBS_DIM]; H],
            fc1_bias: [0.0; H],
            fc2_weight: [[0.0; H]; H],
            fc2_bias: [0.0; H],
            fc3_weight: [[0.0; H]; N_ACTIONS],
            fc3_bias: [0.0; N_ACTIONS],
        }
    }

    /// The six tensors as flat row-major slices, in [`TENSOR_NAMES`] order.
    pub fn tensors(&self) -> [&[f32]; 6] {
        [
            self.fc1_weight.as_flattened(),
            &self.fc1_bias,
            self.fc2_weight.as_flattened(),
            &self.fc2_bias,
            self.fc3_weight.as_flattened(),
            &self.fc3_bias,
        ]
    }

    /// The six tensors as mutable flat row-major slices, in [`TENSOR_NAMES`] order.
    pub fn tensors_mut(&mut self) -> [&mut [f32]; 6] {
        [
            self.fc1_weight.as_flattened_mut(),
            &mut self.fc1_bias,
            self.fc2_weight.as_flattened_mut(),
            &mut self.fc2_bias,
            self.fc3_weight.as_flattened_mut(),
            &mut self.fc3_bias,
        ]
    }

    /// Q-values `[Q(obs, left), Q(obs, right)]`, in the summation order of the module docs.
    #[inline]
    pub fn forward(&self, obs: &[f32; OBS_DIM]) -> [f32; N_ACTIONS] {
        // Filled in place: returning the layers by value costs a copy of each whenever the
        // dot product is an out-of-line call (the Cortex-M4F's).
        let mut h1 = [0.0; H];
        linear(&mut h1, &self.fc1_weight, &self.fc1_bias, obs, true);
        let mut h2 = [0.0; H];
        linear(&mut h2, &self.fc2_weight, &self.fc2_bias, &h1, true);
        let mut q = [0.0; N_ACTIONS];
        linear(&mut q, &self.fc3_weight, &self.fc3_bias, &h2, false);
        q
    }

    /// The action with the larger Q-value. A tie (or a NaN) picks `Left`, the lower index,
    /// as `argmax` does in NumPy and PyTorch.
    #[inline]
    pub fn greedy_action(&self, obs: &[f32; OBS_DIM]) -> Action {
        argmax(&self.forward(obs))
    }
}

/// `Right` only if its Q-value is strictly larger; ties and NaNs give `Left`.
#[inline]
pub fn argmax(q: &[f32; N_ACTIONS]) -> Action {
    if q[1] > q[0] {
        Action::Right
    } else {
        Action::Left
    }
}

/// `y[o] = dot(w[o], x) + b[o]`, then ReLU if asked (`max(v, 0)`, NaN and `-0.0` to `+0.0`).
#[inline(always)]
fn linear<const I: usize, const O: usize>(
    y: &mut [f32; O],
    w: &[[f32; I]; O],
    b: &[f32; O],
    x: &[f32; I],
    relu: bool,
) {
    for ((y, w), b) in y.iter_mut().zip(w).zip(b) {
        let v = dot(w, x) + b;
        *y = if !relu || v > 0.0 { v } else { 0.0 };
    }
}

/// The dot product in the crate's defined order: [`LANES`] interleaved partial sums, then a
/// fixed tree (see the module docs). Every forward pass in the project goes through here.
///
/// On a hard-float Arm core, lengths that are a multiple of [`LANES`] run `vfp::dot`, which
/// computes the same operations in the same order with block loads; elsewhere, and for other
/// lengths, [`dot_portable`].
#[inline(always)]
pub fn dot<const N: usize>(w: &[f32; N], x: &[f32; N]) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    if N.is_multiple_of(LANES) {
        return vfp::dot(w.as_chunks().0, x.as_chunks().0);
    }
    dot_portable(w, x)
}

/// [`dot`] in plain Rust: the definition of the order, and the path every host takes.
///
/// Lanes start at `-0.0`, the exact identity of IEEE-754 addition (`-0.0 + v == v` for every
/// `v`, signed zeros and NaNs included), so a lane's first step is just its first product.
#[inline(always)]
pub fn dot_portable<const N: usize>(w: &[f32; N], x: &[f32; N]) -> f32 {
    let mut acc = [-0.0f32; LANES];
    let (wc, wr) = w.as_chunks::<LANES>();
    let (xc, xr) = x.as_chunks::<LANES>();
    for (wc, xc) in wc.iter().zip(xc) {
        for ((a, w), x) in acc.iter_mut().zip(wc).zip(xc) {
            *a += w * x;
        }
    }
    for ((a, w), x) in acc.iter_mut().zip(wr).zip(xr) {
        *a += w * x;
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = acc;
    ((a0 + a4) + (a2 + a6)) + ((a1 + a5) + (a3 + a7))
}

/// [`dot`] for the Cortex-M4F/M7 FPU, in hand-written VFP code.
///
/// Compiled from Rust, each of the 4,480 multiply-accumulates of a forward pass comes with two
/// single-float `vldr` loads, because LLVM does not merge them into block loads; here each
/// group of eight weights and eight inputs is one `vldmia` each, which more than halves the
/// instructions executed. The arithmetic is [`dot_portable`]'s, operation for operation:
/// `vmul.f32` starts the lanes (`-0.0 + p == p`), `vmla.f32` multiplies, rounds, then adds
/// (it is not fused), and the lanes are summed in the documented tree, so the Q-values are
/// bit-identical to the host's. The self-test checks that on the device.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[allow(unsafe_code)]
pub mod vfp {
    use super::LANES;

    /// `dot` over `min(w.len(), x.len())` chunks of eight; `-0.0` (the empty sum) for none.
    #[inline]
    pub fn dot(w: &[[f32; LANES]], x: &[[f32; LANES]]) -> f32 {
        let chunks = w.len().min(x.len());
        if chunks == 0 {
            return -0.0;
        }
        // SAFETY: `cartpole_ddqn_vfp_dot` reads `chunks * 8` floats from each pointer, which
        // both slices hold, writes no memory and follows the AAPCS-VFP calling convention.
        unsafe { cartpole_ddqn_vfp_dot(w.as_ptr().cast(), x.as_ptr().cast(), chunks) }
    }

    unsafe extern "C" {
        fn cartpole_ddqn_vfp_dot(w: *const f32, x: *const f32, chunks: usize) -> f32;
    }

    // A function of its own rather than inline `asm!`: Rust cannot name the M4F's
    // single-precision registers in `asm!` operands on stable, while the AAPCS-VFP leaves
    // s0-s15 to the callee, so only s16-s23 need saving. r0 = w, r1 = x, r2 = chunks >= 1;
    // the sum returns in s0.
    core::arch::global_asm!(
        ".syntax unified",
        ".thumb",
        ".fpu fpv4-sp-d16",
        ".section .text.cartpole_ddqn_vfp_dot,\"ax\",%progbits",
        ".global cartpole_ddqn_vfp_dot",
        ".type cartpole_ddqn_vfp_dot,%function",
        ".thumb_func",
        // One chunk of eight: a block load of weights and of inputs, then `op` (vmul.f32 to
        // start the lanes, vmla.f32 after) into the partial sums s0-s7.
        ".macro cartpole_ddqn_vfp_chunk op",
        "vldmia r0!, {{s8-s15}}",
        "vldmia r1!, {{s16-s23}}",
        "\\op s0, s8, s16",
        "\\op s1, s9, s17",
        "\\op s2, s10, s18",
        "\\op s3, s11, s19",
        "\\op s4, s12, s20",
        "\\op s5, s13, s21",
        "\\op s6, s14, s22",
        "\\op s7, s15, s23",
        ".endm",
        "cartpole_ddqn_vfp_dot:",
        "vpush {{s16-s23}}",
        "cartpole_ddqn_vfp_chunk vmul.f32",
        "subs r2, r2, #1",
        "beq 3f",
        // The shipped width, 64, has 7 more chunks: straight-line code saves the loop's
        // counter and branch, about 1,000 instructions per forward pass.
        "cmp r2, #7",
        "bne 2f",
        ".rept 7",
        "cartpole_ddqn_vfp_chunk vmla.f32",
        ".endr",
        "b 3f",
        "2:",
        "cartpole_ddqn_vfp_chunk vmla.f32",
        "subs r2, r2, #1",
        "bne 2b",
        "3:",
        "vadd.f32 s0, s0, s4",
        "vadd.f32 s2, s2, s6",
        "vadd.f32 s1, s1, s5",
        "vadd.f32 s3, s3, s7",
        "vadd.f32 s0, s0, s2",
        "vadd.f32 s1, s1, s3",
        "vadd.f32 s0, s0, s1",
        "vpop {{s16-s23}}",
        "bx lr",
        ".size cartpole_ddqn_vfp_dot, . - cartpole_ddqn_vfp_dot",
        ".purgem cartpole_ddqn_vfp_chunk",
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::Rng;
    use rand_pcg::Pcg64Mcg;

    fn uniform(rng: &mut Pcg64Mcg, scale: f32) -> f32 {
        ((rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0) * scale
    }

    fn random_net<const H: usize>(rng: &mut Pcg64Mcg) -> Mlp<H> {
        let mut net = Mlp::<H>::zeroed();
        for t in net.tensors_mut() {
            for v in t {
                *v = uniform(rng, 0.5);
            }
        }
        net
    }

    /// The textbook forward pass in f64, one accumulator, written independently of `dot`
    /// (indexed loops on purpose: it should read like the equations, not like the code).
    #[allow(clippy::needless_range_loop)]
    fn reference<const H: usize>(net: &Mlp<H>, obs: &[f32; 4]) -> [f64; 2] {
        let x: [f64; 4] = obs.map(f64::from);
        let mut h1 = [0.0f64; H];
        for o in 0..H {
            let mut s = f64::from(net.fc1_bias[o]);
            for i in 0..4 {
                s += f64::from(net.fc1_weight[o][i]) * x[i];
            }
            h1[o] = s.max(0.0);
        }
        let mut h2 = [0.0f64; H];
        for o in 0..H {
            let mut s = f64::from(net.fc2_bias[o]);
            for i in 0..H {
                s += f64::from(net.fc2_weight[o][i]) * h1[i];
            }
            h2[o] = s.max(0.0);
        }
        let mut q = [0.0f64; 2];
        for o in 0..2 {
            let mut s = f64::from(net.fc3_bias[o]);
            for i in 0..H {
                s += f64::from(net.fc3_weight[o][i]) * h2[i];
            }
            q[o] = s;
        }
        q
    }

    fn check_against_reference<const H: usize>() {
        let mut rng = Pcg64Mcg::new(0xC0FFEE + H as u128);
        for _ in 0..20 {
            let net = random_net::<H>(&mut rng);
            for _ in 0..50 {
                let obs = [2.4, 3.0, 0.21, 3.0].map(|s| uniform(&mut rng, s));
                let got = net.forward(&obs);
                let want = reference(&net, &obs);
                for a in 0..2 {
                    let err = (f64::from(got[a]) - want[a]).abs();
                    // Relative to the value, and to 1 where the value is near zero
                    // (cancellation makes a pure relative error meaningless there).
                    assert!(
                        err <= 1e-5 * want[a].abs().max(1.0),
                        "H={H} {got:?} {want:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn forward_matches_f64_reference_at_every_width() {
        check_against_reference::<16>();
        check_against_reference::<64>();
        check_against_reference::<128>();
    }

    #[test]
    fn parameter_counts_are_the_true_ones() {
        assert_eq!(Mlp::<16>::PARAMS, 386);
        assert_eq!(Mlp::<64>::PARAMS, 4_610);
        assert_eq!(Mlp::<128>::PARAMS, 17_410);
        assert_eq!(core::mem::size_of::<PolicyNet>(), 18_440);
        let net = PolicyNet::zeroed();
        let lens = net.tensors().map(<[f32]>::len);
        let shapes = PolicyNet::SHAPES.map(|s| s.iter().product::<usize>());
        assert_eq!(lens, shapes);
        assert_eq!(lens.iter().sum::<usize>(), 4_610);
    }

    #[test]
    fn dot_follows_the_documented_order() {
        // Values chosen so that a different association gives a different f32.
        let mut w = [0.0f32; 16];
        let x = [1.0f32; 16];
        w[0] = 1e8;
        w[8] = -1e8;
        w[1] = 1.0;
        w[4] = 0.5;
        w[12] = 0.25;
        // Lane 0: 1e8 + -1e8 = 0; lane 1: 1; lane 4: 0.75.
        // ((l0 + l4) + (l2 + l6)) + ((l1 + l5) + (l3 + l7)) = 0.75 + 1 = 1.75.
        assert_eq!(dot(&w, &x), 1.75);
        // A single left-to-right accumulator would have lost the 1.0 and 0.5 in 1e8.
        let sequential = w.iter().fold(0.0f32, |s, w| s + w);
        assert_ne!(sequential, 1.75);
    }

    #[test]
    fn ties_and_nan_pick_left() {
        assert_eq!(argmax(&[1.0, 1.0]), Action::Left);
        assert_eq!(argmax(&[0.0, -0.0]), Action::Left);
        assert_eq!(argmax(&[f32::NAN, 1.0]), Action::Left);
        assert_eq!(argmax(&[1.0, f32::NAN]), Action::Left);
        assert_eq!(argmax(&[1.0, 1.0 + f32::EPSILON]), Action::Right);
        // An all-zero net outputs equal Q-values, so it always pushes left.
        assert_eq!(
            PolicyNet::zeroed().greedy_action(&[0.1, 0.0, -0.1, 0.0]),
            Action::Left
        );
    }

    #[test]
    fn relu_zeroes_negative_and_nan_preactivations() {
        let mut net = Mlp::<8>::zeroed();
        net.fc1_bias = [-1.0, f32::NAN, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        net.fc2_weight = [[1.0; 8]; 8];
        net.fc3_weight = [[1.0; 8]; 2];
        // Only the +2.0 unit survives layer 1; each of 8 units in layer 2 then sees 2.0.
        assert_eq!(net.forward(&[0.0; 4]), [16.0, 16.0]);
    }

    #[test]
    fn a_policy_can_be_a_static() {
        static NET: PolicyNet = PolicyNet::zeroed();
        assert_eq!(NET.forward(&[0.0; 4]), [0.0, 0.0]);
    }
}
