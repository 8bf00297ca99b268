//! The closed loop: the unchanged firmware [`Controller`] against a [`World`], through the
//! pins and sensor a board would have. The pins are `firmware::loopback`'s, the same the
//! microcontroller's self-test uses; encoders are read through the firmware's
//! `ObserverSensor` (or `AlphaBetaSensor`), as on a board.
//!
//! Every random draw comes from a stream seeded by `(seed, episode)` (the project's one
//! mixer): stream 1 the start, 2 the sensor noise, 3 the pushes, 4 a controller's own
//! randomness. So every controller meets the same starts, noise and pushes.

use std::convert::Infallible;

use firmware::cartpole::{CartPole, State, Transition};
use firmware::controller::{Command, Controller, Policy, StateSensor};
use firmware::estimator::{AlphaBeta, AlphaBetaSensor, ObserverSensor};
use firmware::loopback::{Latest, Pins, duty, pins};
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;

use crate::scenario::{Scenario, Sensing};
use crate::world::{Measurement, World};

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
    /// Periods that coasted on a rejected reading.
    pub faults: u32,
}

/// One period of a recorded episode (for rendering).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The true state after the period.
    pub state: State,
    /// The command the controller gave in the period.
    pub command: Command,
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

/// Stream `stream` of episode `episode` of `seed`.
pub fn episode_rng(seed: u64, episode: u64, stream: Stream) -> Pcg64Mcg {
    host_common::seed::rng(seed, episode, stream as u64)
}

/// The start state of episode `episode` of `seed`, as [`run_episode`] draws it.
pub fn start_state(seed: u64, episode: u64) -> State {
    let mut plant = CartPole::new(Default::default(), 1);
    plant.reset(&mut episode_rng(seed, episode, Stream::Start));
    plant.state()
}

/// The twin's sensor: what the scenario's board reads, from the world's measurement.
pub enum TwinSensor {
    /// The exact (maybe noisy) state.
    Exact([f32; 4]),
    /// Encoders through the observer.
    Observer(ObserverSensor<Latest>),
    /// Encoders through the alpha-beta filter.
    AlphaBeta(AlphaBetaSensor<Latest>),
}

impl TwinSensor {
    /// The sensor of `scenario`'s board.
    pub fn of(scenario: &Scenario) -> TwinSensor {
        let rig = &scenario.rig;
        match scenario.sensing {
            Sensing::Exact => TwinSensor::Exact([0.0; 4]),
            Sensing::Observer => {
                TwinSensor::Observer(ObserverSensor::new(rig.observer(), Latest::default()))
            }
            Sensing::AlphaBeta(d) => TwinSensor::AlphaBeta(AlphaBetaSensor::new(
                AlphaBeta::new(rig.encoders, d, rig.params.tau as f32),
                Latest::default(),
            )),
        }
    }

    /// Hands the sensor this period's measurement.
    pub fn set(&mut self, m: Measurement) {
        match (self, m) {
            (TwinSensor::Exact(s), Measurement::State(v)) => *s = v,
            (TwinSensor::Observer(o), Measurement::Counts(c, p)) => o.counter_mut().0 = (c, p),
            (TwinSensor::AlphaBeta(a), Measurement::Counts(c, p)) => a.counter_mut().0 = (c, p),
            _ => unreachable!("a world measures what its scenario's sensor reads"),
        }
    }
}

impl StateSensor for TwinSensor {
    type Reading = [f32; 4];
    type Error = Infallible;
    #[inline]
    fn read(&mut self) -> Result<[f32; 4], Infallible> {
        match self {
            TwinSensor::Exact(s) => Ok(*s),
            TwinSensor::Observer(o) => o.read(),
            TwinSensor::AlphaBeta(a) => a.read(),
        }
    }
    #[inline]
    fn commanded(&mut self, command: Command) {
        if let TwinSensor::Observer(o) = self {
            o.commanded(command);
        }
    }
}

/// An episode in progress: a world and the firmware's controller closed around it.
pub struct Episode<'s, P, R> {
    world: World<'s, R>,
    controller: Controller<P, TwinSensor, Pins, 1>,
}

impl<'s, P: Policy, R: Rng> Episode<'s, P, R> {
    /// Starts `policy` on a world of `scenario` (see [`World::start`]). With `predict`, the
    /// controller runs the rig's predictor over the rig's dead time and decides on the state
    /// its command will meet, as a board that knows its dead time does.
    pub fn start(
        policy: P,
        scenario: &'s Scenario,
        horizon: u32,
        start: &mut impl Rng,
        streams: (R, R),
        predict: bool,
    ) -> Self {
        let world = World::start(scenario, horizon, start, streams.0, streams.1);
        let sensor = TwinSensor::of(scenario);
        let mut controller =
            Controller::with_history(policy, sensor, pins(), scenario.rig.limits());
        if predict && scenario.delay() > 0 {
            controller = controller.with_predictor(scenario.rig.predictor());
        }
        Episode { world, controller }
    }

