//! Trains the cart-pole balance controller and hands it to the firmware.
//!
//! - [`config`]: every hyperparameter, the paper and robust presets, validation.
//! - [`nn`]: batched forward, backward, clipping and Adam for the 4-H-H-2 network.
//! - [`reward`]: the learning reward's grammar and terms, and the prices the selection
//!   judges snapshots at.
//! - [`train`]: the Double DQN / DQN loop, replay buffer, learner and evaluation.
//! - [`run`]: the run directory (metrics, summary, policy files).
//! - [`export`]: a network as Rust or C source, float or int8, for its rig.
//! - [`outdir`]: output directories written as a unit, replaced only if provably ours.
//! - [`reproduce`]: the paper's ablations over many seeds, tables and figures.
//!
//! Policy files (safetensors in and out, Rust and C source) are the `weights` crate's;
//! statistics, seeds, CPU kernels and figures are `host_common`'s.
//!
//! `unsafe` is confined to [`nn`]: its entry points call a kernel compiled with
//! `#[target_feature]`, and the AVX-512 build's 4-row blocks (`kernels::avx512`) use
//! intrinsics, each after checking that the CPU has every feature it enables.
#![deny(unsafe_code)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod config;
pub mod export;
#[allow(unsafe_code)]
pub mod nn;
pub mod outdir;
pub mod reproduce;
pub mod reward;
pub mod run;
pub mod train;
