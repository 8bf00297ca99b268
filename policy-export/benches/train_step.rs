//! Training speed over whole runs of the paper preset, one thread, per kernel:
//! `cargo bench -p policy-export --bench train_step`. Prints a table of microseconds per
//! environment step (acting + one batch-32 gradient step), the figure docs/PERFORMANCE.md
//! records. Whole runs, not a micro-benchmark, so buffer growth and early episodes count.

use policy_export::config::{Config, KernelChoice};
use policy_export::train;

fn main() {
    let seeds: u64 = std::env::var("BENCH_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    println!("paper preset, {seeds} seeds per kernel, one thread");
    println!(
        "{:<10} {:>10} {:>10} {:>14} {:>14}",
        "kernel", "env steps", "wall s", "us/env step", "best seed us"
    );
    for (name, k) in [
        ("portable", KernelChoice::Portable),
        ("avx2", KernelChoice::Avx2),
        ("avx512", KernelChoice::Avx512),
    ] {
        if k.resolve().is_err() {
            println!("{name:<10} (not supported by this CPU)");
            continue;
        }
        let cfg = Config {
            kernel: k,
            ..Config::paper()
        };
        let (mut steps, mut wall, mut best) = (0u64, 0.0f64, f64::INFINITY);
        for seed in 0..seeds {
            let r = train::train(&cfg, seed, &mut |_| {}).expect("paper preset trains");
            let s = r.wall_s;
            steps += r.env_steps;
            wall += s;
            best = best.min(s * 1e6 / r.env_steps as f64);
        }
        println!(
            "{name:<10} {steps:>10} {wall:>10.2} {:>14.1} {best:>14.1}",
            wall * 1e6 / steps as f64
        );
    }
}
