//! The identification mode (`cargo run --release --features identify`): instead of
//! balancing, the board runs `firmware::identify`'s two experiments on `RIG`'s machine and
//! streams their logs over defmt, one message a line, in the text `host-sim identify`
//! reads. First the cart experiment, the pole hanging as it was at power-on; then the
//! swing: hold the cart still, raise the pole about 20 degrees off hanging and let go. The
//! stream ends with the swing's last row, the motor off.

use core::fmt::{self, Write};

use defmt::warn;
use embassy_time::{Duration, Ticker};
use firmware::cartpole::Action;
use firmware::controller::{Actuator, Command};
use firmware::identify::{Cart, Csv, Sink, Step, Swing};
use firmware::rig::Rig;

/// How long the cart experiment runs, s.
const CART_S: f64 = 10.0;
/// How long each bit of its sequence is held, s.
const HOLD_S: f64 = 0.04;
/// The sequence's seed.
const SEED: u32 = 1;
/// How long the swing is logged after the release, s.
const SWING_S: f64 = 20.0;
/// The longest line written: a row is four numbers.
const LINE_MAX: usize = 192;

/// Text written through it goes out as one defmt message a line; a line longer than
/// [`LINE_MAX`] is refused whole rather than cut.
struct Lines {
    buf: [u8; LINE_MAX],
    len: usize,
}

impl Write for Lines {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for b in s.bytes() {
            if b == b'\n' {
                // Only whole characters are written, so the bytes are UTF-8.
                let line = core::str::from_utf8(&self.buf[..self.len]).unwrap_or("");
                defmt::println!("{=str}", line);
                self.len = 0;
            } else if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = b;
                self.len += 1;
            } else {
                self.len = 0;
                return Err(fmt::Error);
            }
        }
        Ok(())
    }
}

fn drive<A: Actuator>(actuator: &mut A, duty: i8) {
    let command = match duty {
        1 => Command::Drive(Duty::RIGHT),
        -1 => Command::Drive(Duty::LEFT),
        _ => Command::Coast,
    };
    if actuator.drive(command).is_err() {
        warn!("the bridge refused a command");
    }
}

/// One experiment's periods: each period's counts to `step`, its duty to the motor at once,
/// then its row to the log.
async fn experiment<A: Actuator>(
    actuator: &mut A,
    counts: fn() -> (i32, i32),
    ticker: &mut Ticker,
    csv: &mut Csv<Lines>,
    mut step: impl FnMut(i32, i32) -> Step,
) {
    loop {
        ticker.next().await;
        let (cart, pole) = counts();
        match step(cart, pole) {
            Step::Wait => drive(actuator, 0),
            Step::Log(row) => {
                drive(actuator, row.duty);
                if csv.record(&row).is_err() {
                    warn!("a log line too long for the buffer");
                }
            }
            Step::Done => break,
        }
    }
    drive(actuator, 0);
}

/// Runs both experiments on `rig` at its period, reading `counts` and driving `actuator`.
pub async fn run<A: Actuator>(rig: &Rig, mut actuator: A, counts: fn() -> (i32, i32)) {
    let tau = rig.params.tau;
    let periods = |s: f64| ((s / tau) as u32).max(1);
    let mut ticker = Ticker::every(Duration::from_micros((tau * 1e6) as u64));
    let mut csv = Csv(Lines {
        buf: [0; LINE_MAX],
        len: 0,
    });
    let mut cart = Cart::new(rig, periods(CART_S), periods(HOLD_S), SEED);
    // The instructions as comment lines, which the log's reader passes over.
    let _ = writeln!(
        csv.0,
        "# cartpole-rp2040 identification mode: the pole hanging, hands off"
    );
    let _ = csv.header(&cart.header(rig));
    experiment(&mut actuator, counts, &mut ticker, &mut csv, |c, p| {
        cart.step(c, p)
    })
    .await;
    let mut swing = Swing::new(rig.encoders, periods(SWING_S));
    let _ = writeln!(
        csv.0,
        "# hold the cart still, raise the pole about 20 degrees off hanging and let go"
    );
    let _ = csv.header(&swing.header(rig));
    experiment(&mut actuator, counts, &mut ticker, &mut csv, |c, p| {
        swing.step(c, p)
    })
    .await;
}
