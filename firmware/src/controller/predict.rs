//! Dead-time compensation: a command takes `delay` periods to reach the motor, so the state
//! it acts on is not the one just read but the one `delay` periods later. The predictor
//! advances the reading by the commands already sent and still on their way, through the
//! rig's plant in f32 ([`Plant`], the plant's one set of equations), so that the policy
//! decides on the state its command will meet: a Smith predictor in its simplest form.
//!
//! The f32 plant uses `micromath`'s `sin` and `cos` (the tests below hold a 16-period
//! prediction within 4e-4 rad of the f64 plant with `libm`, a quarter of a 4,096-count
//! encoder's step), at a fraction of `libm`'s cost on a core without an FPU. The
//! plant itself keeps `libm`, for bit-exactness with Gymnasium.

use crate::cartpole::{Params, Plant};
use crate::config::ConfigError;
use crate::network::OBS_DIM;

/// Most periods of dead time the predictor can bridge.
pub const MAX_PREDICT: usize = 16;

/// `delay`, if the dead-time line holds it.
pub(crate) const fn dead_time(delay: usize) -> Result<usize, ConfigError> {
    if delay <= MAX_PREDICT {
        Ok(delay)
    } else {
        Err(ConfigError::TooLarge("dead_time"))
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

    /// Empties the line, as at [`DeadTime::new`].
    pub fn clear(&mut self) {
        *self = DeadTime::new(self.delay);
    }

    /// The commands still in flight, oldest first.
    pub fn in_flight(&self) -> impl Iterator<Item = T> + '_ {
        (0..self.delay).map(|k| self.line[(self.head + k) % self.delay])
    }
}

/// The commands in flight and the plant that advances a reading past them.
#[derive(Clone, Debug, PartialEq)]
pub struct Predictor {
    plant: Plant<f32>,
    /// Motor duties sent and not yet at the motor.
    sent: DeadTime<f32>,
}

impl Predictor {
    /// A predictor for the plant `p` with `delay` periods (at most [`MAX_PREDICT`]) of dead
    /// time. Refused: a plant that is no machine ([`Params::check`]), whose prediction
    /// would be NaN, and a dead time beyond the line.
    pub fn new(p: &Params, delay: usize) -> Result<Predictor, ConfigError> {
        Ok(Predictor {
            plant: Plant::new(&p.check()?),
            sent: DeadTime::new(dead_time(delay)?),
        })
    }

    /// Periods of dead time bridged.
    pub fn delay(&self) -> usize {
        self.sent.delay()
    }

    /// The reading advanced by the commands in flight, oldest first: the state the next
    /// command will meet. With no dead time, the reading itself.
    pub fn predict(&self, reading: &[f32; OBS_DIM]) -> [f32; OBS_DIM] {
        self.sent
            .in_flight()
            .fold(*reading, |s, duty| self.plant.euler(&s, duty, 0.0))
    }

    /// Forgets the commands in flight, as at [`Predictor::new`].
    pub fn clear(&mut self) {
        self.sent.clear();
    }

    /// Records the motor duty commanded this period (`0` for coasting, see
    /// [`Command::level`](super::Command::level)).
    pub fn record(&mut self, duty: f32) {
        self.sent.send(duty);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cartpole::{Real, State, advance};

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
            ws = ws.max((f64::from(Real::sin(x)) - libm::sin(f64::from(x))).abs());
            wc = wc.max((f64::from(Real::cos(x)) - libm::cos(f64::from(x))).abs());
        }
        assert!(ws < 1.1e-3 && wc < 1.1e-3, "{ws} {wc}");
    }

    /// The prediction over `n` periods of mixed pushes, and the f64 plant's state after them.
    fn ahead(n: usize) -> ([f32; 4], [f32; 4]) {
        let p = Params::default();
        let mut pred = Predictor::new(&p, n).unwrap();
        let start = State::from_array([0.3, -0.5, 0.08, -0.6]);
        let mut truth = start;
        for k in 0..n {
            let duty = if k % 3 == 0 { 1.0 } else { -1.0 };
            pred.record(duty as f32);
            truth = advance(&p, &truth, duty, 0.0);
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
        let p = Params::default();
        let m = Plant::<f32>::new(&p);
        let mut pred = Predictor::new(&p, 2).unwrap();
        pred.record(1.0);
        pred.record(-1.0);
        let r = [0.0, 0.0, 0.05, 0.0];
        assert_eq!(pred.predict(&r), m.euler(&m.euler(&r, 1.0, 0.0), -1.0, 0.0));
        pred.record(0.3);
        assert_eq!(pred.predict(&r), m.euler(&m.euler(&r, -1.0, 0.0), 0.3, 0.0));
        let none = Predictor::new(&p, 0).unwrap();
        assert_eq!(none.predict(&r), r);
        // Cleared, the line holds no force: two coasting periods ahead.
        pred.clear();
        assert_eq!(pred.predict(&r), m.euler(&m.euler(&r, 0.0, 0.0), 0.0, 0.0));
        pred.record(1.0);
        assert_eq!(pred.predict(&r), m.euler(&m.euler(&r, 0.0, 0.0), 1.0, 0.0));
    }

    #[test]
    fn a_plant_or_dead_time_no_machine_has_is_refused() {
        let p = Params::default();
        assert_eq!(
            Predictor::new(&p, MAX_PREDICT + 1),
            Err(ConfigError::TooLarge("dead_time"))
        );
        assert!(Predictor::new(&p, MAX_PREDICT).is_ok());
        let mut massless = p;
        massless.masscart = 0.0;
        assert_eq!(
            Predictor::new(&massless, 1),
            Err(ConfigError::NotPositive("params.masscart"))
        );
    }
}
