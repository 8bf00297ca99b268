//! The cart-pole plant: Gymnasium's `CartPole-v1`, bit for bit.
//!
//! [`Params::default`] is Gymnasium's environment, and [`step`] performs its Euler step in
//! exactly Gymnasium's order of floating-point operations, in f64, with `libm`'s `sin`/`cos`.
//! That makes every state equal to Gymnasium's to the last bit (checked against recorded
//! trajectories in this crate's tests), on the host and on a microcontroller alike.
//!
//! The equations of motion are written once, generic over f32 and f64, in [`dynamics`]: the
//! motor (a stall force less its back-EMF and drag), Gymnasium's equations and Florian's with
//! friction. This module is the physics and the episode bookkeeping (termination, truncation,
//! random starts, with the `rand` feature). It is not a renderer, and it knows nothing of
//! networks or controllers.

pub mod dynamics;

pub use dynamics::{Plant, Real};

use crate::config::{ConfigError, check, non_negative, positive};

/// Episode length in the paper (and old `CartPole-v0`): solved at a 100-episode mean >= 195.
pub const PAPER_EPISODE_STEPS: u32 = 200;
/// Episode length of Gymnasium's `CartPole-v1`: solved at a 100-episode mean >= 475.
pub const V1_EPISODE_STEPS: u32 = 500;

/// A push of the cart: the plant's whole action space.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Action {
    /// Push the cart towards -x with the full force (Gymnasium's action 0).
    Left = 0,
    /// Push the cart towards +x with the full force (Gymnasium's action 1).
    Right = 1,
}

impl Action {
    /// Both actions in Gymnasium's index order.
    pub const ALL: [Action; 2] = [Action::Left, Action::Right];

    /// Gymnasium's index of the action (0 = left, 1 = right).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The action with Gymnasium's index `i`; any index but 1 is `Left`, so that a
    /// corrupted index can never produce an undefined push.
    pub const fn from_index(i: usize) -> Action {
        if i == 1 { Action::Right } else { Action::Left }
    }

    /// The motor duty of the push: `1` towards +x, `-1` towards -x.
    pub const fn level(self) -> f64 {
        match self {
            Action::Right => 1.0,
            Action::Left => -1.0,
        }
    }
}

/// Physical constants and episode limits. `Default` is Gymnasium's `CartPole-v1`; robustness
/// studies change single fields (a 20% heavier pole, a weaker motor). The layout is C's
/// (`repr(C)`): the C API's `struct cartpole_rig` starts with these fields in this order.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Params {
    /// Gravitational acceleration, m/s^2.
    pub gravity: f64,
    /// Mass of the cart, kg.
    pub masscart: f64,
    /// Mass of the pole, kg.
    pub masspole: f64,
    /// Half the pole's length, m (Gymnasium calls it `length`).
    pub length: f64,
    /// The motor's force on the cart at full duty and standstill (its stall force), N:
    /// Gymnasium's push.
    pub force_mag: f64,
    /// How much of that force the cart's speed takes away, N s/m: the motor's back-EMF and
    /// the drive's viscous drag in one term ([`Plant::motor_force`]). Zero (a motor that
    /// pushes with the same force at any speed), as in Gymnasium, by default. Duty off is duty
    /// zero: a short-braked motor, whose back-EMF still acts.
    pub motor_damping: f64,
    /// The control period, s: the Euler step of Gymnasium's plant, and the period a
    /// controller runs at.
    pub tau: f64,
    /// The episode terminates once |theta| exceeds this, rad.
    pub theta_threshold_radians: f64,
    /// The episode terminates once |x| exceeds this, m.
    pub x_threshold: f64,
    /// Coulomb friction coefficient between cart and track (dimensionless; Florian's
    /// `mu_c`): a force `mu_c * N_c` against the cart's motion, `N_c` the track's normal
    /// force. Zero, as in Gymnasium, by default.
    pub cart_friction: f64,
    /// Viscous friction at the pivot, N m s/rad (Florian's `mu_p`): a torque
    /// `-mu_p * theta_dot` on the pole. Zero by default.
    pub pole_friction: f64,
}

