//! `host-sim envelope`: measures where a policy drives in the episodes it balances: the
//! runtime monitor's envelope, written beside the shipped policy (`shipped/src/envelope.rs`)
//! or, for another, printed as the JSON `eval --envelope` reads.

use std::path::PathBuf;

use anyhow::{Result, ensure};
use clap::Args;
use firmware::link::digest;
use host_common::provenance::Provenance;
use host_sim::envelope::{Report, rust_module, visited};
use host_sim::eval::ControllerKind;
use indicatif::{ProgressBar, ProgressStyle};
use shipped::policy::RIG;
use weights::files::write_atomic;

use crate::subject::{Monitor, Subject};

/// Most episodes per scenario.
const MAX_EPISODES: u64 = 100_000;
/// Longest episode, periods.
const MAX_HORIZON: u32 = 1_000_000;

#[derive(Args)]
pub struct EnvelopeArgs {
    /// Scenario specs or sets (see `eval`) whose balanced episodes the envelope covers.
    #[arg(long, value_delimiter = ',', default_value = "all,hard")]
    scenario: Vec<String>,
    /// Episodes per scenario.
    #[arg(long, default_value_t = 100)]
    episodes: u64,
    /// Periods per episode.
    #[arg(long, default_value_t = 10_000)]
    horizon: u32,
    /// Seed of the starts, noise and pushes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The share of each channel's readings the envelope covers before its margin (1: the
    /// largest reading seen).
    #[arg(long, default_value_t = 1.0)]
    quantile: f64,
    /// The factor on each channel's quantile. Read and checked in f64, so a value just past a
    /// bound is refused rather than rounded into it.
    #[arg(long, default_value_t = 1.1)]
    margin: f64,
    /// Write the shipped crate's module (`shipped/src/envelope.rs`) here: the shipped policy's
    /// only.
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    subject: Subject,
    /// Print the measurement as JSON.
    #[arg(long)]
    json: bool,
}

/// Measures and writes; every argument and the output's place are checked first.
pub fn run(a: &EnvelopeArgs) -> Result<()> {
    check(a)?;
    if let (Some(policy), Some(_)) = (&a.subject.policy, &a.out) {
        anyhow::bail!(
            "--out writes the shipped crate's module, the shipped policy's envelope: for --policy {} \
             use --json and give the file to eval --envelope",
            weights::shown(policy)
        );
    }
    let outputs: Vec<(&str, &std::path::Path)> =
        a.out.iter().map(|p| ("--out", p.as_path())).collect();
    crate::check_io(&a.subject.inputs(), &outputs)?;
    let (machine, net) = a
        .subject
        .load_for(&[ControllerKind::Policy], &Monitor::default())?;
    let scenarios = crate::parse_scenarios(&a.scenario, &machine)?;
    let bar = ProgressBar::new(scenarios.len() as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} scenarios, {elapsed} (eta {eta}) {msg}")
            .expect("static template"),
    );
    let v = visited(&net, &scenarios, a.horizon, a.episodes, a.seed, |s| {
        bar.set_message(s.name.clone());
        bar.inc(1);
    });
    bar.finish_and_clear();
    ensure!(
        v.balanced > 0,
        "no episode balanced for {} periods: there are no readings to take an envelope from",
        a.horizon
    );
    let names: Vec<String> = scenarios.iter().map(|s| s.name.clone()).collect();
    let provenance = Provenance::of_this_run("host-sim");
    let report = Report::of(
        &v,
        (net.digest(), digest::rig(&machine.rig)),
        names,
        (a.episodes, a.horizon),
        a.quantile,
        a.margin as f32,
        provenance,
    );
    if let Some(out) = &a.out {
        let provenance = [
            format!(
                "measured: `host-sim envelope --scenario {} --episodes {} --horizon {} --seed {} \
                 --quantile {} --margin {}`",
                a.scenario.join(","),
                a.episodes,
                a.horizon,
                a.seed,
                a.quantile,
                a.margin
            ),
            format!(
                "{} readings of {} balanced episodes of {}",
                v.periods, v.balanced, v.episodes
            ),
        ];
        let text = rust_module(report.envelope, net.digest(), &RIG, &provenance);
        write_atomic(out, text.as_bytes())?;
        host_common::errln!("{}", weights::shown(out));
    }
    if a.json {
        host_common::outln!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        host_common::outln!("{}", format(&report));
    }
    Ok(())
}

/// The counts and shares `a` asks for, each within its bounds.
fn check(a: &EnvelopeArgs) -> Result<()> {
    ensure!(
        (1..=MAX_EPISODES).contains(&a.episodes),
        "--episodes must be in [1, {MAX_EPISODES}], got {}",
        a.episodes
    );
    ensure!(
        (1..=MAX_HORIZON).contains(&a.horizon),
        "--horizon must be in [1, {MAX_HORIZON}], got {}",
        a.horizon
    );
    ensure!(
        host_sim::envelope::quantile_taken(a.quantile),
        "--quantile must be a normal number in (0, 1], got {:?}",
        a.quantile
    );
    ensure!(
        host_sim::envelope::MARGINS.contains(&a.margin),
        "--margin must be in [{}, {}], got {:?}",
        host_sim::envelope::MARGINS.start(),
        host_sim::envelope::MARGINS.end(),
        a.margin
    );
    Ok(())
}

/// The measurement as a table.
fn format(r: &Report) -> String {
    let mut s = format!(
        "{} readings of {} balanced episodes of {} ({} scenarios, {} periods each)\n\
         {:<10} {:>9} {:>9} {:>9} {:>9}\n",
        r.periods,
        r.balanced,
        r.episodes_run,
        r.scenarios.len(),
        r.horizon,
        "",
        "x m",
        "x_dot m/s",
        "theta rad",
        "omega r/s"
    );
    let rows = ["0.99", "0.999", "0.9999", "largest"];
    for (name, q) in rows.iter().zip(r.quantiles) {
        s += &format!(
            "{name:<10} {:>9.4} {:>9.4} {:>9.4} {:>9.4}\n",
            q[0], q[1], q[2], q[3]
        );
    }
    let e = r.envelope;
    s += &format!(
        "{:<10} {:>9.4} {:>9.4} {:>9.4} {:>9.4}  ({} quantile x {})",
        "envelope", e[0], e[1], e[2], e[3], r.quantile, r.margin
    );
    s
}