    /// The controller's period on this period's measurement: what it commands.
    pub fn decide(&mut self) -> Command {
        let m = self.world.measure();
        self.controller.sensor_mut().set(m);
        self.controller.step()
    }

    /// The world's period under what the controller drives.
    pub fn apply(&mut self) -> Transition {
        self.world.apply(duty(self.controller.actuator()))
    }

    /// The world.
    pub fn world(&self) -> &World<'s, R> {
        &self.world
    }

    /// The controller.
    pub fn controller(&self) -> &Controller<P, TwinSensor, Pins, 1> {
        &self.controller
    }

    /// The policy, to change its state between periods.
    pub fn policy_mut(&mut self) -> &mut P {
        self.controller.policy_mut()
    }
}

/// Runs one episode of `policy` under `scenario` for at most `horizon` periods from the
/// Gymnasium-style random start of (`seed`, `episode`). With `predict`, the controller is
/// told the scenario's dead time and decides on the state its command will meet
/// ([`firmware::controller::predict`], with the rig's model). `on_frame` sees every period.
#[inline(always)]
pub fn run_episode<P: Policy>(
    policy: P,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episode: u64,
    predict: bool,
    mut on_frame: impl FnMut(Frame),
) -> EpisodeStats {
    let streams = (
        episode_rng(seed, episode, Stream::Noise),
        episode_rng(seed, episode, Stream::Pushes),
    );
    let mut start = episode_rng(seed, episode, Stream::Start);
    let mut ep = Episode::start(policy, scenario, horizon, &mut start, streams, predict);
    let mut stats = EpisodeStats::default();
    let mut previous: Option<Command> = None;
    loop {
        let command = ep.decide();
        if previous.is_some_and(|p| p != command) {
            stats.switches += 1;
        }
        if command == Command::Coast {
            stats.faults += 1;
        }
        previous = Some(command);
        let t = ep.apply();
        let s = ep.world().state();
        stats.steps += 1;
        stats.sum_theta2 += s.theta * s.theta;
        stats.sum_x2 += s.x * s.x;
        stats.sum_abs_x += s.x.abs();
        on_frame(Frame { state: s, command });
        if t.terminated || t.truncated {
            stats.success = !t.terminated;
            return stats;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::cartpole::{Params, advance, step};
    use firmware::policy::POLICY;

    /// Pushes towards `theta + 0.5 theta_dot`, never coasting.
    struct Rule;
    impl Policy for Rule {
        fn scores(&mut self, o: &[f32; 4]) -> [f32; 2] {
            [0.0, o[2] + 0.5 * o[3]]
        }
    }

    #[test]
    fn nominal_twin_is_the_plant_under_the_policy_bit_for_bit() {
        for episode in 0..20 {
            let mut frames = Vec::new();
            let stats = run_episode(&POLICY, &Scenario::nominal(), 500, 7, episode, false, |f| {
                frames.push(f)
            });
            let mut plant = CartPole::new(Params::default(), 500);
            let mut obs = plant.reset(&mut episode_rng(7, episode, Stream::Start));
            assert_eq!(plant.state(), start_state(7, episode));
            for f in &frames {
                let action = POLICY.greedy_action(&obs);
                assert_eq!(f.command, Command::Push(action));
                obs = plant.step(action).obs;
                assert_eq!(plant.state(), f.state);
            }
            assert_eq!(stats.steps as usize, frames.len());
        }
    }

    #[test]
    fn delay_applies_the_previous_command() {
        let delayed = Scenario::parse("delay").unwrap();
        let mut frames = Vec::new();
        run_episode(Rule, &delayed, 50, 3, 0, false, |f| frames.push(f));
        let p = Params::default();
        let mut s = start_state(3, 0);
        // The first period applies no force; then each applies its predecessor's command.
        s = advance(&p, &s, 0.0, 0.0);
        assert_eq!(frames[0].state, s);
        for w in frames.windows(2) {
            let Command::Push(a) = w[0].command else {
                panic!("exact sensors never coast")
            };
            s = step(&p, &s, a);
            assert_eq!(w[1].state, s);
        }
    }

    #[test]
    fn prediction_bridges_a_long_dead_time() {
        // Six periods of dead time topple the shipped policy; told of them, it balances.
        let late = Scenario::parse("delay=6").unwrap();
        let blind = run_episode(&POLICY, &late, 500, 2, 0, false, |_| {});
        let told = run_episode(&POLICY, &late, 500, 2, 0, true, |_| {});
        assert!(!blind.success && told.success, "{blind:?} {told:?}");
    }

    #[test]
    fn pushes_topple_and_noise_is_seeded() {
        // A 0.5 N s push every period overwhelms the 10 N motor: the pole falls quickly.
        let brutal = Scenario::parse("push=0.5/1").unwrap();
        let st = run_episode(&POLICY, &brutal, 500, 1, 0, false, |_| {});
        let calm = run_episode(&POLICY, &Scenario::nominal(), 500, 1, 0, false, |_| {});
        assert!(st.steps < 100 && calm.success, "{st:?} {calm:?}");
        let noisy = Scenario::parse("noise=4").unwrap();
        let run = |seed| {
            let mut v = Vec::new();
            run_episode(&POLICY, &noisy, 300, seed, 0, false, |f| v.push(f));
            v
        };
        assert_eq!(run(5), run(5));
        let mut exact = Vec::new();
        run_episode(&POLICY, &Scenario::nominal(), 300, 5, 0, false, |f| {
            exact.push(f)
        });
        assert_ne!(run(5), exact);
    }

    /// The records of an episode of the bang-bang rule on the true state: each period's
    /// true state before the reading, and what the controller received and sent.
    fn rule_episode(spec: &str, periods: usize) -> (Scenario, Vec<(State, [f32; 4], Command)>) {
        struct Truth;
        impl Policy for Truth {
            fn scores(&mut self, o: &[f32; 4]) -> [f32; 2] {
                [0.0, o[2] + 0.5 * o[3]]
            }
        }
        let s = Scenario::parse(spec).unwrap();
        let streams = (Pcg64Mcg::new(2), Pcg64Mcg::new(3));
        let mut ep = Episode::start(Truth, &s, 500, &mut Pcg64Mcg::new(1), streams, false);
        let mut out = Vec::new();
        for _ in 0..periods {
            let truth = ep.world().state();
            let command = ep.decide();
            out.push((truth, ep.controller().last().unwrap().obs, command));
            ep.apply();
        }
        (s, out)
    }

    #[test]
    fn encoders_quantise_and_the_observer_recovers_the_velocities() {
        let (_, periods) = rule_episode("encoder=4096", 200);
        let (mut worst_x, mut worst_w) = (0.0f64, 0.0f64);
        for (truth, obs, _) in &periods[10..] {
            worst_x = worst_x.max((f64::from(obs[0]) - truth.x).abs());
            worst_w = worst_w.max((f64::from(obs[3]) - truth.theta_dot).abs());
        }
        // A cart count is 1 / 20480 m = 49 um, a pole count 1.5 mrad. The observer predicts
        // with the plant and the command, so its position stays within one count and its
        // rate within 0.1 rad/s, where differencing the counts would be off by 0.08 rad/s
        // per count.
        assert!(worst_x < 4.9e-5, "{worst_x}");
        assert!(worst_w < 0.1, "{worst_w}");
    }

    /// The twin's observer is the board's: built for the rig (Gymnasium's machine, whatever
    /// the scenario's physics), told the dead time and each command the controller sends,
    /// fed the true state's counts. An observer built by hand that way gives the readings
    /// the controller received, bit for bit; one that ignores the dead time is worse.
    #[test]
    fn the_observer_is_told_the_dead_time_and_the_commands() {
        use firmware::estimator::{Observer, Tuning};
        let (s, periods) = rule_episode("encoder=512+delay=3+force=0.8+length=0.7", 300);
        let enc = s.rig.encoders;
        let make = |delay| Observer::new(enc, &Params::default(), Tuning::DEFAULT, delay);
        let (mut board, mut blind) = (make(3), make(0));
        let (mut err_board, mut err_blind) = (0.0f64, 0.0f64);
        for (k, (truth, obs, command)) in periods.iter().enumerate() {
            let (cart, pole) = enc.counts(truth.x, truth.theta);
            assert_eq!(*obs, board.update(cart, pole), "period {k}");
            let b = blind.update(cart, pole);
            if k > 10 {
                err_board += (f64::from(obs[3]) - truth.theta_dot).powi(2);
                err_blind += (f64::from(b[3]) - truth.theta_dot).powi(2);
            }
            board.command(command.level());
            blind.command(command.level());
        }
        // The plant is not the rig's, so neither observer is exact; the blind one is clearly
        // worse.
        assert!(err_board * 3.0 < err_blind, "{err_board} vs {err_blind}");
    }
}
