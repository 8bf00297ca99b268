//! Hardware in the loop (`cargo build --release --features hil`): instead of reading its
//! encoders and driving its motor, the board answers a world simulated on the host, over
//! USB CDC-ACM, one frame of `docs/LINK.md` a control period. Its controller is the one it
//! balances with (`firmware::link::Target`: the observer, predictor, limits and policy of
//! `RIG`, in either format), run on this core, timed on its clock; its H-bridge is never
//! driven. `host-sim eval --pil serial:/dev/ttyACM0` runs `eval`'s rows through it and
//! compares every answer with the same code run on the host.

use defmt::{info, warn};
use embassy_futures::join::join;
use embassy_rp::Peri;
use embassy_rp::peripherals::USB;
use embassy_rp::usb::{Driver, InterruptHandler};
use embassy_time::{Instant, TICK_HZ};
use embassy_usb::class::cdc_acm::{CdcAcmClass, State};
use embassy_usb::driver::EndpointError;
use embassy_usb::{Builder, Config};
use firmware::link::MAX_FRAME;

embassy_rp::bind_interrupts!(struct Irqs {
    USBCTRL_IRQ => InterruptHandler<USB>;
});

/// A full-speed bulk packet; every frame (`MAX_FRAME` bytes) fits one.
const PACKET: u16 = 64;
const _: () = assert!(MAX_FRAME < PACKET as usize);

/// Serves the link on USB for ever, a session per connection.
pub async fn run(usb: Peri<'static, USB>) -> ! {
    let mut config = Config::new(0x1209, 0x0001);
    config.manufacturer = Some("cartpole-ddqn");
    config.product = Some("cart-pole controller, hardware in the loop");
    config.max_packet_size_0 = 64;
    let (mut config_descriptor, mut bos, mut control) = ([0; 256], [0; 256], [0; 64]);
    let mut state = State::new();
    let mut builder = Builder::new(
        Driver::new(usb, Irqs),
        config,
        &mut config_descriptor,
        &mut bos,
        &mut [],
        &mut control,
    );
    let mut class = CdcAcmClass::new(&mut builder, &mut state, PACKET);
    let mut device = builder.build();
    let link = async {
        loop {
            class.wait_connection().await;
            info!("hil: host connected");
            let e = serve(&mut class).await;
            warn!("hil: link ended: {}", e);
        }
    };
    join(device.run(), link).await;
    unreachable!("the USB device and the link run for ever")
}

/// One connection: every frame answered, each period timed from its frame's last byte.
async fn serve<'d>(class: &mut CdcAcmClass<'d, Driver<'d, USB>>) -> EndpointError {
    let mut target = shipped::target(TICK_HZ as u32);
    let mut buf = [0u8; PACKET as usize];
    loop {
        let n = match class.read_packet(&mut buf).await {
            Ok(n) => n,
            Err(e) => {
                warn!("hil: {} frames refused", target.refused());
                return e;
            }
        };
        for &b in &buf[..n] {
            let arrived = Instant::now();
            if let Some(answer) = target.receive(b, || arrived.elapsed().as_ticks() as u32)
                && let Err(e) = class.write_packet(answer).await
            {
                return e;
            }
        }
    }
}
