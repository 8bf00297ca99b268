//! The closed loop: the unchanged firmware [`Controller`] against a [`World`], through the
//! pins and sensor a board would have. The pins are `firmware::loopback`'s, the same the
//! microcontroller's self-test uses; encoders are read through the firmware's
//! `ObserverSensor` (or `AlphaBetaSensor`), as on a board.
//!
//! Every random draw comes from a stream seeded by `(seed, episode)` (the project's one
//! mixer): stream 1 the start, 2 the sensor noise, 3 the pushes, 4 a controller's own
//! randomness. So every controller meets the same starts, noise and pushes.

use firmware::ConfigError;
use firmware::cartpole::{CartPole, Params, State, Transition};
use firmware::controller::{Command, Controller, FaultFlags, Limits, Policy, Sensed};
use firmware::estimator::Estimate;
use firmware::link::LinkSensor;
use firmware::loopback::{Pins, duty, pins};
use firmware::rig::Options;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;

use crate::scenario::Scenario;
use crate::world::World;

/// What one episode did, summed over its periods.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EpisodeStats {
    /// Periods survived.
    pub steps: u32,
    /// Whether it ended by reaching the horizon rather than by a fall or leaving the track.
    pub success: bool,
    /// Sum of theta^2, rad^2.
    pub sum_theta2: f64,
    /// Sum of x^2, m^2.
    pub sum_x2: f64,
    /// Sum of |x|, m.
    pub sum_abs_x: f64,
    /// Periods whose command differs from the previous period's.
    pub switches: u32,
    /// Reversals: periods that push the motor the other way from the last period that pushed
    /// it, a push being a duty of at least [`REVERSAL_DUTY`] (coasting and smaller duties
    /// between them are no direction).
    pub reversals: u32,
    /// Sum of |duty| (fractions of the full push; 0 coasting).
    pub sum_abs_duty: f64,
    /// Sum of |duty - the previous period's duty|: the duty's total variation.
    pub sum_duty_change: f64,
    /// Sum of the motor's squared current as a share of its stall current
    /// ([`firmware::cartpole::Params::current`]), at the cart's speed as the period starts.
    pub sum_heat: f64,
    /// Periods that coasted on a rejected reading.
    pub faults: u32,
    /// Periods a runtime monitor's fallback decided.
    pub fallback: u32,
}

/// One period of a recorded episode (for rendering).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The true state after the period.
    pub state: State,
    /// The command the controller gave in the period.
    pub command: Command,
    /// The reading it decided on (its sensor's estimate of the state at the period's start;
    /// zeros when the reading never arrived).
    pub reading: [f32; 4],
}

/// The random streams of episode `episode` of `seed`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Stream {
    /// The start state.
    Start = 1,
    /// Sensor noise.
    Noise = 2,
    /// Push sides.
    Pushes = 3,
    /// A controller's own randomness (the random baseline).
    Policy = 4,
}

/// Stream `stream` of episode `episode` of `seed`, as [`Draws::of`] draws it.
pub fn episode_rng(seed: u64, episode: u64, stream: Stream) -> Pcg64Mcg {
    Draws::of(seed).rng(episode, stream as u64)
}

/// The start state of episode `episode` of `seed`, as [`crate::lockstep::run_episode`] draws it.
pub fn start_state(seed: u64, episode: u64) -> State {
    let mut plant = CartPole::new(Default::default(), 1);
    plant.reset(&mut episode_rng(seed, episode, Stream::Start));
    plant.state()
}

/// The twin's sensor: the link's, which reads what the world measured as the scenario's
/// board does (the exact state, or counts through its observer or filter), in the format
/// `O` its network takes: `[f32; 4]`, or Q3.12 for an integer network, as a board hands
/// its observer's estimate over.
pub type TwinSensor<O = [f32; 4]> = LinkSensor<O>;

/// The sensor of `scenario`'s board, refused as the firmware refuses its observer or
/// filter; with `watch`, its observer watches for frozen encoders
/// ([`firmware::estimator::Observer::watching`]).
pub fn sensor<O: Estimate>(scenario: &Scenario, watch: bool) -> Result<TwinSensor<O>, ConfigError> {
    let rig = &scenario.rig;
    LinkSensor::new(scenario.sensing, rig, || {
        let o = rig.observer()?;
        Ok(if watch { o.watching() } else { o })
    })
}

/// What a board knows beyond its readings: its dead time, and where its policy may drive.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Aids {
    /// Decide on the state the command will meet: the rig's predictor over the scenario's
    /// dead time, as a board that knows its dead time does.
    pub predict: bool,
    /// Run under the runtime monitor ([`firmware::controller::monitor`]) with this envelope,
    /// the fallback designed for the scenario's rig, and the observer watching for frozen
    /// encoders.
    pub envelope: Option<Limits>,
}

