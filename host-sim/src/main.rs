//! `host-sim`: checks and exercises the firmware's plant and controller on the host.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use firmware::cartpole::Params;
use host_sim::replay;

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Replay { files } => run_replay(&files),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
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
