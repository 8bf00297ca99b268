//! Keys read only in one mode of another key's: one changed where its mode is off would be
//! read by nothing, and is refused ([`Config::unread`]), or put back where a preset's own
//! value would otherwise be recorded unread.

use super::{Config, ConfigError, TargetUpdate};

/// A key read only in one mode of another's.
struct Modal {
    key: &'static str,
    /// What turns the mode on.
    when: When,
    /// Whether the mode is on.
    reads: fn(&Config) -> bool,
}

/// What turns a mode on.
enum When {
    /// The key that sets the mode, and what it must be, in words.
    Key(&'static str, &'static str),
    /// What must hold, in words, and what the configuration has instead.
    Said(&'static str, fn(&Config) -> String),
}

const fn modal(
    key: &'static str,
    mode: &'static str,
    needs: &'static str,
    reads: fn(&Config) -> bool,
) -> Modal {
    Modal {
        key,
        when: When::Key(mode, needs),
        reads,
    }
}

/// The keys read in one mode alone. Hard target updates never read `tau` (the weights came
/// out identical for any), soft ones never the period; an exploration that starts at its
/// floor has no decay; without periodic evaluations nothing stops a run early or has
/// snapshots for finalists; without finalists there is no trial; without a discount above 0
/// no target network enters the loss; in worlds without dead time
/// the predictor has nothing to advance the readings over.
const MODAL: &[Modal] = &[
    modal("eps_decay", "eps_start", "other than eps_end", decays),
    modal("eps_unit", "eps_start", "other than eps_end", decays),
    modal("algo", "gamma", "above 0", bootstraps),
    modal("target_update", "gamma", "above 0", bootstraps),
    modal("tau", "gamma", "above 0", bootstraps),
    modal("target_period", "gamma", "above 0", bootstraps),
    modal("target_period_unit", "gamma", "above 0", bootstraps),
    modal("tau", "target_update", "soft", soft),
    modal("target_period", "target_update", "hard", hard),
    modal("target_period_unit", "target_update", "hard", hard),
    modal("eval_episodes", "eval_every", "above 0", evaluates),
    modal("stop_when_perfect", "eval_every", "above 0", evaluates),
    modal("patience", "eval_every", "above 0", evaluates),
    modal("settle", "eval_every", "above 0", evaluates),
    modal("finalists", "eval_every", "above 0", evaluates),
    modal("finalist_episodes", "finalists", "above 0", trials),
    modal("finalist_max_steps", "finalists", "above 0", trials),
    modal("finalist_domain", "finalists", "above 0", trials),
    modal("board_int8", "finalists", "above 0", trials),
    modal("trial_margin", "finalists", "above 0", trials),
    Modal {
        key: "compensate",
        when: When::Said("a world has dead time", no_dead_time),
        reads: has_dead_time,
    },
];

/// Whether the loss looks past the next reward: with `gamma` 0 the target network (how it
/// is chosen, copied or averaged) never enters it, and the weights came out the same.
fn bootstraps(c: &Config) -> bool {
    c.gamma > 0.0
}

fn soft(c: &Config) -> bool {
    c.target_update == TargetUpdate::Soft
}

fn hard(c: &Config) -> bool {
    c.target_update == TargetUpdate::Hard
}

pub(super) fn decays(c: &Config) -> bool {
    c.eps_start != c.eps_end
}

fn evaluates(c: &Config) -> bool {
    c.eval_every > 0
}

fn trials(c: &Config) -> bool {
    c.finalists > 0
}

/// The domains a run draws its worlds from: training's, the evaluations', and the trial's
/// when there is one.
fn drawn(c: &Config) -> Vec<&String> {
    let mut domains = vec![&c.domain, &c.eval_domain];
    if trials(c) {
        domains.push(&c.finalist_domain);
    }
    domains
}

/// The machine's dead time, in periods (0 for a rig that does not read: refused by its key).
fn own_dead_time(c: &Config) -> u32 {
    c.machine().map_or(0, |m| m.rig.dead_time)
}

/// Whether a world drawn from any domain of the run has dead time. A domain that does not
/// parse on the machine (refused by its own key) is taken as the machine itself.
fn has_dead_time(c: &Config) -> bool {
    let Ok(machine) = c.machine() else {
        return false;
    };
    drawn(c).iter().any(|d| {
        twin::Domain::parse_on(d, &machine).map_or(machine.rig.dead_time, |d| d.most_dead_time())
            > 0
    })
}

fn no_dead_time(c: &Config) -> String {
    match own_dead_time(c) {
        0 => "the machine trained for has no dead time and no domain draws any".into(),
        own => format!(
            "every domain drawn sets the machine's dead time of {} to none",
            twin::machine::periods(own)
        ),
    }
}

impl Config {
    /// Refuses a key changed from `preset` (by a `--config` file or a flag) where the mode
    /// that reads it is off: the value would be recorded and dropped. A key the mode does not
    /// read, at its preset's value, is put back to its declared default ([`Config::paper`],
    /// where every preset leaves the keys its modes do not read), so the configuration
    /// records nothing unread; and a key at its default asks for nothing. So a preset's own
    /// values, and a configuration `--print-config` wrote, read back whole over any preset,
    /// are never refused.
    pub fn unread(&mut self, preset: &Config) -> Result<(), ConfigError> {
        let table = |c: &Config| {
            toml::Table::try_from(c)
                .map_err(|e| ConfigError(format!("internal: config is not TOML: {e}")))
        };
        let (mut now, before, default) = (table(self)?, table(preset)?, table(&Config::paper())?);
        // A mode put back may turn off another (no periodic evaluations, so no finalists,
        // so no trial): until nothing changes.
        let unread = loop {
            let unread: Vec<&Modal> = MODAL.iter().filter(|m| !(m.reads)(self)).collect();
            let back: Vec<&str> = unread
                .iter()
                .map(|m| m.key)
                .filter(|k| now[*k] == before[*k] && now[*k] != default[*k])
                .collect();
            if back.is_empty() {
                break unread;
            }
            for key in back {
                now.insert(key.to_string(), default[key].clone());
            }
            *self = now
                .clone()
                .try_into()
                .map_err(|e| ConfigError(format!("internal: config from TOML: {e}")))?;
        };
        // Reals shortest (`1e-300`), where TOML writes every decimal place out.
        let shown = |key: &str| match &now[key] {
            toml::Value::String(s) => weights::quote(s),
            toml::Value::Float(x) => format!("{x:?}"),
            v => v.to_string(),
        };
        let errs: Vec<String> = unread
            .iter()
            .filter(|m| now[m.key] != default[m.key])
            .map(|m| match m.when {
                When::Key(mode, needs) => format!(
                    "{} = {} is read only when {mode} is {needs}; {mode} = {} ignores it",
                    m.key,
                    shown(m.key),
                    shown(mode)
                ),
                When::Said(needs, found) => format!(
                    "{} = {} is read only when {needs}; {}",
                    m.key,
                    shown(m.key),
                    found(self)
                ),
            })
            .collect();
        if errs.is_empty() {
            Ok(())
        } else {
            Err(ConfigError(errs.join("; ")))
        }
    }
}
