//! The board's side of identifying what a scale and a ruler cannot measure (the motor's stall
//! force and damping, friction, the dead time, the pole's effective length): two
//! experiments, run period by period from encoder counts, each logged as text that
//! `host-sim identify` fits a rig to.
//!
//! - [`Cart`]: the pole hanging down, the cart driven by a pseudo-random binary sequence
//!   ([`Prbs`]) of full-duty pushes, kept on the track by a safety rule: once the point where
//!   the cart would stop is past [`Cart::OUTER`] of the usable track
//!   (`x_threshold - end_stop_margin`), the command points back to the centre (braking the
//!   cart first if it moves away from it) until the cart itself is inside [`Cart::INNER`]
//!   of it. The stopping point is the cart's position, looked ahead by its last count
//!   difference over the dead time, the period a command waits for and two more (a rig
//!   file's dead time may be short), plus its braking distance at a quarter of the largest
//!   change of count difference seen so far: the motor's full push as the cart itself shows
//!   it, whatever the rig file guessed (a stronger motor or a lighter cart reaches a higher
//!   speed but brakes as hard), taken at a quarter for the swinging pole's pull on the
//!   cart. The sequence runs on underneath, so its timing never depends on the track.
//! - [`Swing`]: no motor (duty 0), the cart held still by hand or a brake, the pole raised to
//!   about 20 degrees off hanging and let go. Logging starts once the pole is raised past
//!   [`Swing::RAISE_DEG`] and runs until the given number of periods after the release (the
//!   pole falling back by a degree from the highest point it was held at).
//!
//! Each period the board reads its counts, passes them to `step`, drives the duty of the
//! [`Step::Log`] it gets and hands the [`Row`] to a [`Sink`]: [`Csv`] writes the log's text
//! through any [`core::fmt::Write`] (a line buffer sent over defmt, a UART, a `String`).
//!
//! # The log
//!
//! ```text
//! # cart-pole identification log
//! # experiment: cart
//! # period_s: 0.02
//! # cart_counts_per_m: 15000
//! # pole_counts_per_rev: 2400
//! # pole_zero: hanging
//! # prbs: degree 8, hold 2 periods, seed 1; back to the centre once the cart would stop past 0.5 of the usable track (0.35 m), until inside 0.2
//! period,duty,cart_counts,pole_counts
//! 0,1,0,0
//! 1,1,0,0
//! 2,-1,4,0
//! ```
//!
//! Comment lines (`#`) first: `experiment` (`cart` or `swing`), `period_s` (the control
//! period, s), the two encoders' resolutions, and `pole_zero: hanging` (pole count 0 is the
//! pole hanging straight down, where it was at power-on). Other comment lines are free
//! text. Then the header row [`COLUMNS`] and one row per period, numbered from 0 without
//! gaps: the counts read at the start of the period and the duty commanded on them (`1`
//! full towards +x, `-1` full towards -x, `0` off); the motor applies it after the rig's
//! dead time. Several logs may follow each other in one stream, each with its own comment
//! lines. Everything here is integer arithmetic on the counts and never panics, whatever
//! they are.
//!
//! # Signs
//!
//! The counts are the balance controller's, wired the same way: the cart's grow as the
//! cart moves towards +x (the way a duty of `1` pushes it), and the pole's grow with the
//! plant's angle `theta` ([`crate::cartpole`]), as the pole turns the way that tips an
//! upright pole towards +x. That way carries a hanging pole's tip towards **-x**: with +x to
//! the right, the pole's counts grow as it turns clockwise, upright or hanging. So in the
//! cart experiment a push towards +x first leaves the hanging pole's tip behind, towards
//! -x, and its counts grow. The pole's counts are not wrapped: a pole that went over the
//! top hangs again at a multiple of the revolution.

use core::fmt::{self, Display, Write};

use crate::estimator::Encoders;
use crate::rig::Rig;

/// The log's header row.
pub const COLUMNS: &str = "period,duty,cart_counts,pole_counts";
/// The comment key naming the experiment.
pub const KEY_EXPERIMENT: &str = "experiment";
/// The comment key of the control period, s.
pub const KEY_PERIOD: &str = "period_s";
/// The comment key of the cart encoder's counts per metre.
pub const KEY_CART_COUNTS: &str = "cart_counts_per_m";
/// The comment key of the pole encoder's counts per revolution.
pub const KEY_POLE_COUNTS: &str = "pole_counts_per_rev";
/// The comment key of where the pole's count 0 is.
pub const KEY_POLE_ZERO: &str = "pole_zero";
/// The one value of [`KEY_POLE_ZERO`]: count 0 is the pole hanging down.
pub const POLE_ZERO_HANGING: &str = "hanging";

/// Which experiment a log records.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Experiment {
    /// The pole hanging, the cart driven by the PRBS.
    Cart,
    /// The cart held, the pole swinging freely.
    Swing,
}

