//! What a configuration may ask for, checked before any work starts: every count has an upper
//! limit, so a run's memory is bounded (the replay buffer is the largest allocation: about 70
//! bytes a transition, 350 MB at its limit) and a typo cannot ask for a year of training.
//! Real-valued settings must survive the conversion to f32 the kernels do.

use firmware::network::SUPPORTED_WIDTHS;

use super::{Config, ConfigError};

/// Largest TOML file `--config` reads.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;
/// Most seeds one `train --seeds` runs.
pub const MAX_SEEDS: u64 = 10_000;

/// One count of a configuration and the range it accepts.
pub struct Count {
    /// Its key (the TOML key; the flag is `--` and the key with `-` for `_`).
    pub key: &'static str,
    /// Smallest accepted value.
    pub min: u64,
    /// Largest accepted value.
    pub max: u64,
    get: fn(&Config) -> u64,
}

/// Every count's accepted range, in the order `docs/HOSTILE_INPUT.md` lists them.
pub const COUNTS: [Count; 15] = [
    Count {
        key: "episodes",
        min: 1,
        max: 1_000_000,
        get: |c| c.episodes as u64,
    },
    Count {
        key: "max_steps",
        min: 1,
        max: 1_000_000,
        get: |c| c.max_steps.into(),
    },
    Count {
        key: "eval_max_steps",
        min: 1,
        max: 1_000_000,
        get: |c| c.eval_max_steps.into(),
    },
    Count {
        key: "buffer_size",
        min: 1,
        max: 5_000_000,
        get: |c| c.buffer_size as u64,
    },
    Count {
        key: "batch_size",
        min: 1,
        max: 4_096,
        get: |c| c.batch_size as u64,
    },
    Count {
        key: "train_every",
        min: 1,
        max: 1_000_000,
        get: |c| c.train_every as u64,
    },
    Count {
        key: "updates_per_train",
        min: 1,
        max: 1_000,
        get: |c| c.updates_per_train as u64,
    },
    Count {
        key: "max_env_steps",
        min: 0,
        max: 1_000_000_000,
        get: |c| c.max_env_steps,
    },
    Count {
        key: "target_period",
        min: 1,
        max: 1_000_000_000,
        get: |c| c.target_period as u64,
    },
    Count {
        key: "eval_every",
        min: 0,
        max: 1_000_000,
        get: |c| c.eval_every as u64,
    },
    Count {
        key: "eval_episodes",
        min: 1,
        max: 100_000,
        get: |c| c.eval_episodes as u64,
    },
    Count {
        key: "final_eval_episodes",
        min: 1,
        max: 100_000,
        get: |c| c.final_eval_episodes as u64,
    },
    Count {
        key: "finalists",
        min: 0,
        max: 100,
        get: |c| c.finalists as u64,
    },
    Count {
        key: "finalist_episodes",
        min: 0,
        max: 100_000,
        get: |c| c.finalist_episodes as u64,
    },
    Count {
        key: "finalist_max_steps",
        min: 0,
        max: 1_000_000,
        get: |c| c.finalist_max_steps.into(),
    },
];

impl Config {
    /// Checks every value before any work starts; the error lists every problem.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let mut errs = Vec::new();
        let mut check = |ok: bool, msg: String| {
            if !ok {
                errs.push(msg);
            }
        };
        check(
            SUPPORTED_WIDTHS.contains(&self.width),
            format!(
                "width must be one of {SUPPORTED_WIDTHS:?}, got {}",
                self.width
            ),
        );
        for c in &COUNTS {
            let v = (c.get)(self);
            check(
                (c.min..=c.max).contains(&v),
                format!("{} must be in [{}, {}], got {v}", c.key, c.min, c.max),
            );
        }
        check(
            self.finalists == 0 || (self.finalist_episodes > 0 && self.finalist_max_steps > 0),
            format!(
                "finalists ({}) need finalist_episodes and finalist_max_steps >= 1, got {} and {}",
                self.finalists, self.finalist_episodes, self.finalist_max_steps
            ),
        );
        // The kernels compute in f32: a value must stay positive and finite there.
        let f32_positive = |v: f64| v.is_finite() && v > 0.0 && (v as f32).is_normal();
        check(
            f32_positive(self.lr),
            format!("lr must be > 0 and finite in f32, got {}", self.lr),
        );
        for (name, b) in [
            ("adam_beta1", self.adam_beta1),
            ("adam_beta2", self.adam_beta2),
        ] {
            check(
                (0.0..1.0).contains(&b),
                format!("{name} must be in [0, 1), got {b}"),
            );
        }
        check(
            f32_positive(self.adam_eps),
            format!(
                "adam_eps must be a normal f32 > 0 (at least {:e}), got {}",
                f32::MIN_POSITIVE,
                self.adam_eps
            ),
        );
        check(
            (0.0..=1.0).contains(&self.gamma),
            format!("gamma must be in [0, 1], got {}", self.gamma),
        );
        check(
            self.batch_size <= self.buffer_size,
            format!(
                "batch_size ({}) must not exceed buffer_size ({})",
                self.batch_size, self.buffer_size
            ),
        );
        check(
            self.learning_starts <= self.buffer_size,
            format!(
                "learning_starts ({}) must not exceed buffer_size ({})",
                self.learning_starts, self.buffer_size
            ),
        );
        check(
            self.tau <= 1.0 && f32_positive(self.tau),
            format!("tau must be in (0, 1], got {}", self.tau),
        );
        for (name, e) in [("eps_start", self.eps_start), ("eps_end", self.eps_end)] {
            check(
                (0.0..=1.0).contains(&e),
                format!("{name} must be in [0, 1], got {e}"),
            );
        }
        check(
            self.eps_decay.is_finite() && self.eps_decay > 0.0,
            format!("eps_decay must be > 0 and finite, got {}", self.eps_decay),
        );
        check(
            self.grad_clip >= 0.0 && (self.grad_clip as f32).is_finite(),
            format!(
                "grad_clip must be >= 0 and finite in f32 (0 disables it), got {}",
                self.grad_clip
            ),
        );
        for (key, spec) in [
            ("domain", &self.domain),
            ("eval_domain", &self.eval_domain),
            ("finalist_domain", &self.finalist_domain),
        ] {
            if let Err(e) = twin::Domain::parse(spec) {
                errs.push(format!("{key}: {e}"));
            }
        }
        if let Err(e) = crate::train::Reward::parse(&self.reward) {
            errs.push(format!("reward: {e}"));
        }
        if errs.is_empty() {
            self.kernel.resolve().map(|_| ())
        } else {
            Err(ConfigError(errs.join("; ")))
        }
    }
}
