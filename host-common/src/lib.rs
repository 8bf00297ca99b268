//! What the two host tools, the trainer (`policy-export`) and the simulator (`host-sim`),
//! share besides policy files (those are the `weights` crate's):
//!
//! - [`cli`]: command-line parsing whose refusals stay short and exit 2.
//! - [`kernel`]: which build of the vectorised host code runs on this CPU.
//! - [`seed`]: the one mixer that turns a run's seed into independent random streams.
//! - [`stats`]: the one confidence-interval convention of every table the project prints.
//! - [`plot`]: the bundled font and the line charts every figure uses.
//!
//! Neither trainer nor simulator: it knows nothing of networks, plants or controllers.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod cli;
pub mod kernel;
pub mod plot;
pub mod seed;
pub mod stats;
