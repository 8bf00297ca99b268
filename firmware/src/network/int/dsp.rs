//! The integer network's layers with the DSP extension's dual multiply-accumulate (`smlad`),
//! for ARMv7E-M cores (Cortex-M4 and M7, with or without FPU; `build.rs` says why not the
//! M33).
//!
//! `smlad` adds two 16 x 16-bit products in one instruction. The activations are unpacked
//! once per layer into halfword pairs ([`Pairs`]: `x0 | x2 << 16`, `x1 | x3 << 16` per group
//! of four); each word of four weights becomes two such pairs with two `sxtb16`, as in
//! CMSIS-NN's int8 kernels. Four rows share every activation load, which takes far fewer
//! instructions per multiply-accumulate than ARMv6-M code (`super::thumb`). Each layer's bias
//! and requantisation run in the same routine, with `usat` for the two clamps, shorter than
//! LLVM's rendering of [`Requant::apply`]. The counts are in `docs/QUANTISATION.md`.
//!
//! Integer sums are the same in any order and the requantisation is [`Requant::apply`]'s
//! arithmetic, so the activations and Q-values are the portable code's, bit for bit; the
//! tests (on the host, against the portable code) cannot run this, so the self-test compares
//! the two on the device.
#![allow(unsafe_code)]

use core::mem::MaybeUninit;

use super::Requant;
use crate::network::OBS_DIM;

/// Activations as the kernels read them: per group of four `[x0, x2, x1, x3]`, so that each
/// pair of halfwords is one word `x0 | x2 << 16`, then `x1 | x3 << 16`. Aligned for `ldrd`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(8))]
pub struct Pairs<const N: usize>([u16; N]);

/// Room for [`Pairs`], filled by [`PairsBuf::unpack`]: zeroing it first would cost as much
/// as the unpacking.
#[repr(C, align(8))]
pub struct PairsBuf<const N: usize>(MaybeUninit<Pairs<N>>);

impl<const N: usize> Pairs<N> {
    /// Room for the unpacked activations.
    #[inline(always)]
    pub fn uninit() -> PairsBuf<N> {
        PairsBuf(MaybeUninit::uninit())
    }
}

impl<const N: usize> PairsBuf<N> {
    /// Unpacks `x` here; `N` a non-zero multiple of 8.
    #[inline(always)]
    pub fn unpack(&mut self, x: &[u8; N]) -> &Pairs<N> {
        const { assert!(N > 0 && N.is_multiple_of(8) && N < 1 << 24) };
        // SAFETY: the routine reads `N` bytes from `x` and writes all `N` halfwords of the
        // buffer (8-byte aligned); it follows the AAPCS. So the buffer is initialised after.
        unsafe {
            cartpole_ddqn_unpack_u8(x.as_ptr(), N, self.0.as_mut_ptr().cast());
            self.0.assume_init_ref()
        }
    }
}

/// The first hidden layer: `requant(w . obs + b)` per unit; `H` a non-zero multiple of 4.
#[inline]
pub fn input<const H: usize>(
    w: &[[i8; OBS_DIM]; H],
    b: &[i32; H],
    r: &[Requant; H],
    obs: &[i16; OBS_DIM],
) -> [u8; H] {
    const { assert!(H > 0 && H.is_multiple_of(4) && H < 1 << 24) };
    let mut y = MaybeUninit::<[u8; H]>::uninit();
    let [x0, x1, x2, x3] = obs.map(|v| u32::from(v as u16));
    let pairs = [x0 | x2 << 16, x1 | x3 << 16];
    // SAFETY: the routine reads `H` rows of four weights, `H` biases and requantisations and
    // two pair words, writes all `H` bytes of `y` (so it is initialised after), and follows
    // the AAPCS.
    unsafe {
        cartpole_ddqn_smlad_input(
            w.as_ptr().cast(),
            pairs.as_ptr(),
            b.as_ptr(),
            r.as_ptr(),
            y.as_mut_ptr().cast(),
            H,
        );
        y.assume_init()
    }
}

/// The second hidden layer: `requant(w . x + b)` per unit; `H` a non-zero multiple of 8.
#[inline]
pub fn hidden<const H: usize>(
    w: &[[i8; H]; H],
    b: &[i32; H],
    r: &[Requant; H],
    x: &[u8; H],
) -> [u8; H] {
    const { assert!(H > 0 && H.is_multiple_of(8) && H < 1 << 24) };
    let mut buf = Pairs::uninit();
    let pairs = buf.unpack(x);
    let mut y = MaybeUninit::<[u8; H]>::uninit();
    // SAFETY: the routine reads the `H x H` weights, `H` halfword pairs (8-byte aligned), `H`
    // biases and requantisations, writes all `H` bytes of `y` (so it is initialised after),
    // and follows the AAPCS.
    unsafe {
        cartpole_ddqn_smlad_hidden(
            w.as_ptr().cast(),
            H,
            pairs.0.as_ptr(),
            b.as_ptr(),
            r.as_ptr(),
            y.as_mut_ptr().cast(),
        );
        y.assume_init()
    }
}

