//! The closed loop: the unchanged firmware [`Controller`] against a [`World`], through the
//! pins and sensor a board would have. The pins are `firmware::loopback`'s, the same the
//! microcontroller's self-test uses.
//!
//! Every random draw comes from a stream seeded by `(seed, episode)` (the project's one
//! mixer): stream 1 the start, 2 the sensor noise, 3 the pushes, 4 a controller's own
//! randomness. So every controller meets the same starts, noise and pushes.

use std::cell::Cell;
use std::convert::Infallible;

use firmware::cartpole::{CartPole, Params, State};
use firmware::controller::{Command, Controller, Limits, Model, Policy, Predictor, StateSensor};
use firmware::loopback::{CellDuty, CellPin, force as bridge_force};
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

/// Stream `stream` of episode `episode` of `seed`.
pub fn episode_rng(seed: u64, episode: u64, stream: u64) -> Pcg64Mcg {
    host_common::seed::rng(seed, episode, stream)
}

/// Seeded stream for a controller's own randomness (the random baseline) in `episode`.
pub fn policy_rng(seed: u64, episode: u64) -> Pcg64Mcg {
    episode_rng(seed, episode, 4)
}

/// The start state of episode `episode` of `seed`, as [`run_episode`] draws it.
pub fn start_state(seed: u64, episode: u64) -> State {
    let mut plant = CartPole::new(Default::default(), 1);
    plant.reset(&mut episode_rng(seed, episode, 1));
    plant.state()
}

/// A predictor over `delay` periods with the nominal plant's model: what a controller that
/// knows its dead time (but not the plant's perturbations) runs.
pub fn nominal_predictor(delay: u32) -> Predictor {
    Predictor::new(Model::of(&Params::default()), delay as usize)
}

/// The sensor: whatever the world reported this period.
struct Reading<'a>(&'a Cell<[f32; 4]>);

impl StateSensor for Reading<'_> {
    type Error = Infallible;
    #[inline]
    fn read(&mut self) -> Result<[f32; 4], Infallible> {
        Ok(self.0.get())
    }
}

/// Runs one episode of `policy` under `scenario` for at most `horizon` periods from the
/// Gymnasium-style random start of (`seed`, `episode`). With `predict`, the controller is
/// told the scenario's dead time and decides on the state its command will meet
/// ([`firmware::controller::predict`], with the nominal model). `on_frame` sees every period.
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
    let mut world = World::start(
        scenario,
        horizon,
        &mut episode_rng(seed, episode, 1),
        episode_rng(seed, episode, 2),
        episode_rng(seed, episode, 3),
    );
    let reading = Cell::new([0.0f32; 4]);
    let direction = Cell::new(false);
    let duty = Cell::new(0u16);
    let mut controller: Controller<_, _, _, _, 1> = Controller::new(
        policy,
        Reading(&reading),
        CellPin(&direction),
        CellDuty(&duty),
        Limits::default(),
    );
    if predict && scenario.delay > 0 {
        controller = controller.with_predictor(nominal_predictor(scenario.delay));
    }
    let force_mag = scenario.params.force_mag;
    let mut stats = EpisodeStats::default();
    let mut previous: Option<Command> = None;
    loop {
        reading.set(world.observe());
        let command = controller.step();
        if previous.is_some_and(|p| p != command) {
            stats.switches += 1;
        }
        if command == Command::Coast {
            stats.faults += 1;
        }
        previous = Some(command);
        let t = world.apply(bridge_force(direction.get(), duty.get(), force_mag));
        let s = world.state();
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
    use firmware::cartpole::{Params, step, step_with_force};
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
            let mut obs = plant.reset(&mut episode_rng(7, episode, 1));
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
        s = step_with_force(&p, &s, 0.0);
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
}
