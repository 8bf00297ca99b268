//! What a configuration may ask for, checked before any work starts: every count has an upper
//! limit, so a run's memory is bounded (the replay buffer is the largest allocation: about 70
//! bytes a transition, 350 MB at its limit) and a typo cannot ask for a year of training.
//! Real-valued settings must survive the conversion to f32 the kernels do.
//!
//! A key's own limit is declared with the key (`config_keys!` in the parent module) and lands
//! in [`LIMITS`]; what involves several keys, and whether this CPU has the kernel, is checked
//! here in [`Config::validate`]; a key changed where the mode that would read it is off, in
//! [`Config::unread`].

use std::fmt;
use std::ops::RangeInclusive;

use super::modal::decays;
use super::{Config, ConfigError, Unit};

/// Largest TOML file `--config` reads: room for a rig's text (64 KiB) and every key beside
/// it. A TOML document costs about 80 bytes a byte while it is parsed, whatever the keys.
pub const MAX_CONFIG_BYTES: u64 = 128 << 10;
/// Most seeds one `train --seeds` runs.
pub const MAX_SEEDS: u64 = 10_000;

/// What one key accepts.
#[derive(Clone, Debug, PartialEq)]
pub enum Limit {
    /// A count in this range.
    Count(RangeInclusive<u64>),
    /// One of these whole numbers.
    OneOf(&'static [usize]),
    /// A real number > 0 that stays finite and normal in f32.
    PositiveInF32,
    /// The same, described by the smallest value it accepts: for a key whose useful values
    /// are tiny, where underflow to 0 is the likely mistake.
    NormalInF32,
    /// A real number in [0, 1).
    BelowOne,
    /// A real number in [0, 1].
    ZeroToOne,
    /// A real number in (0, 1] that stays normal in f32.
    AboveZeroToOne,
    /// A real number > 0, finite.
    Positive,
    /// A clipping threshold: >= 0 and finite in f32; 0 turns the clipping off.
    Clip,
    /// A domain spec of the grammar (`twin::grammar::parse`); `Config::relations` builds it
    /// on the machine trained for.
    Domain,
    /// A learning-reward spec `reward::Reward::parse` accepts.
    Reward,
    /// A rig file's text `twin::rigfile::parse` accepts, or nothing.
    Rig,
    /// Duty levels ([`super::parse_levels`]), or nothing.
    Levels,
}

/// A key's value as its [`Limit`] sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value<'a> {
    /// A count.
    Whole(u64),
    /// A real number.
    Real(f64),
    /// A spec.
    Text(&'a str),
}

impl From<&usize> for Value<'_> {
    fn from(v: &usize) -> Self {
        // usize is at most 64 bits wide on every target this crate builds for.
        Value::Whole(*v as u64)
    }
}

impl From<&u32> for Value<'_> {
    fn from(v: &u32) -> Self {
        Value::Whole((*v).into())
    }
}

impl From<&u64> for Value<'_> {
    fn from(v: &u64) -> Self {
        Value::Whole(*v)
    }
}

impl From<&f64> for Value<'_> {
    fn from(v: &f64) -> Self {
        Value::Real(*v)
    }
}

impl<'a> From<&'a String> for Value<'a> {
    fn from(v: &'a String) -> Self {
        Value::Text(v)
    }
}

/// One key's limit, and how to read the key.
pub struct KeyLimit {
    /// Its key (the TOML key; the flag is `--` and the key with `-` for `_`).
    pub key: &'static str,
    /// What it accepts.
    pub limit: Limit,
    pub(super) get: fn(&Config) -> Value<'_>,
}

impl KeyLimit {
    /// Checks the key of `c`; the error is a sentence that names it.
    pub fn check(&self, c: &Config) -> Result<(), String> {
        self.limit.check(self.key, (self.get)(c))
    }
}

impl Limit {
    /// What a whole-number limit takes, as its refusals say it; `None` for the others.
    fn counts(&self) -> Option<String> {
        match self {
            Limit::Count(r) => Some(format!("in [{}, {}]", r.start(), r.end())),
            Limit::OneOf(set) => Some(format!("one of {set:?}")),
            _ => None,
        }
    }

