//! The board's logs (the format of `firmware::identify`), read and checked: everything a log
//! says is checked before any fitting, and a bad one is refused naming its file, line and
//! what was expected there.

use firmware::estimator::Encoders;
use firmware::identify::{
    COLUMNS, Experiment, KEY_CART_COUNTS, KEY_EXPERIMENT, KEY_PERIOD, KEY_POLE_COUNTS,
    KEY_POLE_ZERO, POLE_ZERO_HANGING,
};
use twin::Machine;
use weights::{Error, Result, quote};

/// Largest log file read.
pub const MAX_LOG_BYTES: u64 = 32 << 20;
/// Most rows one log may have.
pub const MAX_ROWS: usize = 1 << 20;
/// Most log files one fit reads.
pub const MAX_LOG_FILES: usize = 64;
/// Most bytes of log files one fit reads, all together.
pub const MAX_TOTAL_LOG_BYTES: u64 = 64 << 20;
/// Most seconds of logs one fit takes, all together: the fit's time and memory grow in
/// proportion to them.
pub const MAX_TOTAL_SECONDS: f64 = 1800.0;
/// The shortest log fitted (of a swing: after the release), s.
pub const MIN_SECONDS: f64 = 3.0;
/// The least travel between the cart's extreme counts that excites a cart log, m.
pub const MIN_CART_TRAVEL_M: f64 = 0.01;
/// The least swing amplitude after the release that excites a swing log, degrees.
pub const MIN_SWING_DEG: f64 = 2.0;
/// The fewest passes through hanging a swing log must show after the release.
pub const MIN_CROSSINGS: usize = 4;
/// How far the cart of a swing log may move from where it started, m: it is held.
pub const MAX_HELD_TRAVEL_M: f64 = 0.005;
/// The farthest the cart may move in one period before its counts are taken as corrupt, m.
pub const MAX_CART_JUMP_M: f64 = 0.25;

/// One experiment's log.
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// The file it came from, for messages.
    pub origin: String,
    /// The line its comment header starts on.
    pub line: usize,
    /// Which experiment.
    pub experiment: Experiment,
    /// The control period, s.
    pub period_s: f64,
    /// The encoders' resolutions.
    pub encoders: Encoders,
    /// Each period's duty.
    pub duty: Vec<f64>,
    /// Each period's cart count.
    pub cart: Vec<i32>,
    /// Each period's pole count (0 hanging).
    pub pole: Vec<i32>,
    /// Each period's line.
    pub lines: Vec<usize>,
}

/// A log's header keys as they are read.
#[derive(Default)]
struct Keys {
    experiment: Option<Experiment>,
    period_s: Option<f64>,
    cart: Option<u32>,
    pole: Option<u32>,
    hanging: bool,
}

fn input(origin: &str, line: usize, what: String) -> Error {
    Error::Input(format!("{origin}:{line}: {what}"))
}

impl Keys {
    /// Reads one comment line; `# key: value` for the keys of the format, free text
    /// otherwise.
    fn read(&mut self, origin: &str, line: usize, comment: &str) -> Result<()> {
        let Some((key, value)) = comment.split_once(':') else {
            return Ok(());
        };
        let (key, value) = (key.trim(), value.trim());
        let bad = |want: &str| {
            input(
                origin,
                line,
                format!("{key}: expected {want}, found {}", quote(value)),
            )
        };
        let twice = || {
            input(
                origin,
                line,
                format!("{key}: expected once per log, found again"),
            )
        };
        let count = |v: &str| weights::whole::<u32>(v).filter(|&c| c > 0);
        match key {
            KEY_EXPERIMENT => {
                let e = Experiment::from_name(value).ok_or_else(|| bad("\"cart\" or \"swing\""))?;
                self.experiment.replace(e).map_or(Ok(()), |_| Err(twice()))
            }
            KEY_PERIOD => {
                let p = value
                    .parse::<f64>()
                    .ok()
                    .filter(|p| p.is_finite() && *p > 0.0);
                let p = p.ok_or_else(|| bad("a period in seconds"))?;
                self.period_s.replace(p).map_or(Ok(()), |_| Err(twice()))
            }
            KEY_CART_COUNTS => {
                let c = count(value)
                    .ok_or_else(|| bad(&format!("a whole number in [1, {}]", u32::MAX)))?;
                self.cart.replace(c).map_or(Ok(()), |_| Err(twice()))
            }
            KEY_POLE_COUNTS => {
                let c = count(value)
                    .ok_or_else(|| bad(&format!("a whole number in [1, {}]", u32::MAX)))?;
                self.pole.replace(c).map_or(Ok(()), |_| Err(twice()))
            }
            KEY_POLE_ZERO if value == POLE_ZERO_HANGING => {
                if std::mem::replace(&mut self.hanging, true) {
                    Err(twice())
                } else {
                    Ok(())
                }
            }
            KEY_POLE_ZERO => Err(bad(&quote(POLE_ZERO_HANGING))),
            _ => Ok(()),
        }
    }

