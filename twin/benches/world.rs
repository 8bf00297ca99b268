//! The continuous-time world's speed: control periods per second of one core, a world
//! integrating the plant with Runge-Kutta sub-steps under a held duty, against Gymnasium's
//! one Euler step. `cargo bench -p twin --bench world` prints one line per world; each is
//! the best of five runs, since a shared machine's noise only ever slows a run down.

use std::hint::black_box;
use std::time::Instant;

use firmware::cartpole::{Plant, State};
use twin::machine::{Integration, Machine, advance};

const PERIODS: u32 = 2_000_000;

fn periods_per_second(machine: &Machine) -> f64 {
    let plant = Plant::new(&machine.rig.params);
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        let mut s = State::from_array([0.0, 0.0, 0.05, 0.0]);
        for k in 0..PERIODS {
            // A bang-bang duty that keeps the pole near upright, so the state stays physical.
            let duty = if s.theta + 0.2 * s.theta_dot > 0.0 {
                1.0
            } else {
                -1.0
            };
            s = advance(&plant, machine.integration, black_box(&s), duty, 0.0);
            if k % 4096 == 0 {
                s = State::from_array([0.0, 0.0, 0.05, 0.0]);
            }
        }
        black_box(s);
        best = best.min(t.elapsed().as_secs_f64());
    }
    f64::from(PERIODS) / best
}

fn main() {
    let desk = twin::rigfile::parse(include_str!("../../rigs/desk.toml"), "rigs/desk.toml")
        .expect("the desk rig parses");
    println!("{:<52} {:>16}", "world", "periods/s");
    let rows = [
        ("Gymnasium's machine, Euler", Machine::GYMNASIUM),
        ("desk rig, 20 ms, RK4 at 1 ms", desk),
        (
            "desk rig, 20 ms, RK4 at 1 ms, friction",
            Machine {
                rig: firmware::rig::Rig {
                    params: firmware::cartpole::Params {
                        cart_friction: 0.05,
                        pole_friction: 0.001,
                        ..desk.rig.params
                    },
                    ..desk.rig
                },
                integration: Integration::rk4(0.02, 0.001),
            },
        ),
    ];
    for (name, m) in rows {
        println!("{name:<52} {:>16.0}", periods_per_second(&m));
    }
}
