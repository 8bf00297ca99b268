//! `host-sim soak`: one episode of many simulated hours (24 by default: 4.32 million periods
//! at 50 Hz) through the scenario's sensors and faults, for what only a long run shows: an
//! estimate that drifts (f32 sums over millions of periods), rejections where no fault was
//! injected, a controller that holds for minutes and not for a day.

use std::time::Instant;

use anyhow::Result;
use clap::Args;
use firmware::cartpole::State;
use firmware::controller::Command;
use host_sim::eval::{self, ControllerKind};
use serde::Serialize;
use twin::Scenario;

use crate::subject::{Monitor, Subject};

/// Longest soak, simulated hours: ten days.
const MAX_HOURS: f64 = 240.0;

#[derive(Args)]
pub struct SoakArgs {
    /// Simulated hours of one episode.
    #[arg(long, default_value_t = 24.0)]
    hours: f64,
    /// One scenario spec (see `eval`), faults included.
    #[arg(long, default_value = "noise+encoder")]
    scenario: String,
    /// Which controller drives.
    #[arg(long, default_value = "policy")]
    controller: ControllerKind,
    #[command(flatten)]
    subject: Subject,
    #[command(flatten)]
    monitor: Monitor,
    /// Seed of the start, noise and pushes (episode 0 of it, as in `eval`).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Print the result as JSON.
    #[arg(long)]
    json: bool,
}

/// What a soak found. Errors are the largest `|reading - truth|` per channel (m, m/s, rad,
/// rad/s) over the periods whose reading the controller took.
#[derive(Serialize)]
struct Soak {
    controller: ControllerKind,
    scenario: String,
    seed: u64,
    periods: u32,
    periods_run: u32,
    simulated_hours: f64,
    balanced: bool,
    /// Periods that coasted: a reading rejected or missing.
    coasting_periods: u32,
    max_error_first_hour: [f64; 4],
    max_error_last_hour: [f64; 4],
    max_error: [f64; 4],
    wall_s: f64,
}

/// Runs the soak `a` asks for; whether the controller balanced to the end.
pub fn run(a: &SoakArgs) -> Result<bool> {
    anyhow::ensure!(
        a.hours > 0.0 && weights::plain(a.hours) && a.hours <= MAX_HOURS,
        "--hours must be a normal number of simulated hours in (0, {MAX_HOURS}], found {:?}",
        a.hours
    );
    let (machine, net) = a.subject.load_for(&[a.controller], &a.monitor)?;
    let scenario = Scenario::parse_on(&a.scenario, &machine).map_err(anyhow::Error::msg)?;
    let tau = scenario.params.tau;
    // Less than a period ran one, and reported the hours it ran, not those asked for.
    anyhow::ensure!(
        a.hours * 3600.0 >= tau,
        "--hours {:?} is less than one period of {tau} s; expected at least {:e}",
        a.hours,
        tau / 3600.0
    );
    let periods = (a.hours * 3600.0 / tau).ceil();
    anyhow::ensure!(
        periods <= u32::MAX as f64,
        "--hours {} is {periods} periods of {tau} s, more than one episode counts",
        a.hours
    );
    let (periods, hour) = (periods as u32, ((3600.0 / tau).round() as u32).max(1));
    let started = Instant::now();
    let mut hours: Vec<[f64; 4]> = Vec::new();
    let mut truth: Option<State> = None;
    let mut k = 0u32;
    let stats = eval::episode(a.controller, &net, &scenario, periods, a.seed, 0, |f| {
        if k.is_multiple_of(hour) {
            hours.push([0.0; 4]);
        }
        let worst = hours.last_mut().expect("pushed at the hour's first period");
        // The reading estimates the state at the period's start: the last period's end.
        if let (Some(t), Command::Drive(_)) = (truth, f.command) {
            let t: [f64; 4] = t.to_array();
            for ((w, r), t) in worst.iter_mut().zip(f.reading).zip(t) {
                *w = w.max((f64::from(r) - t).abs());
            }
        }
        truth = Some(f.state);
        k += 1;
    });
    let soak = Soak {
        controller: a.controller,
        scenario: scenario.name.clone(),
        seed: a.seed,
        periods,
        periods_run: stats.steps,
        simulated_hours: f64::from(stats.steps) * tau / 3600.0,
        balanced: stats.steps == periods,
        coasting_periods: stats.faults,
        max_error_first_hour: hours.first().copied().unwrap_or_default(),
        max_error_last_hour: hours.last().copied().unwrap_or_default(),
        max_error: hours
            .iter()
            .fold([0.0; 4], |m, h| std::array::from_fn(|i| m[i].max(h[i]))),
        wall_s: started.elapsed().as_secs_f64(),
    };
    if a.json {
        host_common::outln!("{}", serde_json::to_string_pretty(&soak)?);
    } else {
        host_common::out!("{}", report(&soak, tau));
    }
    Ok(soak.balanced)
}

fn report(s: &Soak, tau: f64) -> String {
    let row = |name: &str, e: &[f64; 4]| {
        format!(
            "  {name:<12} {:>12.3e} {:>12.3e} {:>12.3e} {:>12.3e}\n",
            e[0], e[1], e[2], e[3]
        )
    };
    format!(
        "soak: {} in {}, seed {}: {} of {} periods ({:.2} h at {} ms) in {:.1} s\n  \
         balanced to the end: {}\n  coasting periods (a reading rejected or missing): {}\n  \
         largest |reading - truth|: {:>10} {:>12} {:>12} {:>12}\n{}{}{}",
        s.controller,
        s.scenario,
        s.seed,
        s.periods_run,
        s.periods,
        s.simulated_hours,
        tau * 1e3,
        s.wall_s,
        if s.balanced { "yes" } else { "no" },
        s.coasting_periods,
        "x m",
        "x_dot m/s",
        "theta rad",
        "theta_dot",
        row("first hour", &s.max_error_first_hour),
        row("last hour", &s.max_error_last_hour),
        row("whole run", &s.max_error),
    )
}
