//! `libcartpole_policy.a`: the shipped policy's forward pass for C firmware.
//!
//! Link it and include `capi/include/cartpole_policy.h`:
//!
//! ```sh
//! cargo build --release -p capi --target thumbv7em-none-eabihf
//! # -> target/thumbv7em-none-eabihf/release/libcartpole_policy.a
//! ```
//!
//! The symbol is `firmware::ffi::cartpole_policy_forward`, the very function the Rust
//! firmware binary calls; this crate only packages it (and, on a microcontroller, supplies
//! the panic handler a static library must have; the forward pass cannot panic).
#![cfg_attr(target_os = "none", no_std)]

pub use firmware::ffi::cartpole_policy_forward;

#[cfg(target_os = "none")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    loop {
        core::hint::spin_loop();
    }
}