/// Gymnasium's `CartPole-v1`.
pub const GYMNASIUM: Params = Params {
    gravity: 9.8,
    masscart: 1.0,
    masspole: 0.1,
    length: 0.5,
    force_mag: 10.0,
    motor_damping: 0.0,
    tau: 0.02,
    // Gymnasium writes `12 * 2 * math.pi / 360`; the same order gives the same bits.
    theta_threshold_radians: 12.0 * 2.0 * core::f64::consts::PI / 360.0,
    x_threshold: 2.4,
    cart_friction: 0.0,
    pole_friction: 0.0,
};

impl Default for Params {
    /// [`GYMNASIUM`].
    fn default() -> Self {
        GYMNASIUM
    }
}

/// How many numbers a [`Params`] holds.
pub const PARAMS_LEN: usize = 11;
// Params is these numbers and nothing else, so [`Params::values`] cannot leave one out.
const _: () = assert!(core::mem::size_of::<Params>() == PARAMS_LEN * 8);

impl Params {
    /// The motor's current at duty `duty` while the cart moves at `x_dot`, as a share of its
    /// stall current: `duty - motor_damping * x_dot / force_mag`, the force the motor makes
    /// ([`Plant::motor_force`]) over its stall force. Its square is the motor's heating
    /// against a stall at full duty.
    pub fn current(&self, duty: f64, x_dot: f64) -> f64 {
        duty - self.motor_damping * x_dot / self.force_mag
    }

    /// Every field, in the order of the declaration: what a dump or a digest of the machine
    /// takes.
    pub const fn values(&self) -> [f64; PARAMS_LEN] {
        [
            self.gravity,
            self.masscart,
            self.masspole,
            self.length,
            self.force_mag,
            self.motor_damping,
            self.tau,
            self.theta_threshold_radians,
            self.x_threshold,
            self.cart_friction,
            self.pole_friction,
        ]
    }

    /// `self`, if it is a machine the observer and predictor can model: every field finite,
    /// masses, length, motor force, period and both failure thresholds above zero (the
    /// linearisation divides by the masses and the length), damping and friction not
    /// negative.
    pub const fn check(self) -> Result<Params, ConfigError> {
        check!(positive(self.gravity, "params.gravity"));
        check!(positive(self.masscart, "params.masscart"));
        check!(positive(self.masspole, "params.masspole"));
        check!(positive(self.length, "params.length"));
        check!(positive(self.force_mag, "params.force_mag"));
        check!(non_negative(self.motor_damping, "params.motor_damping"));
        check!(positive(self.tau, "params.tau"));
        check!(positive(
            self.theta_threshold_radians,
            "params.theta_threshold_radians"
        ));
        check!(positive(self.x_threshold, "params.x_threshold"));
        check!(non_negative(self.cart_friction, "params.cart_friction"));
        check!(non_negative(self.pole_friction, "params.pole_friction"));
        Ok(self)
    }

    /// Cart plus pole, computed as Gymnasium does (`masspole + masscart`).
    pub fn total_mass(&self) -> f64 {
        self.masspole + self.masscart
    }

    /// Pole mass times half-length, computed as Gymnasium does.
    pub fn polemass_length(&self) -> f64 {
        self.masspole * self.length
    }

    /// Whether `state` lies outside the allowed cart position or pole angle.
    pub fn is_terminal(&self, s: &State) -> bool {
        s.x < -self.x_threshold
            || s.x > self.x_threshold
            || s.theta < -self.theta_threshold_radians
            || s.theta > self.theta_threshold_radians
    }
}

/// The plant's full state, in Gymnasium's order `[x, x_dot, theta, theta_dot]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct State {
    /// Cart position, m (+ to the right).
    pub x: f64,
    /// Cart velocity, m/s.
    pub x_dot: f64,
    /// Pole angle from upright, rad (+ leaning right).
    pub theta: f64,
    /// Pole angular velocity, rad/s.
    pub theta_dot: f64,
}

impl State {
    /// From Gymnasium's array order.
    pub const fn from_array(a: [f64; 4]) -> State {
        State {
            x: a[0],
            x_dot: a[1],
            theta: a[2],
            theta_dot: a[3],
        }
    }

