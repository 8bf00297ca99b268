//! Dead-time compensation: a command takes `delay` periods to reach the motor, so the state
//! it acts on is not the one just read but the one `delay` periods later. The predictor
//! advances the reading by the commands already sent and still on their way, through the
//! nominal plant (Gymnasium's equations, Euler steps, in f32), so that the policy decides on
//! the state its command will meet: a Smith predictor in its simplest form.
//!
//! It uses `micromath`'s `sin` and `cos`: at most 1.1e-3 from the true values on the angles a
//! balancing pole takes (measured in the tests). A 16-period prediction in f32 with them ends
//! within 4e-4 rad of the f64 plant with `libm` (a quarter of a 4,096-count encoder's step;
//! a 5-period one within 1e-4), at a fraction of `libm`'s cost on a core without an FPU. The
//! plant itself keeps `libm`, for bit-exactness with Gymnasium.

use micromath::F32Ext;

use crate::cartpole::{Action, Params};
use crate::network::OBS_DIM;

/// Most periods of dead time the predictor can bridge.
pub const MAX_PREDICT: usize = 16;

/// The nominal plant in f32, as the predictor integrates it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Model {
    gravity: f32,
    masspole: f32,
    total_mass: f32,
    length: f32,
    polemass_length: f32,
    tau: f32,
    force_mag: f32,
}

impl Model {
    /// The model of a plant with parameters `p` (friction is not modelled).
    pub fn of(p: &Params) -> Model {
        Model {
            gravity: p.gravity as f32,
            masspole: p.masspole as f32,
            total_mass: p.total_mass() as f32,
            length: p.length as f32,
            polemass_length: p.polemass_length() as f32,
            tau: p.tau as f32,
            force_mag: p.force_mag as f32,
        }
    }

    /// The full push, N.
    pub fn force_mag(&self) -> f32 {
        self.force_mag
    }

    /// One Euler step of the model under `force`.
    #[inline]
    pub fn step(&self, s: &[f32; OBS_DIM], force: f32) -> [f32; OBS_DIM] {
        let [x, x_dot, theta, theta_dot] = *s;
        let (sin, cos) = (F32Ext::sin(theta), F32Ext::cos(theta));
        let temp = (force + self.polemass_length * theta_dot * theta_dot * sin) / self.total_mass;
        let theta_acc = (self.gravity * sin - cos * temp)
            / (self.length * (4.0 / 3.0 - self.masspole * cos * cos / self.total_mass));
        let x_acc = temp - self.polemass_length * theta_acc * cos / self.total_mass;
        [
            x + self.tau * x_dot,
            x_dot + self.tau * x_acc,
            theta + self.tau * theta_dot,
            theta_dot + self.tau * theta_acc,
        ]
    }
}

/// Commands on their way to the motor: a line `delay` periods long. The twin's actuator, the
/// predictor and the encoder observer each keep one, so all three agree on which command
/// acts in which period.
#[derive(Clone, Debug, PartialEq)]
pub struct DeadTime<T> {
    /// The commands sent in the last `delay` periods, oldest at `head`.
    line: [T; MAX_PREDICT],
    head: usize,
    delay: usize,
}

impl<T: Copy + Default> DeadTime<T> {
    /// A line of `delay` periods (clamped to [`MAX_PREDICT`]), empty: until it fills, the
    /// motor gets `T::default()` (no force).
    pub fn new(delay: usize) -> DeadTime<T> {
        DeadTime {
            line: [T::default(); MAX_PREDICT],
            head: 0,
            delay: delay.min(MAX_PREDICT),
        }
    }

    /// Periods of dead time.
    pub fn delay(&self) -> usize {
        self.delay
    }

    /// Sends this period's command; returns the one that reaches the motor now: the command
    /// of `delay` periods ago, or `command` itself without dead time.
    pub fn send(&mut self, command: T) -> T {
        if self.delay == 0 {
            return command;
        }
        let out = core::mem::replace(&mut self.line[self.head], command);
        self.head = (self.head + 1) % self.delay;
        out
    }

    /// The commands still in flight, oldest first.
    pub fn in_flight(&self) -> impl Iterator<Item = T> + '_ {
        (0..self.delay).map(|k| self.line[(self.head + k) % self.delay])
    }
}

/// The commands in flight and the model that advances a reading past them.
#[derive(Clone, Debug, PartialEq)]
pub struct Predictor {
    model: Model,
    /// Forces sent and not yet at the motor.
    sent: DeadTime<f32>,
}

