//! Every hyperparameter of a training run, its presets, and their validation.
//!
//! A run's configuration is built in layers: a preset ([`Config::paper`], the paper's Table
//! 2, or [`Config::robust`], tuned here for a deployable controller), then a TOML file whose
//! keys are the field names below, then single command-line flags ([`Overrides`]). The result
//! is written whole into the run's `summary.json`, so a run can always be repeated.
//!
//! # One declaration per key
//!
//! Each key is declared once, in the `config_keys!` list below: its doc, name, type, paper
//! default and, if it has one, its own limit. The macro (in `keys.rs`) generates from that
//! list everything that names every key, so that none of them can miss one:
//!
//! - the [`Config`] struct: its fields are the TOML keys, in the order `summary.json` and
//!   `--print-config` write them, and a file with any other key is refused;
//! - [`Config::paper`], every key at its default (the other presets are changes to it);
//! - [`Overrides`], one flag `--key-with-dashes` per key (the values of an enum's flag are
//!   its `clap::ValueEnum` names), and [`Overrides::apply`], which lays them over a
//!   configuration; a key marked `#[flag(file)]` holds a file's text, and its flag, which
//!   names the file (any path, text or not), is the command's to declare and read;
//! - the reading of files that lack keys: `#[serde(default)]` marks a key added after files
//!   were first written, and a file without it gets its paper default, the value runs had
//!   before it existed; a file without any other key is refused;
//! - [`LIMITS`], every key's own limit in declaration order, which [`Config::validate`]
//!   checks before the rules that relate keys to each other (`limits.rs`), and from which
//!   the limits table of `docs/HOSTILE_INPUT.md` can be generated.
//!
//! A macro, rather than serde and a validation trait, because serde derives only the TOML
//! side: the flags (a second struct of `Option`s), the paper defaults and the limits would
//! each stay a list kept in step with the struct by hand.
//!
//! Adding a key is one entry in the list. A switch that older files lack, say:
//!
//! ```text
//! /// Start each episode from the last one's final state.
//! #[serde(default)]
//! carry_over: bool = false;
//! ```
//!
//! gives `Config::carry_over`, `carry_over = true` in TOML and `--carry-over <CARRY_OVER>`.
//! A key with a limit names it after the default (`steps: u32 = 100, limit
//! Limit::Count(1..=1_000);`); a new kind of limit is a new [`Limit`] variant. A key's enum (the kernel's, say) changes in the enum
//! alone: its serde names are its TOML values and its `clap::ValueEnum` names its flag's.

use std::fmt;

use firmware::network::SUPPORTED_WIDTHS;
use serde::{Deserialize, Serialize};
use weights::{excerpt, quote};

use crate::nn::{Kernel, Loss};

mod deploy;
mod keys;
mod limits;
mod modal;

pub use deploy::{
    RIG_LEVELS, deploy_domain, deploy_eval_domain, deploy_finalist_domain, rig_effort,
};

use keys::config_keys;

/// How a configuration's `rig` is named in its refusals: it holds a rig file's text (the
/// command line's `--rig` reads the file into it), so a path there is a slip.
const RIG_TEXT: &str = "`rig` (a rig file's text, not a path)";
pub use limits::{KeyLimit, Limit, MAX_CONFIG_BYTES, MAX_SEEDS, Value};

/// Which TD target the learner regresses on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Algo {
    /// Double DQN: the online net picks `a* = argmax Q_online(s')`, the target net scores it.
    Ddqn,
    /// DQN: the target net both picks and scores, `max_a Q_target(s', a)`.
    Dqn,
}

/// Weight initialisation; biases start at 0.01 either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum Init {
    /// Xavier/Glorot normal: `N(0, 2 / (fan_in + fan_out))`.
    #[serde(rename = "xavier")]
    #[value(name = "xavier")]
    Xavier,
    /// Fixed `N(0, 0.1^2)`.
    #[serde(rename = "normal0.1")]
    #[value(name = "normal0.1")]
    Normal01,
}

/// How the target network follows the online one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum TargetUpdate {
    /// Copy the online weights every `target_period` units.
    Hard,
    /// Polyak-average every environment step with weight `tau`.
    Soft,
}

/// What `target_period` and the epsilon schedule count.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    /// Completed episodes.
    Episodes,
    /// Environment steps.
    Steps,
}

