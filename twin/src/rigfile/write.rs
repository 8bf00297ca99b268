//! A [`Machine`] written as a rig file, and the degrees a rig file gives its failure angle
//! in.

use std::fmt::Write;

use super::Machine;
use crate::machine::{Integration, Uncertainty};

/// Degrees to radians as Gymnasium converts its 12 degrees, so that Gymnasium's rig file
/// gives Gymnasium's threshold bit for bit.
pub(super) fn radians(deg: f64) -> f64 {
    deg * 2.0 * core::f64::consts::PI / 360.0
}

/// The degrees [`radians`] turns into `rad` exactly (the nearest f64 that does, where the
/// plain conversion's rounding would miss by an ulp).
fn degrees(rad: f64) -> f64 {
    let d = rad * 360.0 / (2.0 * core::f64::consts::PI);
    let ulp = |k: i64| f64::from_bits((d.to_bits() as i64 + k) as u64);
    [0, 1, -1, 2, -2, 3, -3]
        .into_iter()
        .map(ulp)
        .find(|&c| radians(c) == rad)
        .unwrap_or(d)
}

/// `machine` as a rig file that [`parse`] reads back to it, bit for bit (every f64 in its
/// shortest round-tripping form; the pole by its centre of mass).
pub fn to_toml(machine: &Machine) -> String {
    let (r, p) = (&machine.rig, &machine.rig.params);
    let mut s = String::new();
    let _ = writeln!(s, "cart_mass_kg = {:?}", p.masscart);
    let _ = writeln!(s, "pole_mass_kg = {:?}", p.masspole);
    let _ = writeln!(s, "pole_com_m = {:?}", p.length);
    let _ = writeln!(s, "track_half_length_m = {:?}", p.x_threshold);
    let _ = writeln!(s, "end_stop_margin_m = {:?}", r.end_stop_margin);
    let _ = writeln!(s, "period_s = {:?}", p.tau);
    let _ = writeln!(s, "dead_time_periods = {}", r.dead_time);
    let _ = writeln!(s, "gravity_m_s2 = {:?}", p.gravity);
    let _ = writeln!(
        s,
        "failure_angle_deg = {:?}",
        degrees(p.theta_threshold_radians)
    );
    let _ = writeln!(
        s,
        "\n[encoders]\ncart_counts_per_m = {}\npole_counts_per_rev = {}",
        r.encoders.cart_counts_per_m, r.encoders.pole_counts_per_rev
    );
    let _ = writeln!(
        s,
        "\n[actuator]\nstall_force_n = {:?}\ndamping_n_s_per_m = {:?}",
        p.force_mag, p.motor_damping
    );
    let _ = writeln!(
        s,
        "\n[friction]\ncart_coulomb = {:?}\npivot_viscous_n_m_s = {:?}",
        p.cart_friction, p.pole_friction
    );
    match machine.integration {
        Integration::Euler => s.push_str("\n[world]\nintegration = \"euler\"\n"),
        Integration::Rk4 { substeps } => {
            let _ = writeln!(
                s,
                "\n[world]\nintegration = \"continuous\"\nsubstep_s = {:?}",
                p.tau / f64::from(substeps)
            );
        }
    }
    let t = &r.tuning;
    let _ = writeln!(
        s,
        "\n[observer]\nforce_sd = {:?}\naccel_sd = [{:?}, {:?}]",
        t.force_sd, t.accel_sd[0], t.accel_sd[1]
    );
    let u = &machine.uncertainty;
    if *u != Uncertainty::NONE {
        let _ = writeln!(
            s,
            "\n[identified]\nstall_force = {:?}\ndamping = {:?}\npole_com = {:?}",
            u.stall_force, u.damping, u.pole_com
        );
    }
    s
}
