//! Replay of recorded Gymnasium `CartPole-v1` trajectories through `firmware::cartpole`.
//!
//! The file format is JSON Lines, one case a line, as `tests/data/record_gymnasium.py`
//! writes it: `initial_state`, `actions` (0/1), `states` (`len(actions) + 1` states, each
//! `[x, x_dot, theta, theta_dot]`), optionally `states_hex` (the same as `float.hex()`
//! strings, preferred because they are exact whatever the decimal parser), `terminated`
//! (per step) and `terminated_at` (1-based, or null). Other keys are ignored.
//!
//! Each case is checked two ways: open-loop from its initial state with the recorded
//! actions (every state and the termination step must agree), and one step from every
//! recorded state (every next state must agree bit for bit).

use std::path::Path;

use anyhow::{Context, Result, bail, ensure};
use firmware::cartpole::{self, Action, Params, State};
use serde::Deserialize;

mod bounded;

/// One recorded trajectory.
#[derive(Clone, Debug, Deserialize)]
pub struct Case {
    /// The seed the recorder drew the case with, if it says.
    #[serde(default)]
    pub seed: Option<u64>,
    /// How the case was drawn, if it says.
    #[serde(default)]
    pub kind: Option<String>,
    /// `[x, x_dot, theta, theta_dot]` before the first action.
    pub initial_state: [f64; 4],
    /// Gymnasium action indices: 0 = left, 1 = right.
    #[serde(deserialize_with = "bounded::actions")]
    pub actions: Vec<u8>,
    /// `states[i]` before `actions[i]`, `states[i + 1]` after it.
    #[serde(deserialize_with = "bounded::states")]
    pub states: Vec<[f64; 4]>,
    /// `states` exactly, read from `float.hex()` strings (exact whatever the decimal
    /// parser); empty where the file has none.
    #[serde(default, deserialize_with = "bounded::hex_states")]
    pub states_hex: Vec<[f64; 4]>,
    /// Per step: did Gymnasium flag termination after it?
    #[serde(deserialize_with = "bounded::flags")]
    pub terminated: Vec<bool>,
    /// 1-based step that terminated, or `None`.
    pub terminated_at: Option<u32>,
}

impl Case {
    /// The recorded states, exactly: from `states_hex` when present, else the decimals.
    pub fn exact_states(&self) -> &[[f64; 4]] {
        if self.states_hex.is_empty() {
            &self.states
        } else {
            &self.states_hex
        }
    }

    fn validate(&self) -> Result<()> {
        ensure!(
            self.states.len() == self.actions.len() + 1,
            "{} actions need {} states, found {}",
            self.actions.len(),
            self.actions.len() + 1,
            self.states.len()
        );
        ensure!(
            self.terminated.len() == self.actions.len(),
            "{} actions need {} terminated flags, found {}",
            self.actions.len(),
            self.actions.len(),
            self.terminated.len()
        );
        if let Some(bad) = self.actions.iter().find(|&&a| a > 1) {
            bail!("action {bad} is not 0 (left) or 1 (right)");
        }
        ensure!(
            self.actions.len() <= MAX_ACTIONS,
            "expected at most {MAX_ACTIONS} actions, found {}",
            self.actions.len()
        );
        ensure!(
            self.states_hex.is_empty() || self.states_hex.len() == self.states.len(),
            "states_hex has {} rows but states has {}",
            self.states_hex.len(),
            self.states.len()
        );
        // Replay reads the hex strings; decimals that say otherwise would be ignored, so the
        // file contradicts itself (the decimals parse exactly: serde_json's float_roundtrip).
        let differs = |(a, b): &(&[f64; 4], &[f64; 4])| {
            a.iter().zip(*b).any(|(x, y)| x.to_bits() != y.to_bits())
        };
        let mut pairs = self.states.iter().zip(&self.states_hex).enumerate();
        if let Some((row, (dec, hex))) = pairs.find(|(_, p)| differs(p)) {
            bail!(
                "states row {row} is {dec:?} but states_hex row {row} is {hex:?}; expected \
                 the same states in both"
            );
        }
        self.agrees_with_itself(differs)
    }

