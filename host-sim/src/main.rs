//! `host-sim`: checks and exercises the firmware's plant and controller on the host.
#![deny(clippy::print_stdout, clippy::print_stderr)]

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Parser, Subcommand};
use firmware::cartpole::Params;
use host_common::provenance::Provenance;
use host_sim::eval::{self, ControllerKind, Row};
use host_sim::replay;
use indicatif::{ProgressBar, ProgressStyle};
use twin::{Machine, Scenario};

mod envelope_cmd;
mod eval_cmd;
mod identify_cmd;
mod pil_cmd;
mod render_cmd;
mod results_cmd;
mod soak_cmd;
mod startup_cmd;
mod subject;
mod tables_cmd;
mod world_arg;

use subject::{Monitor, Subject};

/// The board's machine without --policy or --rig, as messages name it.
const GYMNASIUM: &str = "Gymnasium's machine";

/// Most states `agree` compares: a hundred million take minutes.
const MAX_AGREE_STATES: u64 = 100_000_000;

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
    Eval(EvalArgs),
    /// Compare the integer network (what `policy-export export --quant int8` writes) with the
    /// float one on states the float policy visits: how often they choose the same action,
    /// and, where they do not, how close the float network was to choosing the other.
    Agree(AgreeArgs),
    /// Draw one episode: an animated GIF of the cart and pole, and a PNG of x, theta and the
    /// commands over time.
    Render(render_cmd::RenderArgs),
    /// Fit a rig's motor (stall force, damping), friction (the cart's Coulomb, the pivot's
    /// viscous), the pole's effective length and the dead time to the board's logs of its
    /// identification experiments, by simulation-error minimisation; print each estimate
    /// with a 95% interval and write the identified rig file. Exits 2 on bad input.
    Identify(identify_cmd::IdentifyArgs),
    /// Write the logs of the board's identification experiments (a cart and a swing) as a
    /// board measured as --rig would stream them from the true machine --world: a rig whose
    /// truth is known, to try `identify` and what follows it on. Exits 2 on bad input.
    SimulateLogs(identify_cmd::SimulateLogsArgs),
    /// Run one episode of many simulated hours (24 by default) through a scenario's sensors
    /// and faults, and report the largest error of the controller's readings in the first
    /// hour, the last hour and the whole run, and its coasting periods. Exits 1 if it did
    /// not balance to the end, 2 on bad input.
    Soak(soak_cmd::SoakArgs),
    /// Run episodes from power-on through the board's start-up: the pole hanging (or
    /// swinging, or lifted by a hand), its zero taken as gravity gives it, swung up or
    /// caught, then balanced; report how often and how fast the pole was up (f32 and int8),
    /// the track it took and the zero's error. Exits 2 on bad input.
    Startup(startup_cmd::StartupArgs),
    /// Measure where a policy drives in the episodes it balances (the default and hard sets
    /// by default): the runtime monitor's envelope, a quantile of each channel's readings
    /// with a margin; the shipped policy's as the firmware's `envelope` module with --out,
    /// any policy's as JSON for `eval --envelope` with --json. Exits 2 on bad input.
    Envelope(envelope_cmd::EnvelopeArgs),
    /// Print the parts scenarios and domains are made of, with their values' bounds and
    /// defaults: the Markdown table docs/SCENARIOS.md shows.
    Parts,
    /// Write the results tables and values of README.md and docs/*.md from the files of
    /// docs/results/: every block between a `<!-- results: docs/results/FILE.json OPTION...
    /// -->` line and a `<!-- /results -->` line, and every figure between `<!-- value: ...
    /// -->` and `<!-- /value -->`; and each results file's page, docs/results/NAME.md (its
    /// command, date and machine, and every row). With --check, exit 1 listing the ones that
    /// differ. Exits 2 on a malformed marker, a value that is not one row's or an unreadable
    /// file, naming the document and line.
    Tables(tables_cmd::TablesArgs),
    /// The steps of docs/results/manifest.toml, how every generated and results file is made
    /// (`steps`, for scripts/regenerate.sh), and which rows of a results file moved when it
    /// was measured again (`moved OLD NEW`). Exits 2 on a malformed manifest or file.
    Results(results_cmd::ResultsArgs),
}