impl Experiment {
    /// The name the log gives it.
    pub const fn name(self) -> &'static str {
        match self {
            Experiment::Cart => "cart",
            Experiment::Swing => "swing",
        }
    }

    /// The experiment named `name`, if any.
    pub fn from_name(name: &str) -> Option<Experiment> {
        [Experiment::Cart, Experiment::Swing]
            .into_iter()
            .find(|e| e.name() == name)
    }
}

/// One logged period.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Row {
    /// Period number within the log, from 0.
    pub period: u32,
    /// The duty commanded: `1`, `-1` or `0`.
    pub duty: i8,
    /// The cart encoder's count at the start of the period.
    pub cart_counts: i32,
    /// The pole encoder's count at the start of the period (0 hanging).
    pub pole_counts: i32,
}

/// What an experiment asks of the board this period.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Not started yet: keep the motor off, log nothing.
    Wait,
    /// Drive `row.duty` and log the row.
    Log(Row),
    /// Over: keep the motor off.
    Done,
}

/// A maximal-length linear-feedback shift register (Galois form) of 3 to 16 bits, each bit
/// held for a number of periods: the cart experiment's pseudo-random binary sequence. Its
/// `2^degree - 1` bits have an almost flat spectrum up to the bit rate, and over one
/// sequence the two levels are balanced to one bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prbs {
    state: u16,
    mask: u16,
    degree: u8,
    hold: u32,
    left: u32,
    level: i8,
}

/// Feedback masks of maximal-length registers of 3 to 16 bits (each checked in the tests to
/// cycle through every non-zero state).
const MASKS: [u16; 14] = [
    0x5, 0x9, 0x12, 0x21, 0x41, 0x8e, 0x108, 0x204, 0x402, 0x829, 0x100d, 0x2015, 0x4001, 0x8016,
];

impl Prbs {
    /// The fewest bits a register may have.
    pub const MIN_DEGREE: u8 = 3;
    /// The most bits a register may have.
    pub const MAX_DEGREE: u8 = 16;

    /// A register of `degree` bits (clamped to 3 to 16) started from `seed` (reduced to a
    /// non-zero state), each bit held for `hold` periods (at least 1).
    pub fn new(degree: u8, seed: u32, hold: u32) -> Prbs {
        let degree = degree.clamp(Self::MIN_DEGREE, Self::MAX_DEGREE);
        let states = (1u32 << degree) - 1;
        Prbs {
            state: (seed % states + 1) as u16,
            mask: MASKS[usize::from(degree - Self::MIN_DEGREE)],
            degree,
            hold: hold.max(1),
            left: 0,
            level: 1,
        }
    }

    /// The fewest bits whose sequence, each bit held `hold` periods, lasts `periods`.
    pub fn degree_for(periods: u32, hold: u32) -> u8 {
        let bits = periods.div_ceil(hold.max(1));
        (Self::MIN_DEGREE..Self::MAX_DEGREE)
            .find(|&d| (1u32 << d) > bits)
            .unwrap_or(Self::MAX_DEGREE)
    }

    /// The register's length in bits.
    pub fn degree(&self) -> u8 {
        self.degree
    }

    /// Periods each bit is held.
    pub fn hold(&self) -> u32 {
        self.hold
    }

    /// The next period's level: `1` or `-1`.
    pub fn next_level(&mut self) -> i8 {
        if self.left == 0 {
            let out = self.state & 1;
            self.state >>= 1;
            if out == 1 {
                self.state ^= self.mask;
            }
            self.level = if out == 1 { 1 } else { -1 };
            self.left = self.hold;
        }
        self.left -= 1;
        self.level
    }
}

/// A log's comment lines, as [`Csv::header`] writes them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Header {
    /// The experiment.
    pub experiment: Experiment,
    /// The control period, s.
    pub period_s: f64,
    /// The encoders' resolutions.
    pub encoders: Encoders,
    /// The experiment's own settings, as free text.
    pub detail: Detail,
}

/// An experiment's settings, for the log's free-text comment line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Detail {
    /// The cart experiment's sequence and safety rule.
    Cart {
        /// Register length, bits.
        degree: u8,
        /// Periods per bit.
        hold: u32,
        /// The sequence's seed.
        seed: u32,
        /// The usable track, m.
        usable_m: f64,
    },
    /// The swing experiment's length after the release.
    Swing {
        /// Periods logged after the release.
        periods: u32,
    },
}

impl Display for Detail {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Detail::Cart {
                degree,
                hold,
                seed,
                usable_m,
            } => write!(
                f,
                "prbs: degree {degree}, hold {hold} periods, seed {seed}; back to the centre \
                 once the cart would stop past {} of the usable track ({usable_m} m), until \
                 inside {}",
                Cart::OUTER,
                Cart::INNER
            ),
            Detail::Swing { periods } => write!(
                f,
                "swing: the cart held, no motor; logged from a pole raised past {} degrees \
                 until {periods} periods after its release",
                Swing::RAISE_DEG
            ),
        }
    }
}

/// Where rows go.
pub trait Sink {
    /// Why a row could not be recorded.
    type Error;
    /// Records one row.
    fn record(&mut self, row: &Row) -> Result<(), Self::Error>;
}

/// The log's text, written through a [`core::fmt::Write`].
pub struct Csv<W>(pub W);

