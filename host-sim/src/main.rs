//! `host-sim`: checks and exercises the firmware's plant and controller on the host.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use firmware::cartpole::Params;
use host_sim::eval::{self, ControllerKind, Net, Row};
use host_sim::{render, replay};
use indicatif::{ProgressBar, ProgressStyle};
use twin::Scenario;
use weights::files::{check_output, remove_stale, temp_path_keeping_extension};

/// Most episodes per row of `eval`: a row keeps each episode's statistics (48 bytes), so
/// 480 MB at the limit.
const MAX_EPISODES: u64 = 10_000_000;
/// Longest episode `eval` runs, in periods (about 5.6 hours of control).
const MAX_HORIZON: u32 = 1_000_000;
/// Most rows of one `eval`.
const MAX_ROWS: usize = 10_000;
/// Longest episode `render` draws: it keeps every period (40 bytes) and draws each
/// `--stride`-th into the GIF.
const MAX_RENDER_HORIZON: u32 = 100_000;

#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Replay recorded Gymnasium CartPole trajectories (JSON Lines) through the plant and
    /// report, per case, the largest deviation and whether termination agrees. Exits 1 on
    /// any mismatch.
    Replay {
        /// One or more .jsonl files.
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Run the unchanged firmware controller in closed loop against the plant: N seeded
    /// episodes per controller, scenario and horizon, and a table with 95% confidence
    /// intervals. Exits 2 on bad input.
    Eval {
        /// Episodes per row.
        #[arg(long, default_value_t = 1000)]
        episodes: u64,
        /// Periods per episode (50 per second); several give several tables.
        #[arg(long, value_delimiter = ',', default_value = "500")]
        horizon: Vec<u32>,
        /// Scenarios, one row each: `nominal`, or parts joined by `+` from noise[=SCALE],
        /// delay[=N], force=F, length=F, polemass=F, cartmass=F, friction=C[/P],
        /// encoder=N[/M[/D]], push[=IMPULSE[/EVERY]]; `all` is the robustness set of
        /// docs/CONTROL.md, `hard` the set beyond it, `hard-candidates` what that set is chosen
        /// from.
        #[arg(long, value_delimiter = ',', default_value = "all")]
        scenario: Vec<String>,
        /// Controllers to compare.
        #[arg(long, value_delimiter = ',', default_value = "policy,lqr,rule,random")]
        controller: Vec<ControllerKind>,
        /// A policy instead of the one compiled into firmware: a run directory, or a
        /// safetensors state dict as PyTorch saves it (fc1/fc2/fc3, nn.Sequential indices,
        /// prefixed layouts), of any supported width.
        #[arg(long)]
        policy: Option<PathBuf>,
        /// Tensor-name prefix of the network in --policy, when it holds several.
        #[arg(long, requires = "policy")]
        prefix: Option<String>,
        /// Seed of the starts, noise and pushes.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Print one JSON object with a `rows` array instead of the table.
        #[arg(long)]
        json: bool,
        /// Exit 1 if the network's success rate falls below this in any row (0 to 1).
        #[arg(long)]
        min_success: Option<f64>,
    },
    /// Compare the integer network (what `policy-export export --quant int8` writes) with the
    /// float one on states the float policy visits: how often they choose the same action,
    /// and, where they do not, how close the float network was to choosing the other.
    Agree {
        /// A policy instead of the one compiled into firmware (see `eval`).
        #[arg(long)]
        policy: Option<PathBuf>,
        /// Tensor-name prefix of the network in --policy, when it holds several.
        #[arg(long, requires = "policy")]
        prefix: Option<String>,
        /// Visited states to compare (spread over the default set's rows).
        #[arg(long, default_value_t = 1_000_000)]
        states: u64,
        /// Seed of the episodes.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Print one JSON object instead of the tables.
        #[arg(long)]
        json: bool,
    },
    /// Draw one episode: an animated GIF of the cart and pole, and a PNG of x, theta and the
    /// commands over time.
    Render {
        /// Output directory; gets episode.gif and episode.png.
        #[arg(long, default_value = "render")]
        out: PathBuf,
        /// Which controller drives.
        #[arg(long, default_value = "policy")]
        controller: ControllerKind,
        /// A policy file instead of the compiled-in one (see `eval`).
        #[arg(long)]
        policy: Option<PathBuf>,
        /// Tensor-name prefix of the network in --policy, when it holds several.
        #[arg(long, requires = "policy")]
        prefix: Option<String>,
        /// One scenario spec (see `eval`).
        #[arg(long, default_value = "nominal")]
        scenario: String,
        /// Periods to run at most.
        #[arg(long, default_value_t = 500)]
        horizon: u32,
        /// Seed and episode number of the start (as in `eval`).
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(long, default_value_t = 0)]
        episode: u64,
        /// Draw every k-th period in the GIF (it plays in real time).
        #[arg(long, default_value_t = 2)]
        stride: usize,
    },
}