/// The kernel choice as configured: `auto` picks the fastest this CPU has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum KernelChoice {
    /// The fastest supported kernel.
    Auto,
    /// The target's baseline: NEON on aarch64; on x86-64, SSE2 with the fused
    /// multiply-adds in software (the same bits, slowly: a reference for tests).
    Portable,
    /// AVX2 + FMA.
    Avx2,
    /// AVX-512F + FMA.
    Avx512,
}

impl KernelChoice {
    /// The kernel to run, or an error if this CPU lacks it.
    pub fn resolve(self) -> Result<Kernel, ConfigError> {
        let k = match self {
            KernelChoice::Auto => return Ok(Kernel::detect()),
            KernelChoice::Portable => Kernel::Portable,
            KernelChoice::Avx2 => Kernel::Avx2,
            KernelChoice::Avx512 => Kernel::Avx512,
        };
        if k.supported() {
            Ok(k)
        } else {
            Err(ConfigError(format!(
                "kernel {self:?} is not supported by this CPU"
            )))
        }
    }
}

/// The named starting points of a configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// The paper's Table 2.
    Paper,
    /// Table 2 with Morvan Zhou's learning reward and a target copy every 50 environment
    /// steps: the two changes its headline needs (`docs/REPRODUCTION.md`).
    PaperFixed,
    /// CartPole-v1 (500-step episodes) in few environment steps: the robust preset with
    /// Morvan's learning reward and a 50,000-step budget (`docs/REPRODUCTION.md`).
    Fast,
    /// Tuned to balance the nominal plant perfectly (see `docs/TRAINING.md`).
    Robust,
    /// The shipped recipe: the robust preset in randomised worlds, with dead-time
    /// compensation and a reward shaped for an upright, centred pole (`docs/TRAINING.md`).
    Deploy,
}