impl<W: Write> Csv<W> {
    /// Writes a log's comment lines and its header row.
    pub fn header(&mut self, h: &Header) -> fmt::Result {
        let w = &mut self.0;
        writeln!(w, "# cart-pole identification log")?;
        writeln!(w, "# {KEY_EXPERIMENT}: {}", h.experiment.name())?;
        writeln!(w, "# {KEY_PERIOD}: {}", h.period_s)?;
        writeln!(w, "# {KEY_CART_COUNTS}: {}", h.encoders.cart_counts_per_m)?;
        writeln!(w, "# {KEY_POLE_COUNTS}: {}", h.encoders.pole_counts_per_rev)?;
        writeln!(w, "# {KEY_POLE_ZERO}: {POLE_ZERO_HANGING}")?;
        writeln!(w, "# {}", h.detail)?;
        writeln!(w, "{COLUMNS}")
    }
}

impl<W: Write> Sink for Csv<W> {
    type Error = fmt::Error;
    fn record(&mut self, r: &Row) -> fmt::Result {
        writeln!(
            self.0,
            "{},{},{},{}",
            r.period, r.duty, r.cart_counts, r.pole_counts
        )
    }
}

/// The cart experiment: the PRBS on a hanging pole, inside the track (see [the
/// module](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cart {
    prbs: Prbs,
    seed: u32,
    periods: u32,
    period: u32,
    usable_m: f64,
    outer: i64,
    inner: i64,
    lookahead: i64,
    last: Option<i32>,
    speed: Option<i64>,
    braking: i64,
    returning: i8,
}

impl Cart {
    /// The fraction of the usable track past which the cart is sent back.
    pub const OUTER: f64 = 0.5;
    /// The fraction of the usable track inside which the sequence takes over again.
    pub const INNER: f64 = 0.2;
    /// Periods looked ahead beyond the dead time: the one a command waits for, and two for a
    /// dead time the rig file puts short.
    pub const LOOKAHEAD_EXTRA: i64 = 3;

    /// `periods` periods of the sequence seeded `seed`, each bit held `hold` periods, on
    /// `rig`'s track and encoders, looking ahead over its dead time.
    pub fn new(rig: &Rig, periods: u32, hold: u32, seed: u32) -> Cart {
        let usable = rig.params.x_threshold - rig.end_stop_margin;
        let usable = if usable > 0.0 { usable } else { 0.0 };
        let counts =
            |fraction: f64| (usable * fraction * f64::from(rig.encoders.cart_counts_per_m)) as i64;
        Cart {
            prbs: Prbs::new(Prbs::degree_for(periods, hold), seed, hold),
            seed,
            periods,
            period: 0,
            usable_m: usable,
            outer: counts(Self::OUTER),
            inner: counts(Self::INNER),
            lookahead: i64::from(rig.dead_time.min(1 << 16)) + Self::LOOKAHEAD_EXTRA,
            last: None,
            speed: None,
            braking: 0,
            returning: 0,
        }
    }

    /// The log's comment lines for this experiment on `rig`.
    pub fn header(&self, rig: &Rig) -> Header {
        Header {
            experiment: Experiment::Cart,
            period_s: rig.params.tau,
            encoders: rig.encoders,
            detail: Detail::Cart {
                degree: self.prbs.degree(),
                hold: self.prbs.hold(),
                seed: self.seed,
                usable_m: self.usable_m,
            },
        }
    }

    /// Where the cart at `x` moving by `v` counts a period stops, counts: `v` over the
    /// lookahead, then `2 v^2 / a` at a change of count difference `a` a period, the braking
    /// distance at a quarter of it. Saturating, so that no count overflows it.
    fn stopping_point(&self, x: i64, v: i64) -> i64 {
        let braking = v.saturating_mul(v).saturating_mul(2) / self.braking.max(1);
        let braking = if v < 0 { -braking } else { braking };
        x.saturating_add(v.saturating_mul(self.lookahead))
            .saturating_add(braking)
    }

    /// This period, from the counts just read.
    pub fn step(&mut self, cart_counts: i32, pole_counts: i32) -> Step {
        if self.period >= self.periods {
            return Step::Done;
        }
        let level = self.prbs.next_level();
        let x = i64::from(cart_counts);
        let v = self.last.map_or(0, |last| x - i64::from(last));
        self.last = Some(cart_counts);
        if let Some(before) = self.speed {
            self.braking = self.braking.max((v - before).abs());
        }
        self.speed = Some(v);
        if self.returning != 0 && x.abs() < self.inner {
            self.returning = 0;
        }
        let stop = self.stopping_point(x, v);
        if stop.abs() > self.outer {
            self.returning = if stop > 0 { -1 } else { 1 };
        }
        let row = Row {
            period: self.period,
            duty: if self.returning != 0 {
                self.returning
            } else {
                level
            },
            cart_counts,
            pole_counts,
        };
        self.period += 1;
        Step::Log(row)
    }
}

mod swing;
pub use swing::Swing;

#[cfg(test)]
mod tests;
