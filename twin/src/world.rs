//! One episode of a scenario, period by period: what the sensors report, then what the
//! actuator does with a command. The simulator runs the firmware's controller against it; the
//! trainer learns in it. One code path, so a policy is trained in the world it is judged in.
//!
//! A period is [`World::observe`] (the reading the controller gets: the true state rounded to
//! f32, with noise, or encoder counts through the estimator), then [`World::apply`] (the
//! command enters the dead-time line; the force that leaves it, plus any push, steps the
//! plant).

use firmware::cartpole::Params;
use firmware::cartpole::{CartPole, State, Transition, unit_f64};
use firmware::controller::predict::DeadTime;
use firmware::estimator::{AlphaBeta, Encoders, Observer, Tuning};
use rand_core::Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::scenario::{Estimation, Scenario};

/// The board's estimator in an `encoder` scenario.
enum Estimator {
    Observer(Observer),
    AlphaBeta(AlphaBeta),
}

impl Estimator {
    fn new(scenario: &Scenario, enc: Encoders) -> Estimator {
        match scenario.estimation {
            // The board models its plant as the nominal one and knows its own dead time (as
            // the predictor does), nothing of a scenario's physics.
            Estimation::Observer => Estimator::Observer(Observer::new(
                enc,
                &Params::default(),
                Tuning::DEFAULT,
                scenario.delay as usize,
            )),
            Estimation::AlphaBeta(d) => {
                Estimator::AlphaBeta(AlphaBeta::new(enc, d, scenario.params.tau as f32))
            }
        }
    }

    fn encoders(&self) -> Encoders {
        match self {
            Estimator::Observer(o) => o.encoders(),
            Estimator::AlphaBeta(a) => a.encoders(),
        }
    }

    fn update(&mut self, cart: i32, pole: i32) -> [f32; 4] {
        match self {
            Estimator::Observer(o) => o.update(cart, pole),
            Estimator::AlphaBeta(a) => a.update(cart, pole),
        }
    }
}

