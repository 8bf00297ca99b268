//! The twin's worlds as Python sees them: one ([`Twin`]) or many stepped in one call
//! ([`VecTwin`]); the Gymnasium classes around them are `python/cartpole_ddqn/env.py`.

use std::path::{Path, PathBuf};

use firmware::cartpole::Transition;
use firmware::controller::Limits;
use host_sim::eval::{MAX_HORIZON, Motor};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1};
use pyo3::prelude::*;

use crate::lane::{Handed, Lane, Worlds};
use crate::{MAX_ENVS, WORLDS_PER_CHECK, interruptible, value_error};
use twin::Machine;
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
            .map(|d| Worlds::Random(Box::new(d)))
            .map_err(value_error),
        (s, None) => twin::Scenario::parse_on(s.unwrap_or("nominal"), &machine)
            .map(|s| Worlds::Fixed(Box::new(s)))
            .map_err(value_error),
    }
}

/// `max_episode_steps` as a horizon: at least one period and at most `host-sim eval`'s
/// longest; none, no truncation.
pub(crate) fn horizon(max_episode_steps: Option<i64>) -> PyResult<u32> {
    match max_episode_steps {
        None => Ok(u32::MAX),
        Some(n) => u32::try_from(n)
            .ok()
            .filter(|n| (1..=MAX_HORIZON).contains(n))
            .ok_or_else(|| {
                value_error(format!(
                    "max_episode_steps must be a whole number in [1, {MAX_HORIZON}]; found {n}"
                ))
            }),
    }
}

/// The duty levels `levels=` gives (checked as `--levels`), or the paper's two.
pub(crate) fn levels(levels: Option<Vec<f64>>) -> PyResult<Handed> {
    match crate::given_levels(levels)? {
        Some(given) => Handed::new(&given).map_err(value_error),
        None => Ok(Handed::bang_bang()),
    }
}

/// Gymnasium's action: the index of one of `levels`.
pub(crate) fn action(a: i64, levels: &Handed) -> PyResult<usize> {
    usize::try_from(a)
        .ok()
        .filter(|&i| i < levels.len())
        .ok_or_else(|| {
            value_error(format!(
                "an action must be the index of a duty level, 0 to {}; found {a}",
                levels.len() - 1
            ))
        })
}

/// The motor figures of the episode so far (`host_sim::eval::Motor`), in the order of
/// `Motor::NAMES`.
fn motor(lane: &Lane) -> [f64; 4] {
    Motor::of(&lane.stats(), lane.scenario().params.tau).values()
}

/// The runtime monitor's envelope: none, the shipped policy's (`"shipped"`), or the file
/// `host-sim envelope --json` wrote for another policy; refused where the file records
/// another rig than `machine`'s.
fn envelope(path: Option<PathBuf>, machine: &Machine) -> PyResult<Option<Limits>> {
    match path {
        None => Ok(None),
        Some(p) if p == Path::new(SHIPPED) => Ok(Some(shipped::envelope::ENVELOPE)),
        Some(p) => {
            let (limits, rig) = host_sim::envelope::read_for(&p, None).map_err(value_error)?;
            host_sim::envelope::measured_on(rig, &machine.rig).map_err(value_error)?;
            Ok(Some(limits))
        }
    }
}

/// The name that asks for the shipped policy's envelope (a file of that name: `./shipped`).
const SHIPPED: &str = "shipped";

/// What both environments are made of: their worlds, the duty levels the actions drive, the
/// periods an episode may last, and what the board knows (whether the policy is shown the
/// predicted state, the monitor's envelope).
struct Setup {
    worlds: Worlds,
    levels: Handed,
    horizon: u32,
    aids: Aids,
}

/// The world arguments both environments take: scenario, domain, rig.
type WorldArgs<'a> = (Option<&'a str>, Option<&'a str>, Option<PathBuf>);

