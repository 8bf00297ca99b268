//! The plant's equations of motion, once, generic over the float type: in f64 they are
//! Gymnasium's step bit for bit (the plant of every episode), in f32 what a board runs to
//! predict over its dead time and to observe its encoders.
//!
//! [`Plant::derivative`] is the one definition of the dynamics: the motor's force at a duty
//! ([`Plant::motor_force`]), then Gymnasium's equations (Barto, Sutton and Anderson 1983) or,
//! with friction, Florian's (2007). [`Plant::euler`] is Gymnasium's integration step; a
//! continuous-time world integrates the same derivative with finer steps.

use core::ops::{Add, Div, Mul, Neg, Sub};

use super::Params;

/// The float types the plant is computed in: f64 with `libm`'s sine and cosine (Gymnasium's
/// bits), f32 with `micromath`'s (a fraction of `libm`'s cost on a core without an FPU, within
/// 1.1e-3 of the true values; measured in the predictor's tests).
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// `v` rounded to this type.
    fn of(v: f64) -> Self;
    /// The sine.
    fn sin(self) -> Self;
    /// The cosine.
    fn cos(self) -> Self;
    /// The sine and the cosine, as [`Real::sin`] and [`Real::cos`] give them.
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const ONE: f64 = 1.0;
    #[inline(always)]
    fn of(v: f64) -> f64 {
        v
    }
    #[inline(always)]
    fn sin(self) -> f64 {
        libm::sin(self)
    }
    #[inline(always)]
    fn cos(self) -> f64 {
        libm::cos(self)
    }
    // `sin_cos` stays the two calls, not `libm::sincos`: as the only caller of libm's
    // argument reduction, `sincos` takes it inline, and with it the scratch arrays of the
    // large-argument path, into the frame of every plant step on a microcontroller, for
    // angles a balancing pole never reaches. Two callers keep the reduction out of line.
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
    #[inline(always)]
    fn of(v: f64) -> f32 {
        v as f32
    }
    #[inline(always)]
    fn sin(self) -> f32 {
        micromath::F32Ext::sin(self)
    }
    #[inline(always)]
    fn cos(self) -> f32 {
        micromath::F32Ext::cos(self)
    }
}

/// A plant's constants in `T`, derived once from [`Params`] the way Gymnasium derives them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plant<T> {
    gravity: T,
    masspole: T,
    total_mass: T,
    length: T,
    polemass_length: T,
    force_mag: T,
    motor_damping: T,
    tau: T,
    cart_friction: T,
    pole_friction: T,
    four_thirds: T,
}

impl<T: Real> Plant<T> {
    /// The plant of `p` in `T`.
    pub fn new(p: &Params) -> Plant<T> {
        Plant {
            gravity: T::of(p.gravity),
            masspole: T::of(p.masspole),
            total_mass: T::of(p.total_mass()),
            length: T::of(p.length),
            polemass_length: T::of(p.polemass_length()),
            force_mag: T::of(p.force_mag),
            motor_damping: T::of(p.motor_damping),
            tau: T::of(p.tau),
            cart_friction: T::of(p.cart_friction),
            pole_friction: T::of(p.pole_friction),
            four_thirds: T::of(4.0 / 3.0),
        }
    }

    /// The control period, s.
    pub fn tau(&self) -> T {
        self.tau
    }

    /// The motor's force on the cart at duty `duty` (`1` full towards +x, `-1` full towards
    /// -x, `0` off) while the cart moves at `x_dot`: `force_mag * duty - motor_damping * x_dot`,
    /// the stall force less the back-EMF and viscous drag, in one term. The one place a
    /// command becomes a force.
    #[inline(always)]
    pub fn motor_force(&self, duty: T, x_dot: T) -> T {
        self.force_mag * duty - self.motor_damping * x_dot
    }

    /// `d/dt [x, x_dot, theta, theta_dot]` at duty `duty` with an external horizontal force
    /// `external` (N, pushes) on the cart.
    #[inline(always)]
    pub fn derivative(&self, s: &[T; 4], duty: T, external: T) -> [T; 4] {
        self.derivative_at(s, s[2].sin_cos(), duty, external)
    }

