//! Which step of the integer board's pipeline makes an int8 policy fail where its float
//! policy holds: the same episodes (the deploy recipe's trial worlds for the rig, drawn from
//! the trial's streams of `--seed`, as long as the trial's) run by four boards that differ in
//! one step at a time:
//!
//! - the float network on the observer's float estimate (the float board);
//! - the float network on the estimate rounded to Q3.12 before the predictor (the integer
//!   board's rounding, with the float network's decisions);
//! - the int8 network on the float estimate, rounded only as the network reads it (the
//!   quantised decisions, with the float board's reading);
//! - the int8 network on the Q3.12 estimate (the integer board).
//!
//! Each row gives the episodes held and the cart's mean position over the periods run. Then,
//! on the float board's own periods, how often the int8 network would choose another level,
//! and the mean of the difference in duty it would drive (a bias one way shows as a mean far
//! from zero).
//!
//! ```sh
//! cargo run --release -p cartpole-examples --example int8_drift -- \
//!     --policy RUN --rig rigs/desk-identified.toml --seed 5 --episodes 25
//! ```
//!
//! `docs/SWEEP.md` ("Why an integer board fails where its float board holds") shows what it
//! found.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Parser;
use firmware::controller::{Duty, Greedy, Levels, Policy, Reading};
use firmware::estimator::Estimate;
use firmware::network::int::QMlp;
use firmware::network::{Mlp, argmax};
use policy_export::config::Config;
use policy_export::train::{Eval, EvalStreams, quantised};
use twin::{Domain, Episode, Machine, Scenario};

#[derive(Parser)]
struct Args {
    /// The policy: a run directory or a policy file, 64 wide.
    #[arg(long)]
    policy: PathBuf,
    /// The rig file it was trained for.
    #[arg(long)]
    rig: PathBuf,
    /// The run's seed: the trial's streams of it.
    #[arg(long, default_value_t = 5)]
    seed: u64,
    /// Episodes of 10,000 periods.
    #[arg(long, default_value_t = 25)]
    episodes: u64,
    /// The worlds, instead of the deploy recipe's trial worlds for the rig.
    #[arg(long)]
    domain: Option<String>,
}

/// The float network deciding on the integer board's Q3.12 reading.
#[derive(Clone, Copy)]
struct Rounded<'n, const A: usize>(Greedy<&'n Mlp<64, A>, A>);

impl<const A: usize> Policy<[i16; 4]> for Rounded<'_, A> {
    type Scores = [f32; A];
    fn scores(&mut self, obs: &[i16; 4]) -> [f32; A] {
        self.0.net.forward(&obs.state())
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.0.levels.duty(i)
    }
}

/// The trial's episodes: their streams, and the periods each lasts at most (the recipe's
/// `finalist_max_steps`, 10,000 at 50 Hz).
struct Trial {
    streams: EvalStreams,
    periods: u32,
}

impl Trial {
    /// Whether `policy` held episode `e` in `world` to the end, and the sum of the cart's
    /// position over the periods it ran, with their count.
    fn held<P: Policy<O>, O: Estimate>(&self, p: P, world: &Scenario, e: u64) -> (bool, f64, u64) {
        let mut ep: Episode<_, _, O> = self.streams.draws.episode(p, world, self.periods, e, true);
        let (mut sum_x, mut n) = (0.0, 0);
        loop {
            ep.decide();
            let t = ep.apply();
            sum_x += ep.world().state().x;
            n += 1;
            if t.terminated || t.truncated {
                return (!t.terminated, sum_x, n);
            }
        }
    }