impl Setup {
    fn new(
        (scenario, domain, rig): WorldArgs<'_>,
        (levels, max_episode_steps): (Option<Vec<f64>>, Option<i64>),
        predict: bool,
        envelope: Option<PathBuf>,
    ) -> PyResult<Setup> {
        let machine = crate::machine(rig.as_deref())?;
        let worlds = worlds(scenario, domain, rig)?;
        // Without dead time the predictor has nothing to advance a reading over: the
        // observation was the same either way, as `train --compensate` is refused.
        if !predict && worlds.most_dead_time() == 0 {
            return Err(value_error(
                "predict=False changes nothing where no world has dead time (the predictor \
                 has none to advance the reading over); leave predict out",
            ));
        }
        // The shipped envelope was measured on Gymnasium's machine: on another it bounds
        // readings of another plant.
        if envelope.as_deref() == Some(Path::new(SHIPPED)) && machine != Machine::GYMNASIUM {
            return Err(value_error(
                "envelope=\"shipped\" was measured on Gymnasium's machine, and rig= gives \
                 another; measure one on the rig (`host-sim envelope --rig`) and give its file",
            ));
        }
        Ok(Setup {
            worlds,
            levels: self::levels(levels)?,
            horizon: horizon(max_episode_steps)?,
            aids: Aids {
                predict,
                envelope: self::envelope(envelope, &machine)?,
            },
        })
    }

    /// Episode `episode` of `seed`.
    fn start(&self, seed: u64, episode: u64) -> Lane {
        let run = (&self.levels, self.horizon);
        Lane::start(&self.worlds, run, (seed, episode), self.aids)
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
    #[pyo3(signature = (scenario=None, domain=None, rig=None, max_episode_steps=None, predict=true, envelope=None, levels=None))]
    fn new(
        scenario: Option<&str>,
        domain: Option<&str>,
        rig: Option<PathBuf>,
        max_episode_steps: Option<i64>,
        predict: bool,
        envelope: Option<PathBuf>,
        levels: Option<Vec<f64>>,
    ) -> PyResult<Twin> {
        let (world, run) = ((scenario, domain, rig), (levels, max_episode_steps));
        Ok(Twin {
            setup: Setup::new(world, run, predict, envelope)?,
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

    /// One period under `action`: the next reading, terminated, truncated, the duty driven.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: i64,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, bool, bool, f32)> {
        let a = self::action(action, &self.setup.levels)?;
        let lane = self.lane_mut()?;
        let t = lane.step(a);
        Ok((
            PyArray1::from_slice(py, &lane.obs()),
            t.terminated,
            t.truncated,
            lane.duty(),
        ))
    }

    /// Ends the episode: the next step() needs a reset() first, as before the first one
    /// (it stepped on from the last state).
    fn close(&mut self) {
        self.lane = None;
    }

    /// The duty level each action drives, a fraction of the full push.
    #[getter]
    fn levels(&self) -> Vec<f32> {
        self.setup.levels.fractions()
    }

    /// The episode's motor figures so far, by the names of `host-sim eval --json`.
    fn motor(&self) -> PyResult<Vec<(&'static str, f64)>> {
        let figures = self::motor(self.lane()?);
        Ok(Motor::NAMES.into_iter().zip(figures).collect())
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
    crate::not_running("call reset() before step()")
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
    duty: Vec<f32>,
}

/// What one vector step returns: readings `[n, 4]`, rewards, terminated, truncated, and
/// each world's duty in the period.
type VecStep<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<f32>>,
);

#[pymethods]
impl VecTwin {
    #[new]
    #[pyo3(signature = (scenario=None, domain=None, rig=None, max_episode_steps=None, predict=true, envelope=None, levels=None))]
    fn new(
        scenario: Option<&str>,
        domain: Option<&str>,
        rig: Option<PathBuf>,
        max_episode_steps: Option<i64>,
        predict: bool,
        envelope: Option<PathBuf>,
        levels: Option<Vec<f64>>,
    ) -> PyResult<VecTwin> {
        let (world, run) = ((scenario, domain, rig), (levels, max_episode_steps));
        Ok(VecTwin {
            setup: Setup::new(world, run, predict, envelope)?,
            lanes: Vec::new(),
            seeds: Vec::new(),
            episodes: Vec::new(),
            ended: Vec::new(),
            obs: Vec::new(),
            reward: Vec::new(),
            terminated: Vec::new(),
            truncated: Vec::new(),
            duty: Vec::new(),
        })
    }

    /// Starts episode 0 of `seeds[i]` in world `i` (at most [`MAX_ENVS`] worlds); the
    /// readings `[n, 4]`. Interrupted (Ctrl-C), it leaves no world started.
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seeds: Vec<u64>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let n = seeds.len();
        if !(1..=MAX_ENVS).contains(&n) {
            return Err(value_error(format!(
                "expected 1 to {MAX_ENVS} environments (one seed each); found {n}"
            )));
        }
        self.lanes.clear();
        let mut lanes = Vec::with_capacity(n);
        let setup = &self.setup;
        interruptible(py, n as u64, WORLDS_PER_CHECK, |r| {
            lanes.extend(r.map(|i| setup.start(seeds[i as usize], 0)));
        })?;
        self.lanes = lanes;
        self.seeds = seeds;
        self.episodes = vec![0; n];
        self.ended = vec![false; n];
        self.obs = self.lanes.iter().flat_map(Lane::obs).collect();
        self.reward = vec![0.0; n];
        self.terminated = vec![false; n];
        self.truncated = vec![false; n];
        self.duty = vec![0.0; n];
        readings(py, &self.obs)
    }

    /// One period of every world under `actions` (one per world, the index of a duty
    /// level). Interrupted (Ctrl-C), some worlds have stepped and others not: it leaves the
    /// environment to be reset before the next step.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray1<'py, i64>,
    ) -> PyResult<VecStep<'py>> {
        if self.lanes.is_empty() {
            return Err(not_reset());
        }
        let actions = actions.as_slice()?;
        if actions.len() != self.lanes.len() {
            return Err(value_error(format!(
                "expected one action per environment, {}; found {}",
                self.lanes.len(),
                actions.len()
            )));
        }
        let levels = &self.setup.levels;
        let actions: Vec<usize> = actions
            .iter()
            .map(|&a| action(a, levels))
            .collect::<PyResult<_>>()?;
        let n = self.lanes.len() as u64;
        if let Err(e) = interruptible(py, n, WORLDS_PER_CHECK, |r| {
            self.advance(r.start as usize..r.end as usize, &actions);
        }) {
            self.lanes.clear();
            return Err(e);
        }
        Ok((
            readings(py, &self.obs)?,
            PyArray1::from_slice(py, &self.reward),
            PyArray1::from_slice(py, &self.terminated),
            PyArray1::from_slice(py, &self.truncated),
            PyArray1::from_slice(py, &self.duty),
        ))
    }

