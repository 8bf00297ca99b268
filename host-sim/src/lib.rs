//! The host side of the closed loop: the firmware's plant and controller run here against a
//! simulated world, and are checked against Gymnasium.
//!
//! - [`replay`]: replays recorded Gymnasium trajectories through `firmware::cartpole` and
//!   reports, per case, how far the states drift (they should not move by a single bit).
//! - [`agree`]: how often the integer network acts as the float one, and where they part.
//! - [`baselines`]: discrete LQR from the Riccati equation, the angle rule, random.
//! - [`envelope`]: where a policy drives in the episodes it balances: the runtime
//!   monitor's envelope.
//! - [`eval`]: many seeded episodes per controller and scenario, statistics with 95% CIs.
//! - [`manifest`]: how every generated and results file is made, in order.
//! - [`moved`]: which rows of a results file moved beyond their intervals when measured again.
//! - [`pil`]: processor-in-the-loop, the board's controller on a target driven over the
//!   link, compared period by period with the same code run here.
//! - [`render`]: an animated GIF and a time-series PNG of one episode.
//! - [`tables`]: the documents' results tables and figures, and each results file's page,
//!   rendered from the results files.
//!
//! Policies run through `host_common::wide`, the firmware's forward pass laid out for host
//! SIMD, bit-identical.

#![forbid(unsafe_code)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod agree;
pub mod baselines;
pub mod batch;
pub mod envelope;
pub mod eval;
pub mod identify;
pub mod manifest;
pub mod moved;
pub mod pil;
pub mod render;
pub mod replay;
pub mod tables;
