//! A policy of one's own through the C controller. Headers are exported here by the
//! exporters `policy-export export --format c` runs (the float writer and the int8 one),
//! for the desk rig as `twin::rigfile` reads `rigs/desk.toml`, and compiled with
//! `tests/exported_controller.c` as C99, C++11 and C++17 against the library. What the C
//! compiler makes of the header's `struct cartpole_rig` must be Rust's `Rig` bit for bit and
//! `CartpoleRig`'s layout; the controller `cartpole_controller_init_mlpH` /
//! `_qmlpH` builds from the header's weights and rig must decide every period of a closed
//! loop as a firmware `Controller` built here, in Rust, from the same weights and the parsed
//! rig (`Rig::observer`, `predictor`, `limits`); bad rigs and NULLs must be refused, writing
//! nothing.

mod common;
#[path = "common/steps.rs"]
mod steps;

use std::collections::HashSet;
use std::fmt::Write as _;
use std::mem::{align_of, offset_of, size_of};
use std::path::PathBuf;

use cartpole_policy::{
    CARTPOLE_ERR_NULL, CARTPOLE_ERR_RIG, CARTPOLE_ERR_UNINITIALISED, CARTPOLE_OK, CartpoleRig,
};
use common::{Compiler, EVERY, compile_and_run, manifest};
use firmware::cartpole::{Params, State, advance};
use firmware::controller::{Command, Controller, Policy};
use firmware::estimator::{Encoders, ObserverSensor, Tuning};
use firmware::loopback::{self, Latest, Pins};
use firmware::network::int::QMlp;
use firmware::network::{Mlp, shapes};
use firmware::rig::{Options, Rig};
use shipped::policy::POLICY;
use steps::Scores;
use weights::Weights;
use weights::quant::{self, Granularity, Quantised};
use weights::source::c_header;

/// The machine of `rigs/desk.toml`, read as every tool reads a rig file.
fn desk() -> Rig {
    twin::rigfile::load(&manifest().join("../rigs/desk.toml"))
        .unwrap()
        .rig
}

/// A header to compile: its text, the init that builds its controller, and a tag that names
/// its files.
struct Header {
    text: String,
    init: String,
    tag: String,
}

fn float_header(w: &Weights, rig: &Rig, tag: &str) -> Header {
    Header {
        text: c_header(w, "test_policy", &["source: the capi test".into()], rig).unwrap(),
        init: format!("cartpole_controller_init_mlp{}", w.width()),
        tag: tag.into(),
    }
}

fn int_header(q: &Quantised, rig: &Rig, tag: &str) -> Header {
    Header {
        text: quant::c_header(q, "test_policy", &["source: the capi test".into()], rig).unwrap(),
        init: format!("cartpole_controller_init_qmlp{}", q.width()),
        tag: tag.into(),
    }
}

/// The shipped float weights, quantised on a few states near upright.
fn shipped_quantised() -> Quantised {
    let states = [
        [0.0, 0.0, 0.0, 0.0],
        [0.01, -0.02, 0.03, 0.04],
        [-0.1, 0.3, -0.05, 0.2],
        [0.2, -0.4, 0.1, -0.5],
    ];
    let w = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    quant::quantise(&w, &states, Granularity::PerChannel).unwrap()
}