    /// On the float board's periods of episode `e`: periods, where the int8 network chooses
    /// another level, and the sum of its duty less the float network's.
    fn differences<const A: usize>(
        &self,
        (f, q): (Greedy<&Mlp<64, A>, A>, Greedy<&QMlp<64, A>, A>),
        world: &Scenario,
        e: u64,
    ) -> (u64, u64, f64) {
        let mut ep: Episode<_, _, [f32; 4]> =
            self.streams.draws.episode(f, world, self.periods, e, true);
        let (mut n, mut differ, mut sum) = (0, 0, 0.0);
        loop {
            let float = f64::from(ep.decide().level());
            if let Some(r) = ep.controller().last() {
                let choice = argmax(&q.net.forward(&firmware::fixed::from_state(&r.obs.state())));
                let int = f64::from(q.levels.duty(choice).map_or(0.0, |d| d.fraction()));
                n += 1;
                differ += u64::from(int != float);
                sum += int - float;
            }
            let t = ep.apply();
            if t.terminated || t.truncated {
                return (n, differ, sum);
            }
        }
    }
}

/// The four boards' figures: episodes held, the sum of the cart's position and the periods
/// run, each.
fn print(trial: &Trial, (spec, episodes, seed): (&str, u64, u64), boards: [(u64, f64, u64); 4]) {
    println!(
        "{episodes} episodes of {} periods in {spec}, seed {seed}",
        trial.periods
    );
    let names = [
        "float network, float reading (the float board)",
        "float network, reading rounded to Q3.12",
        "int8 network, float reading",
        "int8 network, Q3.12 reading (the integer board)",
    ];
    for (name, (held, sum_x, periods)) in names.iter().zip(boards) {
        let mean_x = sum_x / periods.max(1) as f64;
        println!("{name:<50} held {held:>5} of {episodes}, mean x {mean_x:+.4} m");
    }
}

fn diagnose<const A: usize>(w: &weights::Weights, machine: &Machine, args: &Args) -> Result<()> {
    let levels: Levels<A> = w.to_levels()?;
    let net = w.to_mlp::<64, A>()?;
    let q = quantised((&*net, levels), machine)?;
    let (f, qi) = (Greedy { net: &*net, levels }, Greedy { net: &*q, levels });
    let recipe = Config::deploy_on(machine);
    let spec = args.domain.clone().unwrap_or(recipe.finalist_domain);
    let domain = Domain::parse_on(&spec, machine).map_err(anyhow::Error::msg)?;
    let trial = Trial {
        streams: EvalStreams::of(args.seed, Eval::Trial),
        periods: recipe.finalist_max_steps,
    };
    let (mut boards, mut n, mut differ, mut sum) = ([(0u64, 0.0, 0u64); 4], 0, 0, 0.0);
    for e in 0..args.episodes {
        let world = domain.sample(&mut trial.streams.world(e));
        let held = [
            trial.held::<_, [f32; 4]>(f, &world, e),
            trial.held::<_, [i16; 4]>(Rounded(f), &world, e),
            trial.held::<_, [f32; 4]>(qi, &world, e),
            trial.held::<_, [i16; 4]>(qi, &world, e),
        ];
        for (b, h) in boards.iter_mut().zip(held) {
            *b = (b.0 + u64::from(h.0), b.1 + h.1, b.2 + h.2);
        }
        let d = trial.differences((f, qi), &world, e);
        (n, differ, sum) = (n + d.0, differ + d.1, sum + d.2);
    }
    print(&trial, (&spec, args.episodes, args.seed), boards);
    println!(
        "on the float board's {n} periods, the int8 network chooses another level in {:.2}%; \
         its duty less the float network's, mean per period: {:+.5} of full",
        100.0 * differ as f64 / n.max(1) as f64,
        sum / n.max(1) as f64
    );
    Ok(())
}

fn main() -> Result<()> {
    let args = Args::parse();
    let machine = twin::rigfile::load(&args.rig)?;
    let w = weights::checkpoint::load(&args.policy, None)
        .with_context(|| format!("--policy {}", args.policy.display()))?
        .weights;
    if w.width() != 64 {
        bail!("--policy: expected a network 64 wide; found {}", w.width());
    }
    match w.outputs() {
        2 => diagnose::<2>(&w, &machine, &args),
        3 => diagnose::<3>(&w, &machine, &args),
        5 => diagnose::<5>(&w, &machine, &args),
        7 => diagnose::<7>(&w, &machine, &args),
        9 => diagnose::<9>(&w, &machine, &args),
        n => bail!("--policy: expected 2, 3, 5, 7 or 9 outputs; found {n}"),
    }
}
