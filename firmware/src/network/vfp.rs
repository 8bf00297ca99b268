//! [`dot`](super::dot) for the Cortex-M4F/M7 FPU, in hand-written VFP code.
//!
//! Compiled from Rust, each of the 4,480 multiply-accumulates of a forward pass comes with two
//! single-float `vldr` loads, because LLVM does not merge them into block loads; here each
//! group of eight weights and eight inputs is one `vldmia` each, which more than halves the
//! instructions executed. The arithmetic is [`dot_portable`](super::dot_portable)'s, operation
//! for operation: `vmul.f32` starts the lanes (`-0.0 + p == p`), `vmla.f32` multiplies, rounds,
//! then adds (it is not fused), and the lanes are summed in the documented tree, so the
//! Q-values are bit-identical to the host's. The self-test checks that on the device.
#![allow(unsafe_code)]

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
    // counter and branch on every chunk of every output.
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
