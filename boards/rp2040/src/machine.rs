//! The board on its machine: the encoders on PIO state machines, the H-bridge on a
//! direction pin and a PWM enable, and the balance controller (or, with `identify`, the
//! identification experiments) driving it.

use core::sync::atomic::{AtomicI32, Ordering};

use embassy_executor::Spawner;
use embassy_rp::bind_interrupts;
use embassy_rp::gpio::{Level, Output};
use embassy_rp::peripherals::PIO0;
use embassy_rp::pio::{InterruptHandler, Pio};
use embassy_rp::pio_programs::rotary_encoder::{Direction, PioEncoder, PioEncoderProgram};
use embassy_rp::pwm::{self, Pwm};
use firmware::controller::Bridge;
#[cfg(feature = "desk")]
use shipped::desk_int::RIG;
#[cfg(not(feature = "desk"))]
use shipped::policy_int::RIG;

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

/// Both encoders' counts, as the control loop reads them.
fn counts() -> (i32, i32) {
    (
        CART_COUNTS.load(Ordering::Relaxed),
        POLE_COUNTS.load(Ordering::Relaxed),
    )
}

#[embassy_executor::task]
async fn cart_encoder(mut encoder: PioEncoder<'static, PIO0, 0>) -> ! {
    count(&mut encoder, &CART_COUNTS).await
}

#[embassy_executor::task]
async fn pole_encoder(mut encoder: PioEncoder<'static, PIO0, 1>) -> ! {
    count(&mut encoder, &POLE_COUNTS).await
}

/// The board on its machine: its encoders counted, its H-bridge driven by the balance
/// controller (or the identification experiments).
pub async fn on_the_machine(spawner: Spawner, p: embassy_rp::Peripherals) {
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

    let bridge = Bridge::new(direction, enable);
    #[cfg(feature = "identify")]
    crate::identify::run(&RIG, bridge, counts).await;
    #[cfg(not(feature = "identify"))]
    balance(bridge).await;
}

/// The balance controller, period by period, for ever.
#[cfg(not(feature = "identify"))]
async fn balance<A: firmware::controller::Actuator>(bridge: A) {
    use core::cell::Cell;
    use defmt::{info, warn};
    use embassy_time::{Duration, Instant, Ticker};
    use firmware::estimator::ObserverSensor;
    use firmware::rig::Options;
    use firmware::startup::{Sequencer, Startup};

    // The start-up takes the pole's zero where gravity hangs it, then swings the pole up and
    // hands it to the balance controller (`firmware::startup`); centre the cart before
    // power-on. The encoders are read once a period, for the start-up and the observer
    // alike. The observer's gain is solved once, now. The PIO program counts one step per
    // quadrature cycle (four edges), so the rig's counts per revolution is the encoder's line
    // count.
    // The limits are checked as the board is compiled; the observer's gain and the
    // predictor's plant at start-up, where a refusal halts the board (through the panic
    // handler's log) before the bridge is ever driven. The runtime monitor (LQR outside the
    // shipped policy's envelope, a latched stop, the observer watching for a frozen encoder)
    // is configured as the firmware compiles (`shipped::envelope::ASSURANCE`). With `desk`,
    // the gentle desk policy drives the duty between its nine levels where its scores peak
    // (`Refined`, docs/CONTROL.md) through the PWM, without the monitor: no envelope was
    // measured for it.
    let observer = defmt::unwrap!(RIG.observer()).watching();
    let latest = Cell::new((0, 0));
    let sensor = ObserverSensor::<_, [i16; 4]>::new(observer, || latest.get());
    #[cfg(not(feature = "desk"))]
    let (policy, monitor) = (
        &shipped::policy_int::POLICY_INT,
        Some(shipped::envelope::ASSURANCE),
    );
    #[cfg(feature = "desk")]
    let (policy, monitor) = (
        firmware::controller::Refined(firmware::controller::Greedy {
            net: &shipped::desk_int::POLICY_INT,
            levels: shipped::desk_int::LEVELS,
        }),
        None,
    );
    let options = Options {
        predict: true,
        monitor,
    };
    let mut controller = defmt::unwrap!(RIG.controller(policy, sensor, bridge, options));
    let startup = defmt::unwrap!(Startup::suggested(&RIG));
    let mut sequencer = defmt::unwrap!(Sequencer::new(startup, &RIG));
    let period = Duration::from_micros((RIG.params.tau * 1e6) as u64);
    let per_second = (1.0 / RIG.params.tau) as u32;
    info!("cartpole-rp2040: integer policy, {} Hz", per_second);

    let mut ticker = Ticker::every(period);
    loop {
        ticker.next().await;
        let start = Instant::now();
        latest.set(counts());
        let command = sequencer.run(latest.get(), &mut controller);
        let took = start.elapsed();
        if took >= period {
            // Whole periods lost while this step ran.
            let late = (took.as_ticks() / period.as_ticks()) as u32;
            controller.record_overruns(late);
            warn!("step took {} us: {} overrun(s)", took.as_micros(), late);
        }
        if controller.steps().is_multiple_of(per_second) {
            let faults = controller.faults();
            if let Some(r) = controller.last() {
                info!(
                    "step {}: {} {} obs {} q {} mode {} faults {} transitions {} trim {} rad",
                    r.step,
                    sequencer.phase(),
                    command,
                    r.obs,
                    r.q,
                    controller.mode(),
                    faults,
                    sequencer.transitions(),
                    sequencer.trim()
                );
            }
        }
    }
}