    /// [`Plant::derivative`] with the angle's sine and cosine given, `trig = (sin, cos)` of
    /// `s[2]`: for an integrator that knows them more cheaply than by computing them afresh.
    #[inline(always)]
    pub fn derivative_at(&self, s: &[T; 4], trig: (T, T), duty: T, external: T) -> [T; 4] {
        let force = self.motor_force(duty, s[1]) + external;
        let (xacc, thetaacc) = if self.cart_friction != T::ZERO || self.pole_friction != T::ZERO {
            self.florian(s, trig, force)
        } else {
            self.gymnasium(s, trig, force)
        };
        [s[1], xacc, s[3], thetaacc]
    }

    /// One Euler step of one period, Gymnasium's: positions advance with the old velocities.
    #[inline(always)]
    pub fn euler(&self, s: &[T; 4], duty: T, external: T) -> [T; 4] {
        let d = self.derivative(s, duty, external);
        core::array::from_fn(|i| s[i] + self.tau * d[i])
    }

    /// Gymnasium's accelerations, parenthesised as its numpy expression evaluates: squares
    /// first, then products left to right. Any other association changes the last bit of
    /// some states.
    #[inline(always)]
    fn gymnasium(&self, s: &[T; 4], (sintheta, costheta): (T, T), force: T) -> (T, T) {
        let theta_dot = s[3];
        let temp =
            (force + self.polemass_length * (theta_dot * theta_dot) * sintheta) / self.total_mass;
        let thetaacc = (self.gravity * sintheta - costheta * temp)
            / (self.length
                * (self.four_thirds - self.masspole * (costheta * costheta) / self.total_mass));
        let xacc = temp - self.polemass_length * thetaacc * costheta / self.total_mass;
        (xacc, thetaacc)
    }

    /// The accelerations with friction on the cart and at the pivot, by R. V. Florian,
    /// "Correct equations for the dynamics of the cart-pole system" (Center for Cognitive and
    /// Neural Studies, Romania, 2007), equations (21), (22) and (23) in this project's sign
    /// convention (Gymnasium's: `theta` and `force` positive towards `+x`):
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
    /// with `M = m_c + m`, `w = theta_dot`. The cart's Coulomb friction is proportional to
    /// the track's normal force `N_c`, which depends on `theta_acc`; as Florian suggests, the
    /// sign of `N_c` is taken as positive first (the pole is far lighter than what holds the
    /// cart down) and `theta_acc` is recomputed in the rare step where it comes out negative.
    /// At zero friction the equations reduce to Gymnasium's.
    fn florian(&self, s: &[T; 4], trig: (T, T), force: T) -> (T, T) {
        let [_, x_dot, _, theta_dot] = *s;
        let (sin, cos) = trig;
        let (mc, m, ml) = (self.cart_friction, self.total_mass, self.polemass_length);
        let w2 = theta_dot * theta_dot;
        let normal = |ta: T| m * self.gravity - ml * (ta * sin + w2 * cos);
        let mut ta = self.florian_theta_acc(s, trig, force, T::ONE);
        let mut nc = normal(ta);
        if nc < T::ZERO {
            ta = self.florian_theta_acc(s, trig, force, -T::ONE);
            nc = normal(ta);
        }
        let xacc = (force + ml * (w2 * sin - ta * cos) - mc * nc * sgn(nc * x_dot)) / m;
        (xacc, ta)
    }

    /// Florian's `theta_acc` with `nc_sign` taken as the sign of `N_c`. A method inlined
    /// twice rather than a closure called twice: such a closure stays out of line, and what it
    /// borrows (the plant's constants, the angle's sine and cosine) then has to live in
    /// memory, in the frame of every plant step, friction or not.
    #[inline(always)]
    fn florian_theta_acc(&self, s: &[T; 4], (sin, cos): (T, T), force: T, nc_sign: T) -> T {
        let [_, x_dot, _, theta_dot] = *s;
        let (mc, mp) = (self.cart_friction, self.pole_friction);
        let (m, ml) = (self.total_mass, self.polemass_length);
        let w2 = theta_dot * theta_dot;
        let f = mc * sgn(nc_sign * x_dot);
        let num = self.gravity * sin
            - cos * ((force + ml * w2 * (sin + f * cos)) / m - f * self.gravity)
            - mp * theta_dot / ml;
        num / (self.length * (self.four_thirds - self.masspole * cos / m * (cos - f)))
    }
}

/// The sign of `v`: `1`, `-1`, or `0` for zero (and NaN).
#[inline(always)]
fn sgn<T: Real>(v: T) -> T {
    if v > T::ZERO {
        T::ONE
    } else if v < T::ZERO {
        -T::ONE
    } else {
        T::ZERO
    }
}