    /// Checks `key`'s value as a TOML file gives it, where its limit takes a whole number:
    /// one that is none, or past every count's type, is refused as the limit says, where the
    /// conversion to the key's type named a Rust type ("invalid type: floating point `1.5`,
    /// expected usize") and no range.
    pub fn check_toml(&self, key: &str, v: &toml::Value) -> Result<(), String> {
        let Some(counts) = self.counts() else {
            return Ok(());
        };
        match v.as_integer().and_then(|i| u64::try_from(i).ok()) {
            // Past u32, the narrowest count's type, and so past every limit: refused now as
            // `validate` would; within it, the range is `validate`'s, as a flag's is.
            Some(n) if n > u64::from(u32::MAX) => self.check(key, Value::Whole(n)),
            Some(_) => Ok(()),
            None => Err(format!("{key} must be a whole number {counts}, got {v}")),
        }
    }

    /// Checks one value of `key`; the error is a sentence that names the key.
    pub fn check(&self, key: &str, v: Value<'_>) -> Result<(), String> {
        // The kernels compute in f32: a value must stay positive and finite there.
        let f32_positive = |v: f64| v.is_finite() && v > 0.0 && (v as f32).is_normal();
        // Reals are shown as Rust reads them back, shortest (`{x:?}`): `1e-320`, where
        // `{x}` writes its 320 decimal places out.
        let must = |ok: bool, be: &dyn fmt::Display, got: &dyn fmt::Display| {
            if ok {
                Ok(())
            } else {
                Err(format!("{key} must be {be}, got {got}"))
            }
        };
        // A spec's numbers as they arrive, after any TOML escape (`1e\u002d400`) the
        // check of the file's text cannot see through: each would parse as 0.
        let parsed = |r: Result<(), String>| {
            let hidden = match v {
                Value::Text(s) => weights::hidden_zero(s),
                _ => None,
            };
            hidden.map_or(r, Err).map_err(|e| format!("{key}: {e}"))
        };
        match (self, v) {
            (Limit::Count(r), Value::Whole(n)) => {
                must(r.contains(&n), &self.counts().unwrap_or_default(), &n)
            }
            (Limit::OneOf(set), Value::Whole(n)) => must(
                set.iter().any(|&w| w as u64 == n),
                &self.counts().unwrap_or_default(),
                &n,
            ),
            (Limit::PositiveInF32, Value::Real(x)) => must(
                f32_positive(x),
                &"> 0 and finite in f32",
                &format_args!("{x:?}"),
            ),
            (Limit::NormalInF32, Value::Real(x)) => must(
                f32_positive(x),
                &format_args!("a normal f32 > 0 (at least {:e})", f32::MIN_POSITIVE),
                &format_args!("{x:?}"),
            ),
            (Limit::BelowOne, Value::Real(x)) => must(
                (0.0..1.0).contains(&x) && weights::plain(x),
                &"in [0, 1), zero or normal in f32",
                &format_args!("{x:?}"),
            ),
            (Limit::ZeroToOne, Value::Real(x)) => must(
                (0.0..=1.0).contains(&x) && weights::plain(x),
                &"in [0, 1], zero or normal in f32",
                &format_args!("{x:?}"),
            ),
            (Limit::AboveZeroToOne, Value::Real(x)) => must(
                x <= 1.0 && f32_positive(x),
                &"in (0, 1]",
                &format_args!("{x:?}"),
            ),
            (Limit::Positive, Value::Real(x)) => must(
                x.is_finite() && x > 0.0 && x.is_normal(),
                &"> 0, finite and normal",
                &format_args!("{x:?}"),
            ),
            (Limit::Clip, Value::Real(x)) => must(
                x >= 0.0 && (x as f32).is_finite() && weights::plain(x),
                &">= 0 and finite in f32, zero or normal there (0 disables it)",
                &format_args!("{x:?}"),
            ),
            (Limit::Domain, Value::Text(s)) => parsed(twin::grammar::parse(s, "domain").map(drop)),
            (Limit::Reward, Value::Text(s)) => parsed(crate::reward::Reward::parse(s).map(drop)),
            (Limit::Rig, Value::Text("")) => Ok(()),
            (Limit::Rig, Value::Text(s)) => parsed(
                twin::rigfile::parse(s, super::RIG_TEXT)
                    .map(drop)
                    .map_err(|e| e.to_string()),
            ),
            (Limit::Levels, Value::Text(s)) => parsed(super::parse_levels(s).map(drop)),
            (limit, v) => Err(format!("{key}: a {limit:?} limit cannot judge {v:?}")),
        }
    }
}