    /// Refuses a case whose own fields disagree, which replay reported as the plant's
    /// mismatch (exit 1): the initial state against the first of the states, the step that
    /// terminated against the flags.
    fn agrees_with_itself(&self, differs: impl Fn(&(&[f64; 4], &[f64; 4])) -> bool) -> Result<()> {
        let first = &self.exact_states()[0];
        if differs(&(&self.initial_state, first)) {
            bail!(
                "initial_state is {:?} but states row 0 is {first:?}; expected the same state",
                self.initial_state
            );
        }
        let flagged = (self.terminated.iter().position(|&t| t)).map(|i| i as u32 + 1);
        ensure!(
            flagged == self.terminated_at,
            "terminated_at is {:?} but the first step flagged terminated is {flagged:?}; \
             expected the same",
            self.terminated_at
        );
        Ok(())
    }
}

/// Largest trajectory file read (the repository's two are 0.1 and 0.9 MB).
pub const MAX_FILE_BYTES: u64 = 64 << 20;
/// Most actions in one case.
pub const MAX_ACTIONS: usize = 1_000_000;

/// Reads every case of a JSON Lines file (a regular file of at most [`MAX_FILE_BYTES`]).
pub fn load(path: &Path) -> Result<Vec<Case>> {
    let bytes = weights::files::read_capped(path, MAX_FILE_BYTES)?;
    let text = std::str::from_utf8(&bytes)
        .map_err(|e| anyhow::anyhow!("{}: expected UTF-8 JSON Lines, {e}", weights::shown(path)))?;
    parse(text, &weights::shown(path))
}

/// Every case of JSON Lines `text`; blank lines are skipped. Errors name `origin` and the
/// line.
pub fn parse(text: &str, origin: &str) -> Result<Vec<Case>> {
    let mut cases = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        // As every JSON the tools read: a leading byte-order mark taken.
        let case: Case = weights::json::parse(line)
            .map_err(|e| anyhow::anyhow!("{origin}:{}: not a trajectory case: {e}", n + 1))?;
        case.validate()
            .with_context(|| format!("{origin}:{}", n + 1))?;
        cases.push(case);
    }
    ensure!(!cases.is_empty(), "{origin}: no cases");
    Ok(cases)
}

/// How one case replayed.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseReport {
    /// Steps in the case.
    pub steps: usize,
    /// Largest |ours - Gymnasium's| over every variable of every state of the open-loop
    /// rollout.
    pub rollout_max_abs_dev: f64,
    /// Steps whose rollout state differs from the recording in any bit.
    pub rollout_mismatches: usize,
    /// Steps where one step from the recorded state misses the recorded next state.
    pub step_mismatches: usize,
    /// The 1-based step at which our rollout terminated, or `None`.
    pub terminated_at: Option<u32>,
    /// Did every per-step termination flag, and the termination step, agree?
    pub termination_agrees: bool,
}

impl CaseReport {
    /// Bit-exact everywhere, termination included.
    pub fn matches(&self) -> bool {
        self.rollout_mismatches == 0 && self.step_mismatches == 0 && self.termination_agrees
    }
}

/// Replays one case through the plant with `params` (Gymnasium's for a faithful check).
pub fn replay_case(case: &Case, params: &Params) -> Result<CaseReport> {
    let recorded = case.exact_states();
    let mut state = State::from_array(case.initial_state);
    let mut report = CaseReport {
        steps: case.actions.len(),
        rollout_max_abs_dev: 0.0,
        rollout_mismatches: 0,
        step_mismatches: 0,
        terminated_at: None,
        termination_agrees: true,
    };
    for (i, &a) in case.actions.iter().enumerate() {
        let action = Action::from_index(usize::from(a));
        state = cartpole::step(params, &state, action);
        let want = recorded[i + 1];
        let got = state.to_array();
        if !bit_equal(&got, &want) {
            report.rollout_mismatches += 1;
        }
        report.rollout_max_abs_dev = report.rollout_max_abs_dev.max(deviation(&got, &want));
        let terminal = params.is_terminal(&state);
        if terminal != case.terminated[i] {
            report.termination_agrees = false;
        }
        if terminal && report.terminated_at.is_none() {
            report.terminated_at = Some(i as u32 + 1);
        }

        let one = cartpole::step(params, &State::from_array(recorded[i]), action);
        if !bit_equal(&one.to_array(), &want) {
            report.step_mismatches += 1;
        }
    }
    if report.terminated_at != case.terminated_at {
        report.termination_agrees = false;
    }
    Ok(report)
}

/// Bit for bit, and no NaN on either side: a NaN is never a match, even of itself.
fn bit_equal(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a.iter()
        .zip(b)
        .all(|(x, y)| x.to_bits() == y.to_bits() && !x.is_nan())
}

