//! The board's two experiments run against a simulated machine: the firmware's
//! [`Cart`] and [`Swing`] decide each period from the counts a machine's encoders read, and
//! their rows are written by the firmware's [`Csv`], so a log made here is one a board
//! would stream from that machine. The tests identify machines from such logs, and the
//! example logs in `rigs/` are made this way.

use std::collections::VecDeque;

use firmware::cartpole::{Plant, State};
use firmware::identify::{Cart, Csv, Header, Sink, Step, Swing};
use firmware::rig::Rig;

use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64Mcg;
use twin::machine::{self, Machine};

use crate::identify::held;

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

/// How a machine's encoders read it: where their zero lies, and a vibration or an edge's
/// jitter, a normal deviate of `jitter_counts` (standard deviation, counts) added to each
/// reading before it is rounded to a count.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reading {
    /// Where the counts are zero.
    pub zero: Zero,
    /// The jitter's standard deviation, counts.
    pub jitter_counts: f64,
    /// The jitter's seed.
    pub seed: u64,
}

/// The jitter's stream of [`Reading::seed`] (`host_common::seed`).
const JITTER_STREAM: u64 = 1;

/// A machine's encoders as `board`'s rig reads them.
struct Encoders<'a> {
    board: &'a Rig,
    reading: Reading,
    rng: Pcg64Mcg,
}

impl Encoders<'_> {
    fn new(board: &Rig, reading: Reading) -> Encoders<'_> {
        Encoders {
            board,
            reading,
            rng: host_common::seed::rng(reading.seed, 0, JITTER_STREAM),
        }
    }

    /// The counts read at `s`, the pole's count 0 hanging.
    fn read(&mut self, s: &State) -> (i32, i32) {
        let [cart, pole] = self.board.encoders.per_count();
        let (zero, sd) = (self.reading.zero, self.reading.jitter_counts);
        let mut jitter = || {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            sd * n
        };
        let x = s.x + (zero.cart + jitter()) * cart;
        let theta = s.theta - core::f64::consts::PI + (zero.pole + jitter()) * pole;
        self.board.encoders.counts(x, theta)
    }
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
/// `truth`, whose motor applies each duty after `truth`'s dead time, its encoders read as
/// `reading` says. The pole starts hanging at rest, the cart at rest at the centre.
pub fn cart_log(
    truth: &Machine,
    board: &Rig,
    [periods, hold, seed]: [u32; 3],
    reading: Reading,
) -> String {
    let mut encoders = Encoders::new(board, reading);
    let mut cart = Cart::new(board, periods, hold, seed);
    let mut text = Text::new(&cart.header(board));
    let plant = Plant::new(&truth.rig.params);
    let mut line: VecDeque<f64> = std::iter::repeat_n(0.0, truth.rig.dead_time as usize).collect();
    let mut s = State {
        theta: core::f64::consts::PI,
        ..State::default()
    };
    loop {
        let (c, p) = encoders.read(&s);
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
/// `periods` periods after the release, its encoders read as `reading` says.
pub fn swing_log(
    truth: &Machine,
    board: &Rig,
    raise_deg: f64,
    [rest, lift, periods]: [u32; 3],
    reading: Reading,
) -> String {
    let mut encoders = Encoders::new(board, reading);
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
        let (c, p) = encoders.read(&s);
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

/// How long the cart experiment of [`experiments`] runs, s.
pub const CART_S: f64 = 10.0;
/// How long each bit of its sequence is held, s.
pub const HOLD_S: f64 = 0.04;
/// How long its swing is logged after the release, s.
pub const SWING_S: f64 = 20.0;
/// How far its swing's hand raises the pole, degrees.
pub const RAISE_DEG: f64 = 20.0;

/// One cart and one swing experiment (about 30 s of logs: [`CART_S`] of the sequence,
/// seeded `seed`, and [`SWING_S`] of the swing) as the board running `board` logs them on
/// `truth`.
pub fn experiments(truth: &Machine, board: &Rig, seed: u32, reading: Reading) -> [String; 2] {
    experiments_lasting(truth, board, (seed, reading), [CART_S, SWING_S])
}

/// [`experiments`] of `cart_s` of the sequence and `swing_s` of the swing.
pub fn experiments_lasting(
    truth: &Machine,
    board: &Rig,
    (seed, reading): (u32, Reading),
    [cart_s, swing_s]: [f64; 2],
) -> [String; 2] {
    let tau = board.params.tau;
    let periods = |s: f64| (s / tau).round().max(1.0) as u32;
    [
        cart_log(
            truth,
            board,
            [periods(cart_s), periods(HOLD_S), seed],
            reading,
        ),
        swing_log(
            truth,
            board,
            RAISE_DEG,
            [periods(0.3), periods(0.5), periods(swing_s)],
            reading,
        ),
    ]
}
