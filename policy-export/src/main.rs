//! `policy-export`: trains the cart-pole controller and exports it for firmware.
#![deny(clippy::print_stdout, clippy::print_stderr)]

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Mutex;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use policy_export::config::{Config, ConfigError, KernelChoice};
use policy_export::export::{self, Language};
use policy_export::outdir::Staging;
use policy_export::run::{self, Summary};
use policy_export::train::{self, EpisodeRecord};
use rayon::prelude::*;
use weights::checkpoint;
use weights::files::{check_io, write_atomic};
use weights::levels::GivenLevels;
use weights::quant::Granularity;

mod overrides;

use overrides::{TrainArgs, build_config};

#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train a Double DQN (or DQN) controller and write a run directory.
    Train(Box<TrainArgs>),
    /// Write a policy (a run directory, or a checkpoint as PyTorch users save it) as a Rust
    /// module of const arrays or a C header.
    Export(ExportArgs),
    /// Rerun the paper's Tables 1, 4, 5, 6, its initialisation and target-update choices,
    /// single changes to its preset, learning rewards and readings of its text, and the
    /// tables again on paper-fixed, with many seeds; write tables, JSON and figures.
    Reproduce {
        /// Seeds per configuration.
        #[arg(long, default_value_t = 20)]
        seeds: u64,
        /// Output directory (results.json, tables.md, SVG and PNG figures).
        #[arg(long, default_value = "runs/reproduce")]
        out: PathBuf,
        /// Studies to run (default all): table1, table4, table5, table6, init, target, fix,
        /// shaping, table1-fixed, table4-fixed, table5-fixed, table6-fixed.
        #[arg(long, value_delimiter = ',')]
        study: Vec<String>,
        /// Training kernel for every run.
        #[arg(long, value_enum, default_value = "auto")]
        kernel: KernelChoice,
    },
}

#[derive(Args)]
struct ExportArgs {
    /// A run directory (its policy.safetensors), a safetensors file, a torch.save zip (.pt,
    /// .pth, .cleanrl_model), a Stable-Baselines3 model.zip or an ONNX model: tensors named
    /// fc1/fc2/fc3, nn.Sequential indices (0, 2, 4), or either under a prefix (network.,
    /// q_net.q_net., ...), found by their chain of shapes 4 -> H -> H -> A, one output per
    /// duty level.
    src: PathBuf,
    /// Output file (replaced atomically; never the input, never a device or directory).
    #[arg(long)]
    out: PathBuf,
    /// Rust module (for any crate that depends on `firmware`) or C header.
    #[arg(long, value_enum, default_value = "rust")]
    format: Format,
    /// Name of the static: default POLICY (Rust) or cartpole_policy (C); POLICY_INT or
    /// cartpole_policy_int with --quant.
    #[arg(long)]
    name: Option<String>,
    /// Tensor-name prefix of the network to take, when the file holds several (an online
    /// and a target net); "" for none.
    #[arg(long)]
    prefix: Option<String>,
    /// The duty level each output drives, for a checkpoint that records none (PyTorch,
    /// Stable-Baselines3, ONNX): comma-separated fractions of the full push in increasing
    /// order, one per output (`-1,-0.2,0,0.2,1`). A two-output checkpoint without them
    /// drives the paper's two, full push left and right; a file that records other levels
    /// refuses them.
    #[arg(long, allow_hyphen_values = true)]
    levels: Option<String>,
    /// Write the integer network for cores without an FPU (`firmware::network::int`):
    /// int8 weights calibrated on states the policy visits (`docs/QUANTISATION.md`).
    #[arg(long, value_enum)]
    quant: Option<Quant>,
    /// Weight scales of the hidden layers with --quant: one per tensor or one per unit
    /// (the default, the shipped policy's: `docs/QUANTISATION.md` measures both).
    #[arg(long, value_enum, requires = "quant")]
    granularity: Option<GranularityArg>,
    /// The rig the board runs (a rig file, `rigs/`): its `RIG` constants go beside the
    /// weights. Without it, the rig the policy file records, or Gymnasium's machine; a
    /// different one than the recorded is warned about.
    #[arg(long)]
    rig: Option<PathBuf>,
}

/// The integer formats an export can take.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Quant {
    /// int8 weights, int32 accumulators, u8 activations.
    Int8,
}