    /// The log these keys start, at the header row on `line`.
    fn start(self, origin: &str, first: usize, line: usize) -> Result<Log> {
        let missing = |key: &str| {
            input(
                origin,
                line,
                format!("expected a `# {key}:` line before the header row, found none"),
            )
        };
        let experiment = self.experiment.ok_or_else(|| missing(KEY_EXPERIMENT))?;
        let period_s = self.period_s.ok_or_else(|| missing(KEY_PERIOD))?;
        let cart_counts_per_m = self.cart.ok_or_else(|| missing(KEY_CART_COUNTS))?;
        let pole_counts_per_rev = self.pole.ok_or_else(|| missing(KEY_POLE_COUNTS))?;
        if !self.hanging {
            return Err(missing(KEY_POLE_ZERO));
        }
        Ok(Log {
            origin: origin.to_string(),
            line: first,
            experiment,
            period_s,
            encoders: Encoders {
                cart_counts_per_m,
                pole_counts_per_rev,
            },
            duty: Vec::new(),
            cart: Vec::new(),
            pole: Vec::new(),
            lines: Vec::new(),
        })
    }
}

impl Log {
    /// Appends the data row `text` on `line`.
    fn push(&mut self, line: usize, text: &str) -> Result<()> {
        let at = |what: String| input(&self.origin, line, what);
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        if fields.len() != 4 {
            return Err(at(format!(
                "expected 4 columns ({COLUMNS}), found {}",
                fields.len()
            )));
        }
        if self.duty.len() >= MAX_ROWS {
            return Err(at(format!(
                "expected at most {MAX_ROWS} rows in one log, found more"
            )));
        }
        let expected = self.duty.len();
        let field = |i: usize, name: &str, want: &str| {
            at(format!(
                "{name}: expected {want}, found {}",
                quote(fields[i])
            ))
        };
        let period: usize = weights::whole(fields[0])
            .ok_or_else(|| field(0, "period", &format!("a period number in [0, {MAX_ROWS})")))?;
        if period != expected {
            return Err(at(format!(
                "period: expected {expected}, found {period} (the period numbers must run from 0 without gaps)"
            )));
        }
        // `1e-400` parses as 0, which a board's log never writes so.
        let plain = |d: &f64| weights::plain(*d) && !weights::reads_as_zero(fields[1]);
        let duty = fields[1]
            .parse::<f64>()
            .ok()
            .filter(|d| (-1.0..=1.0).contains(d) && plain(d));
        let duty = duty.ok_or_else(|| field(1, "duty", "a number from -1 to 1, zero or normal"))?;
        // A board's counters are 32-bit: the range named, or the largest 64-bit counts read
        // as "not a whole number".
        let counts = |i, name| {
            let range = format!("a whole number of counts in [{}, {}]", i32::MIN, i32::MAX);
            field(i, name, &range)
        };
        let cart: i32 = (fields[2].parse()).map_err(|_| counts(2, "cart_counts"))?;
        let pole: i32 = (fields[3].parse()).map_err(|_| counts(3, "pole_counts"))?;
        if let (Some(&c), Some(&p)) = (self.cart.last(), self.pole.last()) {
            let per_rev = i64::from(self.encoders.pole_counts_per_rev);
            let jump = (i64::from(pole) - i64::from(p)).abs();
            if jump > per_rev {
                return Err(at(format!(
                    "pole_counts: expected a change of at most a revolution ({per_rev} counts) since the period before, found {jump}"
                )));
            }
            let limit = (MAX_CART_JUMP_M * f64::from(self.encoders.cart_counts_per_m)) as i64;
            let jump = (i64::from(cart) - i64::from(c)).abs();
            if jump > limit {
                return Err(at(format!(
                    "cart_counts: expected a change of at most {MAX_CART_JUMP_M} m ({limit} counts) since the period before, found {jump}"
                )));
            }
        }
        self.duty.push(duty);
        self.cart.push(cart);
        self.pole.push(pole);
        self.lines.push(line);
        Ok(())
    }
}

