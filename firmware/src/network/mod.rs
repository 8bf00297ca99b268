//! The Q-network: 4 inputs, two hidden ReLU layers of width `H`, `A` linear outputs (one per
//! duty level the policy chooses among: the paper's two, full push left and right, by
//! default).
//!
//! This is the one definition of the inference forward pass. The trainer acts with it, the
//! simulator balances with it and the microcontroller runs it, so a policy behaves the same
//! everywhere, bit for bit. It is also the one definition of the network's shape: the
//! parameter count ([`params`]), the tensors' names ([`TENSOR_NAMES`]) and shapes
//! ([`shapes`]), and the shapes the project's tools are built for ([`SUPPORTED_SHAPES`]).
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
//! adds `w[i] * x[i]` for `i = k, k + LANES, k + 2 * LANES, ...` in increasing `i`; the
//! lanes are then added as a tree, `(l0 + l4) + (l2 + l6)` and `(l1 + l5) + (l3 + l7)`, and
//! those two summed; the bias is added last. Independent partial sums break the chain of `n`
//! dependent additions that a single accumulator would form: a host CPU runs the lanes in one
//! SIMD register and a Cortex-M4 overlaps them in its FPU pipeline, while both compute exactly
//! the same IEEE-754 operations (multiplies and adds are never fused), hence the same bits.
//!
//! [`dot_portable`] is the order's definition. Faster renderings compute the same operations
//! and are tested against it bit for bit: `vfp` (hand-written VFP code, hard-float Arm, in
//! this crate) and the host tools' vector renderings (in their own crate, `host-common`).
//!
//! ```
//! use firmware::network::{Mlp, dot};
//! let w = [1.0, 2.0, 3.0, 4.0];
//! let x = [0.5, 0.25, -1.0, 2.0];
//! assert_eq!(dot(&w, &x), 6.0);
//! assert_eq!(Mlp::<64>::PARAMS, 4_610);
//! ```

pub mod int;
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
pub mod vfp;

/// Inputs: the plant's observation `[x, x_dot, theta, theta_dot]`.
pub const OBS_DIM: usize = 4;
/// Outputs of the paper's network: one Q-value per action (left, right).
pub const N_ACTIONS: usize = 2;
/// Partial sums per dot product (see the module docs).
pub const LANES: usize = 8;
/// Hidden width of the paper's network and of the shipped policy.
pub const PAPER_WIDTH: usize = 64;

/// The paper's network: 4-64-64-2.
pub type PolicyNet = Mlp<PAPER_WIDTH>;

macro_rules! supported_shapes {
    ($($h:literal x $a:literal => $($c:ident)/+,)*) => {
        /// `(width, outputs)` of every network the trainer and the simulator are built for
        /// (any other `H` and `A` compile as [`Mlp<H, A>`] too). The list is
        /// [`for_each_shape!`](crate::for_each_shape).
        pub const SUPPORTED_SHAPES: &[(usize, usize)] = &[$(($h, $a)),*];
    };
}
crate::for_each_shape!(supported_shapes);

/// The most outputs of any network in [`SUPPORTED_SHAPES`]: what a link's reply carries at
/// most.
pub const MAX_OUTPUTS: usize = {
    let mut max = 0;
    let mut i = 0;
    while i < SUPPORTED_SHAPES.len() {
        if SUPPORTED_SHAPES[i].1 > max {
            max = SUPPORTED_SHAPES[i].1;
        }
        i += 1;
    }
    max
};

/// The widths of [`for_each_shape!`](crate::for_each_shape)'s two-output shapes, in its
/// order: an accumulator of widths, then the shapes not yet looked at.
macro_rules! supported_widths {
    (@ [$($w:literal)*]) => {
        /// Hidden widths of the paper's two-output network, the two-output shapes of
        /// [`for_each_shape!`](crate::for_each_shape).
        pub const SUPPORTED_WIDTHS: &[usize] = &[$($w),*];
    };
    (@ [$($w:literal)*] $h:literal x 2 => $($c:ident)/+, $($rest:tt)*) => {
        supported_widths!(@ [$($w)* $h] $($rest)*);
    };
    (@ [$($w:literal)*] $h:literal x $a:literal => $($c:ident)/+, $($rest:tt)*) => {
        supported_widths!(@ [$($w)*] $($rest)*);
    };
    ($($shapes:tt)*) => {
        supported_widths!(@ [] $($shapes)*);
    };
}
crate::for_each_shape!(supported_widths);

/// Parameters of a 4-h-h-a network: `4h + h + h*h + h + ah + a` (4,610 for the paper's
/// `h = 64`, `a = 2`).
pub const fn params(h: usize, a: usize) -> usize {
    OBS_DIM * h + h + h * h + h + a * h + a
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

/// A tensor's shape as PyTorch prints it: `[out, in]` for a weight, `[out]` for a bias.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Shape {
    dims: [usize; 2],
    rank: usize,
}

