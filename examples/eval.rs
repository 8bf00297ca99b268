//! The shipped policy evaluated from Rust with `host-sim`'s library, as `host-sim eval`
//! does: `Net::shipped()` through the firmware's controller, 100 seeded episodes of 500
//! periods per row, on the nominal world and on one read through encoders and the
//! observer, in f32 and in int8. Prints each row's success rate, its 95% interval, mean
//! periods and mean |duty|.
//!
//! ```sh
//! cargo run --release -p cartpole-examples --example eval
//! ```
//!
//! Exits non-zero unless every episode of every row balances to the horizon.

use std::process::ExitCode;

use host_sim::eval::{ControllerKind, Net, evaluate};
use twin::Scenario;

const EPISODES: u64 = 100;
const HORIZON: u32 = 500;
const SEED: u64 = 0;

fn main() -> ExitCode {
    let net = Net::shipped();
    let kinds = [ControllerKind::Policy, ControllerKind::PolicyInt];
    println!("{EPISODES} episodes of {HORIZON} periods per row, seed {SEED}");
    println!(
        "{:<10} {:<9} {:>8} {:>17} {:>11} {:>11}",
        "controller", "scenario", "success", "95% interval", "mean steps", "mean |duty|"
    );
    let mut held = true;
    for spec in ["nominal", "encoder"] {
        let scenario = match Scenario::parse(spec) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("scenario {spec}: {e}");
                return ExitCode::FAILURE;
            }
        };
        for kind in kinds {
            let row = evaluate(kind, &net, &scenario, HORIZON, SEED, EPISODES);
            let [lo, hi] = row.success_ci95;
            println!(
                "{:<10} {:<9} {:>7.1}% {:>7.1}% - {:>5.1}% {:>11.1} {:>11.3}",
                row.controller,
                row.scenario,
                100.0 * row.success_rate,
                100.0 * lo,
                100.0 * hi,
                row.mean_steps,
                row.mean_abs_duty.mean
            );
            held &= row.failures == 0;
        }
    }
    if held {
        ExitCode::SUCCESS
    } else {
        eprintln!("an episode fell before {HORIZON} periods");
        ExitCode::FAILURE
    }
}