/// `tests/exported_controller.c` with `header`, compiled by `compiler`, run with `args`.
fn run(header: &Header, compiler: &Compiler, args: &[String]) -> String {
    let name = format!("exported-{}-{}{}", header.tag, args[0], compiler.std);
    let dir = std::env::temp_dir().join(format!("cartpole-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("exported.h"), &header.text).unwrap();
    let main = format!(
        "#define INIT {}\n#include \"exported_controller.c\"\n",
        header.init
    );
    std::fs::write(dir.join("main.c"), main).unwrap();
    let tests = manifest().join("tests");
    let out = compile_and_run(
        compiler,
        &name,
        &[&dir.join("main.c")],
        &[&manifest().join("include"), &dir, &tests],
        args,
    );
    std::fs::remove_dir_all(&dir).unwrap();
    out
}

#[test]
fn c_lays_out_struct_cartpole_rig_as_rust_lays_out_cartpole_rig() {
    let offsets = [
        offset_of!(CartpoleRig, params.gravity),
        offset_of!(CartpoleRig, params.masscart),
        offset_of!(CartpoleRig, params.masspole),
        offset_of!(CartpoleRig, params.length),
        offset_of!(CartpoleRig, params.force_mag),
        offset_of!(CartpoleRig, params.motor_damping),
        offset_of!(CartpoleRig, params.tau),
        offset_of!(CartpoleRig, params.theta_threshold_radians),
        offset_of!(CartpoleRig, params.x_threshold),
        offset_of!(CartpoleRig, params.cart_friction),
        offset_of!(CartpoleRig, params.pole_friction),
        offset_of!(CartpoleRig, cart_counts_per_m),
        offset_of!(CartpoleRig, pole_counts_per_rev),
        offset_of!(CartpoleRig, dead_time),
        offset_of!(CartpoleRig, end_stop_margin),
        offset_of!(CartpoleRig, force_sd),
        offset_of!(CartpoleRig, accel_sd),
    ];
    let mut want = format!("{} {}", size_of::<CartpoleRig>(), align_of::<CartpoleRig>());
    for o in offsets {
        write!(want, " {o}").unwrap();
    }
    want.push('\n');
    let header = float_header(
        &Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap(),
        &desk(),
        "layout",
    );
    for compiler in EVERY {
        assert_eq!(
            run(&header, compiler, &["layout".into()]),
            want,
            "{}",
            compiler.std
        );
    }
}

/// A rig whose decimal forms are awkward for a parser: long mantissas, -0.0, a subnormal,
/// the extremes. Not a machine: only its bits travel.
fn awkward_rig() -> Rig {
    Rig {
        params: Params {
            gravity: 9.80665,
            masscart: 1.0 / 3.0,
            masspole: 0.1 + 0.2,
            length: 0.22,
            force_mag: 5.000_000_000_000_001,
            motor_damping: 2.5e-7,
            tau: 1.0 / 60.0,
            theta_threshold_radians: 12.0 * 2.0 * std::f64::consts::PI / 360.0,
            x_threshold: 123_456_789.123_456_78,
            cart_friction: f64::MIN_POSITIVE,
            pole_friction: -0.0,
        },
        encoders: Encoders {
            cart_counts_per_m: u32::MAX,
            pole_counts_per_rev: 16,
        },
        dead_time: 16,
        end_stop_margin: 5e-324,
        tuning: Tuning {
            force_sd: f64::MAX,
            accel_sd: [0.1, 1e-300],
        },
    }
}

/// What `exported_controller rig` prints for `rig`: f64 bits in hex, u32s in decimal.
fn rig_lines(rig: &Rig) -> String {
    let (p, e, t) = (&rig.params, &rig.encoders, &rig.tuning);
    let bits = |vs: &[f64]| -> String {
        vs.iter()
            .map(|v| format!("{:016x}\n", v.to_bits()))
            .collect()
    };
    bits(&p.values())
        + &format!(
            "{}\n{}\n{}\n",
            e.cart_counts_per_m, e.pole_counts_per_rev, rig.dead_time
        )
        + &bits(&[
            rig.end_stop_margin,
            t.force_sd,
            t.accel_sd[0],
            t.accel_sd[1],
        ])
}

#[test]
fn exported_headers_carry_their_rig_bit_for_bit_in_c_and_cpp() {
    let w = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    let q = shipped_quantised();
    for (rig, what) in [(desk(), "desk"), (awkward_rig(), "awkward")] {
        let want = rig_lines(&rig);
        for header in [
            float_header(&w, &rig, &format!("{what}-f32")),
            int_header(&q, &rig, &format!("{what}-int")),
        ] {
            for compiler in EVERY {
                let got = run(&header, compiler, &["rig".into()]);
                assert_eq!(got, want, "{} {}", header.tag, compiler.std);
            }
        }
    }
}

/// Periods of each closed loop.
const PERIODS: usize = 400;

type Board<P, O> = Controller<P, ObserverSensor<Latest, O>, Pins>;

/// A controller of `policy` as a Rust board builds one from `rig`.
fn board<O: Scores, P: Policy<O>>(policy: P, rig: &Rig) -> Board<P, O> {
    let sensor = ObserverSensor::<_, O>::new(rig.observer().unwrap(), Latest::default());
    let options = Options {
        predict: true,
        monitor: None,
    };
    rig.controller(policy, sensor, loopback::pins(), options)
        .unwrap()
}

/// The line `exported_controller script` prints for the step `c` has just run.
fn step_line<O: Scores, P: Policy<O, Scores = <O as Scores>::Scores>>(c: &Board<P, O>) -> String {
    steps::step_line(CARTPOLE_OK, c.last().unwrap(), c.actuator()) + "\n"
}

/// An outside force on the cart in period `k`, N: a shove, then one that topples the pole,
/// whose fall the controller must coast through.
fn shove(k: usize) -> f64 {
    match k {
        100..=104 => 5.0,
        250..=280 => -20.0,
        _ => 0.0,
    }
}

/// A closed loop of `policy` on `rig`'s plant: the counts script for the C program and what
/// it must print. Asserts that the periods pushed both ways and coasted, so that the
/// comparison means something.
fn closed_loop<O: Scores, P: Policy<O, Scores = <O as Scores>::Scores>>(
    policy: P,
    rig: &Rig,
) -> (String, String) {
    let mut c = board::<O, P>(policy, rig);
    let mut s = State::from_array([0.02, 0.0, 0.03, 0.0]);
    let (mut calls, mut want) = (String::new(), format!("init {CARTPOLE_OK}\n"));
    let mut commands = HashSet::new();
    for k in 0..PERIODS {
        let (cart, pole) = match k {
            // Counts no encoder of the rig gives: the reading is rejected.
            200 => (i32::MAX, i32::MIN),
            _ => rig.encoders.counts(s.x, s.theta),
        };
        c.sensor_mut().counter_mut().0 = (cart, pole);
        commands.insert(c.step());
        writeln!(calls, "count {cart} {pole}").unwrap();
        want.push_str(&step_line(&c));
        s = advance(&rig.params, &s, loopback::duty(c.actuator()), shove(k));
    }
    for command in [
        firmware::controller::Duty::LEFT,
        firmware::controller::Duty::RIGHT,
    ]
    .map(Command::Drive)
    .iter()
    .chain([&Command::Coast])
    {
        assert!(commands.contains(command), "no {command:?} in the loop");
    }
    (calls, want)
}

/// Runs the closed loop's counts through the C controller of `header` for every compiler:
/// each period's line must be Rust's.
fn compare(header: &Header, (calls, want): (String, String)) {
    let path: PathBuf = std::env::temp_dir().join(format!(
        "cartpole-exported-script-{}-{}",
        header.tag,
        std::process::id()
    ));
    std::fs::write(&path, &calls).unwrap();
    for compiler in EVERY {
        let out = run(
            header,
            compiler,
            &["script".into(), path.display().to_string()],
        );
        let mut lines = out.lines().zip(want.lines()).enumerate();
        if let Some((k, (got, want))) = lines.find(|(_, (got, want))| got != want) {
            panic!(
                "{} {}: line {k} the C program printed\n  {got}\nthe firmware's controller\n  {want}",
                header.tag, compiler.std
            );
        }
        assert_eq!(
            out.lines().count(),
            want.lines().count(),
            "{}",
            compiler.std
        );
    }
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn an_exported_float_policy_runs_through_the_c_controller_period_for_period() {
    let rig = desk();
    assert!(
        rig.dead_time > 0,
        "the desk rig has dead time: the predictor runs"
    );
    let header = float_header(
        &Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap(),
        &rig,
        "loop-f32",
    );
    compare(&header, closed_loop::<[f32; 4], _>(&POLICY, &rig));
}

#[test]
fn an_exported_integer_policy_runs_through_the_c_controller_period_for_period() {
    let rig = desk();
    let q = shipped_quantised();
    let net: &'static QMlp<64> = Box::leak(q.to_qmlp().unwrap());
    let header = int_header(&q, &rig, "loop-int");
    compare(&header, closed_loop::<[i16; 4], _>(net, &rig));
}

#[test]
fn refused_inits_return_their_codes_and_write_nothing() {
    let rig = desk();
    let headers = [
        float_header(
            &Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap(),
            &rig,
            "refusals-f32",
        ),
        int_header(&shipped_quantised(), &rig, "refusals-int"),
    ];
    let (null, bad) = (CARTPOLE_ERR_NULL, CARTPOLE_ERR_RIG);
    let want = format!(
        "codes {null} {bad} {CARTPOLE_ERR_UNINITIALISED}\n\
         refused {null} {null} {null} {bad} {bad} {bad} {bad} {bad} 1\n\
         step {CARTPOLE_ERR_UNINITIALISED}\ninit {CARTPOLE_OK}\n"
    );
    for header in &headers {
        for compiler in EVERY {
            let got = run(header, compiler, &["refusals".into()]);
            assert_eq!(got, want, "{} {}", header.tag, compiler.std);
        }
    }
}

/// A 4-16-16-2 network built by hand: the hidden layers pass `relu(obs)` and `relu(-obs)`
/// through, and the outputs score a linear state feedback, so it pushes as a bang-bang
/// controller does (right when the pole leans or falls right).
fn linear_16() -> Weights {
    let gain = [0.5, 1.0, 20.0, 3.0];
    let [mut fc1_w, fc1_b, mut fc2_w, fc2_b, mut fc3_w, fc3_b] =
        shapes(16, 2).map(|s| vec![0.0f32; s.len()]);
    for i in 0..4 {
        fc1_w[i * 4 + i] = 1.0;
        fc1_w[(i + 4) * 4 + i] = -1.0;
    }
    for u in 0..8 {
        fc2_w[u * 16 + u] = 1.0;
        let g = if u < 4 { gain[u] } else { -gain[u - 4] };
        fc3_w[u] = -g;
        fc3_w[16 + u] = g;
    }
    Weights::new(
        16,
        weights::BANG_BANG.to_vec(),
        [fc1_w, fc1_b, fc2_w, fc2_b, fc3_w, fc3_b],
    )
    .unwrap()
}

#[test]
fn an_exported_policy_of_another_width_runs_through_the_c_controller_too() {
    let rig = desk();
    let w = linear_16();
    let net: &'static Mlp<16> = Box::leak(w.to_mlp().unwrap());
    let header = float_header(&w, &rig, "loop-f32-16");
    compare(&header, closed_loop::<[f32; 4], _>(net, &rig));
}
