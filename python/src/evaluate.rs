//! `host-sim eval` for Python: the same rows, built by the same functions from the same
//! arguments (`host_sim::eval::evaluate` for each horizon, scenario and controller, in the
//! command's order), returned as the JSON `eval --json` prints under `rows`. Each row's
//! episodes run range by range (`eval::par_episodes`, the command's parallel runner) on a
//! thread of their own while the caller's thread, the GIL released, looks at Python's
//! signals every few milliseconds: Ctrl-C returns at once, however long an episode, and
//! leaves at most the range in progress to finish unheard.

use std::ops::Range;
use std::path::PathBuf;
use std::sync::{Arc, mpsc};
use std::time::Duration;

use clap::ValueEnum;
use host_sim::eval::{self, ControllerKind, MAX_EPISODES, MAX_HORIZON, Net};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use twin::{EpisodeStats, Machine, Scenario};

use crate::policy::Policy;
use crate::{reserve, value_error};

/// The rows of `controllers` on `scenarios` (specs, or the sets `all`, `hard`, `faults`,
/// `hard-candidates`, Gymnasium's machine alone) at `horizons`, `episodes` each from
/// `seed`; `policy` the network (the shipped one if `None`), `rig` the machine (the
/// policy's if `None`); `levels`, if given, must be the policy's.
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
    levels: Option<Vec<f64>>,
) -> PyResult<String> {
    host_common::cli::check_threads_env().map_err(value_error)?;
    // The Python wrapper (`_whole`) checks `episodes`' range first, with the same words;
    // checked again here for a caller of the native module itself, which it does not guard.
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
    refuse_unread(policy, levels.is_some(), given.is_some(), &kinds)?;
    let shipped;
    let policy = match policy {
        Some(p) => p,
        None => {
            shipped = crate::policy::shipped(py, None)?;
            &shipped
        }
    };
    same_levels(policy, levels)?;
    if let Some(why) = eval::idle_between(&kinds, policy.net.levels()) {
        return Err(value_error(format!("policy: {why}")));
    }
    // Warned of against the rig the policy was trained for, not the one it was loaded for.
    let (machine, other) = match given {
        Some(g) => twin::rigfile::choose(Some(g), policy.trained_for()?),
        None => (policy.machine, None),
    };
    if kinds.iter().any(|k| k.needs_policy()) {
        crate::warn_other_rig(py, other)?;
    }
    // Counted before the specs are parsed, each a row at least: a parse costs far more.
    check_count(horizons.len(), scenarios.len(), kinds.len())?;
    // A spec asked for twice is named as such before a world two specs build is.
    let built = Scenario::words_built_on(&scenarios, &machine).map_err(value_error)?;
    eval::check_rows(&horizons, &built, &kinds, NAMES).map_err(value_error)?;
    let scenarios = Scenario::words_on(&scenarios, &machine).map_err(value_error)?;
    let rows = horizons.len() * scenarios.len() * kinds.len();
    let net = network(policy, &kinds, &machine)?.unwrap_or_else(|| policy.net.clone());
    let mut out = Vec::with_capacity(rows);
    for &h in &horizons {
        for s in &scenarios {
            let s = Arc::new(s.clone());
            for &k in &kinds {
                let job = Job {
                    kind: k,
                    net: net.clone(),
                    scenario: s.clone(),
                    horizon: h,
                    seed,
                };
                let eps = job.episodes(py, episodes)?;
                out.push(eval::row(k, &s, h, seed, &eps));
            }
        }
    }
    serde_json::to_string(&out).map_err(value_error)
}

/// Refuses `policy` and `levels` where no controller of `kinds` runs the network or rounds to
/// its levels, so that they change nothing: the policy is then read for its machine alone,
/// which `rig` (`given`) replaces, or which is Gymnasium's, the machine without it.
fn refuse_unread(
    policy: Option<&Policy>,
    levels: bool,
    given: bool,
    kinds: &[ControllerKind],
) -> PyResult<()> {
    if kinds.iter().any(|k| k.needs_policy()) {
        return Ok(());
    }
    let (read_by, found) = (ControllerKind::read_by(), host_sim::eval::names(kinds));
    if levels {
        return Err(value_error(format!(
            "levels {read_by}; expected one of them, found {found}"
        )));
    }
    let Some(policy) = policy else {
        return Ok(());
    };
    if given || policy.machine == Machine::GYMNASIUM {
        return Err(value_error(format!(
            "policy {read_by}, and for the machine it records where no rig is given, other \
             than Gymnasium's; expected one of them, or no policy, found {found}"
        )));
    }
    Ok(())
}