impl Shape {
    /// The dimensions, outermost first.
    pub fn dims(&self) -> &[usize] {
        &self.dims[..self.rank]
    }

    /// Elements in the tensor.
    pub const fn len(&self) -> usize {
        if self.rank == 1 {
            self.dims[0]
        } else {
            self.dims[0] * self.dims[1]
        }
    }

    /// Whether the tensor holds no element.
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// `Some((out, in))` for a weight matrix, `None` for a bias vector.
    pub const fn matrix(&self) -> Option<(usize, usize)> {
        if self.rank == 2 {
            Some((self.dims[0], self.dims[1]))
        } else {
            None
        }
    }
}

/// The shapes of the six tensors of a 4-h-h-a network, in [`TENSOR_NAMES`] order.
pub const fn shapes(h: usize, a: usize) -> [Shape; 6] {
    const fn m(o: usize, i: usize) -> Shape {
        Shape {
            dims: [o, i],
            rank: 2,
        }
    }
    const fn v(o: usize) -> Shape {
        Shape {
            dims: [o, 0],
            rank: 1,
        }
    }
    [m(h, OBS_DIM), v(h), m(h, h), v(h), m(a, h), v(a)]
}

/// A 4-H-H-A multilayer perceptron with ReLU hidden layers. Field names follow the PyTorch
/// module `fc1`, `fc2`, `fc3` (as in its safetensors export); `weight[o][i]` connects input
/// `i` to output `o`. The layout is C's (`repr(C)`): the C API's `struct cartpole_mlpH` is
/// this type, field for field.
#[derive(Clone, Debug, PartialEq)]
#[repr(C)]
pub struct Mlp<const H: usize, const A: usize = N_ACTIONS> {
    /// First layer weights, `[H][4]`.
    pub fc1_weight: [[f32; OBS_DIM]; H],
    /// First layer biases, `[H]`.
    pub fc1_bias: [f32; H],
    /// Second layer weights, `[H][H]`.
    pub fc2_weight: [[f32; H]; H],
    /// Second layer biases, `[H]`.
    pub fc2_bias: [f32; H],
    /// Output layer weights, `[A][H]`.
    pub fc3_weight: [[f32; H]; A],
    /// Output layer biases, `[A]`.
    pub fc3_bias: [f32; A],
}

impl<const H: usize, const A: usize> Mlp<H, A> {
    /// Number of parameters, [`params`]`(H, A)`.
    pub const PARAMS: usize = params(H, A);

    /// Shapes of the six tensors, [`shapes`]`(H, A)`.
    pub const SHAPES: [Shape; 6] = shapes(H, A);

    /// All parameters zero; usable in `const` and `static` items.
    pub const fn zeroed() -> Self {
        Mlp {
            fc1_weight: [[0.0; OBS_DIM]; H],
            fc1_bias: [0.0; H],
            fc2_weight: [[0.0; H]; H],
            fc2_bias: [0.0; H],
            fc3_weight: [[0.0; H]; A],
            fc3_bias: [0.0; A],
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

    /// Q-values, one per output (`[Q(obs, left), Q(obs, right)]` for the paper's network),
    /// in the summation order of the module docs.
    #[inline]
    pub fn forward(&self, obs: &[f32; OBS_DIM]) -> [f32; A] {
        // Filled in place: returning the layers by value costs a copy of each whenever the
        // dot product is an out-of-line call (the Cortex-M4F's).
        let mut h1 = [0.0; H];
        linear(&mut h1, &self.fc1_weight, &self.fc1_bias, obs, true);
        let mut h2 = [0.0; H];
        linear(&mut h2, &self.fc2_weight, &self.fc2_bias, &h1, true);
        let mut q = [0.0; A];
        linear(&mut q, &self.fc3_weight, &self.fc3_bias, &h2, false);
        q
    }

    /// The output with the largest Q-value ([`argmax`]).
    #[inline]
    pub fn greedy(&self, obs: &[f32; OBS_DIM]) -> usize {
        argmax(&self.forward(obs))
    }
}

/// The index of the largest value; a tie picks the lower index, as `argmax` does in NumPy
/// and PyTorch, and a NaN never wins (index 0 if the first value is NaN). With two outputs:
/// `1` (right) only if its value is strictly larger.
#[inline]
pub fn argmax<T: PartialOrd>(q: &[T]) -> usize {
    let mut best = 0;
    for i in 1..q.len() {
        if q[i] > q[best] {
            best = i;
        }
    }
    best
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

#[cfg(test)]
pub(crate) mod tests;
