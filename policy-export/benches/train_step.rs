//! Training speed over whole runs, one thread, per kernel:
//! `cargo bench -p policy-export --bench train_step`. Prints two tables, the figures
//! docs/PERFORMANCE.md records: microseconds per environment step (acting + one batch-32
//! gradient step) of the paper preset, and what domain randomisation costs per step (the
//! deploy preset against itself with the plant, sensing and reward left nominal). Whole runs,
//! not a micro-benchmark, so buffer growth and early episodes count.

use policy_export::config::{Config, KernelChoice};
use policy_export::train;

fn main() {
    // One thread: the learner's second core is the thread pool's.
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global()
        .expect("the global pool is built once, first");
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
        if cfg!(target_arch = "x86_64") && k == KernelChoice::Portable {
            // Fused multiply-adds in software: the same bits as the others, for tests.
            println!("{name:<10} (a test reference on x86-64, not timed)");
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
    randomisation_cost();
}

/// The deploy preset's training loop with and without its randomised world, and for the desk
/// rig (its continuous world), periodic and finalist evaluations off in each so that only
/// training steps are timed.
fn randomisation_cost() {
    let episodes: usize = std::env::var("BENCH_DR_EPISODES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(400);
    println!();
    println!("deploy preset, {episodes} episodes, seed 0, no evaluations, one thread");
    println!(
        "{:<10} {:>14} {:>14} {:>14} {:>8}",
        "kernel", "world", "env steps", "us/env step", "ratio"
    );
    for (name, k) in [("auto", KernelChoice::Auto)] {
        let randomised = Config {
            kernel: k,
            episodes,
            eval_every: 0,
            finalists: 0,
            ..Config::deploy()
        };
        let nominal = Config {
            domain: String::new(),
            eval_domain: String::new(),
            finalist_domain: String::new(),
            compensate: false,
            reward: String::new(),
            ..randomised.clone()
        };
        // The same recipe for the desk rig: its world continuous, its episodes at its rate.
        let desk = twin::rigfile::parse(include_str!("../../rigs/desk.toml"), "desk")
            .expect("the desk rig parses");
        let rig = Config {
            kernel: k,
            episodes,
            eval_every: 0,
            finalists: 0,
            ..Config::deploy_on(&desk)
        };
        let mut base = 0.0;
        for (world, cfg) in [
            ("nominal", &nominal),
            ("randomised", &randomised),
            ("desk rig", &rig),
        ] {
            let r = train::train(cfg, 0, &mut |_| {}).expect("deploy preset trains");
            let us = r.wall_s * 1e6 / r.env_steps as f64;
            if base == 0.0 {
                base = us;
            }
            println!(
                "{name:<10} {world:>14} {:>14} {us:>14.1} {:>7.2}x",
                r.env_steps,
                us / base
            );
        }
    }
}