/// `weights::quant::Granularity` on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum GranularityArg {
    /// One scale per weight tensor.
    PerTensor,
    /// One scale per hidden unit.
    PerChannel,
}

/// The target language of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Format {
    /// A Rust module defining `pub static NAME: ::firmware::network::Mlp<H>`.
    Rust,
    /// A C header defining `static const struct cartpole_mlpH NAME`.
    C,
}

fn cmd_reproduce(seeds: u64, out: &Path, studies: &[String], kernel: KernelChoice) -> Result<()> {
    use policy_export::reproduce;
    // Every run's per-episode curves are kept for the figures (7 KB a run, 33 configurations).
    const MAX_REPRODUCE_SEEDS: u64 = 1_000;
    if !(2..=MAX_REPRODUCE_SEEDS).contains(&seeds) {
        return Err(ConfigError(format!(
            "--seeds must be in [2, {MAX_REPRODUCE_SEEDS}] (two at least, for confidence \
             intervals), got {seeds}"
        ))
        .into());
    }
    let base = Config {
        kernel,
        ..Config::paper()
    };
    let variants = reproduce::chosen(reproduce::variants(&base), studies)?;
    base.validate()?;
    // The output is checked now and written beside, then renamed: all of it or none.
    let staging = Staging::new(out, "reproduce")?;
    let total = reproduce::distinct_runs(&variants, seeds);
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(total).with_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed} (eta {eta})")
                .expect("static template"),
        )
    } else {
        ProgressBar::hidden()
    };
    let done = std::sync::atomic::AtomicU64::new(0);
    let started = std::time::Instant::now();
    let tick = || {
        bar.inc(1);
        let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        if bar.is_hidden() && (n.is_multiple_of((total / 10).max(1)) || n == total) {
            host_common::errln!("{n}/{total} runs, {:.0} s", started.elapsed().as_secs_f64());
        }
    };
    let runs = reproduce::run(&variants, seeds, &tick)?;
    bar.finish_and_clear();
    let provenance = host_common::provenance::Provenance::of_this_run("policy-export");
    let rows = reproduce::write(staging.path(), &variants, &runs, &provenance)?;
    staging.commit()?;
    host_common::out!("{}", reproduce::tables_md(&rows));
    host_common::errln!(
        "{total} runs in {:.1} s on {} threads; results in {}",
        started.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        weights::shown(out)
    );
    Ok(())
}

fn main() -> ExitCode {
    let cli: Cli = host_common::cli::parse();
    let result = match cli.command {
        Command::Train(args) => cmd_train(*args),
        Command::Export(args) => cmd_export(&args),
        Command::Reproduce {
            seeds,
            out,
            study,
            kernel,
        } => cmd_reproduce(seeds, &out, &study, kernel),
    };
    match result {
        Ok(()) => host_common::cli::exit(0),
        Err(e) => {
            host_common::errln!("error: {e:#}");
            let input = e.downcast_ref::<ConfigError>().is_some()
                || e.downcast_ref::<weights::Error>()
                    .is_some_and(weights::Error::is_input);
            host_common::cli::exit(if input { 2 } else { 1 })
        }
    }
}

fn cmd_train(args: TrainArgs) -> Result<()> {
    let cfg = build_config(&args)?;
    if args.print_config {
        host_common::out!("{}", toml::to_string(&cfg)?);
        return Ok(());
    }
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.into())
            .build_global()
            .map_err(|e| anyhow::anyhow!("--threads {n}: {e}"))?;
    }
    let seeds: Vec<u64> = args
        .seeds
        .clone()
        .map_or(vec![args.seed], Iterator::collect);
    let multi = args.seeds.is_some();
    // The run directory is checked before the work and written beside, then renamed.
    let staging = args
        .out
        .as_deref()
        .map(|d| Staging::new(d, "train"))
        .transpose()?;
    let progress = Progress::new(&cfg);
    let one = |seed: u64| {
        let dir = staging.as_ref().map(|st| {
            if multi {
                st.path().join(format!("seed-{seed}"))
            } else {
                st.path().to_path_buf()
            }
        });
        train_seed(&cfg, seed, &progress, dir.as_deref())
    };
    let summaries: Vec<Summary> = if multi {
        seeds.par_iter().map(|&s| one(s)).collect::<Result<_>>()?
    } else {
        vec![one(seeds[0])?]
    };
    summaries.iter().for_each(print_summary);
    if multi {
        print_aggregate(&summaries, staging.as_ref())?;
    }
    if let Some(st) = staging {
        st.commit()?;
    }
    Ok(())
}