#[derive(Args)]
struct EvalArgs {
    /// Episodes per row.
    #[arg(long, default_value_t = 1000)]
    episodes: u64,
    /// Periods per episode; several give several tables.
    #[arg(long, value_delimiter = ',', default_value = "500")]
    horizon: Vec<u32>,
    /// Scenarios, one row each (see `--help` for the parts).
    #[arg(long, value_delimiter = ',', default_value = "all")]
    scenario: Vec<String>,
    /// Controllers to compare [default: policy,lqr,rule,random; with --pil: policy].
    #[arg(long, value_delimiter = ',')]
    controller: Option<Vec<ControllerKind>>,
    #[command(flatten)]
    subject: Subject,
    #[command(flatten)]
    monitor: Monitor,
    /// The true machine the episodes run in (a rig file), when the board models another
    /// (the one --rig or the policy gives, as its observer, predictor and LQR gain do):
    /// a policy trained for one rig run on another, or a rig identified from a true one.
    #[arg(long)]
    world: Option<PathBuf>,
    /// Seed of the starts, noise and pushes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Print one JSON object with a `rows` array instead of the table.
    #[arg(long)]
    json: bool,
    /// Exit 1 if the network's success rate falls below this in any row (above 0, at most 1).
    #[arg(long)]
    min_success: Option<f64>,
    #[command(flatten)]
    pil: pil_cmd::PilArgs,
}

impl EvalArgs {
    /// The controllers asked for, or the default.
    fn controllers(&self) -> Vec<ControllerKind> {
        use ControllerKind::*;
        match (&self.controller, &self.pil.pil) {
            (Some(c), _) => c.clone(),
            (None, Some(_)) => vec![Policy],
            (None, None) => vec![Policy, Lqr, Rule, Random],
        }
    }
}

#[derive(Args)]
struct AgreeArgs {
    #[command(flatten)]
    subject: Subject,
    /// Visited states to compare (spread over the default set's rows).
    #[arg(long, default_value_t = 1_000_000)]
    states: u64,
    /// Seed of the episodes.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print one JSON object instead of the tables.
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    let (rows, one) = (
        twin::grammar::scenario_help(true),
        twin::grammar::scenario_help(false),
    );
    let cli: Cli = host_common::cli::parse_with(|c| {
        c.mut_subcommand("eval", |e| e.mut_arg("scenario", |a| a.help(rows)))
            .mut_subcommand("render", |r| r.mut_arg("scenario", |a| a.help(one.clone())))
            .mut_subcommand("soak", |r| r.mut_arg("scenario", |a| a.help(one)))
    });
    let result = match cli.command {
        Command::Replay { files } => run_replay(&files),
        Command::Eval(a) => run_eval(&a),
        Command::Agree(a) => run_agree(&a).map(|()| true),
        Command::Render(a) => render_cmd::run(&a).map(|()| true),
        Command::Identify(a) => identify_cmd::run(&a).map(|()| true),
        Command::SimulateLogs(a) => identify_cmd::simulate(&a).map(|()| true),
        Command::Tables(a) => tables_cmd::run(&a),
        Command::Results(a) => results_cmd::run(&a).map(|()| true),
        Command::Soak(a) => soak_cmd::run(&a),
        Command::Startup(a) => startup_cmd::run(&a),
        Command::Envelope(a) => envelope_cmd::run(&a).map(|()| true),
        Command::Parts => {
            host_common::out!("{}", twin::grammar::markdown_table());
            Ok(true)
        }
    };
    match result {
        Ok(true) => host_common::cli::exit(0),
        Ok(false) => host_common::cli::exit(1),
        Err(e) => {
            host_common::errln!("error: {e:#}");
            // Everything but the system failing a read or a write is the input's fault.
            let system = matches!(
                e.downcast_ref::<weights::Error>(),
                Some(weights::Error::Io(_))
            );
            host_common::cli::exit(if system { 1 } else { 2 })
        }
    }
}

