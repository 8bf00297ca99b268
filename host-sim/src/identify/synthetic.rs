//! The board's two experiments run against a simulated machine: the firmware's
//! [`Cart`] and [`Swing`] decide each period from the counts a machine's encoders read, and
//! their rows are written by the firmware's [`Csv`], so a log made here is one a board
//! would stream from that machine. The tests identify machines from such logs, and the
//! example logs in `rigs/` are made this way.

use std::collections::VecDeque;

use firmware::cartpole::{Plant, State};
use firmware::identify::{Cart, Csv, Header, Sink, Step, Swing};
use firmware::rig::Rig;

use crate::identify::held;
use twin::machine::{self, Machine};

/// Where a machine's encoders read their zero: the true cart position and pole angle (from
/// hanging) at count 0's lower edge, anywhere within a count of the start as on a real
/// board, which zeroes its counters wherever they stand at power-on.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Zero {
    /// Fraction of a cart count the start lies above the count's edge, 0 to 1.
    pub cart: f64,
    /// Fraction of a pole count the hanging pole lies above the count's edge, 0 to 1.
    pub pole: f64,
}

/// The counts `rig`'s encoders read at `s` with zero `zero`, the pole's count 0 hanging.
fn counts(rig: &Rig, zero: Zero, s: &State) -> (i32, i32) {
    let [cart, pole] = rig.encoders.per_count();
    rig.encoders.counts(
        s.x + zero.cart * cart,
        s.theta - core::f64::consts::PI + zero.pole * pole,
    )
}

/// A log's text: the header, then the rows.
struct Text(Csv<String>);

impl Text {
    fn new(header: &Header) -> Text {
        let mut csv = Csv(String::new());
        // Writing to a String cannot fail.
        let _ = csv.header(header);
        Text(csv)
    }

    fn record(&mut self, row: &firmware::identify::Row) {
        let _ = self.0.record(row);
    }
}

/// The cart experiment of `periods` periods (bits held `hold` periods, seeded `seed`) as the
/// board running `board` (its track, encoders and assumed dead time) logs it on the machine
/// `truth`, whose motor applies each duty after `truth`'s dead time. The pole starts hanging
/// at rest, the cart at rest at the centre.
pub fn cart_log(
    truth: &Machine,
    board: &Rig,
    periods: u32,
    hold: u32,
    seed: u32,
    zero: Zero,
) -> String {
    let mut cart = Cart::new(board, periods, hold, seed);
    let mut text = Text::new(&cart.header(board));
    let plant = Plant::new(&truth.rig.params);
    let mut line: VecDeque<f64> = std::iter::repeat_n(0.0, truth.rig.dead_time as usize).collect();
    let mut s = State {
        theta: core::f64::consts::PI,
        ..State::default()
    };
    loop {
        let (c, p) = counts(board, zero, &s);
        let Step::Log(row) = cart.step(c, p) else {
            return text.0.0;
        };
        text.record(&row);
        line.push_back(f64::from(row.duty));
        let acting = line.pop_front().unwrap_or(0.0);
        s = machine::advance(&plant, truth.integration, &s, acting, 0.0);
    }
}

/// The swing experiment as the board running `board` logs it on the machine `truth`, its
/// cart held: the pole hangs for `rest` periods, a hand raises it to `raise_deg` off
/// hanging over `lift` periods and holds it for `rest` more, then lets go; the board logs
/// `periods` periods after the release.
pub fn swing_log(
    truth: &Machine,
    board: &Rig,
    raise_deg: f64,
    [rest, lift]: [u32; 2],
    periods: u32,
    zero: Zero,
) -> String {
    let mut swing = Swing::new(board.encoders, periods);
    let mut text = Text::new(&swing.header(board));
    let plant = Plant::new(&held(&truth.rig.params));
    let top = raise_deg.to_radians();
    let hand = |k: u32| {
        let lifted = f64::from(k.saturating_sub(rest)) / f64::from(lift.max(1));
        top * (0.5 - 0.5 * (core::f64::consts::PI * lifted.min(1.0)).cos())
    };
    let mut s = State::default();
    for k in 0.. {
        if k < 2 * rest + lift {
            s = State {
                theta: core::f64::consts::PI + hand(k),
                ..State::default()
            };
        }
        let (c, p) = counts(board, zero, &s);
        match swing.step(c, p) {
            Step::Done => break,
            Step::Log(row) => text.record(&row),
            Step::Wait => {}
        }
        if k + 1 >= 2 * rest + lift {
            s = machine::advance(&plant, truth.integration, &s, 0.0, 0.0);
        }
    }
    text.0.0
}