config_keys! {
    /// Every hyperparameter of a run. Field names are the TOML keys and, with `-` for `_`, the
    /// command-line flags. Each key's default is the paper's (Table 2 and section 3): Double
    /// DQN, 4-64-64-2, Adam 5e-4, gamma 0.98, replay 2,000, batch 32, hard target copy every
    /// 50 episodes, epsilon 0.9 -> 0.01 with scale 200 steps, 300 episodes of 200 steps, clip
    /// 10, MSE, Xavier-normal.
    pub struct Config {
        /// TD target.
        algo: Algo = Algo::Ddqn;
        /// Hidden width: 16, 64 or 128 (64 ships; more levels than two at 64 only).
        width: usize = 64, limit Limit::OneOf(SUPPORTED_WIDTHS);
        /// The duty level of each output, fractions of the full push in increasing order,
        /// comma-separated (`-1,-0.2,0,0.2,1`): the network has one output per level;
        /// empty: the paper's two, full push left and right.
        #[serde(default)]
        levels: String = String::new(), limit Limit::Levels;
        /// Adam learning rate.
        lr: f64 = 5e-4, limit Limit::PositiveInF32;
        /// Adam beta1.
        adam_beta1: f64 = 0.9, limit Limit::BelowOne;
        /// Adam beta2.
        adam_beta2: f64 = 0.999, limit Limit::BelowOne;
        /// Adam epsilon.
        adam_eps: f64 = 1e-8, limit Limit::NormalInF32;
        /// Discount factor.
        gamma: f64 = 0.98, limit Limit::ZeroToOne;
        /// FIFO replay capacity, transitions.
        buffer_size: usize = 2000, limit Limit::Count(1..=5_000_000);
        /// Minibatch size.
        batch_size: usize = 32, limit Limit::Count(1..=4_096);
        /// Transitions stored before the first gradient step (at least `batch_size`).
        learning_starts: usize = 32;
        /// Training is due every this many `train_unit`s.
        train_every: usize = 1, limit Limit::Count(1..=1_000_000);
        /// What `train_every` counts: environment steps, or completed episodes (minimalRL
        /// trains after each episode).
        #[serde(default)]
        train_unit: Unit = Unit::Steps;
        /// Gradient steps each time training is due.
        #[serde(default)]
        updates_per_train: usize = 1, limit Limit::Count(1..=1_000);
        /// Hard copies or soft averaging.
        target_update: TargetUpdate = TargetUpdate::Hard;
        /// Hard update period, in `target_period_unit`.
        target_period: usize = 50, limit Limit::Count(1..=1_000_000_000);
        /// What `target_period` counts.
        target_period_unit: Unit = Unit::Episodes;
        /// Soft update weight.
        tau: f64 = 0.005, limit Limit::AboveZeroToOne;
        /// Exploration at t = 0.
        eps_start: f64 = 0.9, limit Limit::ZeroToOne;
        /// Exploration floor.
        eps_end: f64 = 0.01, limit Limit::ZeroToOne;
        /// Decay scale: `eps = end + (start - end) * exp(-t / eps_decay)`.
        eps_decay: f64 = 200.0, limit Limit::Positive;
        /// What t counts in the epsilon schedule.
        eps_unit: Unit = Unit::Steps;
        /// Training episodes.
        episodes: usize = 300, limit Limit::Count(1..=1_000_000);
        /// A hard budget of environment steps: no step is taken once it is spent. The episode
        /// in progress is cut there and ends as any other (its end-of-episode training and
        /// target copy, if due, and an evaluation); 0: no budget. Evaluation episodes are not
        /// counted.
        #[serde(default)]
        max_env_steps: u64 = 0, limit Limit::Count(0..=1_000_000_000);
        /// Episode truncation: 200 (the paper) or 500 (`CartPole-v1`).
        max_steps: u32 = 200, limit Limit::Count(1..=1_000_000);
        /// Global gradient-norm clip; 0 disables it.
        grad_clip: f64 = 10.0, limit Limit::Clip;
        /// Regression loss.
        loss: Loss = Loss::Mse;
        /// Weight initialisation.
        init: Init = Init::Xavier;
        /// Every this many episodes, score the greedy policy and keep the best one as the
        /// run's policy; 0 keeps the last weights.
        eval_every: usize = 0, limit Limit::Count(0..=1_000_000);
        /// Episodes per such evaluation (their starts are fixed for the run).
        eval_episodes: usize = 10, limit Limit::Count(1..=100_000);
        /// Episode length of those evaluations and of the final one.
        eval_max_steps: u32 = 500, limit Limit::Count(1..=1_000_000);
        /// Stop early once a periodic evaluation is perfect (every episode reaches the limit).
        stop_when_perfect: bool = false;
        /// Stop early once this many periodic evaluations in a row found no better snapshot
        /// than the best so far: the selection says the policy is done; 0 never stops so.
        #[serde(default)]
        patience: usize = 0, limit Limit::Count(0..=1_000_000);
        /// Stop early once this many periodic evaluations in a row were perfect: the
        /// policy has held every episode of the worlds it is chosen on for a while; 0 never
        /// stops so.
        #[serde(default)]
        settle: usize = 0, limit Limit::Count(0..=1_000_000);
        /// Fresh greedy episodes that score the exported policy at the end of a run.
        final_eval_episodes: usize = 100, limit Limit::Count(1..=100_000);
        /// How many of the best periodic snapshots a longer trial chooses the policy among, so
        /// that one which drifts only over long episodes is not shipped; 0: the best periodic
        /// snapshot is the policy.
        #[serde(default)]
        finalists: usize = 0, limit Limit::Count(0..=100);
        /// Episodes of that trial (starts fixed for the run).
        #[serde(default)]
        finalist_episodes: usize = 0, limit Limit::Count(0..=100_000);
        /// Their length.
        #[serde(default)]
        finalist_max_steps: u32 = 0, limit Limit::Count(0..=1_000_000);
        /// Which compiled kernel to train with.
        kernel: KernelChoice = KernelChoice::Auto;
        /// Domain randomisation: the distribution of worlds a training episode is drawn from
        /// (a `twin::Domain` spec, e.g. `length=0.5..1.6+delay=0..3`); empty: the nominal
        /// plant.
        #[serde(default)]
        domain: String = String::new(), limit Limit::Domain;
        /// The worlds of the periodic and final greedy evaluations (a domain spec); empty: the
        /// nominal plant.
        #[serde(default)]
        eval_domain: String = String::new(), limit Limit::Domain;
        /// The worlds of the finalists' trial (a domain spec); empty: `eval_domain`'s.
        #[serde(default)]
        finalist_domain: String = String::new(), limit Limit::Domain;
        /// Try each finalist as its int8 network too (quantised as `export --quant int8`
        /// does), on the same worlds, and rank it by the worse of the two: a board may run
        /// either, so a snapshot whose integer network fails is not shipped.
        #[serde(default)]
        board_int8: bool = false;
        /// How much shorter a finalist's trial survival may be than the best's and still be
        /// chosen, as a fraction of the best: 0 ships the longest survivor (the earlier among
        /// equals); above 0, the finalist of the lowest trial cost among those within it,
        /// since survivals that differ by less than the trial's sampling noise say nothing of
        /// which policy is better, and the cost says which holds the pole more gently.
        #[serde(default)]
        trial_margin: f64 = 0.0, limit Limit::ZeroToOne;
        /// Decide on readings advanced over each world's dead time with the nominal model, as
        /// the deployed controller does (`firmware::controller::predict`).
        #[serde(default)]
        compensate: bool = false;
        /// The learning reward (`reward::Reward`: `env`, `morvan`, `upright=W`, `centre=W`,
        /// `fail-penalty=V`, `scale=K`, joined by `+`); empty: the task's own +1 per step.
        #[serde(default)]
        reward: String = String::new(), limit Limit::Reward;
        /// The rig trained for, as a rig file's text (`twin::rigfile`; on the command line,
        /// `--rig FILE` reads the file): the nominal world, the centre the domains' factors
        /// are relative to, its control period and dead time; empty: Gymnasium's machine.
        #[serde(default)]
        #[flag(file)]
        rig: String = String::new(), limit Limit::Rig;
    }
}