impl Predictor {
    /// A predictor for `delay` periods (clamped to [`MAX_PREDICT`]) of dead time.
    pub fn new(model: Model, delay: usize) -> Predictor {
        Predictor {
            model,
            sent: DeadTime::new(delay),
        }
    }

    /// Periods of dead time bridged.
    pub fn delay(&self) -> usize {
        self.sent.delay()
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The reading advanced by the commands in flight, oldest first: the state the next
    /// command will meet. With no dead time, the reading itself.
    pub fn predict(&self, reading: &[f32; OBS_DIM]) -> [f32; OBS_DIM] {
        self.sent
            .in_flight()
            .fold(*reading, |s, force| self.model.step(&s, force))
    }

    /// Records a full push towards `action`'s side, the command of every period but a
    /// coasting one.
    pub fn record_push(&mut self, action: Action) {
        let f = self.model.force_mag;
        self.record(match action {
            Action::Right => f,
            Action::Left => -f,
        });
    }

    /// Records the force commanded this period (`0` for coasting).
    pub fn record(&mut self, force: f32) {
        self.sent.send(force);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cartpole::{State, step_with_force};

    #[test]
    fn a_dead_time_line_delivers_each_command_its_periods_late() {
        let mut line = DeadTime::<i32>::new(3);
        let out: [i32; 7] = core::array::from_fn(|k| line.send(k as i32 + 1));
        assert_eq!(out, [0, 0, 0, 1, 2, 3, 4]);
        // After sending 1 to 7, the last three are still on their way, oldest first.
        let mut flying = [0; 3];
        for (f, c) in flying.iter_mut().zip(line.in_flight()) {
            *f = c;
        }
        assert_eq!(flying, [5, 6, 7]);
        let mut none = DeadTime::<i32>::new(0);
        assert_eq!((none.send(9), none.in_flight().count()), (9, 0));
        assert_eq!(DeadTime::<f32>::new(1_000).delay(), MAX_PREDICT);
    }

    #[test]
    fn micromaths_sine_and_cosine_are_within_the_documented_error() {
        let (mut ws, mut wc) = (0.0f64, 0.0f64);
        for k in -6000..=6000 {
            let x = k as f32 * 1e-4;
            ws = ws.max((f64::from(F32Ext::sin(x)) - libm::sin(f64::from(x))).abs());
            wc = wc.max((f64::from(F32Ext::cos(x)) - libm::cos(f64::from(x))).abs());
        }
        assert!(ws < 1.1e-3 && wc < 1.1e-3, "{ws} {wc}");
    }

    /// The prediction over `n` periods of mixed pushes, and the f64 plant's state after them.
    fn ahead(n: usize) -> ([f32; 4], [f32; 4]) {
        let p = Params::default();
        let mut pred = Predictor::new(Model::of(&p), n);
        let start = State::from_array([0.3, -0.5, 0.08, -0.6]);
        let mut truth = start;
        for k in 0..n {
            let f = if k % 3 == 0 { 10.0 } else { -10.0 };
            pred.record(f as f32);
            truth = step_with_force(&p, &truth, f);
        }
        (pred.predict(&start.observation()), truth.observation())
    }

    #[test]
    fn predictions_follow_the_true_plant_over_the_dead_time() {
        let (got, want) = ahead(5);
        assert!((got[2] - want[2]).abs() < 1e-4, "{got:?} {want:?}");
        // 16 periods ahead: within 4e-4 rad and 1e-3 m of the f64 plant.
        let (got, want) = ahead(MAX_PREDICT);
        assert!((got[2] - want[2]).abs() < 4e-4, "{got:?} {want:?}");
        assert!((got[0] - want[0]).abs() < 1e-3, "{got:?} {want:?}");
        assert!((got[3] - want[3]).abs() < 5e-3, "{got:?} {want:?}");
    }

    #[test]
    fn the_oldest_command_is_applied_first_and_no_delay_is_the_reading() {
        let m = Model::of(&Params::default());
        let mut pred = Predictor::new(m, 2);
        pred.record(10.0);
        pred.record(-10.0);
        let r = [0.0, 0.0, 0.05, 0.0];
        assert_eq!(pred.predict(&r), m.step(&m.step(&r, 10.0), -10.0));
        pred.record(3.0);
        assert_eq!(pred.predict(&r), m.step(&m.step(&r, -10.0), 3.0));
        let none = Predictor::new(m, 0);
        assert_eq!(none.predict(&r), r);
    }
}
