//! The shipped balance policy: the constants a board compiles beside `firmware`.
//!
//! - [`policy`]: the 4-64-64-2 network (`POLICY`), its duty levels and the rig it was
//!   trained for (`RIG`), written by `policy-export export`.
//! - [`policy_int`]: the same policy in integers (`POLICY_INT`, `firmware::network::int`)
//!   and its `RIG`, for cores without an FPU, written by `policy-export export --quant int8`.
//! - [`desk`], [`desk_int`]: the gentle nine-level policy trained for the identified desk
//!   rig (`docs/RIGS.md`), f32 and int8, each with its `LEVELS` and `RIG`: what a policy with
//!   duty levels costs a core (the self-test counts its forward passes).
//! - [`envelope`]: where the runtime monitor lets the policy drive (`ENVELOPE`) and the
//!   monitor's configuration on its rig (`ASSURANCE`), written by `host-sim envelope`.
//! - [`target`], [`desk_target`]: each policy behind the link (`firmware::link::Target`),
//!   as a board's hardware-in-the-loop build, the `pil` applications and the host's
//!   reference hold it.
//!
//! Every module but this one is generated, by the commands of `docs/results/manifest.toml`
//! (steps `policy-rs`, `policy-safetensors`, `policy-int-rs`, `envelope-rs`, and for the desk
//! policy `rig-desk-rs` and `rig-desk-int-rs` after `rig-desk-train`), which
//! `scripts/regenerate.sh` runs: `--only train --only 'policy-*' --only envelope-rs` trains
//! the policy again and writes them, and `policy.safetensors` beside this crate's manifest
//! (the weights the int8 export and the tests read). The crate is `no_std`, allocates
//! nothing and depends on `firmware` alone; a board depends on both.
#![no_std]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod desk;
pub mod desk_int;
pub mod envelope;
pub mod policy;
pub mod policy_int;

use firmware::link::Target;

// The shipped policies' machines, checked as the crate is compiled.
const _: () = assert!(policy::RIG.check().is_ok());
const _: () = assert!(policy_int::RIG.check().is_ok());
const _: () = assert!(desk::RIG.check().is_ok());
const _: () = assert!(desk_int::RIG.check().is_ok());

/// The shipped policy behind the link: both formats, its two levels, its rig and its
/// envelope, each period timed on a clock of `clock_hz` ticks a second.
pub fn target(clock_hz: u32) -> Target<'static, 64> {
    let nets = (&policy::POLICY, &policy_int::POLICY_INT);
    let envelope = Some(envelope::ENVELOPE);
    Target::new(
        nets.0,
        nets.1,
        policy::LEVELS,
        policy::RIG,
        envelope,
        clock_hz,
    )
}

/// The desk policy behind the link: both formats, its nine levels and the desk rig, and no
/// envelope (none was measured for it: a Start that asks for the runtime monitor is
/// refused), each period timed on a clock of `clock_hz` ticks a second.
pub fn desk_target(clock_hz: u32) -> Target<'static, 64, 9> {
    let nets = (&desk::POLICY, &desk_int::POLICY_INT);
    Target::new(nets.0, nets.1, desk::LEVELS, desk::RIG, None, clock_hz)
}
