//! A board's whole loop, closed on the host against the plant in place of the hardware
//! (`firmware::loopback`'s pins): encoder counts into the rig's observer, the integer
//! policy, the dead-time predictor (where the rig has dead time) and the limits, all built
//! from the `RIG` exported beside the policy, and one `controller.step()` per control period
//! for 10 s of periods. It runs the shipped int8 policy (two levels, full pushes) and the
//! nine-level desk policy, which holds the pole with small duties, and prints for each how
//! long it balanced, its mean |duty|, its motor reversals and the controller's fault
//! counters.
//!
//! ```sh
//! cargo run --release -p cartpole-examples --example board_loop
//! ```
//!
//! Exits non-zero if either policy lets the pole fall or a reading is rejected.

use std::cell::Cell;
use std::process::ExitCode;

use firmware::ConfigError;
use firmware::cartpole::{CartPole, State};
use firmware::controller::{Greedy, Policy};
use firmware::estimator::ObserverSensor;
use firmware::loopback::{duty, pins};
use firmware::rig::{Options, Rig};

const SECONDS: f64 = 10.0;

/// Runs `policy` on `rig` through its encoders and observer for [`SECONDS`] of periods and
/// prints what it did under `name`; whether it held the pole for every period, rejecting no
/// reading.
fn board_loop<P: Policy<[i16; 4]>>(name: &str, policy: P, rig: &Rig) -> Result<bool, ConfigError> {
    let periods = (SECONDS / rig.params.tau).round() as u32;
    let mut plant = CartPole::new(rig.params, periods);
    plant.reset_to(State::from_array([0.02, 0.0, 0.03, 0.0]));
    let counts = |s: State| rig.encoders.counts(s.x, s.theta);
    // A board loads these from its timers or PIO counters.
    let latest = Cell::new(counts(plant.state()));
    let sensor = ObserverSensor::<_, [i16; 4]>::new(rig.observer()?, || latest.get());
    let options = Options {
        predict: true,
        monitor: None,
    };
    let mut controller = rig.controller(policy, sensor, pins(), options)?;
    let (mut sum_abs_duty, mut reversals, mut last_sign) = (0.0, 0, 0.0);
    let mut balanced = 0;
    for _ in 0..periods {
        controller.step();
        let d = duty(controller.actuator());
        sum_abs_duty += d.abs();
        // Pushes too small to take up a gearbox's backlash do not count (as in `host-sim
        // eval`'s reversals per second).
        if d.abs() >= f64::from(twin::run::REVERSAL_DUTY) {
            reversals += u32::from(last_sign != 0.0 && d.signum() != last_sign);
            last_sign = d.signum();
        }
        let t = plant.advance(d, 0.0);
        latest.set(counts(plant.state()));
        if t.terminated {
            break;
        }
        balanced += 1;
    }
    let f = controller.faults();
    let mean_abs_duty = sum_abs_duty / f64::from(controller.steps());
    println!("{name} (a period of {} ms):", rig.params.tau * 1e3);
    println!("  balanced     {balanced} of {periods} periods");
    println!("  mean |duty|  {mean_abs_duty:.3} of the full push");
    println!("  reversals    {reversals} of the motor's direction (pushes of 10% or more)");
    println!(
        "  faults       {} rejected readings, {} overruns",
        f.rejected_readings, f.overruns
    );
    Ok(balanced == periods && f.rejected_readings == 0)
}

fn main() -> ExitCode {
    use shipped::{desk_int, policy_int};
    let desk = Greedy {
        net: &desk_int::POLICY_INT,
        levels: desk_int::LEVELS,
    };
    let runs = [
        board_loop(
            "shipped int8 policy, 2 levels",
            &policy_int::POLICY_INT,
            &policy_int::RIG,
        ),
        board_loop("desk int8 policy, 9 levels", desk, &desk_int::RIG),
    ];
    let mut held = true;
    for run in runs {
        match run {
            Ok(h) => held &= h,
            Err(e) => {
                eprintln!("the rig is refused: {e}");
                held = false;
            }
        }
    }
    if held {
        ExitCode::SUCCESS
    } else {
        eprintln!("a loop did not hold the pole for {SECONDS} s without a fault");
        ExitCode::FAILURE
    }
}