/// An episode in progress.
pub struct World<'s, R> {
    scenario: &'s Scenario,
    plant: CartPole,
    noise: R,
    pushes: R,
    estimator: Option<Estimator>,
    /// Commands on their way to the actuator.
    line: DeadTime<f64>,
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
            noise,
            pushes,
            estimator: scenario.encoders.map(|e| Estimator::new(scenario, e)),
            line: DeadTime::new(scenario.delay as usize),
        }
    }

    /// This period's sensor reading `[x, x_dot, theta, theta_dot]`. Call it once a period:
    /// it draws noise and advances the estimator.
    pub fn observe(&mut self) -> [f32; 4] {
        let s = self.plant.state();
        let noisy = self.scenario.noise_std != [0.0; 4];
        if self.estimator.is_some() {
            let sd = self.scenario.noise_std;
            let mut x = s.x;
            let mut theta = s.theta;
            if noisy {
                x += sd[0] * self.gauss();
                theta += sd[2] * self.gauss();
            }
            let est = self.estimator.as_mut().expect("checked above");
            let (cart, pole) = est.encoders().counts(x, theta);
            return est.update(cart, pole);
        }
        if !noisy {
            return s.observation();
        }
        let mut obs = s.to_array();
        for (v, sd) in obs.iter_mut().zip(self.scenario.noise_std) {
            *v += sd * self.gauss();
        }
        obs.map(|v| v as f32)
    }

    fn gauss(&mut self) -> f64 {
        StandardNormal.sample(&mut self.noise)
    }

    /// Ends the period: the actuator applies the command of `delay` periods ago (`commanded`
    /// itself without dead time), a push may add its force, the plant steps. The board's
    /// observer is told the command, as a fraction of the motor's full force.
    pub fn apply(&mut self, commanded: f64) -> Transition {
        if let Some(Estimator::Observer(o)) = self.estimator.as_mut() {
            o.command((commanded / self.scenario.params.force_mag) as f32);
        }
        let mut force = self.line.send(commanded);
        if let Some(push) = self.scenario.push
            && (self.plant.steps() + 1).is_multiple_of(push.every)
        {
            let side = if unit_f64(&mut self.pushes) < 0.5 {
                -1.0
            } else {
                1.0
            };
            force += side * push.impulse / self.scenario.params.tau;
        }
        self.plant.step_force(force)
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
    pub fn scenario(&self) -> &Scenario {
        self.scenario
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::cartpole::{Action, Params, step_with_force};
    use rand_pcg::Pcg64Mcg;

    fn world(s: &Scenario) -> World<'_, Pcg64Mcg> {
        World::start(
            s,
            500,
            &mut Pcg64Mcg::new(1),
            Pcg64Mcg::new(2),
            Pcg64Mcg::new(3),
        )
    }

    #[test]
    fn the_nominal_world_is_the_plant() {
        let nominal = Scenario::nominal();
        let mut w = world(&nominal);
        let mut plant = CartPole::new(Params::default(), 500);
        let mut obs = plant.reset(&mut Pcg64Mcg::new(1));
        for k in 0..100 {
            assert_eq!(w.observe(), obs);
            let a = Action::from_index(k % 3 / 2);
            let f = if a == Action::Right { 10.0 } else { -10.0 };
            assert_eq!(w.apply(f), plant.step(a));
            obs = plant.state().observation();
        }
    }

    #[test]
    fn dead_time_delivers_each_command_n_periods_late() {
        for d in [1, 2, 5] {
            let s = Scenario::parse(&format!("delay={d}")).unwrap();
            let mut w = world(&s);
            let p = Params::default();
            let mut state = w.state();
            for k in 0..40 {
                w.observe();
                // Command k is +10 N on odd k: it acts in period k + d.
                let cmd = |k: i64| {
                    if k >= 0 && k % 2 == 1 {
                        10.0
                    } else if k >= 0 {
                        -10.0
                    } else {
                        0.0
                    }
                };
                w.apply(cmd(k));
                state = step_with_force(&p, &state, cmd(k - d));
                assert_eq!(w.state(), state, "delay {d}, period {k}");
            }
        }
    }

    /// The rule the encoder tests balance with: bang-bang on the true state.
    fn rule(s: &State) -> f64 {
        if s.theta + 0.5 * s.theta_dot > 0.0 {
            10.0
        } else {
            -10.0
        }
    }

    #[test]
    fn encoders_quantise_and_the_observer_recovers_the_velocities() {
        let s = Scenario::parse("encoder=4096").unwrap();
        let mut w = world(&s);
        let (mut worst_x, mut worst_w) = (0.0f64, 0.0f64);
        for k in 0..200 {
            let obs = w.observe();
            let truth = w.state();
            if k > 10 {
                worst_x = worst_x.max((f64::from(obs[0]) - truth.x).abs());
                worst_w = worst_w.max((f64::from(obs[3]) - truth.theta_dot).abs());
            }
            w.apply(rule(&truth));
        }
        // A cart count is 1 / 20480 m = 49 um, a pole count 1.5 mrad. The observer predicts
        // with the plant and the command, so under the rule's bang-bang forces its position
        // stays within one count (measured: half of one) and its rate within 0.1 rad/s
        // (measured: 0.06), where differencing the counts would be off by 0.08 rad/s per
        // count.
        assert!(worst_x < 4.9e-5, "{worst_x}");
        assert!(worst_w < 0.1, "{worst_w}");
    }

    /// The world's observer is the board's: built for the nominal plant whatever the
    /// scenario's physics, told the dead time and each command as a fraction of the
    /// scenario's full force, fed the true state's counts. An observer built by hand that
    /// way gives its estimates bit for bit; one that ignores the dead time is worse.
    #[test]
    fn the_observer_is_told_the_dead_time_and_the_commands() {
        let s = Scenario::parse("encoder=512+delay=3+force=0.8+length=0.7").unwrap();
        let enc = s.encoders.unwrap();
        let full = s.params.force_mag;
        let mut w = world(&s);
        let make = |delay| Observer::new(enc, &Params::default(), Tuning::DEFAULT, delay);
        let (mut board, mut blind) = (make(3), make(0));
        let (mut err_board, mut err_blind) = (0.0f64, 0.0f64);
        for k in 0..300 {
            let truth = w.state();
            let counts = enc.counts(truth.x, truth.theta);
            let obs = w.observe();
            assert_eq!(obs, board.update(counts.0, counts.1), "period {k}");
            let b = blind.update(counts.0, counts.1);
            if k > 10 {
                err_board += (f64::from(obs[3]) - truth.theta_dot).powi(2);
                err_blind += (f64::from(b[3]) - truth.theta_dot).powi(2);
            }
            // Full force as the rule says, with every fifth period half force and every
            // seventh none: commands a board's PWM could send.
            let f = rule(&truth) * full / 10.0;
            let f = if k % 7 == 0 {
                0.0
            } else if k % 5 == 0 {
                f / 2.0
            } else {
                f
            };
            board.command((f / full) as f32);
            blind.command((f / full) as f32);
            w.apply(f);
        }
        // Measured: 13 times less squared rate error (the plant is not the nominal one, so
        // neither observer is exact).
        assert!(err_board * 5.0 < err_blind, "{err_board} vs {err_blind}");
    }
}
