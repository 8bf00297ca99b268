//! Trains the cart-pole balance controller and hands it to the firmware.
//!
//! - [`config`]: every hyperparameter, the paper and robust presets, validation.
//! - [`nn`]: batched forward, backward, clipping and Adam for the 4-H-H-2 network.
//! - [`train`]: the Double DQN / DQN loop, replay buffer and evaluation.
//! - [`weights`]: policies as tensors, safetensors in and out, atomic writes.
//! - [`export`]: Rust const-array modules and C headers.
//! - [`run`]: the run directory (metrics, summary, policy files).
//! - [`plot`]: the bundled font and the line charts every figure uses.
//! - [`reproduce`]: the paper's ablations over many seeds, tables and figures.
#![deny(unsafe_code)]

pub mod config;
pub mod export;
#[allow(unsafe_code)]
pub mod nn;
pub mod plot;
pub mod reproduce;
pub mod run;
pub mod train;
pub mod weights;
