//! What the microcontroller checks about itself at start-up, and what the host compares it
//! with: Q-values of fixed observations (bit-exactness) and closed-loop episodes against the
//! `no_std` plant.
//!
//! The microcontroller binary prints the results; the same application built for the host
//! prints the host's values in the same format, and an end-to-end test runs both and
//! compares the text. A board can run [`report`] at start-up too, with its own output.

use firmware::ConfigError;
use firmware::cartpole::{CartPole, Params};
use firmware::controller::{FaultCounters, Greedy, Limits, Monitor, Policy, Refined, answer};
use firmware::estimator::Estimate;
use firmware::loopback::{Outcome, run, run_with_encoders};
use firmware::network::int::QMlp;
use firmware::network::{Mlp, dot, dot_portable};
use rand_core::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use shipped::envelope::ASSURANCE;
use shipped::policy::RIG;

/// The shipped policy's forward pass as a C function: the self-test calls it by address, so
/// that the ELF keeps it as a function of its own whose instructions can be counted
/// (`scripts/count_insns.py`). A NULL argument writes nothing, as in the C API.
// SAFETY: an unmangled symbol is `unsafe` because two with one name would clash at link
// time; this application defines each of its names once and links no other C entry points.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn selftest_forward(obs: Option<&[f32; 4]>, q: Option<&mut [f32; 2]>) {
    if let (Some(obs), Some(q)) = (obs, q) {
        *q = shipped::policy::POLICY.forward(obs);
    }
}

/// [`selftest_forward`] for the integer policy (Q3.12 in, its integer outputs out).
// SAFETY: as for `selftest_forward`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn selftest_forward_int(obs: Option<&[i16; 4]>, q: Option<&mut [i32; 2]>) {
    if let (Some(obs), Some(q)) = (obs, q) {
        *q = shipped::policy_int::POLICY_INT.forward(obs);
    }
}

/// The nine-level desk policy's forward pass (`shipped::desk`) as a C function: what a
/// policy with duty levels costs a core, counted as [`selftest_forward`]'s is.
// SAFETY: as for `selftest_forward`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn selftest_forward_levels(obs: Option<&[f32; 4]>, q: Option<&mut [f32; 9]>) {
    if let (Some(obs), Some(q)) = (obs, q) {
        *q = shipped::desk::POLICY.forward(obs);
    }
}

/// [`selftest_forward_levels`] for the same policy in integers (`shipped::desk_int`).
// SAFETY: as for `selftest_forward`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn selftest_forward_levels_int(obs: Option<&[i16; 4]>, q: Option<&mut [i32; 9]>) {
    if let (Some(obs), Some(q)) = (obs, q) {
        *q = shipped::desk_int::POLICY_INT.forward(obs);
    }
}

/// What [`Refined`] adds to a decision of the integer nine-level policy: the duty it
/// drives, in thousandths (`out[0]`), having chosen output `at[0]` of scores that stand
/// `at[1]` and `at[2]` below it on either side (`at[3]` unread). Output `at[0]` beyond the
/// levels drives nothing (`i32::MIN`).
// SAFETY: as for `selftest_forward`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn selftest_refine_int(at: Option<&[i16; 4]>, out: Option<&mut [i32; 9]>) {
    if let (Some(&[i, below, above, _]), Some(out)) = (at, out) {
        let i = usize::from(i.unsigned_abs());
        let mut q = [i32::MIN; 9];
        if let Some(k) = i.checked_sub(1).and_then(|k| q.get_mut(k)) {
            *k = -i32::from(below);
        }
        if let Some(k) = q.get_mut(i + 1) {
            *k = -i32::from(above);
        }
        if let Some(k) = q.get_mut(i) {
            *k = 0;
        }
        let policy = Refined(Greedy {
            net: &shipped::desk_int::POLICY_INT,
            levels: shipped::desk_int::LEVELS,
        });
        let duty = Policy::<[i16; 4]>::drive(&policy, &q, i);
        out[0] = duty.map_or(i32::MIN, |d| d.thousandths().into());
    }
}

