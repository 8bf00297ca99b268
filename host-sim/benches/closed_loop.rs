//! Closed-loop controller steps per second on one core: `firmware::controller::Controller`
//! with its policy, the digital twin and the plant, all together.
//!
//! `cargo bench -p host-sim --bench closed_loop` prints one line per configuration. Every
//! configuration runs the same 400 seeded 500-step episodes on one thread; the best of five
//! repetitions is reported, since a 2-core machine's noise only ever slows a run down.

use std::hint::black_box;
use std::time::Instant;

use firmware::cartpole::{Action, CartPole, Params};
use host_common::kernel::Kernel;
use host_common::wide::WideMlp;
use host_sim::eval::{ControllerKind, Net, episode};
use rand_core::SeedableRng;
use rand_pcg::Pcg64Mcg;
use shipped::policy::POLICY;
use twin::{Scenario, run_episode};

const EPISODES: u64 = 400;
const HORIZON: u32 = 500;

fn best_of(reps: usize, mut f: impl FnMut() -> u64) -> (u64, f64) {
    let mut best = f64::INFINITY;
    let mut steps = 0;
    for _ in 0..reps {
        let t = Instant::now();
        steps = f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    (steps, best)
}

fn line(name: &str, (steps, secs): (u64, f64)) {
    println!(
        "{name:<52} {steps:>9} {:>10.1} {:>12.2}",
        secs * 1e9 / steps as f64,
        steps as f64 / secs / 1e6
    );
}

fn run(kind: ControllerKind, net: &Net) -> (u64, f64) {
    let nominal = Scenario::nominal();
    best_of(5, || {
        (0..EPISODES)
            .map(|i| u64::from(episode(kind, net, &nominal, HORIZON, 0, i, |_| {}).steps))
            .sum()
    })
}

fn main() {
    let net = Net::shipped();
    println!(
        "{:<52} {:>9} {:>10} {:>12}",
        "configuration", "steps", "ns/step", "Msteps/s"
    );
    for kind in [
        ControllerKind::Policy,
        ControllerKind::PolicyInt,
        ControllerKind::Lqr,
        ControllerKind::Rule,
    ] {
        line(&format!("controller + {kind} + plant"), run(kind, &net));
    }
    // What a CPU without this one's best vector unit gets.
    let nominal = Scenario::nominal();
    for kernel in Kernel::ALL {
        if let Some(wide) =
            WideMlp::with_kernel(&POLICY, firmware::controller::Levels::BANG_BANG, kernel)
        {
            let steps = best_of(5, || {
                (0..EPISODES)
                    .map(|i| {
                        let s = run_episode(&*wide, &nominal, HORIZON, 0, i, true, |_| {});
                        u64::from(s.steps)
                    })
                    .sum()
            });
            line(&format!("controller + policy ({kernel:?}) + plant"), steps);
        }
    }
    let obs = [0.01f32, -0.02, 0.03, 0.04];
    line(
        "firmware forward pass alone",
        best_of(5, || {
            for _ in 0..200_000 {
                black_box(POLICY.forward(black_box(&obs)));
            }
            200_000
        }),
    );
    for kernel in Kernel::ALL {
        let Some(wide) =
            WideMlp::with_kernel(&POLICY, firmware::controller::Levels::BANG_BANG, kernel)
        else {
            continue;
        };
        line(
            &format!("host-sim forward pass alone ({kernel:?})"),
            best_of(5, || {
                for _ in 0..200_000 {
                    black_box(wide.forward(black_box(&obs)));
                }
                200_000
            }),
        );
    }
    line(
        "plant step alone",
        best_of(5, || {
            let mut plant = CartPole::new(Params::default(), u32::MAX);
            plant.reset(&mut Pcg64Mcg::seed_from_u64(0));
            for i in 0..2_000_000u32 {
                let a = if i % 2 == 0 {
                    Action::Left
                } else {
                    Action::Right
                };
                black_box(plant.step(black_box(a)));
            }
            2_000_000
        }),
    );
}