/// Refuses more than `MAX_ROWS` rows of `horizons` x `scenarios` x `controllers` lists:
/// the command's check, on the lists' lengths, which Python knows before it builds them.
#[pyfunction]
pub fn check_count(horizons: usize, scenarios: usize, controllers: usize) -> PyResult<()> {
    eval::check_count([horizons, scenarios, controllers], NAMES).map_err(value_error)
}

/// The lists as `evaluate`'s refusals name them: its keywords.
const NAMES: [&str; 3] = ["horizon", "scenario", "controller"];

/// One row's controller, network, scenario, horizon and seed, owned, so that a range of its
/// episodes may run on past an interrupted call.
struct Job {
    kind: ControllerKind,
    net: Arc<Net>,
    scenario: Arc<Scenario>,
    horizon: u32,
    seed: u64,
}

/// Periods a range of episodes runs on each thread (at most; an episode longer than this
/// is a range of its own): what an interrupted evaluation leaves to finish unheard, a tenth
/// of a second or so.
const PERIODS_PER_RANGE: u64 = 1 << 17;

/// How often a caller waiting for a range of episodes looks at Python's signals.
const WAIT: Duration = Duration::from_millis(20);

impl Job {
    /// Episodes `0..episodes`, in ranges of at most [`PERIODS_PER_RANGE`] periods a thread
    /// (one episode at the least). The threads are rayon's, as many as the machine runs at
    /// once. The list is allocated once, whole, as the command's is: grown range by range
    /// it could take up to twice what it holds.
    fn episodes(&self, py: Python<'_>, episodes: u64) -> PyResult<Vec<EpisodeStats>> {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get() as u64);
        let per_range = (PERIODS_PER_RANGE * threads / u64::from(self.horizon)).max(1);
        let mut eps = Vec::new();
        reserve(&mut eps, episodes as usize, "the episodes' statistics")?;
        let mut start = 0;
        while start < episodes {
            let end = start.saturating_add(per_range).min(episodes);
            eps.extend(self.range(py, start..end)?);
            start = end;
        }
        Ok(eps)
    }

    /// Episodes `r` on a thread of their own, this one waiting with the GIL released and
    /// looking at Python's signals every [`WAIT`].
    fn range(&self, py: Python<'_>, r: Range<u64>) -> PyResult<Vec<EpisodeStats>> {
        let (tx, mut rx) = mpsc::channel();
        let (kind, net, s) = (self.kind, self.net.clone(), self.scenario.clone());
        let (horizon, seed) = (self.horizon, self.seed);
        std::thread::Builder::new()
            .name("evaluate".into())
            .spawn(move || {
                // A receiver gone (the call interrupted) wants no answer.
                let _ = tx.send(eval::par_episodes(kind, &net, &s, horizon, seed, r));
            })
            .map_err(|e| PyRuntimeError::new_err(format!("could not start a thread: {e}")))?;
        loop {
            // The receiver crosses to the detached closure and back: it may be sent, not shared.
            let got;
            (got, rx) = py.detach(move || (rx.recv_timeout(WAIT), rx));
            match got {
                Ok(eps) => return Ok(eps),
                Err(mpsc::RecvTimeoutError::Timeout) => py.check_signals()?,
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(PyRuntimeError::new_err(
                        "the evaluation's thread stopped without its episodes",
                    ));
                }
            }
        }
    }
}

/// Refuses `levels` other than the policy's (to the thousandth, as the bridge drives them).
fn same_levels(policy: &Policy, levels: Option<Vec<f64>>) -> PyResult<()> {
    let Some(given) = crate::given_levels(levels)? else {
        return Ok(());
    };
    let theirs: Vec<f32> = policy.net.levels().iter().map(|d| d.fraction()).collect();
    given.agree(&theirs).map_err(value_error)
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
fn network(
    policy: &Policy,
    kinds: &[ControllerKind],
    machine: &Machine,
) -> PyResult<Option<Arc<Net>>> {
    if kinds.iter().any(|k| k.monitored()) {
        policy
            .net
            .check_envelope_on(&machine.rig)
            .map_err(value_error)?;
    }
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
        .map(|n| Some(Arc::new(n)))
        .map_err(|e| value_error(format!("{e:#}")))
}