/// The refined duty of a fixed decision of the integer nine-level policy (a `probe-refine`
/// line), for the host to compare as it compares [`report`]'s.
pub fn refine_probe(
    refine: impl Fn(&[i16; 4], &mut [i32; 9]),
    mut line: impl FnMut(core::fmt::Arguments<'_>),
) {
    let mut duty = [0; 9];
    refine(&[5, 3, 1, 0], &mut duty);
    line(format_args!("probe-refine {}", duty[0]));
}

/// The nine-level policy's outputs on every probe, f32 and int8 (`probe-levels`,
/// `probe-levels-int` lines), for the host to compare bit for bit as it compares
/// [`report`]'s.
pub fn levels_probes(
    forward: impl Fn(&[f32; 4], &mut [f32; 9]),
    forward_int: impl Fn(&[i16; 4], &mut [i32; 9]),
    mut line: impl FnMut(core::fmt::Arguments<'_>),
) {
    for (i, obs) in PROBES.iter().enumerate() {
        let mut q = [0.0; 9];
        forward(obs, &mut q);
        // 192 bytes hold a nine-output line (133 characters).
        let mut text = heapless::String::<192>::new();
        let _ = probe_line(&mut text, "probe-levels", i, obs, &q);
        line(format_args!("{text}"));
    }
    for (i, obs) in INT_PROBES.iter().enumerate() {
        let mut q = [0; 9];
        forward_int(obs, &mut q);
        let mut text = heapless::String::<192>::new();
        let _ = int_probe_line(&mut text, "probe-levels-int", i, obs, &q);
        line(format_args!("{text}"));
    }
}

/// One period of the runtime monitor (`firmware::controller::monitor`) around the integer
/// policy, as a fresh monitor of the shipped assurance decides on `obs`: the policy's
/// outputs inside the envelope, zeros where the fallback decides. Its instructions less
/// [`selftest_forward_int`]'s are the monitor's cost.
// SAFETY: as for `selftest_forward`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn selftest_monitored_int(obs: Option<&[i16; 4]>, q: Option<&mut [i32; 2]>) {
    if let (Some(obs), Some(q)) = (obs, q) {
        let mut monitor = Monitor::new(ASSURANCE);
        let mut counters = FaultCounters::default();
        let mut policy = &shipped::policy_int::POLICY_INT;
        (*q, _, _) = monitor.decide(obs, obs, false, &mut policy, answer, &mut counters);
    }
}

/// Observations whose Q-values must agree bit for bit on every target: a balanced state,
/// leaning states, the edges of the failure box, large rates, and values with long mantissas.
pub const PROBES: [[f32; 4]; 8] = [
    [0.0, 0.0, 0.0, 0.0],
    [0.01, -0.02, 0.03, 0.04],
    [-0.04, 0.03, -0.02, 0.01],
    [2.4, 0.0, 0.2094395, 0.0],
    [-2.4, -1.5, -0.2094395, -2.0],
    [0.5, 1.0, 0.1, 1.5],
    [1.0e-7, -3.3333333, 0.12345679, -0.9876543],
    [-1.1754944e-38, 19.99, -0.41, 19.99],
];

/// Fixed-point observations (Q3.12) whose integer Q-values must agree on every target: the
/// float probes' states rounded, and the extremes of the format.
pub const INT_PROBES: [[i16; 4]; 8] = [
    [0, 0, 0, 0],
    [41, -82, 123, 164],
    [-164, 123, -82, 41],
    [9830, 0, 858, 0],
    [-9830, -6144, -858, -8192],
    [2048, 4096, 410, 6144],
    [32767, -32768, 32767, -32768],
    [-1, 1, -32768, 32767],
];

/// Random observations in [`int_check`].
pub const INT_CASES: u32 = 300;

/// Whether this target's [`QMlp::forward`] runs kernels of its own (hand-written Arm code)
/// rather than the portable definition, so that [`int_check`] compares two implementations.
pub const OWN_INT_KERNELS: bool = cfg!(target_arch = "arm");
/// Whether this target's [`dot`] is a rendering of its own (hand-written VFP code) rather
/// than [`dot_portable`] itself, so that [`dot_check`] compares two implementations.
pub const OWN_DOT: bool = cfg!(all(target_arch = "arm", target_abi = "eabihf"));

/// How many of [`INT_CASES`] seeded random observations give different Q-values through
/// `kernel` (the target's [`QMlp::forward`]: DSP code on a Cortex-M4F, ARMv6-M code on a
/// Cortex-M0) and through `net`'s [`QMlp::forward_portable`] (the definition). A third are
/// anywhere in the `i16` range, the rest within +-0.5 units, where a balancing run lives.
/// Meaningful where [`OWN_INT_KERNELS`]; elsewhere `forward` is the definition itself.
pub fn int_check<const H: usize, const A: usize>(
    net: &QMlp<H, A>,
    kernel: impl Fn(&[i16; 4]) -> [i32; A],
) -> u32 {
    let mut rng = Pcg32::seed_from_u64(0x1A7);
    let mut bad = 0;
    for case in 0..INT_CASES {
        let obs: [i16; 4] = core::array::from_fn(|_| {
            let v = rng.next_u32() as i16;
            if case % 3 == 0 { v } else { v >> 4 }
        });
        if kernel(&obs) != net.forward_portable(&obs) {
            bad += 1;
        }
    }
    bad
}

/// One integer probe line: index, the observation and the two Q-values, in hex.
pub fn int_probe_line<W: core::fmt::Write>(
    out: &mut W,
    name: &str,
    index: usize,
    obs: &[i16; 4],
    q: &[i32],
) -> core::fmt::Result {
    write!(out, "{name} {index}")?;
    for v in obs {
        write!(out, " {:04x}", *v as u16)?;
    }
    write!(out, " ->")?;
    for v in q {
        write!(out, " {:08x}", *v as u32)?;
    }
    Ok(())
}

/// Random vector pairs per length in [`dot_check`].
pub const DOT_CASES: u32 = 200;

/// How many of [`DOT_CASES`] seeded random vector pairs, at each of the lengths 4, 8, 16, 24
/// and 64, give a different result from [`dot`] (the target's own path, hand-written VFP code on
/// a Cortex-M4F) and from [`dot_portable`] (the order's definition, compiled by LLVM). Bits
/// must be equal; two NaNs count as equal, since which operand's payload survives is not part
/// of the order. Half the pairs are raw random bit patterns (NaNs, infinities, subnormals,
/// signed zeros), half are moderate values whose sums cancel.
pub fn dot_check() -> u32 {
    let mut rng = Pcg32::seed_from_u64(0xD07);
    mismatches::<4>(&mut rng)
        + mismatches::<8>(&mut rng)
        + mismatches::<16>(&mut rng)
        + mismatches::<24>(&mut rng)
        + mismatches::<64>(&mut rng)
}

fn mismatches<const N: usize>(rng: &mut Pcg32) -> u32 {
    let mut bad = 0;
    for case in 0..DOT_CASES {
        let mut value = || {
            let bits = rng.next_u32();
            if case % 2 == 0 {
                f32::from_bits(bits)
            } else {
                // Sign and mantissa random, exponent within 2^-8 .. 2^8.
                f32::from_bits((bits & 0x807f_ffff) | ((127 - 8 + (bits >> 23) % 17) << 23))
            }
        };
        let w: [f32; N] = core::array::from_fn(|_| value());
        let x: [f32; N] = core::array::from_fn(|_| value());
        let (a, b) = (dot(&w, &x), dot_portable(&w, &x));
        if a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan()) {
            bad += 1;
        }
    }
    bad
}