/// The output layer: `w[o] . x + b[o]` per output, two rows a pass (an odd last row with
/// itself); `H` a non-zero multiple of 8.
#[inline]
pub fn output<const H: usize, const A: usize>(
    w: &[[i8; H]; A],
    b: &[i32; A],
    x: &[u8; H],
) -> [i32; A] {
    const { assert!(H > 0 && H.is_multiple_of(8) && H < 1 << 24) };
    let mut buf = Pairs::uninit();
    let pairs = buf.unpack(x);
    let mut q = [0i32; A];
    for k in (0..A).step_by(2) {
        let next = (k + 1).min(A - 1);
        let mut acc = [0i32; 2];
        // SAFETY: the routine reads `H` bytes from each row and `H` halfwords from `pairs`
        // (8-byte aligned), writes the two words of `acc`, and follows the AAPCS.
        unsafe {
            cartpole_ddqn_smlad_rows2(
                w[k].as_ptr(),
                w[next].as_ptr(),
                H,
                pairs.0.as_ptr(),
                acc.as_mut_ptr(),
            );
        }
        q[k] = acc[0].wrapping_add(b[k]);
        q[next] = acc[usize::from(next != k)].wrapping_add(b[next]);
    }
    q
}

unsafe extern "C" {
    fn cartpole_ddqn_unpack_u8(x: *const u8, n: usize, pairs: *mut u16);
    fn cartpole_ddqn_smlad_input(
        w: *const i8,
        pairs: *const u32,
        b: *const i32,
        r: *const Requant,
        y: *mut u8,
        rows: usize,
    );
    fn cartpole_ddqn_smlad_hidden(
        w: *const i8,
        n: usize,
        pairs: *const u16,
        b: *const i32,
        r: *const Requant,
        y: *mut u8,
    );
    fn cartpole_ddqn_smlad_rows2(
        wa: *const i8,
        wb: *const i8,
        n: usize,
        pairs: *const u16,
        acc: *mut i32,
    );
}

