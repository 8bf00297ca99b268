//! The twin's worlds as Python sees them: one ([`Twin`]) or many stepped in one call
//! ([`VecTwin`]); the Gymnasium classes around them are `python/cartpole_ddqn/env.py`.

use std::path::{Path, PathBuf};

use firmware::cartpole::{Action, Transition};
use firmware::controller::Limits;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1};
use pyo3::prelude::*;

use crate::lane::{Lane, Worlds};
use crate::value_error;
use twin::run::Aids;

/// The worlds of a scenario or a domain (not both) on the machine of `rig` (Gymnasium's
/// without one), and the horizon in periods.
fn worlds(scenario: Option<&str>, domain: Option<&str>, rig: Option<PathBuf>) -> PyResult<Worlds> {
    let machine = crate::machine(rig.as_deref())?;
    match (scenario, domain) {
        (Some(s), Some(d)) => Err(value_error(format!(
            "expected a scenario or a domain, not both; found scenario {s:?} and domain {d:?}"
        ))),
        (None, Some(d)) => twin::Domain::parse_on(d, &machine)
            .map(Worlds::Random)
            .map_err(value_error),
        (s, None) => twin::Scenario::parse_on(s.unwrap_or("nominal"), &machine)
            .map(Worlds::Fixed)
            .map_err(value_error),
    }
}

/// `max_episode_steps` as a horizon: at least one period; none, no truncation.
fn horizon(max_episode_steps: Option<i64>) -> PyResult<u32> {
    match max_episode_steps {
        None => Ok(u32::MAX),
        Some(n) => u32::try_from(n).ok().filter(|&n| n >= 1).ok_or_else(|| {
            value_error(format!(
                "max_episode_steps must be a whole number in [1, {}]; found {n}",
                u32::MAX
            ))
        }),
    }
}

/// Gymnasium's action index as the plant's action.
fn action(a: i64) -> PyResult<Action> {
    match a {
        0 | 1 => Ok(Action::from_index(a as usize)),
        _ => Err(value_error(format!(
            "an action must be 0 (push left) or 1 (push right); found {a}"
        ))),
    }
}

/// The runtime monitor's envelope: none, the shipped policy's (`"shipped"`), or the file
/// `host-sim envelope --json` wrote for another policy.
fn envelope(path: Option<PathBuf>) -> PyResult<Option<Limits>> {
    match path {
        None => Ok(None),
        Some(p) if p == Path::new(SHIPPED) => Ok(Some(shipped::envelope::ENVELOPE)),
        Some(p) => host_sim::envelope::read(&p).map(Some).map_err(value_error),
    }
}

/// The name that asks for the shipped policy's envelope (a file of that name: `./shipped`).
const SHIPPED: &str = "shipped";

/// What both environments are made of: their worlds, the periods an episode may last, and
/// what the board knows (whether the policy is shown the predicted state, the monitor's
/// envelope).
struct Setup {
    worlds: Worlds,
    horizon: u32,
    aids: Aids,
}

impl Setup {
    fn new(
        (scenario, domain, rig): (Option<&str>, Option<&str>, Option<PathBuf>),
        max_episode_steps: Option<i64>,
        predict: bool,
        envelope: Option<PathBuf>,
    ) -> PyResult<Setup> {
        Ok(Setup {
            worlds: worlds(scenario, domain, rig)?,
            horizon: horizon(max_episode_steps)?,
            aids: Aids {
                predict,
                envelope: self::envelope(envelope)?,
            },
        })
    }

    /// Episode `episode` of `seed`.
    fn start(&self, seed: u64, episode: u64) -> Lane {
        Lane::start(&self.worlds, self.horizon, (seed, episode), self.aids)
    }
}

/// One world of the twin, stepped as a Gymnasium environment.
#[pyclass(module = "cartpole_ddqn._native")]
pub struct Twin {
    setup: Setup,
    seed: u64,
    episode: u64,
    lane: Option<Lane>,
}

#[pymethods]
impl Twin {
    #[new]
    #[pyo3(signature = (scenario=None, domain=None, rig=None, max_episode_steps=None, predict=true, envelope=None))]
    fn new(
        scenario: Option<&str>,
        domain: Option<&str>,
        rig: Option<PathBuf>,
        max_episode_steps: Option<i64>,
        predict: bool,
        envelope: Option<PathBuf>,
    ) -> PyResult<Twin> {
        let world = (scenario, domain, rig);
        Ok(Twin {
            setup: Setup::new(world, max_episode_steps, predict, envelope)?,
            seed: 0,
            episode: 0,
            lane: None,
        })
    }

    /// Starts episode 0 of `seed`, or with none the next episode of the last seed; the
    /// first reading.
    #[pyo3(signature = (seed=None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> Bound<'py, PyArray1<f32>> {
        match seed {
            Some(s) => (self.seed, self.episode) = (s, 0),
            None => self.episode += 1,
        }
        let lane = self.setup.start(self.seed, self.episode);
        let obs = PyArray1::from_slice(py, &lane.obs());
        self.lane = Some(lane);
        obs
    }

    /// One period under `action`: the next reading, terminated, truncated.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: i64,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, bool, bool)> {
        let a = self::action(action)?;
        let lane = self.lane_mut()?;
        let t = lane.step(a);
        Ok((
            PyArray1::from_slice(py, &lane.obs()),
            t.terminated,
            t.truncated,
        ))
    }

    /// The plant's true state `[x, x_dot, theta, theta_dot]` (f64).
    #[getter]
    fn state(&self) -> PyResult<[f64; 4]> {
        Ok(self.lane()?.state().to_array())
    }

    /// Whether the controller would reject this period's reading (the cart coasts).
    #[getter]
    fn rejected(&self) -> PyResult<bool> {
        Ok(self.lane()?.rejected())
    }

    /// Whether the runtime monitor's fallback, not the agent, decided the last period.
    #[getter]
    fn fallback(&self) -> PyResult<bool> {
        Ok(self.lane()?.fallback())
    }

    /// The episode's scenario: its spec, control period (s), and the true plant's track
    /// and angle thresholds.
    #[getter]
    fn world(&self) -> PyResult<(String, f64, f64, f64)> {
        let s = self.lane()?.scenario();
        let p = &s.params;
        Ok((
            s.name.clone(),
            p.tau,
            p.x_threshold,
            p.theta_threshold_radians,
        ))
    }
}

