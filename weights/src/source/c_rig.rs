//! The rig in C: `struct cartpole_rig`, the layout of `capi`'s `CartpoleRig` (every field of
//! [`Rig`] flattened, in its order), and the `static const struct cartpole_rig NAME_rig` an
//! exported header carries beside its weights, so that a C board builds its controller
//! (`cartpole_controller_init_mlpH`) on the machine the policy was trained for.
//!
//! One list of fields ([`fields`]) writes both, so the declaration and the initialiser cannot
//! disagree on the order. The initialiser is positional: designated initialisers are not C++
//! before C++20, and the headers are included from C++ too.

use std::fmt::Write;

use firmware::rig::Rig;

use crate::{Error, Result};

/// A field's value, as C declares and initialises it.
#[derive(Clone, Copy)]
enum Value {
    Double(f64),
    Uint(u32),
    DoublePair([f64; 2]),
}

/// `struct cartpole_rig`'s fields in declared order: name, what it is (with its unit), and
/// `rig`'s value.
fn fields(rig: &Rig) -> [(&'static str, &'static str, Value); 17] {
    let (p, e, t) = (&rig.params, &rig.encoders, &rig.tuning);
    let d = Value::Double;
    [
        ("gravity", "gravitational acceleration, m/s^2", d(p.gravity)),
        ("masscart", "the cart's mass, kg", d(p.masscart)),
        ("masspole", "the pole's mass, kg", d(p.masspole)),
        (
            "length",
            "pivot to the pole's centre of mass, m (half a uniform pole's length)",
            d(p.length),
        ),
        (
            "force_mag",
            "the motor's force on the cart at full duty and standstill (its stall force), N",
            d(p.force_mag),
        ),
        (
            "motor_damping",
            "the force the cart's speed takes from the motor's (back-EMF, drag), N s/m",
            d(p.motor_damping),
        ),
        ("tau", "the control period, s", d(p.tau)),
        (
            "theta_threshold_radians",
            "the pole has fallen beyond this angle from upright, rad",
            d(p.theta_threshold_radians),
        ),
        (
            "x_threshold",
            "the end stops' distance from the track's centre, m",
            d(p.x_threshold),
        ),
        (
            "cart_friction",
            "Coulomb friction between cart and track, dimensionless",
            d(p.cart_friction),
        ),
        (
            "pole_friction",
            "viscous friction at the pivot, N m s/rad",
            d(p.pole_friction),
        ),
        (
            "cart_counts_per_m",
            "cart encoder counts per metre of travel",
            Value::Uint(e.cart_counts_per_m),
        ),
        (
            "pole_counts_per_rev",
            "pole encoder counts per revolution of the pivot",
            Value::Uint(e.pole_counts_per_rev),
        ),
        (
            "dead_time",
            "periods from the reading a command is decided on to the motor applying it",
            Value::Uint(rig.dead_time),
        ),
        (
            "end_stop_margin",
            "how near an end stop the controller stops pushing and coasts, m",
            d(rig.end_stop_margin),
        ),
        (
            "force_sd",
            "observer: standard deviation of an unmodelled force on the cart, N",
            d(t.force_sd),
        ),
        (
            "accel_sd",
            "observer: standard deviations of unmodelled accelerations of the cart (m/s^2)\n     \
             * and of the pole (rad/s^2)",
            Value::DoublePair(t.accel_sd),
        ),
    ]
}

/// The guarded definition of `struct cartpole_rig`: what every exported header shares with
/// `cartpole_policy.h`.
pub fn c_rig_struct() -> String {
    let mut s = String::from(
        "#ifndef CARTPOLE_RIG_DEFINED\n#define CARTPOLE_RIG_DEFINED\n#include <stdint.h>\n\
         /* A cart-pole machine as its board sees it, the fields of Rust's firmware::rig::Rig in\n \
         * its order: the physics, the encoders, the dead time, the end-stop margin, the\n \
         * observer's tuning. */\nstruct cartpole_rig {\n",
    );
    for (name, doc, value) in fields(&Rig::GYMNASIUM) {
        let decl = match value {
            Value::Double(_) => format!("double {name}"),
            Value::Uint(_) => format!("uint32_t {name}"),
            Value::DoublePair(_) => format!("double {name}[2]"),
        };
        let _ = writeln!(s, "    /* {doc} */\n    {decl};");
    }
    s.push_str("};\n#endif\n");
    s
}

/// `v` as a C double literal: the shortest decimal that reads back to it, which C compilers
/// round correctly (`{:?}` always has a '.' or an exponent, so C reads a double).
fn double(field: &str, v: f64) -> Result<String> {
    if v.is_finite() {
        Ok(format!("{v:?}"))
    } else {
        Err(Error::Input(format!(
            "rig: {field} is {v}, which a C initialiser cannot hold"
        )))
    }
}

/// `static const struct cartpole_rig NAME_rig`, `rig` bit for bit, one field a line; `init`
/// is the call of `libcartpole_policy.a` that builds a controller of `name` on it
/// ([`c_init_call`](crate::source::c_init_call)).
pub fn c_rig_item(name: &str, rig: &Rig, init: &str) -> Result<String> {
    let mut s = format!(
        "\n/* The machine {name} was trained for, on which\n * {init} builds its controller:\n \
         * the observer, the dead-time predictor, the limits. */\n\
         static const struct cartpole_rig {name}_rig = {{\n"
    );
    for (field, _, value) in fields(rig) {
        let literal = match value {
            Value::Double(v) => double(field, v)?,
            Value::Uint(v) => v.to_string(),
            Value::DoublePair([a, b]) => {
                format!("{{{}, {}}}", double(field, a)?, double(field, b)?)
            }
        };
        let _ = writeln!(s, "    {literal}, /* {field} */");
    }
    s.push_str("};\n");
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rig_c_cannot_write_is_refused_naming_the_field() {
        let mut rig = Rig::GYMNASIUM;
        rig.tuning.accel_sd[1] = f64::INFINITY;
        let e = c_rig_item("p", &rig, "").unwrap_err();
        assert!(e.is_input() && e.to_string().contains("accel_sd"), "{e}");
        rig.tuning.accel_sd[1] = 1.0;
        rig.params.tau = f64::NAN;
        let e = c_rig_item("p", &rig, "").unwrap_err();
        assert!(e.to_string().contains("tau"), "{e}");
    }
}