/// Checks, before any work, every input a command reads and every output it writes
/// (`weights::files::check_io`), each with its flag.
fn check_io(inputs: &[(&str, PathBuf)], outputs: &[(&str, &Path)]) -> Result<()> {
    let inputs: Vec<(&str, &Path)> = inputs.iter().map(|(f, p)| (*f, p.as_path())).collect();
    Ok(weights::files::check_io(&inputs, outputs)?)
}

fn parse_scenarios(specs: &[String], machine: &Machine) -> Result<Vec<Scenario>> {
    Scenario::words_on(specs, machine).map_err(anyhow::Error::msg)
}

fn run_agree(a: &AgreeArgs) -> Result<()> {
    anyhow::ensure!(
        (1..=MAX_AGREE_STATES).contains(&a.states),
        "--states must be in [1, {MAX_AGREE_STATES}], got {}",
        a.states
    );
    check_io(&a.subject.inputs(), &[])?;
    let (machine, net) = a.subject.load(true, true)?;
    let report = host_sim::agree::agreement(&net, &machine, a.states, a.seed)?;
    if a.json {
        host_common::outln!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        host_common::out!("{}", host_sim::agree::format_report(&report));
    }
    Ok(())
}

fn run_eval(a: &EvalArgs) -> Result<bool> {
    eval_cmd::check_eval(a)?;
    let mut inputs = a.subject.inputs();
    inputs.extend(a.monitor.inputs());
    inputs.extend(a.world.clone().map(|w| ("--world", w)));
    check_io(&inputs, &[])?;
    let controllers = a.controllers();
    let pil = a.pil.place(&a.subject, &a.monitor, &controllers)?;
    let world = a.world.as_deref().map(twin::rigfile::load).transpose()?;
    let flags = ["--horizon", "--scenario", "--controller"];
    // Counted before the policy loads, each spec a row at least; built and judged once the
    // machine the episodes run on is known (`--world`, `--rig` or the policy's own rig): a
    // spec read on another machine could be refused there, or pass where it changes nothing.
    let counts = [a.horizon.len(), a.scenario.len(), controllers.len()];
    eval::check_count(counts, flags).map_err(anyhow::Error::msg)?;
    // A target holds its own policy, on the rig it was built for, which the handshake
    // checks against the scenarios' machine: nothing is loaded here, and --rig alone is the
    // machine (the shipped policy's Gymnasium rig is no concern of it).
    let (machine, net) = match pil {
        Some(_) => a.subject.load(false, false)?,
        None => a.subject.load_for(&controllers, &a.monitor)?,
    };
    let run_on = match (&world, &a.world) {
        (Some(w), Some(path)) => {
            let s = &a.subject;
            let named = world_arg::board_name(s.rig.as_deref(), s.policy.is_some(), GYMNASIUM);
            world_arg::check(w, path, &machine, &named)?;
            w
        }
        _ => &machine,
    };
    // A spec asked for twice is named as such before a world two specs build is.
    let built = Scenario::words_built_on(&a.scenario, run_on).map_err(anyhow::Error::msg)?;
    eval::check_rows(&a.horizon, &built, &controllers, flags).map_err(anyhow::Error::msg)?;
    let mut scenarios = parse_scenarios(&a.scenario, run_on)?;
    if world.is_some() {
        // The board models the machine `--rig` or the policy gives, in the world `--world` is.
        scenarios = (scenarios.into_iter())
            .map(|s| s.known_as(&machine.rig).map_err(anyhow::Error::msg))
            .collect::<Result<_>>()?;
    }
    let jobs: Vec<(u32, &Scenario, ControllerKind)> = a
        .horizon
        .iter()
        .flat_map(|&h| {
            let (s, c) = (&scenarios, &controllers);
            s.iter()
                .flat_map(move |s| c.iter().map(move |&c| (h, s, c)))
        })
        .collect();
    if let Some(place) = pil {
        return pil_cmd::run(a, &place, &jobs);
    }
    let bar = ProgressBar::new(jobs.len() as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} rows, {elapsed} {msg}")
            .expect("static template"),
    );
    let mut rows: Vec<Row> = Vec::with_capacity(jobs.len());
    for (h, s, c) in jobs {
        bar.set_message(format!("{c} on {} at {h}", s.name));
        rows.push(eval::evaluate(c, &net, s, h, a.seed, a.episodes));
        bar.inc(1);
    }
    bar.finish_and_clear();
    report(a, &rows)
}

