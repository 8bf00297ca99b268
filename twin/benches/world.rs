//! The continuous-time world's speed: control periods per second of one core, a world
//! integrating the plant with Runge-Kutta sub-steps under a held duty, against Gymnasium's
//! one Euler step; one world at a time and eight side by side (`machine::rk4_lanes`, as
//! `twin::lockstep` runs an evaluation's episodes); and whole closed-loop periods (the
//! firmware's controller, a bang-bang rule, encoders through the observer) as an evaluation
//! runs them. `cargo bench -p twin --bench world` prints one line per case; each is the best
//! of five runs, since a shared machine's noise only ever slows a run down.

use std::hint::black_box;
use std::time::Instant;

use firmware::cartpole::{Params, Plant, State};
use firmware::controller::Policy;
use twin::machine::{Integration, Lane, Machine, advance, rk4_lanes};
use twin::{Scenario, run_episodes};

const PERIODS: u32 = 2_000_000;

/// A bang-bang duty that keeps the pole near upright, so the state stays physical.
fn duty(s: &State) -> f64 {
    if s.theta + 0.2 * s.theta_dot > 0.0 {
        1.0
    } else {
        -1.0
    }
}

const START: State = State::from_array([0.0, 0.0, 0.05, 0.0]);

fn best_of_five(periods: u64, mut run: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        run();
        best = best.min(t.elapsed().as_secs_f64());
    }
    periods as f64 / best
}

fn alone(machine: &Machine) -> f64 {
    let plant = Plant::new(&machine.rig.params);
    best_of_five(u64::from(PERIODS), || {
        let mut s = START;
        for k in 0..PERIODS {
            s = advance(&plant, machine.integration, black_box(&s), duty(&s), 0.0);
            if k % 4096 == 0 {
                s = START;
            }
        }
        black_box(s);
    })
}

fn side_by_side(machine: &Machine) -> f64 {
    let Integration::Rk4 { substeps } = machine.integration else {
        unreachable!("only a continuous world is integrated in lanes")
    };
    let plant = Plant::new(&machine.rig.params);
    best_of_five(u64::from(PERIODS), || {
        let mut s = [START; 8];
        for k in 0..PERIODS / 8 {
            let lanes = core::array::from_fn(|j| Lane::new(&plant, &s[j], duty(&s[j]), 0.0));
            s = rk4_lanes::<8>(substeps, black_box(lanes));
            if k % 512 == 0 {
                s = [START; 8];
            }
        }
        black_box(s);
    })
}

/// Pushes towards `theta + 0.2 theta_dot`, as [`duty`].
struct Rule;
impl Policy for Rule {
    type Scores = [f32; 2];
    fn duty(&self, i: usize) -> Option<firmware::controller::Duty> {
        firmware::controller::Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, o: &[f32; 4]) -> [f32; 2] {
        [0.0, o[2] + 0.2 * o[3]]
    }
}

fn closed_loop(machine: &Machine, spec: &str) -> f64 {
    let s = Scenario::parse_on(spec, machine).expect("a valid scenario");
    let (episodes, horizon) = (64, 4_000);
    let run = || run_episodes(|_| Rule, &s, horizon, 0, 0..episodes, true);
    let periods = run().iter().map(|t| u64::from(t.steps)).sum();
    best_of_five(periods, || {
        black_box(run());
    })
}

fn main() {
    let desk = twin::rigfile::parse(include_str!("../../rigs/desk.toml"), "rigs/desk.toml")
        .expect("the desk rig parses");
    let friction = Machine {
        rig: firmware::rig::Rig {
            params: Params {
                cart_friction: 0.05,
                pole_friction: 0.001,
                ..desk.rig.params
            },
            ..desk.rig
        },
        ..desk
    };
    println!("{:<60} {:>14}", "world", "periods/s");
    let rows: [(&str, f64); 7] = [
        ("Gymnasium's machine, Euler", alone(&Machine::GYMNASIUM)),
        ("desk rig, 20 ms, RK4 at 1 ms, one world", alone(&desk)),
        (
            "desk rig, 20 ms, RK4 at 1 ms, 8 worlds side by side",
            side_by_side(&desk),
        ),
        ("desk rig with friction, one world", alone(&friction)),
        (
            "desk rig with friction, 8 worlds side by side",
            side_by_side(&friction),
        ),
        (
            "closed loop, desk rig, exact state",
            closed_loop(&desk, "nominal"),
        ),
        (
            "closed loop, desk rig, encoders + observer",
            closed_loop(&desk, "encoder"),
        ),
    ];
    for (name, rate) in rows {
        println!("{name:<60} {rate:>14.0}");
    }
}
