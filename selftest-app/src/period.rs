//! A board's whole control periods for counting instructions: the start-up
//! (`firmware::startup`) around the controller of the integer nine-level desk policy, its
//! duty refined between the levels, read through the watching observer with its predictor,
//! as the RP2040 board runs with `desk`.

use core::cell::Cell;

use firmware::controller::{Greedy, Refined};
use firmware::estimator::ObserverSensor;
use firmware::rig::Options;
use firmware::startup::{Phase, Sequencer, Startup};
use shipped::desk_int::{LEVELS, POLICY_INT, RIG};

/// Builds the desk board's controller and start-up, then runs `periods[0]` periods: the pole
/// hanging at rest until zeroed, then held upright, flickering by a count, and caught; `out`
/// gets whether the last period balanced (1, else 0) and the periods balanced. Two calls'
/// instructions differ by the periods between them: one balancing period's cost, set-up
/// (the observer's gain) cancelled.
// SAFETY: `no_mangle` exports the symbol for the instruction counter; no other item in the
// program defines it.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn selftest_startup_periods(periods: Option<&[i16; 4]>, out: Option<&mut [i32; 2]>) {
    let (Some(periods), Some(out)) = (periods, out) else {
        return;
    };
    let Ok(observer) = RIG.observer() else {
        return;
    };
    let latest = Cell::new((0, 0));
    let sensor = ObserverSensor::<_, [i16; 4]>::new(observer.watching(), || latest.get());
    let policy = Refined(Greedy {
        net: &POLICY_INT,
        levels: LEVELS,
    });
    let options = Options {
        predict: true,
        monitor: None,
    };
    let (Ok(mut controller), Ok(startup)) = (
        RIG.controller(policy, sensor, firmware::loopback::pins(), options),
        Startup::suggested(&RIG),
    ) else {
        return;
    };
    let Ok(mut sequencer) = Sequencer::new(startup, &RIG) else {
        return;
    };
    let upright = (RIG.encoders.pole_counts_per_rev / 2) as i32;
    let mut balanced = 0;
    for k in 0..periods[0].max(0) {
        let pole = match sequencer.zero() {
            None => 0,
            Some(_) => upright + i32::from(k & 1),
        };
        latest.set((0, pole));
        sequencer.run(latest.get(), &mut controller);
        balanced += i32::from(sequencer.phase() == Phase::Balancing);
    }
    *out = [i32::from(sequencer.phase() == Phase::Balancing), balanced];
}
