//! The board on its machine: the cart's encoder on TIM2 (PA0, PA1: A0, A1), the pole's on
//! TIM3 (PA6, PA7: D12, D11), the H-bridge's direction on PB5 (D4) and its enable on TIM1
//! channel 1 (PA8: D7) at 20 kHz, and the balance controller driving it.

use core::cell::Cell;

use defmt::{info, warn};
use embassy_stm32::Peripherals;
use embassy_stm32::gpio::{Level, Output, OutputType, Speed};
use embassy_stm32::time::khz;
use embassy_stm32::timer::qei::{Config as QeiConfig, Qei};
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::timer::{GeneralInstance4Channel, low_level::CountingMode};
use embassy_time::{Duration, Instant, Ticker};
use firmware::controller::Bridge;
use firmware::estimator::ObserverSensor;
use firmware::rig::Options;
use firmware::startup::{Sequencer, Startup};
#[cfg(feature = "desk")]
use shipped::desk::RIG;
#[cfg(not(feature = "desk"))]
use shipped::policy::RIG;

/// A timer's 16-bit count carried into 32 bits: each period adds what it moved since the
/// last, which a 20 ms period keeps far below half the counter's range.
struct Counter<'d, T: GeneralInstance4Channel> {
    qei: Qei<'d, T>,
    last: u16,
    total: i32,
}

impl<'d, T: GeneralInstance4Channel> Counter<'d, T> {
    fn new(qei: Qei<'d, T>) -> Self {
        let last = qei.count();
        Counter {
            qei,
            last,
            total: 0,
        }
    }

    fn read(&mut self) -> i32 {
        let now = self.qei.count();
        self.total = self
            .total
            .wrapping_add(i32::from(now.wrapping_sub(self.last) as i16));
        self.last = now;
        self.total
    }
}

/// The balance controller, period by period, for ever.
pub async fn balance(p: Peripherals) -> ! {
    let mut cart = Counter::new(Qei::new(p.TIM2, p.PA0, p.PA1, QeiConfig::default()));
    let mut pole = Counter::new(Qei::new(p.TIM3, p.PA6, p.PA7, QeiConfig::default()));
    let direction = Output::new(p.PB5, Level::Low, Speed::Low);
    let enable_pin = PwmPin::new(p.PA8, OutputType::PushPull);
    let pwm = SimplePwm::new(
        p.TIM1,
        Some(enable_pin),
        None,
        None,
        None,
        khz(20),
        CountingMode::EdgeAlignedUp,
    );
    let mut enable = pwm.split().ch1;
    enable.enable();
    let bridge = Bridge::new(direction, enable);

    // The start-up takes the pole's zero where gravity hangs it, then swings the pole up and
    // hands it to the balance controller (`firmware::startup`); centre the cart before
    // power-on. The encoders are read once a period, for the start-up and the observer
    // alike. The observer's gain is solved once, now; a refusal halts the board (through the
    // panic handler's log) before the bridge is ever driven. The runtime monitor (LQR outside the
    // shipped policy's envelope, a latched stop, the observer watching for a frozen encoder)
    // is configured as the firmware compiles (`shipped::envelope::ASSURANCE`). With `desk`,
    // the gentle desk policy drives the duty between its nine levels where its scores peak
    // (`Refined`, docs/CONTROL.md) through the PWM, without the monitor: no envelope was
    // measured for it.
    let latest = Cell::new((0, 0));
    let observer = defmt::unwrap!(RIG.observer()).watching();
    let sensor = ObserverSensor::<_, [f32; 4]>::new(observer, || latest.get());
    #[cfg(not(feature = "desk"))]
    let (policy, monitor) = (&shipped::policy::POLICY, Some(shipped::envelope::ASSURANCE));
    #[cfg(feature = "desk")]
    let (policy, monitor) = (
        firmware::controller::Refined(firmware::controller::Greedy {
            net: &shipped::desk::POLICY,
            levels: shipped::desk::LEVELS,
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
    info!("cartpole-stm32f446: f32 policy, {} Hz", per_second);

    let mut ticker = Ticker::every(period);
    loop {
        ticker.next().await;
        let start = Instant::now();
        latest.set((cart.read(), pole.read()));
        let command = sequencer.run(latest.get(), &mut controller);
        let took = start.elapsed();
        if took >= period {
            // Whole periods lost while this step ran.
            let late = (took.as_ticks() / period.as_ticks()) as u32;
            controller.record_overruns(late);
            warn!("step took {} us: {} overrun(s)", took.as_micros(), late);
        }
        if controller.steps().is_multiple_of(per_second)
            && let Some(r) = controller.last()
        {
            info!(
                "step {}: {} {} obs {} q {} mode {} faults {} transitions {} trim {} rad",
                r.step,
                sequencer.phase(),
                command,
                r.obs,
                r.q,
                controller.mode(),
                controller.faults(),
                sequencer.transitions(),
                sequencer.trim()
            );
        }
    }
}