impl From<bool> for Aids {
    /// Told the dead time or not; no monitor.
    fn from(predict: bool) -> Aids {
        Aids {
            predict,
            envelope: None,
        }
    }
}

/// Why [`Episode::start`] may take the board's parts as built: every scenario's rig comes
/// from a rig file or a spec, each checked against the firmware when it is read.
const CHECKED: &str = "a scenario's board is checked as its rig file and spec are read";

impl Scenario {
    /// Whether the firmware builds this scenario's board: its sensor (the observer or
    /// filter of its encoders), its limits and its predictor.
    pub fn check_board(&self) -> Result<(), ConfigError> {
        sensor::<[f32; 4]>(self, false)?;
        self.rig.limits()?;
        self.rig.predictor()?;
        Ok(())
    }
}

/// An episode in progress: a world and the firmware's controller closed around it, its
/// readings in the format `O`.
pub struct Episode<'s, P: Policy<O>, R, O: Estimate = [f32; 4]> {
    pub(crate) world: World<'s, R>,
    pub(crate) controller: Controller<P, TwinSensor<O>, Pins>,
    /// Whether the observer watches for frozen encoders (kept across a `reset` fault).
    watch: bool,
}

impl<'s, P: Policy<O>, R: Rng, O: Estimate> Episode<'s, P, R, O> {
    /// Starts `policy` on a world of `scenario` (see [`World::start`]), with the board's
    /// `aids` (a `bool` says whether it is told its dead time).
    pub fn start(
        policy: P,
        scenario: &'s Scenario,
        horizon: u32,
        start: &mut impl Rng,
        streams: (R, R),
        aids: impl Into<Aids>,
    ) -> Self {
        let aids = aids.into();
        let world = World::start(scenario, horizon, start, streams.0, streams.1);
        let watch = aids.envelope.is_some();
        let rig = &scenario.rig;
        let options = Options {
            predict: aids.predict,
            monitor: aids.envelope.map(|e| rig.lqr_assurance(e).expect(CHECKED)),
        };
        let sensor = sensor(scenario, watch).expect(CHECKED);
        let controller = rig
            .controller(policy, sensor, pins(), options)
            .expect(CHECKED);
        Episode {
            world,
            controller,
            watch,
        }
    }

    /// The first half of [`Episode::decide`]: the board restarted if a fault says so, the
    /// world measured, and the controller's reading of it (what its policy will be shown).
    pub fn sense(&mut self) -> Sensed<O> {
        let scenario = self.world.scenario();
        if scenario.faults.resets(self.world.steps()) {
            *self.controller.sensor_mut() = sensor(scenario, self.watch).expect(CHECKED);
            self.controller.restart();
        }
        let m = self.world.measure();
        self.controller.sensor_mut().set(m);
        self.controller.sense()
    }

    /// The second half of the period with the action decided outside the controller (a
    /// learner exploring, an agent): `decide` is asked only where the policy would drive
    /// ([`Controller::act_with`]).
    pub fn act_with(&mut self, sensed: Sensed<O>, decide: impl FnOnce(&O) -> usize) -> Command {
        let command = self.controller.act_with(sensed, decide);
        self.overran();
        command
    }

    /// A `late` fault's overrun, counted after the period's command.
    fn overran(&mut self) {
        let k = self.world.steps();
        if self
            .world
            .scenario()
            .faults
            .late
            .is_some_and(|w| w.holds(k))
        {
            self.controller.record_overruns(1);
        }
    }

    /// The world's period under what the controller drives.
    pub fn apply(&mut self) -> Transition {
        self.world.apply(duty(self.controller.actuator()))
    }

    /// The world.
    pub fn world(&self) -> &World<'s, R> {
        &self.world
    }

    /// Whether a monitor's fallback decided the last period.
    pub fn fallback(&self) -> bool {
        self.controller
            .last()
            .is_some_and(|r| r.faults.contains(FaultFlags::FALLBACK))
    }

    /// The controller.
    pub fn controller(&self) -> &Controller<P, TwinSensor<O>, Pins> {
        &self.controller
    }
}

impl<P: Policy<O>, R: Rng, O: Estimate> Episode<'_, P, R, O> {
    /// The controller's period on this period's measurement: what it commands. A `reset`
    /// fault restarts the controller first; a `late` one counts an overrun after.
    pub fn decide(&mut self) -> Command {
        let sensed = self.sense();
        self.act(sensed)
    }

    /// The second half of [`Episode::decide`] on what [`Episode::sense`] found.
    pub fn act(&mut self, sensed: Sensed<O>) -> Command {
        let command = self.controller.act(sensed);
        self.overran();
        command
    }
}