/// The duty levels `spec` lists (comma-separated fractions of the full push), or the
/// paper's two for an empty spec; refused as `weights::levels::parse_levels` refuses them.
pub fn parse_levels(spec: &str) -> Result<Vec<f32>, String> {
    if spec.trim().is_empty() {
        return Ok(weights::BANG_BANG.to_vec());
    }
    weights::levels::parse_levels(spec, "levels").map_err(|e| e.to_string())
}

impl Config {
    /// The duty level of each output (`validate` has checked them).
    pub fn levels(&self) -> Result<Vec<f32>, ConfigError> {
        parse_levels(&self.levels).map_err(ConfigError)
    }

    /// The machine `rig` describes (`validate` has checked it).
    pub fn machine(&self) -> Result<twin::Machine, ConfigError> {
        if self.rig.is_empty() {
            return Ok(twin::Machine::GYMNASIUM);
        }
        twin::rigfile::parse(&self.rig, RIG_TEXT).map_err(|e| ConfigError(e.to_string()))
    }

    /// The configuration as the project's files record it (policy files, the reproduction's
    /// results): every key, but `board_int8`, `trial_margin` and `settle` while they are
    /// off, so the files of runs that use none of them keep the bytes they had before the
    /// keys existed.
    pub fn recorded(&self) -> serde_json::Result<serde_json::Value> {
        let mut v = serde_json::to_value(self)?;
        if let Some(map) = v.as_object_mut() {
            if !self.board_int8 {
                map.remove("board_int8");
            }
            if self.trial_margin == 0.0 {
                map.remove("trial_margin");
            }
            if self.settle == 0 {
                map.remove("settle");
            }
        }
        Ok(v)
    }
}

impl Config {
    /// The paper preset with the fewest changes that make its headline (a trailing 100-episode
    /// mean of 195 by episode 160) hold: see [`Config::with_paper_fixes`].
    pub fn paper_fixed() -> Config {
        Config::paper().with_paper_fixes()
    }

    /// The two changes of `paper-fixed`, on any configuration: the learner sees Morvan Zhou's
    /// reward, and the target net is copied every 50 environment steps rather than every 50
    /// episodes. Each alone converges by episode 160 in at most 3 of 20 seeds; together in
    /// 20 of 20 (`docs/REPRODUCTION.md`, the shaping study).
    pub fn with_paper_fixes(self) -> Config {
        Config {
            reward: "morvan".into(),
            target_period_unit: Unit::Steps,
            ..self
        }
    }

    /// CartPole-v1 in few environment steps: the robust preset learning from Morvan's
    /// reward, within a budget of 50,000 environment steps, stopping at the first greedy
    /// snapshot that balances 100 evaluation episodes of 500 steps.
    pub fn fast() -> Config {
        Config {
            reward: "morvan".into(),
            max_env_steps: 50_000,
            // Never reached: no CartPole episode is shorter than 8 steps.
            episodes: 10_000,
            ..Config::robust()
        }
    }

