//! Everything that must run on the microcontroller, and nothing that needs an allocator.
//!
//! This is the crate a board depends on: a `no_std` library without a runtime, a
//! critical-section implementation, a memory map or a panic handler, so it sits beside any
//! board's HAL. The QEMU self-test application is a crate of its own (`selftest-app`).
//!
//! - [`cartpole`]: the plant, Gymnasium's `CartPole-v1` dynamics in f64, step for step; its
//!   equations once, generic over f32 and f64, with a DC motor and friction.
//! - [`rig`]: the machine a board runs on, given once: physics, encoders, dead time, track.
//! - [`network`]: the 4-H-H-2 ReLU Q-network, its one forward pass and its shape; [`network::int`]
//!   its integer-only counterpart.
//! - [`fixed`]: the integer pipeline's fixed-point format, Q3.12.
//! - [`estimator`]: encoder counts to `[x, x_dot, theta, theta_dot]`: the model-based
//!   [`estimator::Observer`], an integer alpha-beta filter that needs no model, and the
//!   sensors that put them behind a controller.
//! - [`linear`]: the plant linearised about upright; LQR and Kalman gains designed on it.
//! - [`controller`]: one control period: sensor, sanitise, predict, policy, actuator.
//! - [`link`]: the framed, checked link to a host's simulated world, for processor- and
//!   hardware-in-the-loop runs.
//! - [`config`]: [`ConfigError`], why a checked constructor refused a configuration.
//! - [`identify`]: the board's identification experiments (a PRBS on the cart, a free swing
//!   of the pole) and their log.
//! - [`loopback`]: cells in place of sensor and pins, to close the loop against the plant.
//!
//! The shipped policy, its rig and its envelope are generated constants in a crate of their
//! own, `shipped`, which depends on this one; this crate holds no generated file.
//!
//! The crate links neither `std` nor `alloc`. Its `unsafe` is confined to the hand-written
//! dot products for Arm cores (`network::vfp` on hard-float cores, the integer kernels in
//! `network::int`), which the self-test checks against the portable ones on the device. The
//! C ABI is the `capi` crate's; the self-test is the `selftest-app` crate's. With the `defmt`
//! feature, the telemetry types implement `defmt::Format`; with `rand`, the plant draws
//! random starts.
#![no_std]
#![deny(unsafe_code)]
#![warn(missing_docs)]

// The unit tests run the shipped policy: the `shipped` crate's generated modules, compiled
// here as `crate::shipped` (a test cannot link `shipped`, whose `firmware` is not the test
// build's), name this crate `::firmware` as any crate depending on it does.
#[cfg(test)]
extern crate self as firmware;
#[cfg(test)]
#[path = "../../shipped/src"]
#[allow(dead_code)] // The modules whole, as the crate has them; not every test reads each constant.
mod shipped {
    pub mod desk;
    pub mod desk_int;
    pub mod envelope;
    pub mod policy;
    pub mod policy_int;
}

pub mod cartpole;
pub mod config;
pub mod controller;
pub mod estimator;
pub mod fixed;
pub mod identify;
pub mod linear;
pub mod link;
pub mod loopback;
pub mod network;
pub mod rig;
pub mod startup;

pub use cartpole::Action;
pub use config::ConfigError;

/// Calls `$m!` with every network shape the trainer, the simulator and the C API are built
/// for, as `width x outputs`, each beside the names of its C entry points: the float and the
/// integer forward pass, then the float and the integer controller's init. The paper's two
/// outputs at three widths, and the duty levels of a gentler policy at the shipped width. The
/// project's one list of shapes ([`network::SUPPORTED_SHAPES`], [`network::SUPPORTED_WIDTHS`]).
///
/// ```
/// macro_rules! count {
///     ($($h:literal x $a:literal => $($c:ident)/+,)*) => { [$($h),*].len() };
/// }
/// assert_eq!(firmware::for_each_shape!(count), firmware::network::SUPPORTED_SHAPES.len());
/// ```
#[macro_export]
macro_rules! for_each_shape {
    ($m:ident) => {
        $m! {
            16 x 2 => cartpole_mlp16_forward / cartpole_qmlp16_forward
                / cartpole_controller_init_mlp16 / cartpole_controller_init_qmlp16,
            64 x 2 => cartpole_mlp64_forward / cartpole_qmlp64_forward
                / cartpole_controller_init_mlp64 / cartpole_controller_init_qmlp64,
            128 x 2 => cartpole_mlp128_forward / cartpole_qmlp128_forward
                / cartpole_controller_init_mlp128 / cartpole_controller_init_qmlp128,
            64 x 3 => cartpole_mlp64x3_forward / cartpole_qmlp64x3_forward
                / cartpole_controller_init_mlp64x3 / cartpole_controller_init_qmlp64x3,
            64 x 5 => cartpole_mlp64x5_forward / cartpole_qmlp64x5_forward
                / cartpole_controller_init_mlp64x5 / cartpole_controller_init_qmlp64x5,
            64 x 7 => cartpole_mlp64x7_forward / cartpole_qmlp64x7_forward
                / cartpole_controller_init_mlp64x7 / cartpole_controller_init_qmlp64x7,
            64 x 9 => cartpole_mlp64x9_forward / cartpole_qmlp64x9_forward
                / cartpole_controller_init_mlp64x9 / cartpole_controller_init_qmlp64x9,
        }
    };
}
