//! The plant against Gymnasium's own trajectories (`tests/data/`, recorded by
//! `tests/data/record_gymnasium.py`): every state, bit for bit, and every termination.

use std::path::PathBuf;
use std::process::Command;

use firmware::cartpole::{self, Action, CartPole, Params, State};
use host_sim::replay::{self, Case};

fn reference_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data")
}

fn cases(file: &str) -> Vec<Case> {
    let path = reference_dir().join(file);
    replay::load(&path).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()))
}

const FILES: [&str; 2] = ["gym_traj_public.jsonl", "gym_traj_public_long.jsonl"];

#[test]
fn every_recorded_step_is_reproduced_bit_for_bit() {
    let p = Params::default();
    let mut steps = 0;
    for file in FILES {
        for (i, case) in cases(file).iter().enumerate() {
            let states = case.exact_states();
            for (k, &a) in case.actions.iter().enumerate() {
                let next = cartpole::step(
                    &p,
                    &State::from_array(states[k]),
                    Action::from_index(a.into()),
                );
                assert_eq!(
                    next.to_array().map(f64::to_bits),
                    states[k + 1].map(f64::to_bits),
                    "{file} case {i} step {k}"
                );
                assert_eq!(
                    p.is_terminal(&next),
                    case.terminated[k],
                    "{file} case {i} step {k}"
                );
                steps += 1;
            }
        }
    }
    assert_eq!(steps, 4_859);
}

#[test]
fn open_loop_rollouts_reproduce_every_state_and_termination() {
    for file in FILES {
        for (i, case) in cases(file).iter().enumerate() {
            let mut env = CartPole::new(Params::default(), u32::MAX);
            env.reset_to(State::from_array(case.initial_state));
            let states = case.exact_states();
            let mut terminated_at = None;
            for (k, &a) in case.actions.iter().enumerate() {
                let t = env.step(Action::from_index(a.into()));
                assert_eq!(
                    env.state().to_array(),
                    states[k + 1],
                    "{file} case {i} step {k}"
                );
                assert_eq!(t.obs, env.state().observation());
                if t.terminated && terminated_at.is_none() {
                    terminated_at = Some(k as u32 + 1);
                }
            }
            assert_eq!(terminated_at, case.terminated_at, "{file} case {i}");
            assert!(
                replay::replay_case(case, &Params::default())
                    .unwrap()
                    .matches()
            );
        }
    }
}

#[test]
fn exact_decimal_parsing_agrees_with_the_hex_states() {
    // serde_json's float_roundtrip feature makes the decimals exact; without it, some
    // values land one unit in the last place off and this test says so.
    for file in FILES {
        for case in cases(file) {
            let hex = case.exact_states();
            assert_eq!(hex, case.states);
        }
    }
}

#[test]
fn replay_cli_passes_on_gymnasium_and_fails_on_a_tampered_file() {
    let exe = env!("CARGO_BIN_EXE_host-sim");
    let good = reference_dir().join(FILES[0]);
    let out = Command::new(exe).arg("replay").arg(&good).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(
        stdout.contains("20 cases, 430 steps, 0 mismatched"),
        "{stdout}"
    );

    // Nudge one recorded state by one ulp: the replay must notice and exit 1.
    let text = std::fs::read_to_string(&good).unwrap();
    let mut case: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    let v = case["states"][3][2].as_f64().unwrap();
    case["states"][3][2] = serde_json::json!(f64::from_bits(v.to_bits() + 1));
    case.as_object_mut().unwrap().remove("states_hex");
    let dir = std::env::temp_dir().join(format!("replay-tampered-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("tampered.jsonl");
    std::fs::write(&bad, format!("{case}\n")).unwrap();
    let out = Command::new(exe).arg("replay").arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("MISMATCH"));

    let out = Command::new(exe)
        .arg("replay")
        .arg(dir.join("missing.jsonl"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    std::fs::remove_dir_all(&dir).unwrap();
}