core::arch::global_asm!(
    ".syntax unified",
    ".thumb",
    // One row's four weights at `load` against the pair in r8/r9, into `acc`.
    ".macro cartpole_ddqn_smlad_row acc, load:vararg",
    "\\load",
    "sxtb16 r12, r11, ror #8",
    "sxtb16 r11, r11",
    "smlad \\acc, r11, r8, \\acc",
    "smlad \\acc, r12, r9, \\acc",
    ".endm",
    // `acc` plus the bias at [b], then Requant::apply with the word at [r] (multiplier,
    // pre_shift << 16, post_shift << 24), stored as a byte at [y]; all three advance. The
    // two clamps are `usat`: a non-positive accumulator gives t = 0, hence y = 0.
    ".macro cartpole_ddqn_requant acc, t1, t2, b, r, y",
    "ldr \\t1, [\\b], #4",
    "add \\acc, \\acc, \\t1",
    "ldr \\t1, [\\r], #4",
    "ubfx \\t2, \\t1, #16, #5",
    "asr \\acc, \\acc, \\t2",
    "usat \\acc, #15, \\acc",
    "uxth \\t2, \\t1",
    "mul \\acc, \\acc, \\t2",
    "ubfx \\t2, \\t1, #24, #5",
    "mov \\t1, #1",
    "lsl \\t1, \\t1, \\t2",
    "add \\acc, \\acc, \\t1, lsr #1",
    "lsr \\acc, \\acc, \\t2",
    "usat \\acc, #8, \\acc",
    "strb \\acc, [\\y], #1",
    ".endm",
    // input: r0 = weights (four per row), r1 = the two pair words of the observation,
    // r2 = biases, r3 = requantisations, [sp] = y, [sp + 4] = rows (>= 1).
    ".section .text.cartpole_ddqn_smlad_input,\"ax\",%progbits",
    ".global cartpole_ddqn_smlad_input",
    ".type cartpole_ddqn_smlad_input,%function",
    ".thumb_func",
    "cartpole_ddqn_smlad_input:",
    "push {{r4-r11, lr}}",
    "ldr r10, [sp, #36]",
    "ldr lr, [sp, #40]",
    "ldrd r8, r9, [r1]",
    "1:",
    "ldr r11, [r0], #4",
    "sxtb16 r12, r11, ror #8",
    "sxtb16 r11, r11",
    "smuad r4, r11, r8",
    "smlad r4, r12, r9, r4",
    "cartpole_ddqn_requant r4, r5, r6, r2, r3, r10",
    "subs lr, lr, #1",
    "bne 1b",
    "pop {{r4-r11, pc}}",
    ".size cartpole_ddqn_smlad_input, . - cartpole_ddqn_smlad_input",
    // hidden: r0 = weights (n rows of n), r1 = n, r2 = pairs, r3 = biases, [sp] = the
    // requantisations, [sp + 4] = y. Per group of four rows: r0/r1 point at rows 0 and 2
    // (rows 1 and 3 are r10 = n bytes further), r3 counts the loop, r4-r7 are the sums,
    // r8/r9 an activation pair, r11/r12 weights, lr the pairs. The biases, requantisations
    // and y live at [sp], [sp + 4], [sp + 8] between groups, the rows left at [sp + 12].
    ".section .text.cartpole_ddqn_smlad_hidden,\"ax\",%progbits",
    ".global cartpole_ddqn_smlad_hidden",
    ".type cartpole_ddqn_smlad_hidden,%function",
    ".thumb_func",
    "cartpole_ddqn_smlad_hidden:",
    "push {{r4-r11, lr}}",
    "sub sp, sp, #16",
    "str r3, [sp]",
    "ldr r4, [sp, #52]",
    "str r4, [sp, #4]",
    "ldr r4, [sp, #56]",
    "str r4, [sp, #8]",
    "str r1, [sp, #12]",
    "mov r10, r1",
    "mov lr, r2",
    "2:",
    "add r1, r0, r10, lsl #1",
    "mov r2, lr",
    "lsrs r3, r10, #3",
    "movs r4, #0",
    "movs r5, #0",
    "movs r6, #0",
    "movs r7, #0",
    "1:",
    ".rept 2",
    "ldrd r8, r9, [r2], #8",
    "cartpole_ddqn_smlad_row r5, ldr r11, [r0, r10]",
    "cartpole_ddqn_smlad_row r4, ldr r11, [r0], #4",
    "cartpole_ddqn_smlad_row r7, ldr r11, [r1, r10]",
    "cartpole_ddqn_smlad_row r6, ldr r11, [r1], #4",
    ".endr",
    "subs r3, r3, #1",
    "bne 1b",
    // r0 has moved one row on, to row 1: the next group starts three rows further.
    "add r0, r0, r10, lsl #1",
    "add r0, r0, r10",
    "ldr r1, [sp]",
    "ldr r2, [sp, #4]",
    "ldr r3, [sp, #8]",
    "cartpole_ddqn_requant r4, r8, r9, r1, r2, r3",
    "cartpole_ddqn_requant r5, r8, r9, r1, r2, r3",
    "cartpole_ddqn_requant r6, r8, r9, r1, r2, r3",
    "cartpole_ddqn_requant r7, r8, r9, r1, r2, r3",
    "str r1, [sp]",
    "str r2, [sp, #4]",
    "str r3, [sp, #8]",
    "ldr r1, [sp, #12]",
    "subs r1, r1, #4",
    "str r1, [sp, #12]",
    "bne 2b",
    "add sp, sp, #16",
    "pop {{r4-r11, pc}}",
    ".size cartpole_ddqn_smlad_hidden, . - cartpole_ddqn_smlad_hidden",
    // rows2: r0 = row a, r1 = row b, r2 = n, r3 = pairs, [sp] = the two sums' destination.
    ".section .text.cartpole_ddqn_smlad_rows2,\"ax\",%progbits",
    ".global cartpole_ddqn_smlad_rows2",
    ".type cartpole_ddqn_smlad_rows2,%function",
    ".thumb_func",
    "cartpole_ddqn_smlad_rows2:",
    "push {{r4-r11, lr}}",
    "ldr lr, [sp, #36]",
    "lsrs r10, r2, #3",
    "mov r2, r3",
    "mov r3, r10",
    "movs r4, #0",
    "movs r5, #0",
    "1:",
    ".rept 2",
    "ldrd r8, r9, [r2], #8",
    "cartpole_ddqn_smlad_row r4, ldr r11, [r0], #4",
    "cartpole_ddqn_smlad_row r5, ldr r11, [r1], #4",
    ".endr",
    "subs r3, r3, #1",
    "bne 1b",
    "strd r4, r5, [lr]",
    "pop {{r4-r11, pc}}",
    ".size cartpole_ddqn_smlad_rows2, . - cartpole_ddqn_smlad_rows2",
    // unpack: r0 = x, r1 = n, r2 = pairs (8-byte aligned): eight bytes in, eight halfwords
    // out per iteration.
    ".section .text.cartpole_ddqn_unpack_u8,\"ax\",%progbits",
    ".global cartpole_ddqn_unpack_u8",
    ".type cartpole_ddqn_unpack_u8,%function",
    ".thumb_func",
    "cartpole_ddqn_unpack_u8:",
    "push {{r4-r7}}",
    "lsrs r1, r1, #3",
    "1:",
    // Two loads, not `ldrd`: the activations are bytes, not necessarily word-aligned.
    "ldr r3, [r0], #4",
    "ldr r4, [r0], #4",
    "uxtb16 r5, r3, ror #8",
    "uxtb16 r3, r3",
    "uxtb16 r6, r4, ror #8",
    "uxtb16 r4, r4",
    "strd r3, r5, [r2], #8",
    "strd r4, r6, [r2], #8",
    "subs r1, r1, #1",
    "bne 1b",
    "pop {{r4-r7}}",
    "bx lr",
    ".size cartpole_ddqn_unpack_u8, . - cartpole_ddqn_unpack_u8",
);
