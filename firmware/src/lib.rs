//! Everything that must run on the microcontroller, and nothing that needs an allocator.
//!
//! - [`cartpole`]: the plant, Gymnasium's `CartPole-v1` dynamics in f64, step for step.
//! - [`network`]: the 4-H-H-2 ReLU Q-network and its one forward pass.
//!
//! The crate is `no_std`, links neither `std` nor `alloc`, and has no `unsafe`. Host crates
//! (`policy-export`, `host-sim`) build on it; it depends on none of them.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod cartpole;
pub mod network;

pub use cartpole::Action;
