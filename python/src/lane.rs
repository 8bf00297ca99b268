//! One world of the twin stepped as Gymnasium steps an environment: the agent sees the
//! reading the board's controller would decide on, then chooses the action.
//!
//! `host-sim eval` runs a whole period inside `firmware::controller::Controller::step`, which
//! reads and decides in one call. An agent outside decides between the two, so a lane splits
//! the period where the controller calls its policy and runs the controller's own parts in
//! its order: the world's measurement (`twin::World`, as eval's episodes build it), the
//! board's sensor, the reading's sanitising against the board's limits and the dead-time
//! predictor before the decision; the predictor's record, the pins, the sensor's
//! `commanded` and the world's period after it. A rejected reading coasts whatever the agent
//! chose, as the controller does.

use firmware::cartpole::{Action, State, Transition};
use firmware::controller::{
    Actuator, Command, FaultFlags, Limits, Predictor, Reading, StateSensor,
};
use firmware::loopback::{Pins, duty, pins};
use rand_pcg::Pcg64Mcg;
use self_cell::self_cell;
use twin::run::{Stream, TwinSensor, episode_rng};
use twin::{Domain, Scenario, World};

/// The seeded stream a domain's world is drawn from, after the four of `twin::run::Stream`.
const DOMAIN_STREAM: u64 = 5;

/// Why a lane may take its board as built: scenarios and domains are checked against the
/// firmware as they are parsed.
const CHECKED: &str = "a scenario's board is checked as its spec is parsed";

/// Where a lane's worlds come from.
#[derive(Clone, Debug)]
pub enum Worlds {
    /// The same scenario every episode.
    Fixed(Scenario),
    /// A scenario drawn from the domain each episode.
    Random(Domain),
}

impl Worlds {
    /// The world of episode `episode` of `seed`.
    fn scenario(&self, seed: u64, episode: u64) -> Scenario {
        match self {
            Worlds::Fixed(s) => s.clone(),
            Worlds::Random(d) => {
                d.sample(&mut host_common::seed::rng(seed, episode, DOMAIN_STREAM))
            }
        }
    }
}

type Running<'s> = World<'s, Pcg64Mcg>;

self_cell!(
    /// A scenario and the episode running in it.
    struct Live {
        owner: Scenario,
        #[covariant]
        dependent: Running,
    }
);

/// One episode in progress, paused where the controller would call its policy.
pub struct Lane {
    live: Live,
    sensor: TwinSensor,
    limits: Limits,
    predictor: Option<Predictor>,
    pins: Pins,
    /// Periods an episode may last.
    horizon: u32,
    /// What the policy is shown: the reading, advanced over the dead time if predicting.
    shown: [f32; 4],
    /// Whether the controller would reject this period's reading (and coast).
    rejected: bool,
}

impl Lane {
    /// Episode `episode` of `seed`, with the start, noise and push streams `host-sim eval`
    /// gives the same episode; with `predict`, the policy is shown the predicted state when
    /// the scenario has dead time, as eval's policy is.
    pub fn start(worlds: &Worlds, horizon: u32, seed: u64, episode: u64, predict: bool) -> Lane {
        let scenario = worlds.scenario(seed, episode);
        let board = scenario.board(false).expect(CHECKED);
        let predictor = (predict && scenario.delay() > 0).then_some(board.predictor);
        let live = Live::new(scenario, |s| {
            let mut start = episode_rng(seed, episode, Stream::Start);
            let noise = episode_rng(seed, episode, Stream::Noise);
            let pushes = episode_rng(seed, episode, Stream::Pushes);
            World::start(s, horizon, &mut start, noise, pushes)
        });
        let mut lane = Lane {
            live,
            sensor: board.sensor,
            limits: board.limits,
            predictor,
            pins: pins(),
            horizon,
            shown: [0.0; 4],
            rejected: false,
        };
        lane.read();
        lane
    }

    /// The first half of a period: a `reset` fault restarts the board, the world measures,
    /// the sensor reads, the reading is sanitised and predicted.
    fn read(&mut self) {
        let (sensor, predictor) = (&mut self.sensor, &mut self.predictor);
        self.live.with_dependent_mut(|scenario, world| {
            if scenario.faults.resets(world.steps()) {
                *sensor = twin::run::sensor(scenario, false).expect(CHECKED);
                if let Some(p) = predictor {
                    p.clear();
                }
            }
            sensor.set(world.measure());
        });
        let (obs, flags) = match self.sensor.read() {
            Ok(obs) => (obs, obs.flags(&self.limits)),
            Err(_) => (<[f32; 4]>::ZERO, FaultFlags::SENSOR_ERROR),
        };
        self.rejected = flags.reading_rejected();
        self.shown = match &self.predictor {
            Some(p) if !self.rejected => obs.predicted(p),
            _ => obs,
        };
    }

    /// The second half of the period under the agent's `action` (Gymnasium's index: 1
    /// right, 0 left), then the next period's reading. An episode reaching the horizon is
    /// truncated even as it terminates, as Gymnasium's `TimeLimit` says.
    pub fn step(&mut self, action: Action) -> Transition {
        let command = if self.rejected {
            Command::Coast
        } else {
            Command::Push(action)
        };
        if let Some(p) = &mut self.predictor {
            p.record(command.level());
        }
        // The loopback pins are memory and never refuse a command.
        let driven = self.pins.drive(command);
        debug_assert!(driven.is_ok());
        self.sensor.commanded(command);
        let d = duty(&self.pins);
        let mut t = self.live.with_dependent_mut(|_, world| world.apply(d));
        t.truncated = self.live.borrow_dependent().steps() >= self.horizon;
        self.read();
        t
    }

    /// What the policy is shown this period.
    pub fn obs(&self) -> [f32; 4] {
        self.shown
    }

    /// Whether the controller rejects this period's reading (the cart coasts).
    pub fn rejected(&self) -> bool {
        self.rejected
    }

    /// The plant's true state.
    pub fn state(&self) -> State {
        self.live.borrow_dependent().state()
    }

    /// The scenario this episode runs in.
    pub fn scenario(&self) -> &Scenario {
        self.live.borrow_owner()
    }
}