impl Config {
    /// Checks every value before any work starts; the error lists every problem.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.within_limits()?;
        self.kernel.resolve().map(|_| ())
    }

    /// Every value within its limit and the keys' relations held: what a configuration a
    /// file records must satisfy, wherever it was made (its kernel is the question of the
    /// machine that runs it, [`Config::validate`]). The error lists every problem.
    pub fn within_limits(&self) -> Result<(), ConfigError> {
        let mut errs: Vec<String> = super::LIMITS
            .iter()
            .filter_map(|l| l.check(self).err())
            .collect();
        errs.extend(self.relations());
        if errs.is_empty() {
            Ok(())
        } else {
            Err(ConfigError(errs.join("; ")))
        }
    }

    /// What keys must satisfy together: each problem as a sentence that names the keys.
    fn relations(&self) -> Vec<String> {
        let mut errs = Vec::new();
        for (key, v) in [
            ("batch_size", self.batch_size),
            ("learning_starts", self.learning_starts),
        ] {
            if v > self.buffer_size {
                errs.push(format!(
                    "{key} ({v}) must not exceed buffer_size ({})",
                    self.buffer_size
                ));
            }
        }
        if let Ok(levels) = super::parse_levels(&self.levels)
            && !firmware::network::SUPPORTED_SHAPES.contains(&(self.width, levels.len()))
        {
            errs.push(
                weights::shape::unsupported(self.width, levels.len()).to_string()
                    + " (width and levels)",
            );
        }
        errs.extend(self.domains_on_rig());
        // Judged of a decay its own limit takes: `eps_decay = 0` was refused twice.
        let own = super::LIMITS.iter().find(|l| l.key == "eps_decay");
        if own.is_none_or(|l| l.check(self).is_ok()) {
            errs.extend(self.decay_that_never_moves());
            errs.extend(self.decay_over_at_once());
        }
        if self.finalists > 0 && (self.finalist_episodes == 0 || self.finalist_max_steps == 0) {
            errs.push(format!(
                "finalists ({}) need finalist_episodes and finalist_max_steps >= 1, got {} and {}",
                self.finalists, self.finalist_episodes, self.finalist_max_steps
            ));
        }
        errs
    }
}

impl Config {
    /// A decay so long that epsilon never leaves `eps_start` in the longest run the
    /// configuration allows (it is at its end what it was at the start): `eps_end`, and the
    /// decay itself, would then be read by nothing, as where the two ends are equal.
    fn decay_that_never_moves(&self) -> Option<String> {
        let (t, unit) = match self.eps_unit {
            Unit::Episodes => (self.episodes as f64, "episodes"),
            Unit::Steps => (self.episodes as f64 * f64::from(self.max_steps), "steps"),
        };
        // A step budget ends the run sooner, and an episode takes a step at least.
        let t = match self.max_env_steps {
            0 => t,
            budget => t.min(budget as f64),
        };
        let epsilon = |t| crate::train::epsilon(self, t);
        (epsilon(t) == epsilon(0.0) && decays(self)).then(|| {
            format!(
                "eps_decay ({:?}) leaves epsilon at eps_start for the whole run ({t} {unit} at \
                 most), so eps_end is never approached; expected a decay the run can move",
                self.eps_decay
            )
        })
    }

    /// The mirror of [`Self::decay_that_never_moves`]: a decay so short that epsilon is at
    /// `eps_end` from the second step (or episode) on, so `eps_start` is read once.
    fn decay_over_at_once(&self) -> Option<String> {
        let epsilon = |t| crate::train::epsilon(self, t);
        (epsilon(1.0) == epsilon(f64::INFINITY) && decays(self)).then(|| {
            format!(
                "eps_decay ({:?}) takes epsilon to eps_end within one {}, so eps_start is read \
                 once; expected a decay over more of the run",
                self.eps_decay,
                match self.eps_unit {
                    Unit::Episodes => "episode",
                    Unit::Steps => "step",
                }
            )
        })
    }

    /// Each domain key's refusal on the machine trained for (`rig`): a domain's factors
    /// scale that machine, whose motor may have no damping. Judged once the rig reads (a rig
    /// that does not is refused by its own key) and the domain parses (refused by its own).
    fn domains_on_rig(&self) -> Vec<String> {
        let Ok(machine) = self.machine() else {
            return Vec::new();
        };
        super::LIMITS
            .iter()
            .filter(|l| l.limit == Limit::Domain)
            .filter_map(|l| match (l.get)(self) {
                Value::Text(s) if twin::grammar::parse(s, "domain").is_ok() => {
                    twin::Domain::parse_on(s, &machine)
                        .err()
                        .map(|e| format!("{}: {e}", l.key))
                }
                _ => None,
            })
            .collect()
    }
}
