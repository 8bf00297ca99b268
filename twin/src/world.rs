//! One episode of a scenario's plant, period by period: what the sensors measure, then what
//! the actuator does with the motor's duty. The controller between the two is the
//! firmware's, run by [`crate::run`]; this module is the world around it.
//!
//! A period is [`World::measure`] (the exact state rounded to f32, with noise, or the two
//! encoders' counts; glitched, stuck or missing as the scenario's faults say), then
//! [`World::apply`] (the duty enters the dead-time line, unless the period was late; the
//! duty that leaves it, held over the period and weakened by a weak motor, plus any push,
//! drives the plant one period, by the scenario's integration).

use firmware::cartpole::{CartPole, Plant, State, Transition, unit_f64};
use firmware::controller::predict::DeadTime;
use rand_core::Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::machine::{self, Integration, Lane};
use crate::scenario::Scenario;

/// What the sensors report in one period: the link's, which a board's sensor reads.
pub use firmware::link::Measurement;

/// An episode in progress.
pub struct World<'s, R> {
    scenario: &'s Scenario,
    plant: CartPole,
    /// The true plant's equations, for a world that integrates them itself.
    dynamics: Plant<f64>,
    noise: R,
    pushes: R,
    /// Motor duties on their way to the motor.
    line: DeadTime<f64>,
    /// The measurement a stuck sensor repeats.
    held: Option<Measurement>,
    /// The duty the bridge holds, which a late period's command does not replace.
    bridge: f64,
}

impl<'s, R: Rng> World<'s, R> {
    /// Starts an episode of at most `horizon` periods from a Gymnasium-style random start
    /// drawn from `start` (four uniform draws, as `CartPole::reset`), with `noise` and
    /// `pushes` as the streams of sensor noise and push sides.
    pub fn start(
        scenario: &'s Scenario,
        horizon: u32,
        start: &mut impl Rng,
        noise: R,
        pushes: R,
    ) -> World<'s, R> {
        let mut plant = CartPole::new(scenario.params, horizon);
        plant.reset(start);
        World {
            scenario,
            plant,
            dynamics: Plant::new(&scenario.params),
            noise,
            pushes,
            line: DeadTime::new(scenario.delay() as usize),
            held: None,
            bridge: 0.0,
        }
    }

    /// This period's measurement, as the scenario's faults leave it. Call it once a period:
    /// it draws the noise.
    pub fn measure(&mut self) -> Measurement {
        let k = self.plant.steps();
        let faults = &self.scenario.faults;
        let m = faults.corrupt(self.sense(), k, &self.scenario.rig.encoders);
        if faults.stuck.is_some_and(|w| w.holds(k))
            && let Some(held) = self.held
        {
            return held;
        }
        self.held = Some(m);
        if faults.drop.is_some_and(|w| w.holds(k)) {
            return Measurement::Missing;
        }
        m
    }

    /// What a sound sensor reads of the state now.
    fn sense(&mut self) -> Measurement {
        let s = self.plant.state();
        let sd = self.scenario.noise_std;
        let noisy = sd != [0.0; 4];
        if self.scenario.reads_counts() {
            let (mut x, mut theta) = (s.x, s.theta);
            if self.scenario.jitter > 0.0 {
                // Within a few milliseconds the second-order term stays below one count.
                let early_or_late = 2.0 * unit_f64(&mut self.noise) - 1.0;
                let dt = self.scenario.jitter * self.scenario.params.tau * early_or_late;
                x += dt * s.x_dot;
                theta += dt * s.theta_dot;
            }
            if noisy {
                x += sd[0] * self.gauss();
                theta += sd[2] * self.gauss();
            }
            let (cart, pole) = self.scenario.rig.encoders.counts(x, theta);
            return Measurement::Counts(cart, pole);
        }
        if !noisy {
            return Measurement::State(s.observation());
        }
        let mut obs = s.to_array();
        for (v, sd) in obs.iter_mut().zip(sd) {
            *v += sd * self.gauss();
        }
        Measurement::State(obs.map(|v| v as f32))
    }

    fn gauss(&mut self) -> f64 {
        StandardNormal.sample(&mut self.noise)
    }

    /// Ends the period: the motor applies the duty of `delay` periods ago (`duty` itself
    /// without dead time), a push may add its force, the plant steps.
    pub fn apply(&mut self, duty: f64) -> Transition {
        let drive = self.drive(duty);
        let next = machine::advance(
            &self.dynamics,
            self.scenario.integration,
            &self.plant.state(),
            drive.duty,
            drive.external,
        );
        self.land(next)
    }

    /// The first half of [`World::apply`]: what acts on the cart over this period. The
    /// caller integrates it (alone, or beside other worlds: `crate::lockstep`) and hands the
    /// state to [`World::land`].
    pub(crate) fn drive(&mut self, duty: f64) -> Drive {
        let k = self.plant.steps();
        let faults = &self.scenario.faults;
        if !faults.late.is_some_and(|w| w.holds(k)) {
            self.bridge = duty;
        }
        let mut acting = self.line.send(self.bridge);
        if let Some((factor, w)) = faults.weak
            && w.holds(k)
        {
            acting *= factor;
        }
        let mut external = 0.0;
        if let Some(push) = self.scenario.push
            && (self.plant.steps() + 1).is_multiple_of(push.every)
        {
            let side = if unit_f64(&mut self.pushes) < 0.5 {
                -1.0
            } else {
                1.0
            };
            external = side * push.impulse / self.scenario.params.tau;
        }
        Drive {
            duty: acting,
            external,
        }
    }

    /// The second half of [`World::apply`]: the plant takes the integrated state.
    pub(crate) fn land(&mut self, next: State) -> Transition {
        self.plant.set_next(next)
    }

    /// The Runge-Kutta steps of this world's period; `None` for Gymnasium's Euler step.
    pub(crate) fn substeps(&self) -> Option<u32> {
        match self.scenario.integration {
            Integration::Rk4 { substeps } => Some(substeps),
            Integration::Euler => None,
        }
    }

    /// This period's integration under `drive`, as [`machine::rk4_lanes`] takes it.
    pub(crate) fn lane(&self, drive: Drive) -> Lane {
        Lane::new(
            &self.dynamics,
            &self.plant.state(),
            drive.duty,
            drive.external,
        )
    }

    /// The plant's true state.
    pub fn state(&self) -> State {
        self.plant.state()
    }

    /// Periods run.
    pub fn steps(&self) -> u32 {
        self.plant.steps()
    }

    /// The scenario.
    pub fn scenario(&self) -> &'s Scenario {
        self.scenario
    }
}

/// What acts on a world's cart over one period: the duty leaving the dead-time line and the
/// push's force.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Drive {
    duty: f64,
    external: f64,
}

#[cfg(test)]
pub(crate) mod tests;
