//! The host side of the closed loop: the firmware's plant and controller run here against a
//! simulated world, and are checked against Gymnasium.
//!
//! - [`replay`]: replays recorded Gymnasium trajectories through `firmware::cartpole` and
//!   reports, per case, how far the states drift (they should not move by a single bit).
#![forbid(unsafe_code)]

pub mod replay;
