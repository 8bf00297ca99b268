//! `struct cartpole_rig`: the machine a policy was trained for, as C holds it, the fields of
//! [`Rig`] flattened in its order. The exported C headers define one beside their weights
//! (`NAME_rig`), and `cartpole_controller_init_mlpH` builds a controller on it; C may also
//! fill one in, so every field is checked before a controller is built on it.

use core::f64::consts::FRAC_PI_2;

use firmware::cartpole::Params;
use firmware::controller::predict::MAX_PREDICT;
use firmware::estimator::{Encoders, Tuning};
use firmware::rig::Rig;

/// `struct cartpole_rig` of `capi/include/cartpole_policy.h`, field for field.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartpoleRig {
    /// Gravitational acceleration, m/s^2.
    pub gravity: f64,
    /// The cart's mass, kg.
    pub masscart: f64,
    /// The pole's mass, kg.
    pub masspole: f64,
    /// Pivot to the pole's centre of mass, m.
    pub length: f64,
    /// The motor's stall force, N.
    pub force_mag: f64,
    /// The force the cart's speed takes from the motor's, N s/m.
    pub motor_damping: f64,
    /// The control period, s.
    pub tau: f64,
    /// The pole has fallen beyond this angle, rad.
    pub theta_threshold_radians: f64,
    /// The end stops' distance from the track's centre, m.
    pub x_threshold: f64,
    /// Coulomb friction between cart and track.
    pub cart_friction: f64,
    /// Viscous friction at the pivot, N m s/rad.
    pub pole_friction: f64,
    /// Cart encoder counts per metre.
    pub cart_counts_per_m: u32,
    /// Pole encoder counts per revolution.
    pub pole_counts_per_rev: u32,
    /// Periods of dead time.
    pub dead_time: u32,
    /// How near an end stop the controller coasts, m.
    pub end_stop_margin: f64,
    /// The observer's unmodelled force, N.
    pub force_sd: f64,
    /// The observer's unmodelled accelerations of the cart (m/s^2) and the pole (rad/s^2).
    pub accel_sd: [f64; 2],
}

impl From<&Rig> for CartpoleRig {
    fn from(rig: &Rig) -> CartpoleRig {
        let p = &rig.params;
        CartpoleRig {
            gravity: p.gravity,
            masscart: p.masscart,
            masspole: p.masspole,
            length: p.length,
            force_mag: p.force_mag,
            motor_damping: p.motor_damping,
            tau: p.tau,
            theta_threshold_radians: p.theta_threshold_radians,
            x_threshold: p.x_threshold,
            cart_friction: p.cart_friction,
            pole_friction: p.pole_friction,
            cart_counts_per_m: rig.encoders.cart_counts_per_m,
            pole_counts_per_rev: rig.encoders.pole_counts_per_rev,
            dead_time: rig.dead_time,
            end_stop_margin: rig.end_stop_margin,
            force_sd: rig.tuning.force_sd,
            accel_sd: rig.tuning.accel_sd,
        }
    }
}

/// `v` finite and in `(lo, hi]`, or `[lo, hi]` where `closed`.
fn within(v: f64, (lo, hi): (f64, f64), closed: bool) -> bool {
    v.is_finite() && (v > lo || (closed && v == lo)) && v <= hi
}

/// `n` in `[lo, hi]`.
fn counts(n: u32, (lo, hi): (u32, u32)) -> bool {
    (lo..=hi).contains(&n)
}

impl CartpoleRig {
    /// The rig, if every field is one a machine can have: the ranges of a rig file
    /// (`twin::rigfile`; the header lists them). Outside them the observer's gain may not
    /// exist, and its solver would spin through all its iterations at start-up on NaNs.
    pub fn to_rig(&self) -> Option<Rig> {
        let positive = |v: f64, hi: f64| within(v, (0.0, hi), false);
        let non_negative = |v: f64, hi: f64| within(v, (0.0, hi), true);
        let physics = positive(self.gravity, 100.0)
            && positive(self.masscart, 1000.0)
            && positive(self.masspole, 1000.0)
            && positive(self.length, 100.0)
            && positive(self.force_mag, 1e4)
            && non_negative(self.motor_damping, 1e4)
            && within(self.tau, (0.002, 0.05), true)
            && positive(self.theta_threshold_radians, FRAC_PI_2)
            && positive(self.x_threshold, 100.0)
            && non_negative(self.cart_friction, 1.0)
            && non_negative(self.pole_friction, 0.1);
        let machine = counts(self.cart_counts_per_m, (16, 1 << 26))
            && counts(self.pole_counts_per_rev, (16, 1 << 24))
            && counts(self.dead_time, (0, MAX_PREDICT as u32))
            && non_negative(self.end_stop_margin, 100.0)
            && self.end_stop_margin < self.x_threshold
            && positive(self.force_sd, 1e4)
            && self.accel_sd.iter().all(|&sd| positive(sd, 1e4));
        (physics && machine).then(|| self.rig())
    }

    /// The fields as a [`Rig`], unchecked.
    fn rig(&self) -> Rig {
        Rig {
            params: Params {
                gravity: self.gravity,
                masscart: self.masscart,
                masspole: self.masspole,
                length: self.length,
                force_mag: self.force_mag,
                motor_damping: self.motor_damping,
                tau: self.tau,
                theta_threshold_radians: self.theta_threshold_radians,
                x_threshold: self.x_threshold,
                cart_friction: self.cart_friction,
                pole_friction: self.pole_friction,
            },
            encoders: Encoders {
                cart_counts_per_m: self.cart_counts_per_m,
                pole_counts_per_rev: self.pole_counts_per_rev,
            },
            dead_time: self.dead_time,
            end_stop_margin: self.end_stop_margin,
            tuning: Tuning {
                force_sd: self.force_sd,
                accel_sd: self.accel_sd,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::policy::RIG;

    #[test]
    fn a_rig_goes_to_c_and_back_unchanged() {
        for rig in [Rig::GYMNASIUM, RIG] {
            assert_eq!(CartpoleRig::from(&rig).to_rig(), Some(rig));
        }
    }

    #[test]
    fn a_field_no_machine_has_is_refused() {
        let good = CartpoleRig::from(&Rig::GYMNASIUM);
        let bad: [fn(&mut CartpoleRig); 16] = [
            |r| r.tau = f64::NAN,
            |r| r.tau = 0.0,
            |r| r.tau = 1.0,
            |r| r.gravity = f64::INFINITY,
            |r| r.masscart = -1.0,
            |r| r.masspole = 0.0,
            |r| r.length = -0.0,
            |r| r.force_mag = 0.0,
            |r| r.motor_damping = -1e-9,
            |r| r.pole_friction = 0.5,
            |r| r.cart_counts_per_m = 0,
            |r| r.pole_counts_per_rev = 15,
            |r| r.dead_time = MAX_PREDICT as u32 + 1,
            |r| r.end_stop_margin = r.x_threshold,
            |r| r.force_sd = 0.0,
            |r| r.accel_sd[1] = f64::NAN,
        ];
        for (i, spoil) in bad.iter().enumerate() {
            let mut r = good;
            spoil(&mut r);
            assert_eq!(r.to_rig(), None, "spoiled field {i}: {r:?}");
        }
        // The bounds themselves are machines.
        let mut edge = good;
        (edge.tau, edge.dead_time, edge.cart_counts_per_m) = (0.002, MAX_PREDICT as u32, 16);
        (edge.motor_damping, edge.cart_friction) = (0.0, 1.0);
        assert!(edge.to_rig().is_some());
    }
}
