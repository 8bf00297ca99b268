//! Hardware in the loop (`cargo build --release --features hil`): instead of reading its
//! encoders and driving its motor, the board answers a world simulated on the host over the
//! ST-LINK's virtual serial port (USART2: PA2, PA3) at the link's baud rate, one frame of
//! `docs/LINK.md` a control period. Its controller is the one it balances with
//! (`firmware::link::Target`, in either format), run on this core and timed on its clock;
//! its H-bridge is never driven. `host-sim eval --pil serial:/dev/ttyACM0`.

use defmt::warn;
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::{Peripherals, bind_interrupts, peripherals};
use embassy_time::{Instant, TICK_HZ};
use embedded_io_async::{Read, Write};
use firmware::link::BAUD;

bind_interrupts!(struct Irqs {
    USART2 => usart::BufferedInterruptHandler<peripherals::USART2>;
});

/// Serves the link for ever.
pub async fn run(p: Peripherals) -> ! {
    let (mut tx_buf, mut rx_buf) = ([0u8; 64], [0u8; 64]);
    let mut config = usart::Config::default();
    config.baudrate = BAUD;
    let mut uart = defmt::unwrap!(BufferedUart::new(
        p.USART2,
        p.PA3,
        p.PA2,
        &mut tx_buf,
        &mut rx_buf,
        Irqs,
        config,
    ));
    let mut target = shipped::target(TICK_HZ as u32);
    let mut buf = [0u8; 32];
    loop {
        let n = match uart.read(&mut buf).await {
            Ok(n) => n,
            Err(e) => {
                // A framing or overrun error loses bytes: the frame they belonged to fails
                // its check and is refused, and the host ends the run.
                warn!("hil: {}, {} frames refused", e, target.refused());
                continue;
            }
        };
        for &b in &buf[..n] {
            let arrived = Instant::now();
            if let Some(answer) = target.receive(b, || arrived.elapsed().as_ticks() as u32)
                && let Err(e) = uart.write_all(answer).await
            {
                warn!("hil: {}", e);
            }
        }
    }
}