    /// The deployable preset: same network, chosen by experiment (`docs/TRAINING.md`).
    pub fn robust() -> Config {
        Config {
            gamma: 0.99,
            lr: 1e-3,
            buffer_size: 50_000,
            batch_size: 64,
            learning_starts: 1_000,
            target_update: TargetUpdate::Soft,
            tau: 0.005,
            eps_start: 1.0,
            eps_end: 0.01,
            eps_decay: 2_000.0,
            episodes: 800,
            max_steps: 500,
            loss: Loss::Huber,
            eval_every: 5,
            eval_episodes: 100,
            stop_when_perfect: true,
            ..Config::paper()
        }
    }

    /// The shipped recipe: per episode a world drawn from ranges wider than the evaluation's
    /// default set (physics, friction, noise, encoders, dead time, pushes), the policy told
    /// each world's dead time, a learning reward that costs leaning and wandering, and the
    /// snapshot chosen on worlds like the default set's, read through encoders; the run
    /// stops once 50 evaluations in a row (500 episodes) found no better snapshot. Every
    /// choice and its evidence: `docs/TRAINING.md`.
    pub fn deploy() -> Config {
        Config::deploy_on(&twin::Machine::GYMNASIUM)
    }

    /// The preset's configuration.
    pub fn preset(p: Preset) -> Config {
        Config::preset_on(p, &twin::Machine::GYMNASIUM)
    }

    /// The preset's configuration for `machine`: the deploy recipe made for it
    /// ([`Config::deploy_on`]); the others as they are, on its rig.
    pub fn preset_on(p: Preset, machine: &twin::Machine) -> Config {
        let c = match p {
            Preset::Paper => Config::paper(),
            Preset::PaperFixed => Config::paper_fixed(),
            Preset::Fast => Config::fast(),
            Preset::Robust => Config::robust(),
            Preset::Deploy => return Config::deploy_on(machine),
        };
        Config {
            rig: if *machine == twin::Machine::GYMNASIUM {
                String::new()
            } else {
                twin::rigfile::to_toml(machine)
            },
            ..c
        }
    }

    /// Overlays the keys of a TOML document; an unknown key, a wrongly typed value or a
    /// number that reads as zero (`1e-400`) is an error that names it.
    pub fn overlay_toml(&self, text: &str, origin: &str) -> Result<Config, ConfigError> {
        if let Some(why) = weights::hidden_zero(text) {
            return Err(ConfigError(format!("{origin}: {why}")));
        }
        let file: toml::Table = toml::from_str(text).map_err(|e| {
            let why = weights::located(text, e.span(), e.message());
            ConfigError(format!("{origin}: {why}"))
        })?;
        let mut merged = toml::Table::try_from(self)
            .map_err(|e| ConfigError(format!("internal: config is not TOML: {e}")))?;
        for (k, v) in file {
            if let Some(l) = LIMITS.iter().find(|l| l.key == k) {
                (l.limit.check_toml(&k, &v)).map_err(|e| ConfigError(format!("{origin}: {e}")))?;
            }
            if !merged.contains_key(&k) {
                let known: Vec<&str> = merged.keys().map(String::as_str).collect();
                return Err(ConfigError(format!(
                    "{origin}: unknown key {} (known keys: {})",
                    quote(&k),
                    known.join(", ")
                )));
            }
            merged.insert(k, v);
        }
        merged.try_into().map_err(|e: toml::de::Error| {
            // serde's reason, then "in `key`" on a line of its own: one line, key first.
            let text = e.to_string();
            let mut lines = text.lines();
            let why = excerpt(lines.next().unwrap_or_default());
            let key = lines.find_map(|l| l.strip_prefix("in `")?.strip_suffix('`'));
            let key = key.map_or(String::new(), |k| format!("{}: ", excerpt(k)));
            ConfigError(format!("{origin}: {key}{why}"))
        })
    }
}

/// A configuration that cannot be run; the command line exits with status 2 on it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigError(pub String);

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid configuration: {}", self.0)
    }
}

impl std::error::Error for ConfigError {}

#[cfg(test)]
mod tests;
