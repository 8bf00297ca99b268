//! The `train` command's arguments, and the configuration they build in layers: a preset,
//! then a TOML file over it, then one flag per key (`config::Overrides`) over that.
//! (A module of the `policy-export` binary, not of the library.)

use std::ops::Range;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use policy_export::config::{Config, ConfigError, MAX_CONFIG_BYTES, MAX_SEEDS, Overrides, Preset};
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
    /// The rig file of the machine to train for (`rigs/`): the preset is made for it, and
    /// the configuration's `rig` key holds its text.
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// One seed.
    #[arg(long, default_value_t = 0, conflicts_with = "seeds")]
    pub seed: u64,
    /// A range of seeds run in parallel, e.g. 0..10; each gets DIR/seed-N.
    #[arg(long, value_parser = parse_range)]
    pub seeds: Option<Range<u64>>,
    /// Run directory (omit to train without writing anything).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the final configuration as TOML and exit. The run's own flags (`--out`,
    /// `--seed`, `--seeds`, `--threads`) are no part of it, so it takes none of them.
    #[arg(long, conflicts_with_all = ["out", "seed", "seeds", "threads"])]
    pub print_config: bool,
    /// Threads to use (default: one per core): with one, a run learns on one core instead
    /// of splitting each batch over two. Only the time changes, never a result.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=host_common::cli::MAX_THREADS as i64))]
    pub threads: Option<u16>,
    #[command(flatten)]
    pub set: Overrides,
}

fn parse_range(s: &str) -> Result<Range<u64>, String> {
    let shown = weights::quote(s);
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("found {shown}; expected START..END, e.g. 0..10"))?;
    let (a, b): (u64, u64) = match (weights::whole(a), weights::whole(b)) {
        (Some(a), Some(b)) => (a, b),
        _ => {
            return Err(format!(
                "expected two whole numbers START..END, each in decimal digits and at most {}, \
                 found {shown}",
                u64::MAX
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
    // On the command line the rig is a file; the preset is made for its machine, and the
    // configuration keeps the file's text, so that a run records the machine it was trained
    // for whole.
    let rig = match &args.rig {
        None => None,
        Some(path) => {
            let (text, origin) = twin::rigfile::read_text(path)?;
            let machine = twin::rigfile::parse(&text, &origin)?;
            Some((text, machine))
        }
    };
    let machine = rig.as_ref().map_or(twin::Machine::GYMNASIUM, |r| r.1);
    let preset = Config::preset_on(args.preset, &machine);
    let mut cfg = preset.clone();
    if let Some(path) = &args.config {
        let bytes = read_capped(path, MAX_CONFIG_BYTES)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            ConfigError(format!(
                "--config {}: expected UTF-8 text, {e}",
                weights::shown(path)
            ))
        })?;
        cfg = cfg.overlay_toml(&text, &weights::shown(path))?;
    }
    args.set.apply(&mut cfg);
    if let Some((text, _)) = rig {
        cfg.rig = text;
    }
    // A value from the file is named by the file; the flags name their own.
    let checked = cfg.validate().and_then(|()| cfg.unread(&preset));
    checked.map_err(|e| match &args.config {
        // The inner error's words alone: its Display says "invalid configuration" too.
        Some(path) => ConfigError(format!(
            "--config {} with the flags: {}",
            weights::shown(path),
            e.0
        )),
        None => e,
    })?;
    Ok(cfg)
}
