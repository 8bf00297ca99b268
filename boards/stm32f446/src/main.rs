//! The cart-pole balance controller on an STM32 Nucleo-F446RE: the shipped policy in f32 on
//! the Cortex-M4F's FPU (`shipped::policy`), two quadrature encoders counted by timers in
//! encoder mode into the encoder observer (`firmware::estimator::ObserverSensor`), an
//! H-bridge driven through embedded-hal 1.0 (`firmware::controller::Bridge` over an
//! `OutputPin` for the direction and a `SetDutyCycle` for the enable), a ticker at the rig's
//! control period and defmt logs. Wiring and flashing: `README.md`.
//!
//! Everything that must agree with the machine comes from `RIG`, the rig the policy was
//! exported with, as on the RP2040 board (`boards/rp2040`).
//!
//! Built with `--features hil`, the board answers a world simulated on the host over the
//! ST-LINK's virtual serial port, its motor never driven ([`hil`]).

#![no_std]
#![no_main]

use embassy_executor::Spawner;
use {defmt_rtt as _, panic_probe as _};

#[cfg(feature = "hil")]
mod hil;
#[cfg(not(feature = "hil"))]
mod machine;

#[embassy_executor::main(
    executor = "embassy_stm32::executor::Executor",
    entry = "cortex_m_rt::entry"
)]
async fn main(spawner: Spawner) {
    let p = embassy_stm32::init(Default::default());
    // Everything runs in this task; nothing is spawned.
    let _ = spawner;
    #[cfg(feature = "hil")]
    hil::run(p).await;
    #[cfg(not(feature = "hil"))]
    machine::balance(p).await;
}