    /// Per world, whether the runtime monitor's fallback decided its last period (false
    /// for a world that has just started an episode).
    fn fallbacks<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        let f: Vec<bool> = self.lanes.iter().map(Lane::fallback).collect();
        PyArray1::from_vec(py, f)
    }

    /// The motor figures of each world's episode so far, by the names of `host-sim eval
    /// --json`: after a step that ended a world's episode, that episode's.
    fn motor<'py>(&self, py: Python<'py>) -> Vec<(&'static str, Bound<'py, PyArray1<f64>>)> {
        let figures: Vec<[f64; 4]> = self.lanes.iter().map(self::motor).collect();
        let column = |k: usize| figures.iter().map(|f| f[k]).collect::<Vec<f64>>();
        (Motor::NAMES.iter().enumerate())
            .map(|(k, &name)| (name, PyArray1::from_vec(py, column(k))))
            .collect()
    }

    /// Ends every world's episode: the next step() needs a reset() first.
    fn close(&mut self) {
        self.lanes.clear();
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
    /// The period of worlds `range`, or the start of a world's next episode if its last
    /// one ended.
    fn advance(&mut self, range: std::ops::Range<usize>, actions: &[usize]) {
        for i in range {
            let lane = &mut self.lanes[i];
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
            self.duty[i] = lane.duty();
        }
    }
}

/// Readings laid out `[n, 4]`.
fn readings<'py>(py: Python<'py>, obs: &[f32]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    PyArray1::from_slice(py, obs).reshape([obs.len() / 4, 4])
}
