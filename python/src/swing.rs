//! The swing-up task as Python sees it: a machine's true world over the full circle
//! ([`twin::startup::FullCircle`], the world `host-sim startup` runs its board in), the pole
//! hanging at the start, an agent's duty level driving each period; the Gymnasium class
//! around it is `SwingUpEnv` in `python/cartpole_ddqn/env.py`.

use std::path::PathBuf;

use firmware::cartpole::State;
use numpy::PyArray1;
use pyo3::prelude::*;
use twin::Machine;
use twin::run::{Stream, episode_rng};
use twin::startup::{Begin, FullCircle};

use crate::env::{action, horizon, levels};
use crate::lane::Handed;
use crate::value_error;

/// What the agent is shown: the cart's position and speed, the cosine and sine of the
/// pole's angle from upright (the same for the same pose after any number of turns, where
/// the angle grows by 2 pi a turn) and its rate.
fn observation(s: &State) -> [f32; 5] {
    let (sin, cos) = s.theta.sin_cos();
    [s.x, s.x_dot, cos, sin, s.theta_dot].map(|v| v as f32)
}

/// A period's outcome as `step` returns it: the observation, the reward, terminated,
/// truncated, and the duty sent.
type Stepped<'py> = (Bound<'py, PyArray1<f32>>, f64, bool, bool, f32);

/// An episode in progress: the world and the periods it has run.
struct Running {
    circle: FullCircle,
    steps: u32,
    over: bool,
}

/// One world of the swing-up task, stepped as a Gymnasium environment.
#[pyclass(module = "cartpole_ddqn._native")]
pub struct SwingUp {
    machine: Machine,
    levels: Handed,
    horizon: u32,
    /// How far the cart may go from the centre before the episode ends: the track's end
    /// stops less the rig's end-stop margin, as the board's limits and `host-sim startup`
    /// count it.
    reach: f64,
    running: Option<Running>,
}

#[pymethods]
impl SwingUp {
    #[new]
    #[pyo3(signature = (rig=None, max_episode_steps=None, levels=None))]
    fn new(
        rig: Option<PathBuf>,
        max_episode_steps: Option<i64>,
        levels: Option<Vec<f64>>,
    ) -> PyResult<SwingUp> {
        let machine = crate::machine(rig.as_deref())?;
        let limits = machine.rig.limits().map_err(value_error)?;
        Ok(SwingUp {
            machine,
            levels: self::levels(levels)?,
            horizon: horizon(max_episode_steps)?,
            reach: f64::from(limits.max_abs()[0]),
            running: None,
        })
    }

    /// Starts the episode of `seed`: the pole hanging nearly at rest (within 0.02 rad and
    /// 0.05 rad/s), the cart within a centimetre of the centre, drawn as `host-sim startup
    /// --start hanging` draws its starts (from its own seeds); the first observation.
    fn reset<'py>(&mut self, py: Python<'py>, seed: u64) -> Bound<'py, PyArray1<f32>> {
        let start = Begin::Hanging.state(&mut episode_rng(seed, 0, Stream::Start));
        self.running = Some(Running {
            circle: FullCircle::new(&self.machine, start),
            steps: 0,
            over: false,
        });
        PyArray1::from_slice(py, &observation(&start))
    }

    /// One period under `action`: the observation, the reward (the pole's height as a
    /// share, `(1 + cos theta) / 2`), whether the cart ended inside the end-stop margin
    /// (terminated), whether the horizon was reached (truncated), and the duty sent (it acts
    /// after the rig's dead time).
    fn step<'py>(&mut self, py: Python<'py>, action: i64) -> PyResult<Stepped<'py>> {
        let duty = self.levels.fractions()[self::action(action, &self.levels)?];
        let (reach, horizon) = (self.reach, self.horizon);
        let run = self.running.as_mut().filter(|r| !r.over).ok_or_else(|| {
            crate::not_running(
                "step() needs a running episode: call reset() first, and after its end",
            )
        })?;
        let stopped = run.circle.step(f64::from(duty), 0.0, |_| {});
        run.steps += 1;
        let s = run.circle.state();
        let terminated = stopped || s.x.abs() > reach;
        let truncated = !terminated && run.steps >= horizon;
        run.over = terminated || truncated;
        let reward = 0.5 * (1.0 + s.theta.cos());
        let obs = PyArray1::from_slice(py, &observation(&s));
        Ok((obs, reward, terminated, truncated, duty))
    }

    /// Ends the episode: the next step() needs a reset() first.
    fn close(&mut self) {
        self.running = None;
    }

    /// The period, s; how far the cart may go from the centre before the episode ends, and
    /// where the end stops hold it, m.
    #[getter]
    fn world(&self) -> (f64, f64, f64) {
        let p = &self.machine.rig.params;
        (p.tau, self.reach, p.x_threshold)
    }

    /// The duty level each action drives, a fraction of the full push.
    #[getter]
    fn levels(&self) -> Vec<f32> {
        self.levels.fractions()
    }

    /// The true state `[x, x_dot, theta, theta_dot]`, the angle counted over whole turns.
    #[getter]
    fn state(&self) -> PyResult<[f64; 4]> {
        let run = self
            .running
            .as_ref()
            .ok_or_else(|| crate::not_running("call reset() first"))?;
        Ok(run.circle.state().to_array())
    }
}