/// Prints the rows; whether the policy met `--min-success` everywhere.
fn report(a: &EvalArgs, rows: &[Row]) -> Result<bool> {
    if a.json {
        let doc = serde_json::json!({
            "seed": a.seed,
            "rows": rows,
            "provenance": Provenance::of_this_run("host-sim"),
        });
        host_common::outln!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        host_common::out!("{}", eval::format_table(rows));
        host_common::out!("{}", eval::format_failures(rows, a.seed));
    }
    Ok(met_min_success(a, rows))
}

/// Whether the network met `--min-success` in every row it drove (as float, integer or
/// monitored policy: `policy-int` at 0% passed); the rows it did not are named.
fn met_min_success(a: &EvalArgs, rows: &[Row]) -> bool {
    let failing: Vec<&Row> = rows
        .iter()
        .filter(|r| {
            a.controllers()
                .iter()
                .any(|k| k.runs_policy() && r.controller == k.to_string())
                && a.min_success.is_some_and(|m| r.success_rate < m)
        })
        .collect();
    for r in &failing {
        host_common::errln!(
            "{} below --min-success on {} at horizon {}: {:.1}%",
            r.controller,
            r.scenario,
            r.horizon,
            100.0 * r.success_rate
        );
    }
    failing.is_empty()
}

/// Most files one `replay` takes: all are checked before the first is replayed.
const MAX_REPLAY_FILES: usize = 1_000;

fn run_replay(files: &[PathBuf]) -> anyhow::Result<bool> {
    anyhow::ensure!(
        files.len() <= MAX_REPLAY_FILES,
        "replay: expected at most {MAX_REPLAY_FILES} files, found {}",
        files.len()
    );
    let inputs: Vec<(&str, PathBuf)> = files.iter().map(|f| ("FILE", f.clone())).collect();
    check_io(&inputs, &[])?;
    // Every file is parsed before anything is printed, and again when its turn comes, so
    // that memory holds one file's cases at a time.
    for f in files {
        replay::load(f)?;
    }
    let params = Params::default();
    let mut all_ok = true;
    for file in files {
        let cases = replay::load(file)?;
        host_common::outln!("{}", weights::shown(file));
        host_common::outln!(
            "{:>4} {:>6} {:>6} {:>12} {:>10} {:>10} {:>11}  result",
            "case",
            "seed",
            "steps",
            "max |dev|",
            "rollout≠",
            "step≠",
            "terminated"
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
            host_common::outln!(
                "{i:>4} {seed:>6} {:>6} {:>12.3e} {:>10} {:>10} {term:>11}  {verdict}",
                r.steps,
                r.rollout_max_abs_dev,
                r.rollout_mismatches,
                r.step_mismatches
            );
            if !r.matches() {
                failed += 1;
            }
        }
        host_common::outln!(
            "{} cases, {steps} steps, {failed} mismatched\n",
            cases.len()
        );
        all_ok &= failed == 0;
    }
    Ok(all_ok)
}
