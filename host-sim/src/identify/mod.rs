//! Identification of what a scale and a ruler cannot measure: the motor's stall force and
//! damping, the cart's Coulomb friction, the pivot's viscous friction, the pole's effective
//! length and the dead time, from the logs of the board's two experiments
//! (`firmware::identify`: a PRBS on the cart under a hanging pole; the pole's free swing
//! under a held cart).
//!
//! The method is output-error (simulation-error) identification (L. Ljung, "System
//! Identification: Theory for the User", 2nd ed., Prentice Hall, 1999, sections 4.3 and
//! 7.3): each experiment is simulated from its logged duties alone, the motor's shifted by
//! the dead time, in the rig's continuous-time world (`twin::machine::advance`), and the
//! simulated positions are compared with the logged counts; the unknowns minimise the sum
//! of the squared differences, found by Levenberg-Marquardt ([`lm`]) in stages ([`fit`]),
//! the dead time by trying each whole number of periods from 0 to
//! [`fit::MAX_DEAD_TIME`]. Unlike a regression on differenced counts (equation error), the
//! estimate is not biased by the encoders' rounding, which enters only as measurement
//! noise. The held cart's pendulum is the plant itself with the cart's mass taken to a
//! billion kilograms ([`held`]): one set of equations for both experiments.
//!
//! - [`log`]: the logs read and checked.
//! - [`model`]: the experiments as the fit simulates them; [`pieces`], the cart logs' pieces.
//! - [`channel`]: one encoder's residuals in a fitted log, and their figures.
//! - [`misfit`]: whether the fit can be trusted, and the logs of a pole read inverted.
//! - [`synthetic`]: the board's experiments run against a simulated machine.
//! - [`report`]: the estimates printed, the identified rig file, the plots.

pub mod channel;
pub mod fit;
pub mod lm;
pub mod log;
pub mod misfit;
pub mod model;
pub mod pieces;
pub mod report;
mod start;
pub mod synthetic;

use firmware::cartpole::Params;
use firmware::identify::Experiment;
use twin::Machine;
use twin::machine::Uncertainty;
use weights::{Error, Result};

pub use fit::{Estimate, Fit, Trace};
pub use log::Log;

/// The cart's mass, kg, that holds it still: the pole's reaction moves it by less than a
/// nanometre.
pub const HELD_CART_KG: f64 = 1e9;

/// `p` with its cart held: the same plant, its cart's mass [`HELD_CART_KG`], no force on it.
pub fn held(p: &Params) -> Params {
    Params {
        masscart: HELD_CART_KG,
        force_mag: 0.0,
        motor_damping: 0.0,
        cart_friction: 0.0,
        ..*p
    }
}

/// Checks `logs` against `machine` (the rig they were recorded on) and that they hold at
/// least one experiment of each kind.
pub fn check(logs: &[Log], machine: &Machine) -> Result<()> {
    let mut seconds = 0.0;
    for log in logs {
        log.check(machine)?;
        seconds += log.duty.len() as f64 * log.period_s;
        if seconds > log::MAX_TOTAL_SECONDS {
            return Err(Error::Input(format!(
                "{}:{}: expected at most {} s of logs in all, found {seconds:.0} s up to this \
                 log's end",
                log.origin,
                log.line,
                log::MAX_TOTAL_SECONDS
            )));
        }
    }
    for e in [Experiment::Cart, Experiment::Swing] {
        if !logs.iter().any(|l| l.experiment == e) {
            return Err(Error::Input(format!(
                "expected at least one {} log among the logs given, found none (the fit needs \
                 a cart and a swing experiment)",
                e.name()
            )));
        }
    }
    Ok(())
}

/// `machine` with the fit's estimates: the motor, friction, pole length and dead time
/// identified, everything else as measured.
pub fn identified(machine: &Machine, fit: &Fit) -> Machine {
    let mut m = *machine;
    m.rig.params = fit.params;
    m.rig.dead_time = fit.dead_time;
    // Relative, as training widens its ranges; a value at a bound has no interval, and one
    // of zero (no damping) nothing to scale.
    let relative = |i: usize| {
        let e = fit.estimates[i];
        match e.half_width {
            Some(h) if e.value > 0.0 => (h / e.value).min(1.0),
            _ => 0.0,
        }
    };
    m.uncertainty = Uncertainty {
        stall_force: relative(model::FORCE),
        damping: relative(model::DAMPING),
        pole_com: relative(model::LENGTH),
    };
    m
}

/// Checks `logs` and fits `machine`'s unknowns to them ([`fitted`]).
pub fn identify(logs: &[Log], machine: &Machine) -> Result<Fit> {
    check(logs, machine)?;
    fitted(logs, machine)
}

/// Fits `machine`'s unknowns to checked `logs`; refused if a cart log does not fit
/// ([`misfit`]) and fits [`misfit::INVERTED_RATIO`] times better with the pole's counts
/// negated: the pole's encoder is wired the other way round.
pub fn fitted(logs: &[Log], machine: &Machine) -> Result<Fit> {
    let found = fit::fit(logs, machine);
    let cart_misfit = misfit::findings(&found)
        .iter()
        .any(|(t, _)| logs[t.log].experiment == Experiment::Cart);
    if cart_misfit {
        let flipped = fit::fit(&misfit::inverted(logs), machine);
        if misfit::worst_cart(&flipped, logs) * misfit::INVERTED_RATIO
            <= misfit::worst_cart(&found, logs)
        {
            return Err(misfit::inverted_refusal(logs, &found, &flipped));
        }
    }
    Ok(found)
}

#[cfg(test)]
mod tests;
