//! `libcartpole_policy.a`: the cart-pole controller for C firmware: the whole control
//! period, or the forward pass alone.
//!
//! Link it and include `capi/include/cartpole_policy.h`:
//!
//! ```sh
//! cargo build --release -p capi --target thumbv7em-none-eabihf
//! # -> target/thumbv7em-none-eabihf/release/libcartpole_policy.a
//! ```
//!
//! A C board runs the same [`Controller::step`](firmware::controller::Controller::step) as
//! every Rust caller, on a `cartpole_controller_t` it allocates (no heap, no global state):
//!
//! 1. once, at start-up: `cartpole_controller_init(&ctl, CARTPOLE_POLICY_INT)` (or `_F32`)
//!    builds the controller from the shipped policy and its exported `RIG`: the observer, the
//!    dead-time predictor when the rig has dead time, the track's limits; and
//!    `cartpole_controller_period_us` gives the rig's control period for the board's timer;
//! 2. each period: read the two encoders' counts, `cartpole_controller_step(&ctl, cart, pole,
//!    &cmd)` (or `cartpole_controller_step_state` with a measured state), and drive the
//!    H-bridge from `cmd`: the direction pin, then the enable's duty out of
//!    `CARTPOLE_DUTY_MAX` (duty off first when the direction changes);
//! 3. now and then: `cartpole_controller_counters`, and `cartpole_controller_record_overruns`
//!    when the timer fired during a step.
//!
//! A policy of one's own, exported by `policy-export export --format c` (`NAME` and
//! `NAME_rig`, the [`CartpoleRig`] it was trained for), runs the same way once
//! `cartpole_controller_init_mlpH(&ctl, &NAME, &NAME_rig)` (or `_qmlpH`, `--quant int8`) has
//! built its controller; a policy of `A > 2` outputs, each driving a duty level, through
//! `cartpole_controller_init_mlp64xA(&ctl, &NAME, NAME_levels, A, &NAME_rig)`, whose steps
//! drive the chosen level (`signed_duty`, a partial duty on the pins).
//!
//! The controller drives the loopback's in-memory pins ([`firmware::loopback::Pins`]), which
//! the step reads back into the command: C drives its bridge from what Rust's `Bridge` would
//! have driven.
//!
//! The forward passes wrap the very functions the Rust firmware runs:
//! `cartpole_policy_forward` (the shipped policy) and `cartpole_mlpS_forward` for every
//! supported shape (`firmware::for_each_shape!`) (any weights, such as a header `policy-export export --format c` wrote),
//! and their integer counterparts. On a microcontroller the crate supplies the panic handler
//! a static library must have (none of its calls can panic).
#![cfg_attr(target_os = "none", no_std)]
#![deny(unsafe_code)]

mod controller;
mod ffi;
mod rig;

pub use controller::*;
pub use ffi::*;
pub use rig::CartpoleRig;

#[cfg(target_os = "none")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    loop {
        core::hint::spin_loop();
    }
}