/// The largest `|a - b|` over the four variables; infinite where either is NaN (`f64::max`
/// would drop a NaN and report no deviation at all).
fn deviation(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| {
        let d = (x - y).abs();
        if d.is_nan() { f64::INFINITY } else { m.max(d) }
    })
}

/// Parses Python's `float.hex()` form (`-0x1.921fb54442d18p+1`, `0x0.0p+0`, subnormals as
/// `0x0.<13 digits>p-1022`, `inf`, `nan`) into the exact f64.
pub fn parse_hex_f64(s: &str) -> Result<f64> {
    let err = || anyhow::anyhow!("{} is not a hexadecimal float", weights::quote(s));
    let (neg, body) = match s.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, s.strip_prefix('+').unwrap_or(s)),
    };
    let magnitude = match body {
        "inf" => f64::INFINITY,
        "nan" => f64::NAN,
        _ => {
            let body = body.strip_prefix("0x").ok_or_else(err)?;
            let (mant, exp) = body.split_once('p').ok_or_else(err)?;
            let exp: i32 = exp.parse().map_err(|_| err())?;
            let (lead, frac) = mant.split_once('.').unwrap_or((mant, ""));
            if frac.len() > 13 || !frac.chars().all(|c| c.is_ascii_hexdigit()) {
                return Err(err());
            }
            let frac = if frac.is_empty() {
                0
            } else {
                u64::from_str_radix(frac, 16).map_err(|_| err())? << (4 * (13 - frac.len()))
            };
            match lead {
                "1" => {
                    let biased = exp + 1023;
                    if !(1..=2046).contains(&biased) {
                        return Err(err());
                    }
                    f64::from_bits(((biased as u64) << 52) | frac)
                }
                "0" if frac == 0 => 0.0,
                "0" if exp == -1022 => f64::from_bits(frac),
                _ => return Err(err()),
            }
        }
    };
    Ok(if neg { -magnitude } else { magnitude })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_floats_parse_exactly() {
        assert_eq!(parse_hex_f64("0x1.0000000000000p+0").unwrap(), 1.0);
        assert_eq!(
            parse_hex_f64("-0x1.921fb54442d18p+1").unwrap(),
            -std::f64::consts::PI
        );
        assert_eq!(parse_hex_f64("0x1.999999999999ap-4").unwrap(), 0.1);
        assert_eq!(parse_hex_f64("0x0.0p+0").unwrap().to_bits(), 0);
        assert_eq!(
            parse_hex_f64("-0x0.0p+0").unwrap().to_bits(),
            (-0.0f64).to_bits()
        );
        assert_eq!(
            parse_hex_f64("0x0.0000000000001p-1022").unwrap(),
            f64::from_bits(1)
        );
        assert_eq!(parse_hex_f64("0x1.fffffffffffffp+1023").unwrap(), f64::MAX);
        assert_eq!(parse_hex_f64("-inf").unwrap(), f64::NEG_INFINITY);
        for bad in [
            "",
            "1.0",
            "0x2.0p+0",
            "0x1.0p+1024",
            "0x1.gp+0",
            "0x1.0",
            "0x1.00000000000000p+0",
        ] {
            assert!(parse_hex_f64(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn malformed_cases_are_rejected_with_the_line() {
        let dir = std::env::temp_dir().join(format!("replay-bad-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.jsonl");
        let good = r#"{"initial_state":[0,0,0,0],"actions":[1],"states":[[0,0,0,0],[0,0,0,0]],"terminated":[false],"terminated_at":null}"#;
        let short = r#"{"initial_state":[0,0,0,0],"actions":[1,0],"states":[[0,0,0,0],[0,0,0,0]],"terminated":[false,false],"terminated_at":null}"#;
        std::fs::write(&path, format!("{good}\n\n{short}\n")).unwrap();
        let e = format!("{:#}", load(&path).unwrap_err());
        assert!(
            e.contains("bad.jsonl:3") && e.contains("2 actions need 3 states"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A case whose fields disagree was replayed and reported as the plant's mismatch.
    #[test]
    fn a_case_that_contradicts_itself_is_refused() {
        let good = r#"{"initial_state":[0,0,0,0],"actions":[1],"states":[[0,0,0,0],[0,0,0,0]],"terminated":[false],"terminated_at":null}"#;
        parse(good, "t").unwrap();
        // A leading byte-order mark, as every JSON the tools read takes it.
        assert_eq!(parse(&format!("\u{feff}{good}"), "t").unwrap().len(), 1);
        for (from, to, want) in [
            (
                "\"initial_state\":[0,0,0,0]",
                "\"initial_state\":[0,0,1,0]",
                "initial_state is",
            ),
            (
                "\"terminated_at\":null",
                "\"terminated_at\":1",
                "terminated_at is Some(1)",
            ),
            (
                "[false]",
                "[true]",
                "the first step flagged terminated is Some(1)",
            ),
        ] {
            let e = format!("{:#}", parse(&good.replace(from, to), "t").unwrap_err());
            assert!(e.starts_with("t:1: ") && e.contains(want), "{e}");
        }
    }

    #[test]
    fn a_list_is_refused_at_its_first_row_past_a_cases_bound() {
        let case = |states: &str, hex: &str| {
            format!(
                r#"{{"initial_state": [0, 0, 0, 0], "actions": [1], "terminated": [false], "terminated_at": null, "states": {states}, "states_hex": {hex}}}"#
            )
        };
        let two = "[[0, 0, 0, 0], [0, 0, 0, 0]]";
        let zero = r#"["0x0.0p+0", "0x0.0p+0", "0x0.0p+0", "0x0.0p+0"]"#;
        let hex = format!("[{zero}, {zero}]");
        assert_eq!(
            parse(&case(two, &hex), "f").unwrap()[0].exact_states(),
            [[0.0; 4]; 2]
        );
        // The decimals must say what the hex strings say: replay reads the hex alone.
        let other = "[[0, 0, 0, 0], [0, 0, 1e-3, 0]]";
        let e = parse(&format!("\n{}", case(other, &hex)), "f").unwrap_err();
        assert_eq!(
            format!("{e:#}"),
            "f:2: states row 1 is [0.0, 0.0, 0.001, 0.0] but states_hex row 1 is \
             [0.0, 0.0, 0.0, 0.0]; expected the same states in both"
        );
        let bad = format!(r#"[{zero}, ["a", "0x0.0p+0", "0x0.0p+0", "0x0.0p+0"]]"#);
        let e = parse(&case(two, &bad), "f").unwrap_err().to_string();
        assert!(e.contains("\"a\" is not a hexadecimal float"), "{e}");
        let many = format!("[{}[0, 0, 0, 0]]", "[0, 0, 0, 0], ".repeat(MAX_ACTIONS + 1));
        let e = parse(&case(&many, "[]"), "f").unwrap_err().to_string();
        assert!(
            e.contains("expected at most 1000001 states, found more"),
            "{e}"
        );
    }

    #[test]
    fn a_nan_in_a_recording_is_a_mismatch_of_infinite_deviation() {
        let p = Params::default();
        let next = cartpole::step(&p, &State::default(), Action::Right).to_array();
        let mut nan = next;
        nan[2] = f64::NAN;
        let case = Case {
            seed: None,
            kind: None,
            initial_state: [0.0; 4],
            actions: vec![1],
            states: vec![[0.0; 4], nan],
            states_hex: vec![],
            terminated: vec![false],
            terminated_at: None,
        };
        let r = replay_case(&case, &p).unwrap();
        assert!(!r.matches());
        assert_eq!(r.rollout_max_abs_dev, f64::INFINITY);
        assert!(!bit_equal(&nan, &nan));
        assert_eq!(deviation(&next, &next), 0.0);
    }

    #[test]
    fn a_wrong_plant_is_caught() {
        // One hand-made case: from rest, a push right moves x_dot by tau * xacc.
        let p = Params::default();
        let next = cartpole::step(&p, &State::default(), Action::Right);
        let case = Case {
            seed: None,
            kind: None,
            initial_state: [0.0; 4],
            actions: vec![1],
            states: vec![[0.0; 4], next.to_array()],
            states_hex: vec![],
            terminated: vec![false],
            terminated_at: None,
        };
        assert!(replay_case(&case, &p).unwrap().matches());
        // By hand: temp = 10/1.1, thetaacc = -temp / (0.5 * (4/3 - 0.1/1.1)),
        // xacc = temp - 0.05 * thetaacc / 1.1.
        let temp = 10.0 / 1.1;
        let thetaacc = -temp / (0.5 * (4.0 / 3.0 - 0.1 / 1.1));
        let xacc = temp - 0.05 * thetaacc / 1.1;
        assert!((next.x_dot - 0.02 * xacc).abs() < 1e-15);
        assert!((next.theta_dot - 0.02 * thetaacc).abs() < 1e-15);

        let heavy = Params {
            masspole: 0.11,
            ..p
        };
        let r = replay_case(&case, &heavy).unwrap();
        assert!(!r.matches() && r.rollout_max_abs_dev > 0.0);
    }
}
