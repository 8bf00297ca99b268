//! One world of the twin stepped as Gymnasium steps an environment: the agent sees the
//! reading the board's controller would decide on, then chooses the action.
//!
//! A lane is `twin::run::Episode`, the world with the firmware's controller closed around
//! it as `host-sim eval` runs them, started with eval's streams for the same seed and
//! episode. Gymnasium wants the observation before the action, so the lane runs the
//! period in its two halves (`Episode::sense`, `Episode::act_with`) and the agent's action
//! is the answer the controller asks for in between. A rejected reading coasts whatever the agent chose, as
//! the controller does. Under the runtime monitor, its fallback overrides the agent's action
//! outside the envelope, as it overrides the policy on a board. Action `i` drives the
//! `i`-th of the environment's duty levels through the period. The lane keeps the episode's
//! tally as `host-sim eval` keeps it (`twin::run::Tally`), for its motor figures.

use std::sync::Arc;

use firmware::ConfigError;
use firmware::cartpole::{State, Transition};
use firmware::controller::{Command, Duty, Policy, Sensed};
use rand_pcg::Pcg64Mcg;
use self_cell::self_cell;
use twin::run::{Aids, Draws, Episode, Tally};
use twin::{Domain, EpisodeStats, Scenario};

/// The seeded stream a domain's world is drawn from, after the four of `twin::run::Stream`.
const DOMAIN_STREAM: u64 = 5;

/// Where a lane's worlds come from.
#[derive(Clone, Debug)]
pub enum Worlds {
    /// The same scenario every episode.
    Fixed(Box<Scenario>),
    /// A scenario drawn from the domain each episode.
    Random(Box<Domain>),
}

impl Worlds {
    /// The most dead time any of its worlds has, periods.
    pub fn most_dead_time(&self) -> u32 {
        match self {
            Worlds::Fixed(s) => s.delay(),
            Worlds::Random(d) => d.most_dead_time(),
        }
    }

    /// The world of episode `episode` of `seed`.
    fn scenario(&self, seed: u64, episode: u64) -> Scenario {
        match self {
            Worlds::Fixed(s) => (**s).clone(),
            Worlds::Random(d) => {
                d.sample(&mut host_common::seed::rng(seed, episode, DOMAIN_STREAM))
            }
        }
    }
}

/// The duty levels an agent chooses among, in action order: the policy of a controller whose
/// every decision is handed to it, as `firmware::controller::Levels` is for a count known
/// as the firmware is compiled.
#[derive(Clone, Debug)]
pub struct Handed(Arc<[Duty]>);

impl Handed {
    /// The levels a caller gave (`levels=`, checked as the tools' `--levels` are).
    pub fn new(levels: &weights::levels::GivenLevels) -> Result<Handed, ConfigError> {
        let duties = levels.levels().iter().map(|&f| Duty::from_fraction(f));
        Ok(Handed(duties.collect::<Result<_, _>>()?))
    }

    /// The paper's two: full push left (action 0), full push right (action 1).
    pub fn bang_bang() -> Handed {
        Handed(
            firmware::controller::Levels::BANG_BANG
                .duties()
                .as_slice()
                .into(),
        )
    }

    /// How many levels there are: the actions `0..len`.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Each level as a fraction of the full push.
    pub fn fractions(&self) -> Vec<f32> {
        self.0.iter().map(|d| d.fraction()).collect()
    }
}

impl Policy for Handed {
    type Scores = ();
    fn scores(&mut self, _: &[f32; 4]) {}
    fn duty(&self, i: usize) -> Option<Duty> {
        self.0.get(i).copied()
    }
}

/// The lane's episode: its controller asks the agent which of its levels drives.
type Running<'s> = Episode<'s, Handed, Pcg64Mcg>;

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
    /// Periods an episode may last.
    horizon: u32,
    /// This period's first half: what the policy will be shown.
    sensed: Sensed<[f32; 4]>,
    /// What the controller commanded in the last period.
    command: Command,
    tally: Tally,
}

impl Lane {
    /// Episode `episode` of `seed`, with the start, noise and push streams `host-sim eval`
    /// gives the same episode, and the board's `aids` as eval gives them: the predicted
    /// state shown where the scenario has dead time, the runtime monitor with its envelope.
    pub fn start(
        worlds: &Worlds,
        (levels, horizon): (&Handed, u32),
        (seed, episode): (u64, u64),
        aids: Aids,
    ) -> Lane {
        let scenario = worlds.scenario(seed, episode);
        let mut live = Live::new(scenario, |s| {
            Draws::of(seed).episode(levels.clone(), s, horizon, episode, aids)
        });
        let sensed = live.with_dependent_mut(|_, e| e.sense());
        Lane {
            live,
            horizon,
            sensed,
            command: Command::Coast,
            tally: Tally::default(),
        }
    }

    /// The second half of the period under the agent's `action` (the index of the level it
    /// drives; with the paper's two, 1 right, 0 left), then the next period's first half. An
    /// episode reaching the horizon is truncated even as it terminates, as Gymnasium's
    /// `TimeLimit` says.
    pub fn step(&mut self, action: usize) -> Transition {
        let (sensed, tally) = (self.sensed, &mut self.tally);
        let (command, mut t, next) = self.live.with_dependent_mut(|_, e| {
            let command = e.act_with(sensed, |_| action);
            let t = e.apply();
            let (world, fallback) = (e.world(), e.fallback());
            let state = world.state();
            tally.period(&world.scenario().params, (command, fallback), &state, &t);
            (command, t, e.sense())
        });
        t.truncated = self.live.borrow_dependent().world().steps() >= self.horizon;
        self.sensed = next;
        self.command = command;
        t
    }

    /// The duty the last period drove, a fraction of the full push (0 coasting).
    pub fn duty(&self) -> f32 {
        self.command.level()
    }

    /// The episode's statistics so far, as `host-sim eval` sums them.
    pub fn stats(&self) -> EpisodeStats {
        self.tally.stats()
    }

    /// What the policy is shown this period (the reading itself when it is rejected).
    pub fn obs(&self) -> [f32; 4] {
        self.sensed.shown().unwrap_or(self.sensed.reading())
    }

    /// Whether the controller rejects this period's reading (the cart coasts).
    pub fn rejected(&self) -> bool {
        self.sensed.shown().is_none()
    }

    /// Whether the runtime monitor's fallback, not the agent, decided the last period.
    pub fn fallback(&self) -> bool {
        self.live.borrow_dependent().fallback()
    }

    /// The plant's true state.
    pub fn state(&self) -> State {
        self.live.borrow_dependent().world().state()
    }

    /// The scenario this episode runs in.
    pub fn scenario(&self) -> &Scenario {
        self.live.borrow_owner()
    }
}
