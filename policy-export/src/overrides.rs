//! The `train` command's arguments, and the configuration they build in layers: a preset,
//! then a TOML file over it, then one flag per key ([`Overrides`]) over that.
//! (A module of the `policy-export` binary, not of the library.)

use std::ops::Range;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use policy_export::config::{
    Algo, Config, ConfigError, Init, KernelChoice, MAX_CONFIG_BYTES, MAX_SEEDS, Preset,
    TargetUpdate, Unit,
};
use policy_export::nn::Loss;
use weights::files::read_capped;

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct TrainArgs {
    /// Starting point: the paper's Table 2, its fixed version, the fast CartPole-v1 learner,
    /// or the deployable presets.
    #[arg(long, value_enum, default_value = "paper")]
    pub preset: Preset,
    /// TOML file of config keys overriding the preset (flags override it in turn).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// One seed.
    #[arg(long, default_value_t = 0, conflicts_with = "seeds")]
    pub seed: u64,
    /// A range of seeds run in parallel, e.g. 0..10; each gets DIR/seed-N.
    #[arg(long, value_parser = parse_range)]
    pub seeds: Option<Range<u64>>,
    /// Run directory (omit to train without writing anything).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the final configuration as TOML and exit.
    #[arg(long)]
    pub print_config: bool,
    #[command(flatten)]
    pub set: Overrides,
}

fn parse_range(s: &str) -> Result<Range<u64>, String> {
    let shown = weights::quote(s);
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("found {shown}; expected START..END, e.g. 0..10"))?;
    let (a, b): (u64, u64) = match (a.parse(), b.parse()) {
        (Ok(a), Ok(b)) => (a, b),
        _ => {
            return Err(format!(
                "expected two whole numbers START..END, found {shown}"
            ));
        }
    };
    if a >= b {
        return Err(format!("expected a non-empty range, found {a}..{b}"));
    }
    if b - a > MAX_SEEDS {
        return Err(format!(
            "expected at most {MAX_SEEDS} seeds, found {} in {a}..{b}",
            b - a
        ));
    }
    Ok(a..b)
}

pub fn build_config(args: &TrainArgs) -> Result<Config> {
    let mut cfg = Config::preset(args.preset);
    if let Some(path) = &args.config {
        let bytes = read_capped(path, MAX_CONFIG_BYTES)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            ConfigError(format!(
                "--config {}: expected UTF-8 text, {e}",
                path.display()
            ))
        })?;
        cfg = cfg.overlay_toml(&text, &path.display().to_string())?;
    }
    args.set.apply(&mut cfg);
    cfg.validate()?;
    Ok(cfg)
}

/// One flag per configuration key; see `Config` for their meaning.
#[derive(Args)]
pub struct Overrides {
    #[arg(long, value_enum)]
    algo: Option<Algo>,
    #[arg(long)]
    width: Option<usize>,
    #[arg(long)]
    lr: Option<f64>,
    #[arg(long)]
    adam_beta1: Option<f64>,
    #[arg(long)]
    adam_beta2: Option<f64>,
    #[arg(long)]
    adam_eps: Option<f64>,
    #[arg(long)]
    gamma: Option<f64>,
    #[arg(long)]
    buffer_size: Option<usize>,
    #[arg(long)]
    batch_size: Option<usize>,
    #[arg(long)]
    learning_starts: Option<usize>,
    #[arg(long)]
    train_every: Option<usize>,
    #[arg(long, value_enum)]
    train_unit: Option<Unit>,
    #[arg(long)]
    updates_per_train: Option<usize>,
    #[arg(long)]
    max_env_steps: Option<u64>,
    #[arg(long, value_enum)]
    target_update: Option<TargetUpdate>,
    #[arg(long)]
    target_period: Option<usize>,
    #[arg(long, value_enum)]
    target_period_unit: Option<Unit>,
    #[arg(long)]
    tau: Option<f64>,
    #[arg(long)]
    eps_start: Option<f64>,
    #[arg(long)]
    eps_end: Option<f64>,
    #[arg(long)]
    eps_decay: Option<f64>,
    #[arg(long, value_enum)]
    eps_unit: Option<Unit>,
    #[arg(long)]
    episodes: Option<usize>,
    #[arg(long)]
    max_steps: Option<u32>,
    #[arg(long)]
    grad_clip: Option<f64>,
    #[arg(long, value_enum)]
    loss: Option<Loss>,
    #[arg(long, value_enum)]
    init: Option<Init>,
    #[arg(long)]
    eval_every: Option<usize>,
    #[arg(long)]
    eval_episodes: Option<usize>,
    #[arg(long)]
    eval_max_steps: Option<u32>,
    #[arg(long)]
    stop_when_perfect: Option<bool>,
    #[arg(long)]
    final_eval_episodes: Option<usize>,
    #[arg(long)]
    finalists: Option<usize>,
    #[arg(long)]
    finalist_episodes: Option<usize>,
    #[arg(long)]
    finalist_max_steps: Option<u32>,
    #[arg(long, value_enum)]
    kernel: Option<KernelChoice>,
    #[arg(long)]
    compensate: Option<bool>,
    #[arg(long)]
    domain: Option<String>,
    #[arg(long)]
    eval_domain: Option<String>,
    #[arg(long)]
    finalist_domain: Option<String>,
    #[arg(long)]
    reward: Option<String>,
}

impl Overrides {
    pub fn apply(&self, c: &mut Config) {
        macro_rules! set {
            ($($f:ident),*) => { $( if let Some(v) = self.$f { c.$f = v; } )* };
        }
        set!(
            algo,
            width,
            lr,
            adam_beta1,
            adam_beta2,
            adam_eps,
            gamma,
            buffer_size,
            batch_size,
            learning_starts,
            train_every,
            train_unit,
            updates_per_train,
            max_env_steps,
            target_update,
            target_period,
            target_period_unit,
            tau,
            eps_start,
            eps_end,
            eps_decay,
            eps_unit,
            episodes,
            max_steps,
            grad_clip,
            loss,
            init,
            eval_every,
            eval_episodes,
            eval_max_steps,
            stop_when_perfect,
            final_eval_episodes,
            finalists,
            finalist_episodes,
            finalist_max_steps,
            kernel,
            compensate
        );
        for (field, v) in [
            (&mut c.domain, &self.domain),
            (&mut c.eval_domain, &self.eval_domain),
            (&mut c.finalist_domain, &self.finalist_domain),
            (&mut c.reward, &self.reward),
        ] {
            if let Some(v) = v {
                field.clone_from(v);
            }
        }
    }
}