/// The logs in `text`, one or more, each its comment lines, the header row and its rows;
/// `origin` names the file in messages.
pub fn parse(text: &str, origin: &str) -> Result<Vec<Log>> {
    let mut logs: Vec<Log> = Vec::new();
    let mut keys: Option<(usize, Keys)> = None;
    let mut current: Option<Log> = None;
    for (i, raw) in text.lines().enumerate() {
        let (line, t) = (i + 1, raw.trim());
        if t.is_empty() {
            continue;
        }
        if let Some(comment) = t.strip_prefix('#') {
            logs.extend(current.take());
            keys.get_or_insert_with(|| (line, Keys::default()))
                .1
                .read(origin, line, comment)?;
        } else if let Some(log) = current.as_mut() {
            log.push(line, t)?;
        } else if t.replace(' ', "") == COLUMNS {
            let (first, k) = keys.take().unwrap_or((line, Keys::default()));
            current = Some(k.start(origin, first, line)?);
        } else {
            return Err(input(
                origin,
                line,
                format!(
                    "expected the header row {COLUMNS:?} after the comment lines, found {}",
                    quote(t)
                ),
            ));
        }
    }
    if let Some((line, _)) = keys {
        return Err(input(
            origin,
            line,
            format!(
                "expected the header row {COLUMNS:?} after these comment lines, found the end of the file"
            ),
        ));
    }
    logs.extend(current);
    if logs.is_empty() {
        return Err(Error::Input(format!(
            "{origin}: expected a log (comment lines, the header row {COLUMNS:?}, rows), found none"
        )));
    }
    Ok(logs)
}

mod once;
pub use once::check_each_once;

/// A log's first count, 0 for a log of no rows.
fn first_count(counts: &[i32]) -> i64 {
    counts.first().map_or(0, |&c| i64::from(c))
}

/// The pole's count as its offset from the hanging position nearest to where the log
/// starts (a pole that went over the top in an earlier experiment hangs a revolution on),
/// doubled and made odd: twice the midpoint of the count, never zero, so its sign is the
/// side of hanging the pole is on.
pub fn doubled_midpoints(log: &Log) -> Vec<i64> {
    let per_rev = i64::from(log.encoders.pole_counts_per_rev);
    let first = first_count(&log.pole);
    let rev = (first + per_rev / 2).div_euclid(per_rev) * per_rev;
    log.pole
        .iter()
        .map(|&c| 2 * (i64::from(c) - rev) + 1)
        .collect()
}

/// Where a swing log's free swing starts: the last period at the highest count before the
/// pole first passes hanging (a hand may hold it there for a while; the swing from rest
/// leaves the top count within a period or two of its release), or `None` if it never
/// passes hanging.
pub fn release(doubled: &[i64]) -> Option<usize> {
    let first = *doubled.first()?;
    let pass = doubled.iter().position(|&c| c.signum() != first.signum())?;
    let mut k = pass - 1;
    while k > 0 && doubled[k - 1].abs() > doubled[k].abs() {
        k -= 1;
    }
    Some(k)
}

impl Log {
    fn fail(&self, row: Option<usize>, what: String) -> Error {
        let line = row.map_or(self.line, |k| self.lines[k]);
        input(&self.origin, line, what)
    }