/// The smallest duty whose change of direction counts as a reversal: a linear controller's
/// few-thousandths duty that flickers about zero with encoder noise turns no gearbox round,
/// a tenth of the stall torque takes up its backlash.
pub const REVERSAL_DUTY: f32 = 0.1;

/// An episode's statistics as its periods come.
#[derive(Default)]
pub struct Tally {
    stats: EpisodeStats,
    previous: Option<Command>,
    /// The direction the motor was last driven (`true` towards +x).
    direction: Option<bool>,
    /// The cart's speed as the next period starts (the state after the last one).
    x_dot: Option<f64>,
}

impl Tally {
    /// One period on a plant of physics `p`: what was commanded (with `fallback`, by a
    /// monitor's fallback), the state after it, how it ended.
    pub fn period(
        &mut self,
        p: &Params,
        (command, fallback): (Command, bool),
        s: &State,
        t: &Transition,
    ) {
        let stats = &mut self.stats;
        stats.fallback += u32::from(fallback);
        if self.previous.is_some_and(|p| p != command) {
            stats.switches += 1;
        }
        if command == Command::Coast {
            stats.faults += 1;
        }
        let duty = f64::from(command.level());
        let before = self.previous.map_or(0.0, |c| f64::from(c.level()));
        stats.sum_abs_duty += duty.abs();
        stats.sum_duty_change += (duty - before).abs();
        let current = p.current(duty, self.x_dot.unwrap_or(s.x_dot));
        stats.sum_heat += current * current;
        if let Command::Drive(d) = command
            && d.fraction().abs() >= REVERSAL_DUTY
            && let Some(way) = d.direction()
        {
            stats.reversals += u32::from(self.direction.is_some_and(|w| w != way));
            self.direction = Some(way);
        }
        self.x_dot = Some(s.x_dot);
        self.previous = Some(command);
        stats.steps += 1;
        stats.sum_theta2 += s.theta * s.theta;
        stats.sum_x2 += s.x * s.x;
        stats.sum_abs_x += s.x.abs();
        if t.terminated || t.truncated {
            stats.success = !t.terminated;
        }
    }

    /// The statistics so far.
    pub fn stats(&self) -> EpisodeStats {
        self.stats
    }
}

/// Where episodes' random draws come from: under a seed, three streams of each episode's
/// own (its start, its sensor noise, its push sides), indexed by the episode in the
/// project's one mixer (`host_common::seed`). An episode's draws then do not depend on the
/// episodes before it, episodes run in any order and in parallel, and every controller given
/// the same draws meets the same episodes. `host-sim eval`, PIL and the Python environments
/// draw [`Draws::of`]`(seed)`; training's evaluations, streams of their own (`EvalStreams`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Draws {
    /// The seed.
    pub seed: u64,
    /// The mixer's stream numbers of the start, the noise and the pushes.
    pub streams: [u64; 3],
}

impl Draws {
    /// The episodes of `seed` that `host-sim eval` runs: [`Stream::Start`],
    /// [`Stream::Noise`] and [`Stream::Pushes`].
    pub const fn of(seed: u64) -> Draws {
        Draws {
            seed,
            streams: [
                Stream::Start as u64,
                Stream::Noise as u64,
                Stream::Pushes as u64,
            ],
        }
    }

    /// Stream `stream` of episode `episode`.
    pub fn rng(&self, episode: u64, stream: u64) -> Pcg64Mcg {
        host_common::seed::rng(self.seed, episode, stream)
    }

    /// Episode `episode`'s start, noise and pushes streams.
    fn streams_of(&self, episode: u64) -> [Pcg64Mcg; 3] {
        self.streams.map(|s| self.rng(episode, s))
    }

    /// Episode `episode`'s world of `scenario` (see [`World::start`]), for a controller that
    /// runs elsewhere.
    pub fn world<'s>(
        &self,
        scenario: &'s Scenario,
        horizon: u32,
        episode: u64,
    ) -> World<'s, Pcg64Mcg> {
        let [mut start, noise, pushes] = self.streams_of(episode);
        World::start(scenario, horizon, &mut start, noise, pushes)
    }

    /// Episode `episode` started: `policy` on its world of `scenario`, with the board's
    /// `aids` (see [`Episode::start`]).
    pub fn episode<'s, P: Policy<O>, O: Estimate>(
        &self,
        policy: P,
        scenario: &'s Scenario,
        horizon: u32,
        episode: u64,
        aids: impl Into<Aids>,
    ) -> Episode<'s, P, Pcg64Mcg, O> {
        let [mut start, noise, pushes] = self.streams_of(episode);
        Episode::start(policy, scenario, horizon, &mut start, (noise, pushes), aids)
    }
}

#[cfg(test)]
mod tests;
