//! `struct cartpole_rig`: the machine a policy was trained for, as C holds it, the fields of
//! [`Rig`] in its order (flat in C; the physics a nested [`Params`] here, the same layout). The exported C headers define one beside their weights
//! (`NAME_rig`), and `cartpole_controller_init_mlpH` builds a controller on it; C may also
//! fill one in, so every field is checked before a controller is built on it.

use core::f64::consts::FRAC_PI_2;

use firmware::cartpole::Params;
use firmware::controller::predict::MAX_PREDICT;
use firmware::estimator::{Encoders, Tuning};
use firmware::rig::Rig;

/// `struct cartpole_rig` of `capi/include/cartpole_policy.h`, field for field: the physics
/// is the firmware's [`Params`] (`repr(C)`, eleven doubles), so the C struct's first eleven
/// fields are its fields in their order, and the rest follow as C lays them out.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartpoleRig {
    /// The physics: masses, length, motor, period, failure thresholds, friction.
    pub params: Params,
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
        CartpoleRig {
            params: rig.params,
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
    /// The rig, if every field is one a machine can have: the ranges the header lists, a rig
    /// file's (`twin::rigfile`) but open at zero where a rig file asks for a gram or a
    /// millimetre at least, since a board's own constants are no typing slip. Outside them the
    /// observer's gain may not exist, and its solver would spin through all its iterations
    /// at start-up on NaNs.
    pub fn to_rig(&self) -> Option<Rig> {
        let positive = |v: f64, hi: f64| within(v, (0.0, hi), false);
        let non_negative = |v: f64, hi: f64| within(v, (0.0, hi), true);
        let p = &self.params;
        let physics = positive(p.gravity, 100.0)
            && positive(p.masscart, 1000.0)
            && positive(p.masspole, 1000.0)
            && positive(p.length, 100.0)
            && positive(p.force_mag, 1e4)
            && non_negative(p.motor_damping, 1e4)
            && within(p.tau, (0.002, 0.05), true)
            && positive(p.theta_threshold_radians, FRAC_PI_2)
            && positive(p.x_threshold, 100.0)
            && non_negative(p.cart_friction, 1.0)
            && non_negative(p.pole_friction, 0.1);
        let machine = counts(self.cart_counts_per_m, (16, 1 << 26))
            && counts(self.pole_counts_per_rev, (16, 1 << 24))
            && counts(self.dead_time, (0, MAX_PREDICT as u32))
            && non_negative(self.end_stop_margin, 100.0)
            && self.end_stop_margin < p.x_threshold
            && positive(self.force_sd, 1e4)
            && self.accel_sd.iter().all(|&sd| positive(sd, 1e4));
        (physics && machine).then(|| self.rig())
    }

    /// The fields as a [`Rig`], unchecked.
    fn rig(&self) -> Rig {
        Rig {
            params: self.params,
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
    use shipped::policy::RIG;

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
            |r| r.params.tau = f64::NAN,
            |r| r.params.tau = 0.0,
            |r| r.params.tau = 1.0,
            |r| r.params.gravity = f64::INFINITY,
            |r| r.params.masscart = -1.0,
            |r| r.params.masspole = 0.0,
            |r| r.params.length = -0.0,
            |r| r.params.force_mag = 0.0,
            |r| r.params.motor_damping = -1e-9,
            |r| r.params.pole_friction = 0.5,
            |r| r.cart_counts_per_m = 0,
            |r| r.pole_counts_per_rev = 15,
            |r| r.dead_time = MAX_PREDICT as u32 + 1,
            |r| r.end_stop_margin = r.params.x_threshold,
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
        (edge.params.tau, edge.dead_time, edge.cart_counts_per_m) = (0.002, MAX_PREDICT as u32, 16);
        (edge.params.motor_damping, edge.params.cart_friction) = (0.0, 1.0);
        assert!(edge.to_rig().is_some());
    }
}
