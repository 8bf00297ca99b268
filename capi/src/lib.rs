//! `libcartpole_policy.a`: the cart-pole controller's forward pass for C firmware.
//!
//! Link it and include `capi/include/cartpole_policy.h`:
//!
//! ```sh
//! cargo build --release -p capi --target thumbv7em-none-eabihf
//! # -> target/thumbv7em-none-eabihf/release/libcartpole_policy.a
//! ```
//!
//! The symbols wrap the very functions the Rust firmware runs: `cartpole_policy_forward`
//! (the shipped policy) and `cartpole_mlpH_forward` for every supported width (any weights,
//! such as a header `policy-export export --format c` wrote), and their integer
//! counterparts. On a microcontroller the crate supplies the panic handler a static library
//! must have (the forward passes cannot panic).
#![cfg_attr(target_os = "none", no_std)]
#![deny(unsafe_code)]

mod ffi;

pub use ffi::*;

#[cfg(target_os = "none")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    loop {
        core::hint::spin_loop();
    }
}
