//! What the C program of `tests/c_controller.rs` cannot reach: the shipped rigs have no dead
//! time and a 20 ms period, so other rigs are built here.

use super::init::bang_bang;
use super::*;
use firmware::cartpole::{Params, State, advance};
use firmware::controller::{Controller, Predictor};
use firmware::estimator::ObserverSensor;
use firmware::loopback::{self, Latest};
use firmware::rig::Rig;
use shipped::policy::{POLICY, RIG};

extern crate std;
use std::vec::Vec;

/// The shipped rig with `delay` periods of dead time.
fn delayed(delay: u32) -> Rig {
    Rig {
        dead_time: delay,
        ..RIG
    }
}

/// Each period's command (`-1`, `0`, `1`) and Q-values' bits.
type Decisions = Vec<(i32, [u32; 2])>;

/// The library's commands and Q-values over a closed loop, and those of the firmware's
/// controller with `predictor`, on the same counts.
fn against(rig: &Rig, predictor: Option<Predictor>) -> (Decisions, Decisions) {
    let mut slot = Slot::<Float<64, 2>>::new(bang_bang(&POLICY), rig).unwrap();
    let sensor = ObserverSensor::new(rig.observer().unwrap(), Latest::default());
    let mut reference = Controller::new(&POLICY, sensor, loopback::pins(), rig.limits().unwrap());
    if let Some(p) = predictor {
        reference = reference.with_predictor(p);
    }
    let mut s = State::from_array([0.0, 0.1, 0.04, -0.1]);
    let (mut got, mut want) = (Vec::new(), Vec::new());
    for _ in 0..200 {
        let (cart, pole) = rig.encoders.counts(s.x, s.theta);
        let out = slot.step(Handed::Counts(cart, pole)).unwrap();
        got.push((out.command, out.q.map(f32::to_bits)));
        reference.sensor_mut().counter_mut().0 = (cart, pole);
        let command = reference.step();
        let q = reference.last().unwrap().q.map(f32::to_bits);
        want.push((command.level() as i32, q));
        s = advance(&rig.params, &s, loopback::command_duty(command), 0.0);
    }
    (got, want)
}

#[test]
fn an_instance_of_a_rig_with_dead_time_decides_through_the_rigs_predictor() {
    let rig = delayed(2);
    let (got, want) = against(&rig, Some(rig.predictor().unwrap()));
    assert_eq!(got, want);
    // Without the predictor the same counts score otherwise: the comparison sees it.
    let (got, want) = against(&rig, None);
    assert_ne!(got, want);
}

#[test]
fn the_period_is_the_rigs_tau_in_whole_microseconds() {
    for (tau, us) in [
        (0.02, 20_000),
        (0.0125, 12_500),
        (1.0 / 3.0, 333_333),
        (2e-7, 0),
    ] {
        let rig = Rig {
            params: Params { tau, ..RIG.params },
            ..RIG
        };
        assert_eq!(
            Slot::<Int<64, 2>>::new(bang_bang(&shipped::policy_int::POLICY_INT), &rig)
                .unwrap()
                .period_us(),
            us,
            "tau {tau}"
        );
    }
}

#[test]
fn memory_init_did_not_write_is_refused_by_every_call() {
    let mut out = CartpoleCommand {
        command: 7,
        direction: 7,
        duty: 7,
        faults: 7,
        q: [7.0; 2],
        q_int: [7; 2],
        step: 7,
        signed_duty: 7,
    };
    let before = out;
    for byte in [0x00, 0xab, 0xff] {
        out = before;
        let mut c = CartpoleController::filled(byte);
        let state = [0.0; 4];
        assert_eq!(
            cartpole_controller_step(Some(&mut c), 1, 2, Some(&mut out)),
            CARTPOLE_ERR_UNINITIALISED
        );
        assert_eq!(
            cartpole_controller_step_state(Some(&mut c), Some(&state), Some(&mut out)),
            CARTPOLE_ERR_UNINITIALISED
        );
        assert_eq!(out, before);
        assert_eq!(
            cartpole_controller_init(Some(&mut c), 0),
            CARTPOLE_ERR_POLICY_KIND
        );
        assert_eq!(
            cartpole_controller_record_overruns(Some(&mut c), 1),
            CARTPOLE_ERR_UNINITIALISED
        );
        assert_eq!(
            cartpole_controller_refine(Some(&mut c), 1),
            CARTPOLE_ERR_UNINITIALISED
        );
        assert_eq!(
            cartpole_controller_init(Some(&mut c), CARTPOLE_POLICY_INT),
            CARTPOLE_OK
        );
        // The shipped policies' two outputs are both ends: nothing to refine.
        assert_eq!(
            cartpole_controller_refine(Some(&mut c), 1),
            CARTPOLE_ERR_LEVELS
        );
        assert_eq!(
            cartpole_controller_step(Some(&mut c), 1, 2, Some(&mut out)),
            CARTPOLE_OK
        );
        assert_eq!(out.step, 0);
    }
}

