//! What the two host tools, the trainer (`policy-export`) and the simulator (`host-sim`),
//! share besides policy files (those are the `weights` crate's):
//!
//! - [`cli`]: command-line parsing whose refusals stay short, quote input escaped and exit 2.
//! - [`kernel`]: which build of the vectorised host code runs on this CPU.
//! - [`wide`]: the firmware's forward pass laid out for host SIMD, bit-identical: how both
//!   tools run a policy one observation at a time.
//! - [`seed`]: the one mixer that turns a run's seed into independent random streams.
//! - [`stats`]: the one confidence-interval convention of every table the project prints.
//! - [`plot`]: the bundled font and the line charts every figure uses.
//! - [`provenance`]: the command, date, revision and machine a results file records.
//!
//! Neither trainer nor simulator: of the networks it knows only how to run the firmware's
//! forward pass fast, of plants and controllers nothing. Its `unsafe` is confined to the
//! vector code ([`wide`] and `dot_x86`): intrinsics' unaligned loads and stores, and calls of
//! `#[target_feature]` functions after checking the CPU.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod cli;
#[cfg(target_arch = "x86_64")]
pub mod dot_x86;
pub mod kernel;
pub mod plot;
pub mod provenance;
pub mod seed;
pub mod stats;
pub mod wide;