    /// Checks the log against the rig it is fitted for and that it holds enough of an
    /// experiment to fit.
    pub fn check(&self, machine: &Machine) -> Result<()> {
        let (rig, p) = (&machine.rig, &machine.rig.params);
        if (self.period_s - p.tau).abs() > 1e-9 * p.tau {
            return Err(self.fail(
                None,
                format!(
                    "{KEY_PERIOD}: expected the rig's period_s {:?}, found {:?}",
                    p.tau, self.period_s
                ),
            ));
        }
        if self.encoders != rig.encoders {
            let (e, r) = (self.encoders, rig.encoders);
            return Err(self.fail(None, format!(
                "encoders: expected the rig's {} counts per metre and {} per revolution, found {} and {}",
                r.cart_counts_per_m, r.pole_counts_per_rev, e.cart_counts_per_m, e.pole_counts_per_rev
            )));
        }
        let cpm = f64::from(rig.encoders.cart_counts_per_m);
        let start = self.cart.first().copied().unwrap_or(0);
        let travel = |k: usize| f64::from(self.cart[k]) / cpm;
        match self.experiment {
            Experiment::Cart => self.check_cart(p.x_threshold, &travel),
            Experiment::Swing => {
                let moved = (0..self.cart.len())
                    .find(|&k| (f64::from(self.cart[k] - start) / cpm).abs() > MAX_HELD_TRAVEL_M);
                if let Some(k) = moved {
                    return Err(self.fail(Some(k), format!(
                        "cart_counts: expected the cart held within {} mm of where it started in a swing log, found {:.1} mm",
                        MAX_HELD_TRAVEL_M * 1e3,
                        (travel(k) - f64::from(start) / cpm).abs() * 1e3
                    )));
                }
                self.check_swing()
            }
        }
    }

    fn long_enough(&self, periods: usize, what: &str) -> Result<()> {
        let need = (MIN_SECONDS / self.period_s).ceil() as usize;
        if periods < need {
            return Err(self.fail(None, format!(
                "too short: expected at least {MIN_SECONDS} s ({need} periods) {what}, found {periods} periods"
            )));
        }
        Ok(())
    }

    fn check_cart(&self, track: f64, travel: &dyn Fn(usize) -> f64) -> Result<()> {
        self.long_enough(self.duty.len(), "of a cart experiment")?;
        if let Some(k) = (0..self.cart.len()).find(|&k| travel(k).abs() >= track) {
            return Err(self.fail(Some(k), format!(
                "saturated: expected the cart inside the track (track_half_length_m {track}), found it {:.3} m from the centre, at the end stop",
                travel(k).abs()
            )));
        }
        if let Some(&d) = self.duty.iter().find(|&&d| d != 0.0)
            && self.duty.iter().all(|&v| v * d >= 0.0)
        {
            return Err(self.fail(
                None,
                format!(
                    "unexcited: expected duties of both signs in a cart log, found only {}",
                    if d > 0.0 {
                        "positive ones"
                    } else {
                        "negative ones"
                    }
                ),
            ));
        }
        let (lo, hi) = (self.cart.iter().min(), self.cart.iter().max());
        let span = hi.zip(lo).map_or(0.0, |(h, l)| {
            (f64::from(*h) - f64::from(*l)) / f64::from(self.encoders.cart_counts_per_m)
        });
        if span < MIN_CART_TRAVEL_M || self.duty.iter().all(|&d| d == 0.0) {
            return Err(self.fail(None, format!(
                "unexcited: expected the motor to drive the cart over at least {} cm, found {:.2} cm between its extremes",
                MIN_CART_TRAVEL_M * 100.0,
                span * 100.0
            )));
        }
        Ok(())
    }

    fn check_swing(&self) -> Result<()> {
        if let Some(k) = self.duty.iter().position(|&d| d != 0.0) {
            return Err(self.fail(
                Some(k),
                format!(
                    "duty: expected 0 (no motor) in a swing log, found {:?}",
                    self.duty[k]
                ),
            ));
        }
        let doubled = doubled_midpoints(self);
        let unexcited = |found: String| {
            self.fail(None, format!(
                "unexcited: expected the pole let go at least {MIN_SWING_DEG} degrees off hanging and swinging through it {MIN_CROSSINGS} times, found {found}"
            ))
        };
        let Some(start) = release(&doubled) else {
            return Err(unexcited("it never passing hanging".into()));
        };
        let swing = &doubled[start..];
        let amplitude = swing.iter().map(|c| c.abs()).max().unwrap_or(0) as f64 / 2.0 * 360.0
            / f64::from(self.encoders.pole_counts_per_rev);
        let crossings = swing
            .windows(2)
            .filter(|w| w[0].signum() != w[1].signum())
            .count();
        if amplitude < MIN_SWING_DEG || crossings < MIN_CROSSINGS {
            return Err(unexcited(format!(
                "{amplitude:.1} degrees and {crossings} passes"
            )));
        }
        self.long_enough(swing.len(), "after the release of the pole")
    }
}