/// Trains one seed and writes its run into `dir`, if there is one.
fn train_seed(cfg: &Config, seed: u64, progress: &Progress, dir: Option<&Path>) -> Result<Summary> {
    let mut shown = progress.seed(seed);
    let result = train::train(cfg, seed, &mut |e| shown.episode(e))
        .with_context(|| format!("seed {seed}"))?;
    if let Some(b) = &shown.bar {
        b.finish();
    }
    match dir {
        Some(dir) => run::write_run(dir, cfg, seed, &result),
        None => Ok(run::summarize(cfg, seed, &result)),
    }
}

/// How the seeds of one `train` show their progress: a bar each on a terminal, else a line
/// each tenth of the way.
struct Progress {
    bars: Option<MultiProgress>,
    log: Mutex<()>,
    budget: bool,
    len: u64,
    unit: &'static str,
}

/// One seed's share of a [`Progress`].
struct SeedProgress<'a> {
    all: &'a Progress,
    seed: u64,
    bar: Option<ProgressBar>,
    every: u64,
    next_log: u64,
    window: Vec<f64>,
}

impl Progress {
    fn new(cfg: &Config) -> Progress {
        // A budgeted run ends on its step count, long before its episode cap.
        let budget = cfg.max_env_steps > 0;
        let (len, unit) = if budget {
            (cfg.max_env_steps, "steps")
        } else {
            (cfg.episodes as u64, "ep")
        };
        Progress {
            bars: std::io::stderr().is_terminal().then(MultiProgress::new),
            log: Mutex::new(()),
            budget,
            len,
            unit,
        }
    }

    fn seed(&self, seed: u64) -> SeedProgress<'_> {
        let bar = self.bars.as_ref().map(|bars| {
            let b = bars.add(ProgressBar::new(self.len));
            b.set_style(
                ProgressStyle::with_template(&format!(
                    "{{prefix:>8}} {{bar:30}} {{pos:>4}}/{{len}} {} {{elapsed:>4}} (eta {{eta}}) {{msg}}",
                    self.unit
                ))
                .expect("static template"),
            );
            b.set_prefix(format!("seed {seed}"));
            b
        });
        let every = (self.len / 10).max(1);
        SeedProgress {
            all: self,
            seed,
            bar,
            every,
            next_log: every,
            window: Vec::with_capacity(100),
        }
    }
}

impl SeedProgress<'_> {
    fn episode(&mut self, e: &EpisodeRecord) {
        if self.window.len() == 100 {
            self.window.remove(0);
        }
        self.window.push(e.ret);
        let mean = self.window.iter().sum::<f64>() / self.window.len() as f64;
        let msg = format!(
            "{} env steps, return {:>3} mean100 {mean:>6.1} eps {:.3}",
            e.env_steps, e.ret, e.epsilon
        );
        let (all, seed) = (self.all, self.seed);
        let done = if all.budget {
            e.env_steps
        } else {
            e.episode as u64
        };
        match &self.bar {
            Some(b) => {
                b.set_position(done);
                b.set_message(msg);
            }
            None if done >= self.next_log => {
                self.next_log = (done / self.every + 1) * self.every;
                let _g = all.log.lock();
                // The time left, were the rest as fast as what came before.
                let eta = e.wall_s * (all.len.saturating_sub(done)) as f64 / done.max(1) as f64;
                host_common::errln!(
                    "seed {seed} {} {done}/{} ({:.0} s, eta {eta:.0} s): episode {}, {msg}",
                    all.unit,
                    all.len,
                    e.wall_s,
                    e.episode
                );
            }
            None => {}
        }
    }
}

