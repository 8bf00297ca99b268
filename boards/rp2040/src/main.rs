//! The cart-pole balance controller on a Raspberry Pi Pico: the shipped policy in integers
//! (`shipped::policy_int`, no floating point in the forward pass: the RP2040's Cortex-M0+ has
//! no FPU), two quadrature encoders read by PIO state machines into the encoder observer
//! (`firmware::estimator::ObserverSensor`, handing the controller Q3.12 readings), an
//! H-bridge driven through embedded-hal 1.0 (`firmware::controller::Bridge` over an
//! `OutputPin` for the direction and a `SetDutyCycle` for the enable), a ticker at the rig's
//! control period and defmt logs. Wiring and flashing: `README.md`.
//!
//! Everything that must agree with the machine comes from `RIG`, the rig the policy was
//! exported with: the observer's plant, encoders, dead time and tuning, the dead-time
//! predictor, the track's limits and the control period. A policy trained for your own rig
//! (`policy-export train --rig rig.toml`) and exported carries your machine there.
//!
//! Each period: the encoder counts become `[x, x_dot, theta, theta_dot]` in Q3.12 (the
//! observer, told every command), the controller sanitises them against the track's limits
//! (the cart coasts near the end stops), advances them over the dead time, asks the integer
//! policy, and drives the bridge. A step that outlasts its period is counted as an overrun
//! in the controller's fault counters and logged, never hidden.
//!
//! Built with `--features identify`, the board runs the identification experiments instead
//! and streams their logs ([`identify`]); with `--features hil`, it answers a world
//! simulated on the host over USB, its motor never driven ([`hil`]).

#![no_std]
#![no_main]

use embassy_executor::Spawner;
use {defmt_rtt as _, panic_probe as _};

#[cfg(all(feature = "hil", feature = "identify"))]
compile_error!("`hil` answers a simulated world and `identify` drives the motor: pick one");

#[cfg(feature = "hil")]
mod hil;
#[cfg(feature = "identify")]
mod identify;
#[cfg(not(feature = "hil"))]
mod machine;

#[embassy_executor::main(
    executor = "embassy_rp::executor::Executor",
    entry = "cortex_m_rt::entry"
)]
async fn main(spawner: Spawner) {
    let p = embassy_rp::init(Default::default());
    #[cfg(feature = "hil")]
    {
        // The USB device and the link run in this task; nothing is spawned.
        let _ = spawner;
        hil::run(p.USB).await;
    }
    #[cfg(not(feature = "hil"))]
    machine::on_the_machine(spawner, p).await;
}
