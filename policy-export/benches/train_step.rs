//! Training speed over whole runs, one thread, per kernel:
//! `cargo bench -p policy-export --bench train_step`. Prints two tables, the figures
//! docs/PERFORMANCE.md records: microseconds per environment step (acting + one batch-32
//! gradient step) of the paper preset, and what domain randomisation costs per step (the
//! deploy preset against itself with the plant, sensing and reward left nominal). Whole runs,
//! not a micro-benchmark, so buffer growth and early episodes count. A third table sets the
//! paper preset's time against the least it could take on this core: the multiply-adds a
//! gradient step cannot do without, at the rate the core sustains them.

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
    let mut measured = Vec::new();
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
        let us = wall * 1e6 / steps as f64;
        println!("{name:<10} {steps:>10} {wall:>10.2} {us:>14.1} {best:>14.1}");
        measured.push((name, us));
    }
    #[cfg(target_arch = "x86_64")]
    peak::table(&measured);
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

/// The paper preset's step against this core's multiply-add peak.
#[cfg(target_arch = "x86_64")]
mod peak {
    use firmware::network::{N_ACTIONS, OBS_DIM};
    use policy_export::config::Config;
    use std::hint::black_box;
    use std::time::Instant;

    /// Multiply-adds of one gradient step that no rendering can skip: the online network's
    /// forward passes on the batch's states and next states (Double DQN's choice), and the
    /// backward pass (the output layer, the two hidden layers' weights, and the gradient
    /// carried between them). The target network's forward pass is left out: its Q-values
    /// are cached per replay slot and mostly reused.
    fn macs_per_update(cfg: &Config) -> f64 {
        let h = cfg.width;
        let forward = OBS_DIM * h + h * h + h * N_ACTIONS;
        let backward = 2 * h * N_ACTIONS + 2 * h * h + OBS_DIM * h;
        (cfg.batch_size * (2 * forward + backward)) as f64
    }

    /// Twelve independent chains of register-wide multiply-adds, `n` rounds: more chains
    /// than a core's multiply-add units times their latency, so only their throughput limits
    /// it. Written in intrinsics: the compiler keeps generic 16-lane arrays in 256-bit
    /// registers.
    macro_rules! chains {
        ($name:ident, $features:literal, $set1:ident, $fmadd:ident, $reduce:expr) => {
            #[target_feature(enable = $features)]
            fn $name(n: u64, x: f32) -> f32 {
                use core::arch::x86_64::*;
                let mut acc = [$set1(x); 12];
                let (m, c) = ($set1(black_box(0.999_9)), $set1(1e-6));
                for _ in 0..n {
                    for a in &mut acc {
                        *a = $fmadd(*a, m, c);
                    }
                }
                acc.into_iter().map($reduce).sum()
            }
        };
    }
    chains!(
        chains_avx2,
        "avx2,fma",
        _mm256_set1_ps,
        _mm256_fmadd_ps,
        |v| { _mm256_cvtss_f32(v) }
    );
    chains!(
        chains_avx512,
        "avx512f,fma",
        _mm512_set1_ps,
        _mm512_fmadd_ps,
        |v| { _mm512_reduce_add_ps(v) }
    );

    /// Multiply-adds per second, best of three runs of 100 M rounds' worth.
    fn rate(name: &str) -> Option<f64> {
        let (lanes, run): (u64, fn(u64, f32) -> f32) = match name {
            // SAFETY: each is called only where the CPU reports its features.
            "avx2" if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") => {
                (8, |n, x| unsafe { chains_avx2(n, x) })
            }
            "avx512" if is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("fma") => {
                (16, |n, x| unsafe { chains_avx512(n, x) })
            }
            _ => return None,
        };
        let rounds = 100_000_000 / lanes;
        let best = (0..3)
            .map(|_| {
                let t = Instant::now();
                black_box(run(black_box(rounds), black_box(1.0)));
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        Some((rounds * 12 * lanes) as f64 / best)
    }

    /// Prints, per kernel measured, the core's peak, the least time a paper-preset
    /// gradient step could take at it, and the share of the measured step that least is.
    pub fn table(measured: &[(&str, f64)]) {
        let macs = macs_per_update(&Config::paper());
        println!();
        println!("paper preset against this core's multiply-add peak: {macs} per gradient step");
        println!(
            "{:<10} {:>14} {:>16} {:>14} {:>10}",
            "kernel", "peak GMAC/s", "floor us/update", "us/env step", "of peak"
        );
        for &(name, us) in measured {
            let Some(rate) = rate(name) else { continue };
            let floor = macs / rate * 1e6;
            println!(
                "{name:<10} {:>14.1} {floor:>16.2} {us:>14.1} {:>9.0}%",
                rate / 1e9,
                100.0 * floor / us
            );
        }
    }
}