/// Self-test episodes run by the firmware binary.
pub const EPISODES: u32 = 5;
/// Their length, Gymnasium's `CartPole-v1`.
pub const EPISODE_STEPS: u32 = firmware::cartpole::V1_EPISODE_STEPS;

/// The shipped rig's limits, built as the self-test is compiled: a board's `static`
/// configuration, checked by the compiler.
pub const LIMITS: Limits = match RIG.limits() {
    Ok(limits) => limits,
    Err(_) => panic!("the shipped rig leaves no track"),
};

/// One probe line: index, the observation's bits and the Q-values' bits, in hex. Both sides
/// format with this, so a bit difference shows as a text difference.
pub fn probe_line<W: core::fmt::Write>(
    out: &mut W,
    name: &str,
    index: usize,
    obs: &[f32; 4],
    q: &[f32],
) -> core::fmt::Result {
    write!(out, "{name} {index}")?;
    for v in obs {
        write!(out, " {:08x}", v.to_bits())?;
    }
    write!(out, " ->")?;
    for v in q {
        write!(out, " {:08x}", v.to_bits())?;
    }
    Ok(())
}

/// Episode `episode` of the self-test: a Gymnasium-style random start from a seeded PCG32,
/// then `policy` through the controller, reading the exact state in the format `O`, until
/// the pole falls or [`EPISODE_STEPS`] pass.
pub fn episode<O: Estimate, P: Policy<O>>(policy: P, episode: u32) -> Outcome {
    run(policy, &mut start(episode), LIMITS, || 0)
}

