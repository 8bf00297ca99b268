//! The `[identified.misfit]` table of a rig file.

use serde::Deserialize;
use weights::Result;

use super::{Fields, File, parse};

/// The least relative half-width of each identified value (the motor's stall force and
/// damping, the pole's centre of mass) of a rig whose fit did not explain its logs. A
/// misfit's estimates are biased by what the model leaves out, and its intervals, which
/// assume independent residuals, are far too narrow; so the training for such a rig draws
/// those values over +-50%, twice the deploy recipe's own +-25% (`docs/RIGS.md`).
pub const MISFIT_HALF_WIDTH: f64 = 0.5;

/// The `[identified.misfit]` table `host-sim identify` writes when its fit does not explain
/// the logs (`host_sim::identify::misfit`): the rig's model is then not the machine, and
/// its values and intervals are not to be trusted. Absent, the fit held.
#[derive(Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Misfit {
    /// The largest RMS residual of the cart encoder's counts in a log, counts.
    pub cart_rms_counts: f64,
    /// The largest RMS residual of the pole encoder's counts in a log, counts.
    pub pole_rms_counts: f64,
    /// The largest lag-1 autocorrelation of the residuals of an encoder that did not fit.
    pub autocorrelation: f64,
}

impl Misfit {
    /// The table as a rig file holds it, to follow the rest of the file.
    pub fn to_toml(&self) -> String {
        format!(
            "\n[identified.misfit]\ncart_rms_counts = {:?}\npole_rms_counts = {:?}\n\
             autocorrelation = {:?}\n",
            self.cart_rms_counts, self.pole_rms_counts, self.autocorrelation
        )
    }

    /// Refuses values no fit leaves, naming the field.
    pub(super) fn check(&self, fields: Fields) -> Result<()> {
        let counts = (0.0, 1e10);
        for (name, value, range) in [
            ("cart_rms_counts", self.cart_rms_counts, counts),
            ("pole_rms_counts", self.pole_rms_counts, counts),
            ("autocorrelation", self.autocorrelation, (-1.0, 1.0)),
        ] {
            fields.check(&format!("identified.misfit.{name}"), value, range, false)?;
        }
        Ok(())
    }
}

/// The `[identified.misfit]` table of the rig file `text` (checked whole as [`parse`]
/// checks it), if it has one; `origin` names it in errors.
pub fn misfit(text: &str, origin: &str) -> Result<Option<Misfit>> {
    parse(text, origin)?;
    let f: File = super::from_toml(text, origin)?;
    Ok(f.identified.misfit)
}