/// `n` steps of `c` on the same counts; the last command.
fn steps(c: &mut CartpoleController, n: usize) -> CartpoleCommand {
    let mut out = CartpoleCommand {
        command: 7,
        direction: 7,
        duty: 7,
        faults: 7,
        q: [7.0; 2],
        q_int: [7; 2],
        step: 7,
        signed_duty: 7,
    };
    for _ in 0..n {
        assert_eq!(
            cartpole_controller_step(Some(&mut *c), 40, -30, Some(&mut out)),
            CARTPOLE_OK
        );
    }
    out
}

#[test]
fn the_shipped_weights_and_rig_given_by_hand_make_the_shipped_controller() {
    let (mut shipped, mut given) = (CartpoleController::filled(0), CartpoleController::filled(0));
    let rig = crate::CartpoleRig::from(&RIG);
    assert_eq!(
        cartpole_controller_init(Some(&mut shipped), CARTPOLE_POLICY_F32),
        CARTPOLE_OK
    );
    assert_eq!(
        cartpole_controller_init_mlp64(Some(&mut given), Some(&POLICY), Some(&rig)),
        CARTPOLE_OK
    );
    assert_eq!(steps(&mut shipped, 5), steps(&mut given, 5));
}

#[test]
fn a_refused_init_leaves_the_instance_running_as_it_was() {
    let mut c = CartpoleController::filled(0);
    let good = crate::CartpoleRig::from(&shipped::policy_int::RIG);
    let w = &shipped::policy_int::POLICY_INT;
    assert_eq!(
        cartpole_controller_init_qmlp64(Some(&mut c), Some(w), Some(&good)),
        CARTPOLE_OK
    );
    steps(&mut c, 3);
    let mut bad = good;
    bad.params.tau = f64::NAN;
    assert_eq!(
        cartpole_controller_init_qmlp64(Some(&mut c), Some(w), Some(&bad)),
        CARTPOLE_ERR_RIG
    );
    // Every field within its range, and still no finite observer gain: the firmware's
    // refusal is the rig's error too.
    let mut feather = good;
    (feather.params.masscart, feather.params.masspole) = (1e-300, 1e-300);
    assert!(feather.to_rig().is_some());
    assert_eq!(
        cartpole_controller_init_qmlp64(Some(&mut c), Some(w), Some(&feather)),
        CARTPOLE_ERR_RIG
    );
    assert_eq!(
        cartpole_controller_init_qmlp64(Some(&mut c), None, Some(&good)),
        CARTPOLE_ERR_NULL
    );
    assert_eq!(steps(&mut c, 1).step, 3);
}

/// The monitor's fallback must be designed for the instance's machine: another rig is
/// refused, and so is a rig no machine has; a refused call leaves the instance unmonitored.
#[test]
fn the_monitor_takes_only_the_instances_rig() {
    let mut c = CartpoleController::filled(0);
    let slow = delayed(2);
    let w = &POLICY;
    let given = crate::CartpoleRig::from(&slow);
    assert_eq!(
        cartpole_controller_init_mlp64(Some(&mut c), Some(w), Some(&given)),
        CARTPOLE_OK
    );
    // NULL is the shipped rig, which has no dead time: not this instance's.
    assert_eq!(
        cartpole_controller_monitor(Some(&mut c), None, None),
        CARTPOLE_ERR_RIG
    );
    let mut bad = given;
    bad.params.length = -1.0;
    assert_eq!(
        cartpole_controller_monitor(Some(&mut c), None, Some(&bad)),
        CARTPOLE_ERR_RIG
    );
    let nan = [1.0, f32::NAN, 0.1, 1.0];
    assert_eq!(
        cartpole_controller_monitor(Some(&mut c), Some(&nan), Some(&given)),
        CARTPOLE_ERR_ENVELOPE
    );
    assert_eq!(
        cartpole_controller_monitor(None, None, None),
        CARTPOLE_ERR_NULL
    );
    // A tiny envelope: once monitored, the fallback decides every period.
    let tiny = [1e-6; 4];
    steps(&mut c, 2);
    assert_eq!(
        steps(&mut c, 1).faults & u32::from(FaultFlags::FALLBACK.0),
        0
    );
    assert_eq!(
        cartpole_controller_monitor(Some(&mut c), Some(&tiny), Some(&given)),
        CARTPOLE_OK
    );
    let out = steps(&mut c, 1);
    assert_ne!(out.faults & u32::from(FaultFlags::FALLBACK.0), 0, "{out:?}");
    let mut n = CartpoleCounters::default();
    assert_eq!(
        cartpole_controller_counters(Some(&c), Some(&mut n)),
        CARTPOLE_OK
    );
    assert_eq!(
        (n.faults.fallbacks, n.faults.fallback_periods, n.steps),
        (1, 1, 4)
    );
}
