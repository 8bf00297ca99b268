//! The cart-pole balance controller on a Raspberry Pi Pico: the shipped policy in integers
//! (`firmware::policy_int`, no floating point in the forward pass: the RP2040's Cortex-M0+ has
//! no FPU), two quadrature encoders read by PIO state machines into the encoder observer
//! (`firmware::estimator::Observer`), an
//! H-bridge driven through embedded-hal 1.0 (`OutputPin` for the direction, `SetDutyCycle`
//! for the enable), a 50 Hz ticker and defmt logs. Wiring and flashing: `README.md`.
//!
//! Each period: the encoder counts and the last command become `[x, x_dot, theta,
//! theta_dot]` (the observer), the
//! controller sanitises them against the track's limits (the cart coasts near the end stops),
//! asks the integer policy, and drives the bridge. A step that outlasts its period is counted
//! as an overrun in the controller's fault counters and logged, never hidden.

#![no_std]
#![no_main]

use core::convert::Infallible;
use core::sync::atomic::{AtomicI32, Ordering};

use defmt::{info, warn};
use embassy_executor::Spawner;
use embassy_rp::bind_interrupts;
use embassy_rp::gpio::{Level, Output};
use embassy_rp::peripherals::PIO0;
use embassy_rp::pio::{InterruptHandler, Pio};
use embassy_rp::pio_programs::rotary_encoder::{Direction, PioEncoder, PioEncoderProgram};
use embassy_rp::pwm::{self, Pwm};
use embassy_time::{Duration, Instant, Ticker};
use firmware::cartpole::Params;
use firmware::controller::{CONTROL_PERIOD_S, Command, Controller, Limits, StateSensor};
use firmware::estimator::{Encoders, Observer, Tuning};
use firmware::policy_int::POLICY_INT;
use {defmt_rtt as _, panic_probe as _};

/// The rig. The PIO program below counts one step per quadrature cycle (four edges), so a
/// counts-per-revolution figure is the encoder's line count.
const ENCODERS: Encoders = Encoders {
    // A 600-line encoder on a 12 mm GT2 pulley (20 teeth x 2 mm = 40 mm per turn).
    cart_counts_per_m: 15_000,
    // A 2,400-line encoder on the pivot: in the twin the integer policy balances 1,000 of
    // 1,000 200 s episodes through these encoders and the observer (README).
    pole_counts_per_rev: 2_400,
};
/// Half the usable track, centre to end stop, and the margin in which the cart coasts.
const TRACK_HALF_LENGTH_M: f32 = 0.40;
const END_STOP_MARGIN_M: f32 = 0.05;
/// PWM: 125 MHz / 6,250 = 20 kHz, above hearing; full duty is the full push.
const PWM_TOP: u16 = 6_249;

bind_interrupts!(struct Irqs {
    PIO0_IRQ_0 => InterruptHandler<PIO0>;
});

/// Encoder counts, written only by their encoder's task and read by the control loop. Load
/// and store, no read-modify-write: the Cortex-M0+ has no atomic one, and there is one writer.
static CART_COUNTS: AtomicI32 = AtomicI32::new(0);
static POLE_COUNTS: AtomicI32 = AtomicI32::new(0);

async fn count<const SM: usize>(
    encoder: &mut PioEncoder<'static, PIO0, SM>,
    counts: &AtomicI32,
) -> ! {
    loop {
        let step = match encoder.read().await {
            Direction::Clockwise => 1,
            Direction::CounterClockwise => -1,
        };
        counts.store(
            counts.load(Ordering::Relaxed).wrapping_add(step),
            Ordering::Relaxed,
        );
    }
}

#[embassy_executor::task]
async fn cart_encoder(mut encoder: PioEncoder<'static, PIO0, 0>) -> ! {
    count(&mut encoder, &CART_COUNTS).await
}

#[embassy_executor::task]
async fn pole_encoder(mut encoder: PioEncoder<'static, PIO0, 1>) -> ! {
    count(&mut encoder, &POLE_COUNTS).await
}

/// The observer over the two counters, told each command the controller sends: what the
/// controller reads each period.
struct EncoderSensor {
    observer: Observer,
}

impl StateSensor for EncoderSensor {
    type Error = Infallible;
    fn read(&mut self) -> Result<[f32; 4], Infallible> {
        Ok(self.observer.update(
            CART_COUNTS.load(Ordering::Relaxed),
            POLE_COUNTS.load(Ordering::Relaxed),
        ))
    }

    fn commanded(&mut self, command: Command) {
        self.observer.command(command.level());
    }
}

#[embassy_executor::main(
    executor = "embassy_rp::executor::Executor",
    entry = "cortex_m_rt::entry"
)]
async fn main(spawner: Spawner) {
    let p = embassy_rp::init(Default::default());

    // Encoders: cart on GP2/GP3, pole on GP4/GP5 (A/B; swap a pair to flip its sign).
    let Pio {
        mut common,
        sm0,
        sm1,
        ..
    } = Pio::new(p.PIO0, Irqs);
    let program = PioEncoderProgram::new(&mut common);
    let cart = PioEncoder::new(&mut common, sm0, p.PIN_2, p.PIN_3, &program);
    let pole = PioEncoder::new(&mut common, sm1, p.PIN_4, p.PIN_5, &program);
    spawner.spawn(cart_encoder(cart).unwrap());
    spawner.spawn(pole_encoder(pole).unwrap());

    // H-bridge: direction on GP14 (high pushes towards +x), enable PWM on GP15 (slice 7 B).
    let direction = Output::new(p.PIN_14, Level::Low);
    let mut config = pwm::Config::default();
    config.top = PWM_TOP;
    config.compare_b = 0;
    let enable = Pwm::new_output_b(p.PWM_SLICE7, p.PIN_15, config);

    // The pole's zero is where it is at power-on: hold it upright until the first log line.
    // The observer models the rig as the plant the policy was trained on (Gymnasium's
    // cart-pole); put the rig's own masses, pole length and motor force here. Its gain is
    // solved once, now.
    let sensor = EncoderSensor {
        observer: Observer::new(ENCODERS, &Params::default(), Tuning::DEFAULT, 0),
    };
    let limits = Limits::track(TRACK_HALF_LENGTH_M, END_STOP_MARGIN_M);
    let mut controller: Controller<_, _, _, _, 8> =
        Controller::new(&POLICY_INT, sensor, direction, enable, limits);
    info!(
        "cartpole-rp2040: integer policy, {} Hz",
        1.0 / CONTROL_PERIOD_S
    );

    let period = Duration::from_micros((CONTROL_PERIOD_S * 1e6) as u64);
    let mut ticker = Ticker::every(period);
    loop {
        ticker.next().await;
        let start = Instant::now();
        let command = controller.step();
        let took = start.elapsed();
        if took >= period {
            // Whole periods lost while this step ran.
            let late = (took.as_ticks() / period.as_ticks()) as u32;
            controller.record_overruns(late);
            warn!("step took {} us: {} overrun(s)", took.as_micros(), late);
        }
        if controller.steps() % 50 == 0 {
            let faults = controller.faults();
            if let Some(r) = controller.last() {
                info!(
                    "step {}: {} obs {} q {} faults {}",
                    r.step, command, r.obs, r.q, faults
                );
            }
        }
    }
}
