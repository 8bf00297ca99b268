//! Int8 x u8 dot products of two rows at once (and of an odd row alone) in hand-written Thumb
//! code, for every Cortex-M core (ARMv6-M's instruction set, which the larger cores execute
//! too).
//!
//! Compiled from Rust, LLVM keeps the unrolled loop's constant offsets in stack slots on the
//! M0's eight low registers and reloads them for every multiply-accumulate. Here each
//! activation is loaded once for both rows, and one index register addresses the two weight
//! rows and the activations at once (`ldrsb`/`ldrb` with a register offset); the counts
//! are in `docs/QUANTISATION.md`. Integer addition is associative, so the sums
//! are [`super::dot_u8`]'s, bit for bit, whatever the order; the tests and the self-test
//! check it anyway.
#![allow(unsafe_code)]

/// `[wa . x, wb . x]` for `N` a non-zero multiple of 8.
#[inline]
pub fn dot2<const N: usize>(wa: &[i8; N], wb: &[i8; N], x: &[u8; N]) -> [i32; 2] {
    const { assert!(N > 0 && N.is_multiple_of(8) && N < 1 << 24) };
    // SAFETY: the routine reads `N` bytes below each end pointer, which the three arrays
    // hold, writes no memory and follows the AAPCS (it saves r4-r7).
    let both = unsafe {
        cartpole_ddqn_dot2_i8u8(
            wa.as_ptr_range().end,
            wb.as_ptr_range().end,
            x.as_ptr_range().end,
            N,
        )
    };
    [both as u32 as i32, (both >> 32) as u32 as i32]
}

/// `w . x` for `N` a non-zero multiple of 8: an odd row's, which [`dot2`] would compute twice.
#[inline]
pub fn dot1<const N: usize>(w: &[i8; N], x: &[u8; N]) -> i32 {
    const { assert!(N > 0 && N.is_multiple_of(8) && N < 1 << 24) };
    // SAFETY: the routine reads `N` bytes below each end pointer, which the two arrays hold,
    // writes no memory and follows the AAPCS (it saves r4 and r5).
    unsafe { cartpole_ddqn_dot1_i8u8(w.as_ptr_range().end, x.as_ptr_range().end, N) }
}

unsafe extern "C" {
    fn cartpole_ddqn_dot1_i8u8(w_end: *const i8, x_end: *const u8, n: usize) -> i32;
    fn cartpole_ddqn_dot2_i8u8(
        wa_end: *const i8,
        wb_end: *const i8,
        x_end: *const u8,
        n: usize,
    ) -> u64;
}

// r0, r1, r2: the ends of the two rows and of the activations; r3 = n. The index counts from
// -n up to 0, so the increment that ends a group of eight also sets the loop's flags. The two
// sums return in r0 and r1 (a 64-bit result).
core::arch::global_asm!(
    ".syntax unified",
    ".thumb",
    ".section .text.cartpole_ddqn_dot2_i8u8,\"ax\",%progbits",
    ".global cartpole_ddqn_dot2_i8u8",
    ".type cartpole_ddqn_dot2_i8u8,%function",
    ".thumb_func",
    "cartpole_ddqn_dot2_i8u8:",
    "push {{r4, r5, r6, r7}}",
    "rsbs r3, r3, #0",
    "movs r4, #0",
    "movs r5, #0",
    "1:",
    ".rept 8",
    "ldrb r6, [r2, r3]",
    "ldrsb r7, [r0, r3]",
    "muls r7, r6, r7",
    "adds r4, r4, r7",
    "ldrsb r7, [r1, r3]",
    "muls r7, r6, r7",
    "adds r5, r5, r7",
    "adds r3, r3, #1",
    ".endr",
    "bne 1b",
    "movs r0, r4",
    "movs r1, r5",
    "pop {{r4, r5, r6, r7}}",
    "bx lr",
    ".size cartpole_ddqn_dot2_i8u8, . - cartpole_ddqn_dot2_i8u8",
);

// r0, r1: the ends of the row and of the activations; r2 = n, the index as in the routine
// above. The sum returns in r0.
core::arch::global_asm!(
    ".syntax unified",
    ".thumb",
    ".section .text.cartpole_ddqn_dot1_i8u8,\"ax\",%progbits",
    ".global cartpole_ddqn_dot1_i8u8",
    ".type cartpole_ddqn_dot1_i8u8,%function",
    ".thumb_func",
    "cartpole_ddqn_dot1_i8u8:",
    "push {{r4, r5}}",
    "rsbs r2, r2, #0",
    "movs r3, #0",
    "1:",
    ".rept 8",
    "ldrb r4, [r1, r2]",
    "ldrsb r5, [r0, r2]",
    "muls r5, r4, r5",
    "adds r3, r3, r5",
    "adds r2, r2, #1",
    ".endr",
    "bne 1b",
    "movs r0, r3",
    "pop {{r4, r5}}",
    "bx lr",
    ".size cartpole_ddqn_dot1_i8u8, . - cartpole_ddqn_dot1_i8u8",
);