fn main() -> ExitCode {
    let cli: Cli = host_common::cli::parse();
    let result = match cli.command {
        Command::Replay { files } => run_replay(&files),
        Command::Eval {
            episodes,
            horizon,
            scenario,
            controller,
            policy,
            prefix,
            seed,
            json,
            min_success,
        } => run_eval(
            episodes,
            &horizon,
            &scenario,
            &controller,
            load_net(
                policy,
                prefix.as_deref(),
                controller.contains(&ControllerKind::PolicyInt),
            ),
            seed,
            json,
            min_success,
        ),
        Command::Agree {
            policy,
            prefix,
            states,
            seed,
            json,
        } => run_agree(
            load_net(policy, prefix.as_deref(), true),
            states,
            seed,
            json,
        )
        .map(|()| true),
        Command::Render {
            out,
            controller,
            policy,
            prefix,
            scenario,
            horizon,
            seed,
            episode,
            stride,
        } => run_render(
            &out,
            controller,
            load_net(
                policy,
                prefix.as_deref(),
                controller == ControllerKind::PolicyInt,
            ),
            &scenario,
            horizon,
            seed,
            episode,
            stride,
        )
        .map(|()| true),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(e) => {
            eprintln!("error: {e:#}");
            // Everything but a failure to write is the input's fault.
            let system = matches!(
                e.downcast_ref::<weights::Error>(),
                Some(weights::Error::Io(_))
            );
            ExitCode::from(if system { 1 } else { 2 })
        }
    }
}

/// The network to run: the compiled-in policy, or `--policy`'s, with its integer version
/// if `int`. Loaded lazily by the commands, after their cheaper checks.
fn load_net(
    policy: Option<PathBuf>,
    prefix: Option<&str>,
    int: bool,
) -> impl FnOnce() -> Result<Net> {
    move || match policy {
        None => Ok(Net::shipped()),
        Some(path) => {
            let import = weights::checkpoint::load(&path, prefix)?;
            Net::from_weights(&import.weights, int)
                .with_context(|| format!("policy {}", path.display()))
        }
    }
}

fn parse_scenarios(specs: &[String]) -> Result<Vec<Scenario>> {
    let mut out = Vec::new();
    for spec in specs {
        if spec == "all" {
            out.extend(Scenario::default_set());
        } else if spec == "hard" {
            out.extend(Scenario::hard_set());
        } else if spec == "hard-candidates" {
            out.extend(Scenario::hard_candidates());
        } else {
            out.push(Scenario::parse(spec).map_err(anyhow::Error::msg)?);
        }
    }
    Ok(out)
}

/// Most states `agree` compares: a hundred million take minutes.
const MAX_AGREE_STATES: u64 = 100_000_000;

fn run_agree(net: impl FnOnce() -> Result<Net>, states: u64, seed: u64, json: bool) -> Result<()> {
    anyhow::ensure!(
        (1..=MAX_AGREE_STATES).contains(&states),
        "--states must be in [1, {MAX_AGREE_STATES}], got {states}"
    );
    let net = net()?;
    let report = host_sim::agree::agreement(&net, states, seed)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", host_sim::agree::format_report(&report));
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn run_eval(
    episodes: u64,
    horizons: &[u32],
    scenarios: &[String],
    controllers: &[ControllerKind],
    net: impl FnOnce() -> Result<Net>,
    seed: u64,
    json: bool,
    min_success: Option<f64>,
) -> Result<bool> {
    if let Some(m) = min_success {
        anyhow::ensure!(
            (0.0..=1.0).contains(&m),
            "--min-success must lie in [0, 1], got {m}"
        );
    }
    anyhow::ensure!(
        (1..=MAX_EPISODES).contains(&episodes),
        "--episodes must be in [1, {MAX_EPISODES}], got {episodes}"
    );
    if let Some(h) = horizons.iter().find(|&&h| !(1..=MAX_HORIZON).contains(&h)) {
        anyhow::bail!("--horizon must be in [1, {MAX_HORIZON}], got {h}");
    }
    let scenarios = parse_scenarios(scenarios)?;
    let rows = horizons.len() * scenarios.len() * controllers.len();
    anyhow::ensure!(
        rows <= MAX_ROWS,
        "--horizon x --scenario x --controller must make at most {MAX_ROWS} rows, got {rows}"
    );
    let net = net()?;
    let jobs: Vec<(u32, &Scenario, ControllerKind)> = horizons
        .iter()
        .flat_map(|&h| {
            scenarios
                .iter()
                .flat_map(move |s| controllers.iter().map(move |&c| (h, s, c)))
        })
        .collect();
    let bar = ProgressBar::new(jobs.len() as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} rows, {elapsed} {msg}")
            .expect("static template"),
    );
    let mut rows: Vec<Row> = Vec::with_capacity(jobs.len());
    for (h, s, c) in jobs {
        bar.set_message(format!("{c} on {} at {h}", s.name));
        rows.push(eval::evaluate(c, &net, s, h, seed, episodes));
        bar.inc(1);
    }
    bar.finish_and_clear();
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "seed": seed, "rows": rows }))?
        );
    } else {
        print!("{}", eval::format_table(&rows));
        print!("{}", eval::format_failures(&rows, seed));
    }
    let failing: Vec<&Row> = rows
        .iter()
        .filter(|r| {
            r.controller == ControllerKind::Policy.to_string()
                && min_success.is_some_and(|m| r.success_rate < m)
        })
        .collect();
    for r in &failing {
        eprintln!(
            "policy below --min-success on {} at horizon {}: {:.1}%",
            r.scenario,
            r.horizon,
            100.0 * r.success_rate
        );
    }
    Ok(failing.is_empty())
}

