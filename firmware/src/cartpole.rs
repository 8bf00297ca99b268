//! The cart-pole plant: Gymnasium's `CartPole-v1`, bit for bit.
//!
//! [`Params::default`] is Gymnasium's environment, and [`step`] performs its Euler step in
//! exactly Gymnasium's order of floating-point operations, in f64, with `libm`'s `sin`/`cos`.
//! That makes every state equal to Gymnasium's to the last bit (checked against recorded
//! trajectories in this crate's tests), on the host and on a microcontroller alike.
//!
//! This module is the physics and the episode bookkeeping (termination, truncation,
//! random starts). It is not a renderer, and it knows nothing of networks or controllers.

use rand_core::Rng;

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
}

/// Physical constants and episode limits. `Default` is Gymnasium's `CartPole-v1`; robustness
/// studies change single fields (a 20% heavier pole, a weaker motor).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// Gravitational acceleration, m/s^2.
    pub gravity: f64,
    /// Mass of the cart, kg.
    pub masscart: f64,
    /// Mass of the pole, kg.
    pub masspole: f64,
    /// Half the pole's length, m (Gymnasium calls it `length`).
    pub length: f64,
    /// Magnitude of the push, N.
    pub force_mag: f64,
    /// Integration step and control period, s.
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

impl Default for Params {
    fn default() -> Self {
        Params {
            gravity: 9.8,
            masscart: 1.0,
            masspole: 0.1,
            length: 0.5,
            force_mag: 10.0,
            tau: 0.02,
            // Gymnasium writes `12 * 2 * math.pi / 360`; the same order gives the same bits.
            theta_threshold_radians: 12.0 * 2.0 * core::f64::consts::PI / 360.0,
            x_threshold: 2.4,
            cart_friction: 0.0,
            pole_friction: 0.0,
        }
    }
}

impl Params {
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
    step_with_force(
        p,
        s,
        match action {
            Action::Right => p.force_mag,
            Action::Left => -p.force_mag,
        },
    )
}

/// One Euler step under an arbitrary horizontal force (N): pushes, disturbances, a motor
/// that delivers less than its rating. With `force = +-force_mag` it is exactly [`step`].
///
/// Without friction (both coefficients zero, the default) this is Gymnasium's step in
/// Gymnasium's order of operations, bit for bit. With friction it is [`step_with_friction`].
pub fn step_with_force(p: &Params, s: &State, force: f64) -> State {
    if p.cart_friction != 0.0 || p.pole_friction != 0.0 {
        return step_with_friction(p, s, force);
    }
    let total_mass = p.total_mass();
    let polemass_length = p.polemass_length();
    let costheta = libm::cos(s.theta);
    let sintheta = libm::sin(s.theta);
    // Parenthesised as Gymnasium's numpy expression evaluates: squares first, then products
    // left to right. Any other association changes the last bit of some states.
    let temp = (force + polemass_length * (s.theta_dot * s.theta_dot) * sintheta) / total_mass;
    let thetaacc = (p.gravity * sintheta - costheta * temp)
        / (p.length * (4.0 / 3.0 - p.masspole * (costheta * costheta) / total_mass));
    let xacc = temp - polemass_length * thetaacc * costheta / total_mass;
    euler(p, s, xacc, thetaacc)
}

/// One Euler step with friction on the cart and at the pivot, by R. V. Florian, "Correct
/// equations for the dynamics of the cart-pole system" (Center for Cognitive and Neural
/// Studies, Romania, 2007), equations (21), (22) and (23) in this project's sign convention
/// (Gymnasium's: `theta` and `force` positive towards `+x`):
///
/// ```text
/// theta_acc = [ g sin - cos ((F + m l w^2 (sin + mu_c sgn(N_c x_dot) cos)) / M
///                            - mu_c g sgn(N_c x_dot))
///               - mu_p w / (m l) ]
///             / ( l (4/3 - (m cos / M) (cos - mu_c sgn(N_c x_dot))) )
/// N_c       = M g - m l (theta_acc sin + w^2 cos)
/// x_acc     = (F + m l (w^2 sin - theta_acc cos) - mu_c N_c sgn(N_c x_dot)) / M
/// ```
///
/// with `M = m_c + m`, `w = theta_dot`. The cart's Coulomb friction is proportional to the
/// track's normal force `N_c`, which depends on `theta_acc`; as Florian suggests, the sign of
/// `N_c` is taken as positive first (the pole is far lighter than what holds the cart down)
/// and `theta_acc` is recomputed in the rare step where it comes out negative. At zero
/// friction the equations reduce to Gymnasium's (the textbook form of Barto, Sutton and
/// Anderson 1983, whose friction terms Florian corrects).
pub fn step_with_friction(p: &Params, s: &State, force: f64) -> State {
    let (mc, mp) = (p.cart_friction, p.pole_friction);
    let total_mass = p.total_mass();
    let ml = p.polemass_length();
    let (sin, cos) = (libm::sin(s.theta), libm::cos(s.theta));
    let w2 = s.theta_dot * s.theta_dot;
    let sgn = |v: f64| {
        if v > 0.0 {
            1.0
        } else if v < 0.0 {
            -1.0
        } else {
            0.0
        }
    };
    let theta_acc = |nc_sign: f64| {
        let f = mc * sgn(nc_sign * s.x_dot);
        let num = p.gravity * sin
            - cos * ((force + ml * w2 * (sin + f * cos)) / total_mass - f * p.gravity)
            - mp * s.theta_dot / ml;
        num / (p.length * (4.0 / 3.0 - p.masspole * cos / total_mass * (cos - f)))
    };
    let normal = |ta: f64| total_mass * p.gravity - ml * (ta * sin + w2 * cos);
    let mut ta = theta_acc(1.0);
    let mut nc = normal(ta);
    if nc < 0.0 {
        ta = theta_acc(-1.0);
        nc = normal(ta);
    }
    let xacc = (force + ml * (w2 * sin - ta * cos) - mc * nc * sgn(nc * s.x_dot)) / total_mass;
    euler(p, s, xacc, ta)
}