impl Twin {
    fn lane(&self) -> PyResult<&Lane> {
        self.lane.as_ref().ok_or_else(not_reset)
    }

    fn lane_mut(&mut self) -> PyResult<&mut Lane> {
        self.lane.as_mut().ok_or_else(not_reset)
    }
}

fn not_reset() -> PyErr {
    pyo3::exceptions::PyRuntimeError::new_err("call reset() before step()")
}

/// Many worlds of one scenario or domain, stepped together with Gymnasium's next-step
/// autoreset: the step after a world's episode ends starts its next episode, ignoring that
/// world's action, with reward 0 and neither terminated nor truncated.
#[pyclass(module = "cartpole_ddqn._native")]
pub struct VecTwin {
    setup: Setup,
    lanes: Vec<Lane>,
    seeds: Vec<u64>,
    episodes: Vec<u64>,
    ended: Vec<bool>,
    obs: Vec<f32>,
    reward: Vec<f64>,
    terminated: Vec<bool>,
    truncated: Vec<bool>,
}

/// What one vector step returns: readings `[n, 4]`, rewards, terminated, truncated.
type VecStep<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
);

#[pymethods]
impl VecTwin {
    #[new]
    #[pyo3(signature = (scenario=None, domain=None, rig=None, max_episode_steps=None, predict=true, envelope=None))]
    fn new(
        scenario: Option<&str>,
        domain: Option<&str>,
        rig: Option<PathBuf>,
        max_episode_steps: Option<i64>,
        predict: bool,
        envelope: Option<PathBuf>,
    ) -> PyResult<VecTwin> {
        let world = (scenario, domain, rig);
        Ok(VecTwin {
            setup: Setup::new(world, max_episode_steps, predict, envelope)?,
            lanes: Vec::new(),
            seeds: Vec::new(),
            episodes: Vec::new(),
            ended: Vec::new(),
            obs: Vec::new(),
            reward: Vec::new(),
            terminated: Vec::new(),
            truncated: Vec::new(),
        })
    }

    /// Starts episode 0 of `seeds[i]` in world `i`; the readings `[n, 4]`.
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seeds: Vec<u64>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let n = seeds.len();
        self.lanes = seeds.iter().map(|&s| self.setup.start(s, 0)).collect();
        self.seeds = seeds;
        self.episodes = vec![0; n];
        self.ended = vec![false; n];
        self.obs = self.lanes.iter().flat_map(Lane::obs).collect();
        self.reward = vec![0.0; n];
        self.terminated = vec![false; n];
        self.truncated = vec![false; n];
        readings(py, &self.obs)
    }

    /// One period of every world under `actions` (one per world, 0 or 1).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray1<'py, i64>,
    ) -> PyResult<VecStep<'py>> {
        let actions = actions.as_slice()?;
        if actions.len() != self.lanes.len() {
            return Err(value_error(format!(
                "expected one action per environment, {}; found {}",
                self.lanes.len(),
                actions.len()
            )));
        }
        let actions: Vec<Action> = actions
            .iter()
            .map(|&a| action(a))
            .collect::<PyResult<_>>()?;
        py.detach(|| self.advance(&actions));
        Ok((
            readings(py, &self.obs)?,
            PyArray1::from_slice(py, &self.reward),
            PyArray1::from_slice(py, &self.terminated),
            PyArray1::from_slice(py, &self.truncated),
        ))
    }

    /// Per world, whether the runtime monitor's fallback decided its last period (false
    /// for a world that has just started an episode).
    fn fallbacks<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        let f: Vec<bool> = self.lanes.iter().map(Lane::fallback).collect();
        PyArray1::from_vec(py, f)
    }

    /// The plants' true states `[n, 4]` (f64).
    fn states<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat: Vec<f64> = self
            .lanes
            .iter()
            .flat_map(|l| l.state().to_array())
            .collect();
        PyArray1::from_vec(py, flat).reshape([self.lanes.len(), 4])
    }
}

impl VecTwin {
    /// Every world's period, or the start of its next episode if the last one ended.
    fn advance(&mut self, actions: &[Action]) {
        for (i, lane) in self.lanes.iter_mut().enumerate() {
            let t = if self.ended[i] {
                self.episodes[i] += 1;
                let (s, e) = (self.seeds[i], self.episodes[i]);
                *lane = self.setup.start(s, e);
                Transition {
                    obs: [0.0; 4],
                    reward: 0.0,
                    terminated: false,
                    truncated: false,
                }
            } else {
                lane.step(actions[i])
            };
            self.ended[i] = t.terminated || t.truncated;
            self.obs[4 * i..4 * i + 4].copy_from_slice(&lane.obs());
            self.reward[i] = f64::from(t.reward);
            self.terminated[i] = t.terminated;
            self.truncated[i] = t.truncated;
        }
    }
}

/// Readings laid out `[n, 4]`.
fn readings<'py>(py: Python<'py>, obs: &[f32]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    PyArray1::from_slice(py, obs).reshape([obs.len() / 4, 4])
}