/// One line per seed; a warning where the run took no gradient step (too short for
/// `learning_starts` or `train_every`): its policy is the network's initialisation.
fn print_summary(s: &Summary) {
    if s.grad_steps == 0 {
        host_common::errln!(
            "warning: seed {}: the run took no gradient step in its {} env steps \
             (learning_starts {}, train_every {}): the policy is the network as initialised",
            s.seed,
            s.env_steps,
            s.config.learning_starts,
            s.config.train_every
        );
    }
    host_common::outln!(
        "seed {:>3}: {} episodes, final mean100 {:>6.1}, solved@195 {:>4}, policy at {} env \
         steps, greedy eval {:>6.1} (min {:>3}) over {} x {} steps, {:.1} s, {:.1} us/step",
        s.seed,
        s.episodes_run,
        s.final_mean100,
        s.solved_episode_195.map_or("-".into(), |e| e.to_string()),
        s.policy_env_steps,
        s.final_eval.mean,
        s.final_eval.min,
        s.final_eval.episodes,
        s.final_eval.max_steps,
        s.wall_s,
        s.us_per_env_step
    );
    if let Some(b) = &s.board_trial {
        host_common::outln!(
            "seed {:>3}: the policy's trial as its boards run it: f32 mean {:.1} (min {}), \
             int8 mean {:.1} (min {}) over {} x {} periods",
            s.seed,
            b.f32.mean,
            b.f32.min,
            b.int8.mean,
            b.int8.min,
            b.f32.episodes,
            b.f32.max_steps
        );
    }
}

/// The seeds together, printed and written into the run directory as `aggregate.json`.
fn print_aggregate(summaries: &[Summary], staging: Option<&Staging>) -> Result<()> {
    let agg = run::aggregate(summaries);
    host_common::outln!(
        "{} seeds: median final mean100 {:.1}, {} of {} with greedy eval >= 475{}; \
         {} evaluation episodes ({} env steps) chose the policies; median {:.1} s",
        summaries.len(),
        agg.median_final_mean100,
        agg.seeds_greedy_at_least_475,
        summaries.len(),
        agg.policy_env_steps_at_475
            .map_or(String::new(), |(m, max)| format!(
                " (env steps to their policy: median {m:.0}, max {max})"
            )),
        agg.selection_episodes,
        agg.selection_steps,
        agg.median_wall_s
    );
    if let Some(st) = staging {
        write_atomic(
            &st.path().join("aggregate.json"),
            &serde_json::to_vec_pretty(&agg)?,
        )?;
    }
    Ok(())
}

fn cmd_export(a: &ExportArgs) -> Result<()> {
    let lang = match a.format {
        Format::Rust => Language::Rust,
        Format::C => Language::C,
    };
    let name = a
        .name
        .clone()
        .unwrap_or_else(|| export::default_name(lang, a.quant.is_some()).to_string());
    export::check_name(lang, &name)?;
    let levels = a
        .levels
        .as_deref()
        .map(|l| GivenLevels::parse(l, "--levels"))
        .transpose()?;
    let read = run::export_inputs(&a.src);
    let mut inputs: Vec<(&str, &Path)> = read.iter().map(|p| ("SRC", p.as_path())).collect();
    inputs.extend(a.rig.as_deref().map(|r| ("--rig", r)));
    check_io(&inputs, &[("--out", &a.out)])?;
    let import = checkpoint::load_with(&a.src, a.prefix.as_deref(), levels.as_ref())?;
    let prov = run::source_provenance(&a.src, &import)?;
    let granularity = a.quant.map(|Quant::Int8| match a.granularity {
        None => Granularity::default(),
        Some(GranularityArg::PerChannel) => Granularity::PerChannel,
        Some(GranularityArg::PerTensor) => Granularity::PerTensor,
    });
    let source = format!("SRC {}", weights::shown(&a.src));
    let (machine, other) = export::machine(&import, &source, a.rig.as_deref())?;
    twin::rigfile::warn(other);
    let r = export::render(&import, &prov, &machine, lang, granularity, &name)?;
    write_atomic(&a.out, r.text.as_bytes())?;
    let (out, params, how) = (
        weights::shown(&a.out),
        import.weights.params(),
        import.describe(),
    );
    match r.int8 {
        None => host_common::errln!("wrote {out}: {name}, {params} parameters ({how})"),
        Some((bytes, q)) => {
            host_common::errln!(
                "wrote {out}: {name}, {params} parameters in {bytes} bytes ({how}; {q})"
            )
        }
    }
    for warning in run::board_warnings(&a.src) {
        host_common::errln!("{warning}");
    }
    Ok(())
}