/// Gymnasium's semi-implicit-free Euler update: positions advance with the old velocities.
#[inline(always)]
fn euler(p: &Params, s: &State, xacc: f64, thetaacc: f64) -> State {
    State {
        x: s.x + p.tau * s.x_dot,
        x_dot: s.x_dot + p.tau * xacc,
        theta: s.theta + p.tau * s.theta_dot,
        theta_dot: s.theta_dot + p.tau * thetaacc,
    }
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
    pub fn reset<R: Rng + ?Sized>(&mut self, rng: &mut R) -> [f32; 4] {
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
        self.step_force(match action {
            Action::Right => self.params.force_mag,
            Action::Left => -self.params.force_mag,
        })
    }

    /// Advance one control period under an arbitrary force (see [`step_with_force`]).
    pub fn step_force(&mut self, force: f64) -> Transition {
        self.state = step_with_force(&self.params, &self.state, force);
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
pub fn unit_f64<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_params_are_gymnasiums() {
        let p = Params::default();
        assert_eq!(p.total_mass(), 1.1);
        assert_eq!(p.polemass_length(), 0.05);
        assert_eq!(p.theta_threshold_radians, 0.20943951023931953);
    }

    #[test]
    fn truncates_at_the_limit_but_termination_wins() {
        let mut env = CartPole::new(Params::default(), 3);
        env.reset_to(State::default());
        let a = [Action::Left, Action::Right, Action::Left];
        let t: [Transition; 3] = a.map(|a| env.step(a));
        assert!(!t[0].truncated && !t[1].truncated && t[2].truncated);
        assert!(t.iter().all(|t| !t.terminated && t.reward == 1.0));

        let mut env = CartPole::new(Params::default(), 1);
        env.reset_to(State {
            theta: 0.2094,
            theta_dot: 1.0,
            ..State::default()
        });
        let t = env.step(Action::Left);
        assert!(t.terminated && !t.truncated);
    }

    #[test]
    fn reset_is_uniform_in_the_start_box() {
        use rand_pcg::Pcg64Mcg;
        let mut rng = Pcg64Mcg::new(7);
        let mut env = CartPole::new(Params::default(), 500);
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for _ in 0..2000 {
            env.reset(&mut rng);
            for v in env.state().to_array() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        assert!((-0.05..-0.0499).contains(&lo), "{lo}");
        assert!((0.0499..0.05).contains(&hi), "{hi}");
    }

    #[test]
    fn friction_follows_florians_equations() {
        let p = Params {
            cart_friction: 0.1,
            ..Params::default()
        };
        // A cart sliding at 1 m/s under an upright pole at rest, no force: the track's normal
        // force is the whole weight M g, the pole tips forward with
        // theta_acc = mu_c g / (l (4/3 - m / M (1 - mu_c))), and the cart decelerates by the
        // friction and the pole's reaction: x_acc = (-m l theta_acc - mu_c M g) / M.
        let s = State {
            x_dot: 1.0,
            ..State::default()
        };
        let n = step_with_force(&p, &s, 0.0);
        let xacc = (n.x_dot - s.x_dot) / p.tau;
        let tacc = (n.theta_dot - s.theta_dot) / p.tau;
        let want = 0.1 * 9.8 / (0.5 * (4.0 / 3.0 - 0.1 / 1.1 * 0.9));
        assert!((tacc - want).abs() < 1e-12, "{tacc} vs {want}");
        let want_x = (-0.05 * want - 0.1 * 1.1 * 9.8) / 1.1;
        assert!((xacc - want_x).abs() < 1e-12, "{xacc} vs {want_x}");
        // At rest, Coulomb friction exerts nothing.
        let rest = step_with_force(&p, &State::default(), 0.0);
        assert_eq!(rest, State::default());
    }

    #[test]
    fn without_friction_the_friction_equations_are_gymnasiums_to_rounding() {
        let s = State::from_array([0.1, -0.4, 0.15, 1.3]);
        let p = Params::default();
        let a = step_with_force(&p, &s, 7.0);
        let b = step_with_friction(&p, &s, 7.0);
        for (x, y) in a.to_array().iter().zip(b.to_array()) {
            assert!((x - y).abs() <= 1e-15 * x.abs().max(1.0), "{a:?} {b:?}");
        }
    }

    #[test]
    fn pivot_friction_takes_energy_out_of_a_swinging_pole() {
        // A pole swinging through upright (theta_dot = 2) slows less without friction.
        let s = State::from_array([0.0, 0.0, 0.0, 2.0]);
        let free = step_with_force(&Params::default(), &s, 0.0);
        let damped = step_with_force(
            &Params {
                pole_friction: 0.01,
                ..Params::default()
            },
            &s,
            0.0,
        );
        assert!(damped.theta_dot < free.theta_dot, "{damped:?} {free:?}");
    }

    #[test]
    fn action_indices_round_trip() {
        for a in Action::ALL {
            assert_eq!(Action::from_index(a.index()), a);
        }
        assert_eq!(Action::from_index(7), Action::Left);
    }
}