    /// To Gymnasium's array order.
    pub const fn to_array(self) -> [f64; 4] {
        [self.x, self.x_dot, self.theta, self.theta_dot]
    }

    /// The observation Gymnasium returns: the state rounded to f32.
    pub fn observation(&self) -> [f32; 4] {
        self.to_array().map(|v| v as f32)
    }
}

/// One Euler step of the dynamics under `action`, in Gymnasium's exact operation order.
pub fn step(p: &Params, s: &State, action: Action) -> State {
    advance(p, s, action.level(), 0.0)
}

/// One Euler step at motor duty `duty` (`-1` to `1`, see [`Plant::motor_force`]) with an
/// extra horizontal force `external` (N) on the cart: pushes, disturbances. At full duty,
/// without external force, motor damping or friction, this is Gymnasium's step bit for bit.
pub fn advance(p: &Params, s: &State, duty: f64, external: f64) -> State {
    State::from_array(Plant::<f64>::new(p).euler(&s.to_array(), duty, external))
}

/// What one [`CartPole::step`] returns, as Gymnasium's `step` does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transition {
    /// Observation after the step.
    pub obs: [f32; 4],
    /// Always 1.0, the terminating step included.
    pub reward: f32,
    /// The pole fell or the cart left the track.
    pub terminated: bool,
    /// The episode reached its step limit without terminating.
    pub truncated: bool,
}

/// An episode of the plant: state, step count and limits.
#[derive(Clone, Debug)]
pub struct CartPole {
    /// Physics constants; change them between episodes to study robustness.
    pub params: Params,
    state: State,
    steps: u32,
    max_steps: u32,
}

impl CartPole {
    /// A plant whose episodes are truncated after `max_steps` steps
    /// ([`PAPER_EPISODE_STEPS`] or [`V1_EPISODE_STEPS`], or any other).
    pub fn new(params: Params, max_steps: u32) -> CartPole {
        CartPole {
            params,
            state: State::default(),
            steps: 0,
            max_steps,
        }
    }

    /// Start an episode from Gymnasium's random start: each state variable uniform in
    /// [-0.05, 0.05).
    #[cfg(feature = "rand")]
    pub fn reset<R: rand_core::Rng + ?Sized>(&mut self, rng: &mut R) -> [f32; 4] {
        let mut a = [0.0; 4];
        for v in &mut a {
            *v = -0.05 + 0.1 * unit_f64(rng);
        }
        self.reset_to(State::from_array(a))
    }

    /// Start an episode from a given state.
    pub fn reset_to(&mut self, state: State) -> [f32; 4] {
        self.state = state;
        self.steps = 0;
        state.observation()
    }

    /// Advance one control period under `action`.
    pub fn step(&mut self, action: Action) -> Transition {
        self.advance(action.level(), 0.0)
    }

    /// Advance one control period at motor duty `duty` with an external force (see
    /// [`advance`]).
    pub fn advance(&mut self, duty: f64, external: f64) -> Transition {
        self.state = advance(&self.params, &self.state, duty, external);
        self.record_step()
    }

    /// Takes `state` as the state one period on (a world that integrates the plant its own
    /// way) and does the period's bookkeeping.
    pub fn set_next(&mut self, state: State) -> Transition {
        self.state = state;
        self.record_step()
    }

    fn record_step(&mut self) -> Transition {
        self.steps = self.steps.saturating_add(1);
        let terminated = self.params.is_terminal(&self.state);
        Transition {
            obs: self.state.observation(),
            reward: 1.0,
            terminated,
            truncated: !terminated && self.steps >= self.max_steps,
        }
    }

    /// The full f64 state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Steps taken since the last reset.
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// The truncation limit.
    pub fn max_steps(&self) -> u32 {
        self.max_steps
    }
}

/// A uniform f64 in [0, 1) from the top 53 bits of one `next_u64`.
#[cfg(feature = "rand")]
pub fn unit_f64<R: rand_core::Rng + ?Sized>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[cfg(test)]
mod tests;
