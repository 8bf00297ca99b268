//! What the C API adds for a policy's duty levels: the init call that builds its
//! controller, the check that a two-output policy is on the full pushes, and the levels and
//! the duty function of a header of more outputs.

use std::fmt::Write;

use firmware::controller::Duty;
use firmware::network::N_ACTIONS;

use super::c_shape;
use crate::Result;

/// The call of `libcartpole_policy.a` that builds a controller of the exported network
/// `name` (`format` `mlp` or `qmlp`, hidden width `h`, `a` outputs) on `NAME_rig`, and for
/// more than two outputs on its `NAME_levels`.
pub fn c_init_call(format: &str, name: &str, h: usize, a: usize) -> String {
    let c = c_shape(h, a);
    if a == N_ACTIONS {
        format!("cartpole_controller_init_{format}{c}(&ctl, &{name}, &{name}_rig)")
    } else {
        format!(
            "cartpole_controller_init_{format}{c}(&ctl, &{name}, {name}_levels, {a}, &{name}_rig)"
        )
    }
}

/// Refuses what the C API cannot run: a policy of two outputs on other levels than the two
/// full pushes (its two-output controllers drive those; a gentler policy has more outputs).
pub(crate) fn check_c_levels(levels: &[f32]) -> Result<()> {
    if levels.len() == N_ACTIONS && levels != crate::BANG_BANG {
        return Err(crate::Error::Input(format!(
            "the C API runs a two-output policy on the full pushes [-1, 1]; this policy's \
             levels are {levels:?} (a policy of three or more outputs may have any levels)"
        )));
    }
    Ok(())
}

/// What a header of more than two outputs adds: `static const int16_t NAME_levels[A]`, each
/// output's duty in thousandths of the full push ([`Duty`]), and `NAME_duty(q)`, the duty
/// that outputs `q` (of C type `q_type`) choose: the largest, the lowest index of equal ones
/// ([`argmax`](firmware::network::argmax)). Empty for the paper's two outputs, whose levels,
/// the full pushes, `libcartpole_policy.a`'s two-output controllers drive.
pub(crate) fn c_levels_item(name: &str, levels: &[f32], q_type: &str) -> Result<String> {
    if levels.len() == N_ACTIONS {
        return Ok(String::new());
    }
    let a = levels.len();
    let mut list = String::new();
    for (i, l) in levels.iter().enumerate() {
        let d = Duty::from_fraction(*l)
            .map_err(|e| crate::Error::Input(format!("levels: {l} is no duty ({e:?})")))?;
        let sep = if i > 0 { ", " } else { "" };
        let _ = write!(list, "{sep}{}", d.thousandths());
    }
    Ok(format!(
        "\n/* The duty output i of {name} drives, in thousandths of the full push (+ towards +x),\n \
         * in increasing order. */\n\
         static const int16_t {name}_levels[{a}] = {{{list}}};\n\
         \n/* The duty that q, the outputs of {name}, choose: {name}_levels[i] of the largest q[i],\n \
         * the lowest i of equal ones. */\n\
         static inline int16_t {name}_duty(const {q_type} q[{a}]) {{\n    \
         int best = 0;\n    int i;\n    for (i = 1; i < {a}; i++) {{\n        \
         if (q[i] > q[best]) {{\n            best = i;\n        }}\n    }}\n    \
         return {name}_levels[best];\n}}\n"
    ))
}
