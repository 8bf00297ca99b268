//! `host-sim eval` for Python: the same rows, built by the same functions from the same
//! arguments (`host_sim::eval::evaluate` for each horizon, scenario and controller, in the
//! command's order), returned as the JSON `eval --json` prints under `rows`. Each row's
//! episodes run range by range with the GIL released (`eval::par_episodes`, the command's
//! parallel runner), Python's signals looked at between ranges, so Ctrl-C stops a long
//! evaluation within one range.

use std::path::PathBuf;

use clap::ValueEnum;
use host_sim::eval::{self, ControllerKind, MAX_EPISODES, MAX_HORIZON, MAX_ROWS, Net};
use pyo3::prelude::*;
use twin::{EpisodeStats, Machine, Scenario};

use crate::policy::Policy;
use crate::{PERIODS_PER_CHECK, interruptible, reserve, value_error};

/// The rows of `controllers` on `scenarios` (specs, or the sets `all`, `hard`, `faults`,
/// `hard-candidates`) at `horizons`, `episodes` each from `seed`; `policy` the network
/// (the shipped one if `None`), `rig` the machine (the policy's if `None`); `levels`, if
/// given, must be the policy's.
#[pyfunction]
#[pyo3(signature = (policy, scenarios, controllers, episodes, horizons, seed, rig=None, levels=None))]
// One argument per keyword of the Python function (`cartpole_ddqn.evaluate`).
#[allow(clippy::too_many_arguments)]
pub fn evaluate_json(
    py: Python<'_>,
    policy: Option<&Policy>,
    scenarios: Vec<String>,
    controllers: Vec<String>,
    episodes: u64,
    horizons: Vec<u32>,
    seed: u64,
    rig: Option<PathBuf>,
    levels: Option<Vec<f32>>,
) -> PyResult<String> {
    if !(1..=MAX_EPISODES).contains(&episodes) {
        return Err(value_error(format!(
            "episodes must be in [1, {MAX_EPISODES}]; found {episodes}"
        )));
    }
    if let Some(h) = horizons.iter().find(|&&h| !(1..=MAX_HORIZON).contains(&h)) {
        return Err(value_error(format!(
            "horizon must be in [1, {MAX_HORIZON}]; found {h}"
        )));
    }
    let kinds = controllers
        .iter()
        .map(|c| kind(c))
        .collect::<PyResult<Vec<_>>>()?;
    let given = crate::given_machine(rig.as_deref())?;
    let shipped;
    let policy = match policy {
        Some(p) => p,
        None => {
            shipped = crate::policy::shipped(None)?;
            &shipped
        }
    };
    same_levels(policy, levels)?;
    let machine = given.unwrap_or(policy.machine);
    let scenarios = Scenario::words_on(&scenarios, &machine).map_err(value_error)?;
    let rows = horizons.len() * scenarios.len() * kinds.len();
    if rows > MAX_ROWS {
        return Err(value_error(format!(
            "horizons x scenarios x controllers must make at most {MAX_ROWS} rows; found {rows}"
        )));
    }
    let rebuilt = network(policy, &kinds, &machine)?;
    let net = rebuilt.as_ref().unwrap_or(&policy.net);
    let mut out = Vec::with_capacity(rows);
    for &h in &horizons {
        for s in &scenarios {
            for &k in &kinds {
                let eps = episodes_of(py, (k, net, s), h, seed, episodes)?;
                out.push(eval::row(k, s, h, seed, &eps));
            }
        }
    }
    serde_json::to_string(&out).map_err(value_error)
}

/// Episodes `0..episodes` of one controller on one scenario, in ranges of at most
/// [`PERIODS_PER_CHECK`] periods a thread (one episode at the least). The threads are
/// rayon's, as many as the machine runs at once.
fn episodes_of(
    py: Python<'_>,
    (kind, net, scenario): (ControllerKind, &Net, &Scenario),
    horizon: u32,
    seed: u64,
    episodes: u64,
) -> PyResult<Vec<EpisodeStats>> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get() as u64);
    let per_range = PERIODS_PER_CHECK * threads / u64::from(horizon);
    let mut eps = Vec::new();
    interruptible(py, episodes, per_range, |r| {
        reserve(
            &mut eps,
            (r.end - r.start) as usize,
            "the episodes' statistics",
        )?;
        eps.extend(eval::par_episodes(kind, net, scenario, horizon, seed, r));
        Ok(())
    })?;
    Ok(eps)
}

/// Refuses `levels` other than the policy's (to the thousandth, as the bridge drives them).
fn same_levels(policy: &Policy, levels: Option<Vec<f32>>) -> PyResult<()> {
    let Some(given) = crate::given_levels(levels)? else {
        return Ok(());
    };
    let duties = given
        .levels()
        .iter()
        .map(|&f| firmware::controller::Duty::from_fraction(f));
    let duties: Vec<_> = duties.collect::<Result<_, _>>().map_err(value_error)?;
    if duties == policy.net.levels() {
        return Ok(());
    }
    let theirs: Vec<f32> = policy.net.levels().iter().map(|d| d.fraction()).collect();
    Err(value_error(format!(
        "levels {:?}: the policy drives the duty levels {theirs:?}; expected those or no levels",
        given.levels()
    )))
}

/// A controller by the name `host-sim eval --controller` takes.
fn kind(name: &str) -> PyResult<ControllerKind> {
    ControllerKind::from_str(name, false).map_err(|_| {
        let names: Vec<String> = ControllerKind::value_variants()
            .iter()
            .map(ToString::to_string)
            .collect();
        value_error(format!(
            "expected a controller among {}; found {name:?}",
            names.join(", ")
        ))
    })
}

/// The network as `host-sim eval` builds it for `kinds`, where the loaded one will not do:
/// a file's network with its integer version, quantised on `machine`. The monitored
/// controllers need an envelope, which only the shipped policy has.
fn network(policy: &Policy, kinds: &[ControllerKind], machine: &Machine) -> PyResult<Option<Net>> {
    let Some(import) = &policy.import else {
        return Ok(None);
    };
    if kinds.iter().any(|k| k.monitored()) {
        return Err(value_error(
            "expected controllers without the runtime monitor for a loaded policy (its \
             envelope is measured for the shipped policy only); found monitored",
        ));
    }
    if !kinds.iter().any(|k| k.int()) {
        return Ok(None);
    }
    Net::from_weights(&import.weights, Some(machine))
        .map(Some)
        .map_err(|e| value_error(format!("{e:#}")))
}
