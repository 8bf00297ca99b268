//! The digital twin: the world around the controller, shared by the simulator that judges a
//! policy and the trainer that learns it, so both see the same world.
//!
//! - [`machine`]: the machine a world simulates (a rig and how its world advances: Euler, or
//!   continuous time by Runge-Kutta).
//! - [`rigfile`]: rig files (`rig.toml`), read and written.
//! - [`grammar`]: the one grammar and table of parts of scenarios and domains.
//! - [`scenario`]: one world as a spec (`noise+delay=2`, `length=0.8+encoder=1024`): the
//!   rig the board knows, the true physics and friction, sensor noise, encoders with the
//!   firmware's estimator, actuator dead time, pushes; the named sets the tables use.
//! - [`faults`]: what goes wrong in a real loop (encoder glitches, stuck and dropped
//!   readings, overruns, a weak motor, controller resets), as scenario parts.
//! - [`startup`]: episodes from power-on: the pole hanging or lifted, the board's start-up
//!   taking it to balance.
//! - [`world`]: one episode of a scenario's plant, period by period: the measurement, then
//!   the actuator.
//! - [`run`]: the unchanged firmware controller against a world, through pins and the
//!   firmware's sensors, with per-episode statistics and seeded streams.
//! - [`lockstep`]: episodes run to their end, one or side by side, their worlds integrated
//!   together.
//! - [`calibrate`]: the observations a policy visits, to quantise it on.
//! - [`domain`]: distributions over scenarios for domain-randomised training.
//!
//! The plant and the estimator are the firmware's; this crate adds only what surrounds them.
//! It is not an evaluator (the simulator's `eval` is) and not a learner.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod calibrate;
pub mod domain;
pub mod faults;
pub mod grammar;
pub mod lockstep;
pub mod machine;
pub mod rigfile;
pub mod run;
pub mod scenario;
pub mod startup;
pub mod world;

pub use domain::Domain;
pub use lockstep::{run_episode, run_episodes};
pub use machine::{Integration, Machine};
pub use run::{Episode, EpisodeStats, Frame};
pub use scenario::{Push, Scenario};
pub use world::World;