/// The plant of episode `episode`, at its start.
fn start(episode: u32) -> CartPole {
    let mut plant = CartPole::new(Params::default(), EPISODE_STEPS);
    plant.reset(&mut Pcg32::seed_from_u64(u64::from(episode)));
    plant
}

/// Episode `episode` of the self-test read through the shipped rig's encoders and observer,
/// as a board reads its plant, in the reading format `O` the policy takes; refused as the
/// firmware refuses the rig's observer.
pub fn encoder_episode<O: Estimate, P: Policy<O>>(
    policy: P,
    episode: u32,
) -> Result<Outcome, ConfigError> {
    run_with_encoders(policy, &mut start(episode), &RIG, || 0)
}

/// Writes the self-test report, one line per `line` call: the probe lines (Q-values from
/// `forward` and `forward_int`, the entry points under test), the [`dot_check`] and
/// [`int_check`] results, then per format one line per episode, an episode through
/// encoders and the estimator, and a verdict. Returns whether every episode balanced and no
/// kernel differed from its definition.
pub fn report<const H: usize>(
    net: &Mlp<H>,
    qnet: &QMlp<H>,
    forward: impl Fn(&[f32; 4], &mut [f32; 2]),
    forward_int: impl Fn(&[i16; 4], &mut [i32; 2]),
    mut line: impl FnMut(core::fmt::Arguments<'_>),
) -> bool {
    line(format_args!(
        "cartpole-ddqn self-test: 4-{H}-{H}-2 policy, {} parameters, as f32 and as int8",
        Mlp::<H>::PARAMS
    ));
    for (i, obs) in PROBES.iter().enumerate() {
        let mut q = [0.0; 2];
        forward(obs, &mut q);
        let mut text = heapless::String::<96>::new();
        // 96 bytes hold a probe line (64 characters); a truncated line is still a mismatch the
        // host test reports, never a panic.
        let _ = probe_line(&mut text, "probe", i, obs, &q);
        line(format_args!("{text}"));
    }
    for (i, obs) in INT_PROBES.iter().enumerate() {
        let mut q = [0; 2];
        forward_int(obs, &mut q);
        let mut text = heapless::String::<96>::new();
        let _ = int_probe_line(&mut text, "probe-int", i, obs, &q);
        line(format_args!("{text}"));
    }
    let dot_bad = if OWN_DOT {
        let bad = dot_check();
        line(format_args!(
            "dot: {bad} of {} random vector pairs differ from the portable order",
            5 * DOT_CASES
        ));
        bad
    } else {
        line(format_args!(
            "dot: the portable order itself on this target"
        ));
        0
    };
    let int_bad = if OWN_INT_KERNELS {
        let bad = int_check(qnet, |obs| qnet.forward(obs));
        line(format_args!(
            "int: {bad} of {INT_CASES} random observations differ from the portable forward pass"
        ));
        bad
    } else {
        line(format_args!(
            "int: the portable forward pass itself on this target"
        ));
        0
    };
    let float_ok = episodes::<[f32; 4], _>("f32", net, &mut line);
    let int_ok = episodes::<[i16; 4], _>("int8", qnet, &mut line);
    dot_bad == 0 && int_bad == 0 && float_ok && int_ok
}

/// One format's closed-loop part of [`report`]: the seeded episodes on the exact state, the
/// encoder episode in the reading format `O` a board with this policy reads, and their
/// verdict line. Whether they all balanced.
fn episodes<O: Estimate, P: Policy<O> + Copy>(
    format: &str,
    policy: P,
    line: &mut impl FnMut(core::fmt::Arguments<'_>),
) -> bool {
    let mut balanced = 0;
    for e in 0..EPISODES {
        let o = episode::<O, P>(policy, e);
        balanced += u32::from(o.success);
        line(format_args!(
            "{format} episode {e}: {} steps, {}, {} faults",
            o.steps,
            if o.success { "balanced" } else { "FELL" },
            o.faults
        ));
    }
    let enc = match encoder_episode::<O, P>(policy, 0) {
        Ok(enc) => enc,
        Err(e) => {
            line(format_args!("{format} estimator episode: refused: {e}"));
            return false;
        }
    };
    line(format_args!(
        "{format} estimator episode: {} steps through {}-count encoders, {}",
        enc.steps,
        RIG.encoders.pole_counts_per_rev,
        if enc.success { "balanced" } else { "FELL" }
    ));
    line(format_args!(
        "{format} self-test: {balanced} of {EPISODES} episodes balanced for {EPISODE_STEPS} steps"
    ));
    balanced == EPISODES && enc.success
}

#[cfg(test)]
mod tests {
    use super::*;
    use shipped::policy::POLICY;
    use shipped::policy_int::POLICY_INT;

    #[test]
    fn the_shipped_policy_passes_the_self_test_on_the_host_in_both_formats() {
        for e in 0..EPISODES {
            let int = episode::<[i16; 4], _>(&POLICY_INT, e);
            for o in [episode::<[f32; 4], _>(&POLICY, e), int] {
                assert!(
                    o.success && o.steps == EPISODE_STEPS && o.faults == 0,
                    "{e}: {o:?}"
                );
            }
        }
        assert!(
            encoder_episode::<[i16; 4], _>(&POLICY_INT, 0)
                .unwrap()
                .success
        );
        assert!(encoder_episode::<[f32; 4], _>(&POLICY, 0).unwrap().success);
    }

    /// On the host `forward` is the definition itself, so the check is tried on a kernel
    /// that is the definition and on one that is wrong for half the observations.
    #[test]
    fn the_integer_check_counts_the_observations_a_kernel_gets_wrong() {
        let net = &POLICY_INT;
        assert_eq!(int_check(net, |obs| net.forward_portable(obs)), 0);
        let wrong_for_negative_x = |obs: &[i16; 4]| {
            let q = net.forward_portable(obs);
            if obs[0] < 0 { [q[0], q[1] ^ 1] } else { q }
        };
        let bad = int_check(net, wrong_for_negative_x);
        assert!(bad > INT_CASES / 4 && bad < INT_CASES * 3 / 4, "{bad}");
    }

    #[test]
    fn int_probe_lines_show_every_bit() {
        struct S(heapless::String<128>);
        impl core::fmt::Write for S {
            fn write_str(&mut self, s: &str) -> core::fmt::Result {
                self.0.push_str(s).map_err(|_| core::fmt::Error)
            }
        }
        let mut s = S(heapless::String::new());
        int_probe_line(
            &mut s,
            "probe-int",
            1,
            &[1, -1, 32767, -32768],
            &[-2, 65536],
        )
        .unwrap();
        assert_eq!(
            s.0.as_str(),
            "probe-int 1 0001 ffff 7fff 8000 -> fffffffe 00010000"
        );
    }

    #[test]
    fn probe_lines_show_every_bit() {
        struct S(heapless::String<128>);
        impl core::fmt::Write for S {
            fn write_str(&mut self, s: &str) -> core::fmt::Result {
                self.0.push_str(s).map_err(|_| core::fmt::Error)
            }
        }
        let mut s = S(heapless::String::new());
        probe_line(&mut s, "probe", 3, &[1.0, -0.0, 0.5, 2.0], &[1.5, -2.0]).unwrap();
        assert_eq!(
            s.0.as_str(),
            "probe 3 3f800000 80000000 3f000000 40000000 -> 3fc00000 c0000000"
        );
    }
}