#[allow(clippy::too_many_arguments)]
fn run_render(
    out: &std::path::Path,
    controller: ControllerKind,
    net: impl FnOnce() -> Result<Net>,
    scenario: &str,
    horizon: u32,
    seed: u64,
    episode: u64,
    stride: usize,
) -> Result<()> {
    anyhow::ensure!(
        (1..=MAX_RENDER_HORIZON).contains(&horizon),
        "--horizon must be in [1, {MAX_RENDER_HORIZON}] for render, got {horizon}"
    );
    anyhow::ensure!(
        (1..=1000).contains(&stride),
        "--stride must be in [1, 1000], got {stride}"
    );
    let scenario = Scenario::parse(scenario).map_err(anyhow::Error::msg)?;
    // The outputs are checked before the work: a directory (or a new path) holding, if
    // anything, regular files by those names, which are replaced whole.
    let (gif, png) = (out.join("episode.gif"), out.join("episode.png"));
    if let Ok(m) = std::fs::symlink_metadata(out)
        && !m.is_dir()
    {
        anyhow::bail!(
            "--out {}: expected a directory (or a new path), found {}",
            out.display(),
            weights::files::kind(&m.file_type())
        );
    }
    check_output(&gif, &[])?;
    check_output(&png, &[])?;
    let net = net()?;
    let mut frames = Vec::new();
    let stats = eval::episode(controller, &net, &scenario, horizon, seed, episode, |f| {
        frames.push(f)
    });
    std::fs::create_dir_all(out)
        .map_err(|e| weights::Error::Io(format!("creating {}: {e}", out.display())))?;
    let title = format!("{controller}, {}", scenario.name);
    // Drawn under temporary names and renamed, so a failure leaves no half-written picture;
    // the names end in the real extension because the encoders choose the format by it.
    remove_stale(&gif, &["tmp.gif"]);
    remove_stale(&png, &["tmp.png"]);
    let (gif_tmp, png_tmp) = (
        temp_path_keeping_extension(&gif),
        temp_path_keeping_extension(&png),
    );
    let drawn = render::gif(&gif_tmp, &frames, &scenario.params, stride, &title).and_then(|()| {
        render::timeseries(
            &png_tmp,
            &frames,
            &scenario.params,
            &format!(
                "{title}: {} of {horizon} periods, {}",
                stats.steps,
                if stats.success { "balanced" } else { "fell" }
            ),
        )
    });
    if let Err(e) = drawn {
        let _ = std::fs::remove_file(&gif_tmp);
        let _ = std::fs::remove_file(&png_tmp);
        return Err(e);
    }
    for (tmp, path) in [(&gif_tmp, &gif), (&png_tmp, &png)] {
        std::fs::rename(tmp, path)
            .map_err(|e| weights::Error::Io(format!("writing {}: {e}", path.display())))?;
    }
    println!("{}\n{}", gif.display(), png.display());
    Ok(())
}

fn run_replay(files: &[PathBuf]) -> anyhow::Result<bool> {
    let params = Params::default();
    let mut all_ok = true;
    for file in files {
        let cases = replay::load(file)?;
        println!("{}", file.display());
        println!(
            "{:>4} {:>6} {:>6} {:>12} {:>10} {:>10} {:>11}  result",
            "case", "seed", "steps", "max |dev|", "rollout≠", "step≠", "terminated"
        );
        let (mut steps, mut failed) = (0, 0);
        for (i, case) in cases.iter().enumerate() {
            let r = replay::replay_case(case, &params)?;
            steps += r.steps;
            let term = match (r.terminated_at, case.terminated_at) {
                (a, b) if a == b => a.map_or("-".into(), |s| s.to_string()),
                (a, b) => format!("{a:?}≠{b:?}"),
            };
            let seed = case.seed.map_or("-".into(), |s| s.to_string());
            let verdict = if r.matches() { "bit-exact" } else { "MISMATCH" };
            println!(
                "{i:>4} {seed:>6} {:>6} {:>12.3e} {:>10} {:>10} {term:>11}  {verdict}",
                r.steps, r.rollout_max_abs_dev, r.rollout_mismatches, r.step_mismatches
            );
            if !r.matches() {
                failed += 1;
            }
        }
        println!(
            "{} cases, {steps} steps, {failed} mismatched\n",
            cases.len()
        );
        all_ok &= failed == 0;
    }
    Ok(all_ok)
}
