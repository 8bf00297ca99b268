//! Rig files (`rig.toml`): a real cart-pole described as its builder measures it, read into
//! the [`Machine`] every tool takes with `--rig FILE`, and written back by identification.
//!
//! ```toml
//! cart_mass_kg = 0.6          # a scale
//! pole_mass_kg = 0.08
//! pole_com_m = 0.22           # pivot to the pole's centre of mass (or pole_length_m, uniform)
//! track_half_length_m = 0.4   # centre to end stop
//! end_stop_margin_m = 0.05    # the controller coasts this near a stop
//! period_s = 0.02             # 2 ms to 50 ms
//! dead_time_periods = 1
//!
//! [encoders]
//! cart_counts_per_m = 15000
//! pole_counts_per_rev = 2400
//!
//! [actuator]                  # F = stall_force_n * duty - damping_n_s_per_m * x_dot
//! stall_force_n = 5.0
//! damping_n_s_per_m = 3.0
//!
//! [friction]
//! cart_coulomb = 0.0          # Florian's mu_c
//! pivot_viscous_n_m_s = 0.0   # Florian's mu_p
//! ```
//!
//! Optional: `gravity_m_s2` (9.8, Gymnasium's), `failure_angle_deg` (12), a `[world]` table
//! with `integration = "continuous"` (the default: Runge-Kutta steps of at most `substep_s`,
//! 0.001, and at most the period) or `"euler"` (Gymnasium's one step per period), and an `[observer]` table with the
//! observer's `force_sd` and `accel_sd` (`firmware::estimator::Tuning`), and an
//! `[identified]` table that `host-sim identify` writes: how far each fitted value may be off
//! (`stall_force`, `damping`, `pole_com`: the half-width of its 95% interval relative to the
//! value, [`crate::machine::Uncertainty`]), and, where the fit did not explain the logs,
//! an `[identified.misfit]` table ([`Misfit`], read by [`misfit`]), and a `[startup]`
//! table ([`load_startup`]: how the rig starts from power-on). Every value is checked:
//! a rig that is not physical is refused, naming the field.

use std::path::Path;

use firmware::cartpole::Params;
use firmware::estimator::{Encoders, Tuning};
use firmware::rig::Rig;
use firmware::startup::Startup;
use serde::Deserialize;
use weights::{Error, Result, quote};

use crate::grammar::{
    CART_COUNTS_RANGE, CART_FRICTION_RANGE, PIVOT_FRICTION_RANGE, POLE_COUNTS_RANGE,
};
use crate::machine::{Integration, Machine, Uncertainty};

/// Largest rig file read.
pub const MAX_RIG_BYTES: u64 = 64 << 10;
/// The longest Runge-Kutta step a continuous world takes when a rig file names none, s.
pub const DEFAULT_SUBSTEP_S: f64 = 0.001;
/// The shortest step a rig file may name, s: a hundredth of the default.
const MIN_SUBSTEP_S: f64 = 1e-5;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    cart_mass_kg: f64,
    pole_mass_kg: f64,
    pole_com_m: Option<f64>,
    pole_length_m: Option<f64>,
    track_half_length_m: f64,
    end_stop_margin_m: f64,
    period_s: f64,
    // Counts are read as any TOML value and judged by `Fields::whole`: serde named a Rust
    // type ("invalid type: floating point `1.5`, expected u32") and no range.
    dead_time_periods: toml::Value,
    encoders: FileEncoders,
    actuator: Actuator,
    #[serde(default)]
    friction: Friction,
    gravity_m_s2: Option<f64>,
    failure_angle_deg: Option<f64>,
    #[serde(default)]
    world: World,
    observer: Option<Observer>,
    #[serde(default)]
    identified: Identified,
    #[serde(default)]
    startup: startup::Table,
}

/// The `[identified]` table: each fitted value's 95% half-width, relative to the value.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct Identified {
    #[serde(default)]
    stall_force: f64,
    #[serde(default)]
    damping: f64,
    #[serde(default)]
    pole_com: f64,
    #[serde(default)]
    misfit: Option<Misfit>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileEncoders {
    cart_counts_per_m: toml::Value,
    pole_counts_per_rev: toml::Value,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Actuator {
    stall_force_n: f64,
    damping_n_s_per_m: f64,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct Friction {
    #[serde(default)]
    cart_coulomb: f64,
    #[serde(default)]
    pivot_viscous_n_m_s: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct World {
    #[serde(default = "continuous")]
    integration: String,
    substep_s: Option<f64>,
}

impl Default for World {
    fn default() -> World {
        World {
            integration: continuous(),
            substep_s: None,
        }
    }
}

fn continuous() -> String {
    "continuous".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Observer {
    force_sd: f64,
    // A list, not a pair, so that a third value is refused rather than dropped.
    accel_sd: Vec<f64>,
}

/// The checks of one rig file's fields, each refusal naming the file (`origin`) and the
/// field.
#[derive(Clone, Copy)]
struct Fields<'a> {
    origin: &'a str,
}

impl Fields<'_> {
    /// `value`, if finite and within `[lo, hi]` (open at `lo` where `open_lo`).
    fn check(self, field: &str, value: f64, (lo, hi): (f64, f64), open_lo: bool) -> Result<f64> {
        let ok =
            value.is_finite() && (if open_lo { value > lo } else { value >= lo }) && value <= hi;
        // No measurement is a subnormal number: one is a typing slip, and the physics would
        // lose it, or divide by it.
        if ok && !weights::plain(value) {
            return Err(self.refuse(format!(
                "{field}: expected zero or a normal number (in the board's f32 too), found \
                 {value:e}"
            )));
        }
        if ok {
            return Ok(value);
        }
        let bracket = if open_lo { '(' } else { '[' };
        Err(self.refuse(format!(
            "{field}: expected a number in {bracket}{lo}, {hi}], found {value:?}"
        )))
    }

    /// A count: a TOML integer in `[lo, hi]` (within u32's range), or why not.
    fn whole(self, field: &str, value: &toml::Value, (lo, hi): (f64, f64)) -> Result<u32> {
        match value.as_integer() {
            Some(n) if (lo..=hi).contains(&(n as f64)) => Ok(n as u32),
            _ => Err(self.refuse(format!(
                "{field}: expected a whole number in [{lo}, {hi}], found {}",
                weights::excerpt(&value.to_string())
            ))),
        }
    }

    fn refuse(self, what: String) -> Error {
        Error::Input(format!("{}: {what}", self.origin))
    }

    /// The track's half-length and the end-stop margin, which must leave some track.
    fn track(self, f: &File) -> Result<(f64, f64)> {
        let half = self.check(
            "track_half_length_m",
            f.track_half_length_m,
            (1e-3, 100.0),
            false,
        )?;
        let margin = self.check(
            "end_stop_margin_m",
            f.end_stop_margin_m,
            (0.0, 100.0),
            false,
        )?;
        if margin >= half {
            return Err(self.refuse(format!(
                "end_stop_margin_m: expected less than track_half_length_m ({half}), found \
                 {margin}"
            )));
        }
        Ok((half, margin))
    }

    /// The pivot to the pole's centre of mass, given as such or by a uniform pole's length.
    fn pole_com(self, f: &File) -> Result<f64> {
        match (f.pole_com_m, f.pole_length_m) {
            (Some(com), None) => self.check("pole_com_m", com, (1e-3, 100.0), false),
            (None, Some(len)) => Ok(self.check("pole_length_m", len, (2e-3, 200.0), false)? / 2.0),
            (com, _) => Err(self.refuse(format!(
                "expected one of pole_com_m and pole_length_m, found {}",
                if com.is_some() { "both" } else { "neither" }
            ))),
        }
    }

    /// The physics, on a track of half-length `half`. Each value within what a bench rig
    /// could have: no lighter than a gram (a tenth of one for the pole), no shorter than a
    /// millimetre, a motor of a millinewton at least, gravity and the failure angle a tenth at
    /// least; below those a value is a slip (`1e-300` for `0.3`), and the physics divides by it.
    fn params(self, f: &File, half: f64) -> Result<Params> {
        let length = self.pole_com(f)?;
        let c =
            |field: &str, v: f64, range: (f64, f64), open: bool| self.check(field, v, range, open);
        Ok(Params {
            gravity: c(
                "gravity_m_s2",
                f.gravity_m_s2.unwrap_or(9.8),
                (0.1, 100.0),
                false,
            )?,
            masscart: c("cart_mass_kg", f.cart_mass_kg, (1e-3, 1000.0), false)?,
            masspole: c("pole_mass_kg", f.pole_mass_kg, (1e-4, 1000.0), false)?,
            length,
            force_mag: c(
                "actuator.stall_force_n",
                f.actuator.stall_force_n,
                (1e-3, 1e4),
                false,
            )?,
            motor_damping: c(
                "actuator.damping_n_s_per_m",
                f.actuator.damping_n_s_per_m,
                (0.0, 1e4),
                false,
            )?,
            tau: c("period_s", f.period_s, (0.002, 0.05), false)?,
            theta_threshold_radians: radians(c(
                "failure_angle_deg",
                f.failure_angle_deg.unwrap_or(12.0),
                (0.1, 90.0),
                false,
            )?),
            x_threshold: half,
            cart_friction: c(
                "friction.cart_coulomb",
                f.friction.cart_coulomb,
                CART_FRICTION_RANGE,
                false,
            )?,
            pole_friction: c(
                "friction.pivot_viscous_n_m_s",
                f.friction.pivot_viscous_n_m_s,
                PIVOT_FRICTION_RANGE,
                false,
            )?,
        })
    }

    /// The encoders, within the bounds a scenario's encoders have.
    fn encoders(self, e: &FileEncoders) -> Result<Encoders> {
        Ok(Encoders {
            cart_counts_per_m: self.whole(
                "encoders.cart_counts_per_m",
                &e.cart_counts_per_m,
                CART_COUNTS_RANGE,
            )?,
            pole_counts_per_rev: self.whole(
                "encoders.pole_counts_per_rev",
                &e.pole_counts_per_rev,
                POLE_COUNTS_RANGE,
            )?,
        })
    }

    /// The periods of dead time, at most what the predictor bridges.
    fn dead_time(self, periods: &toml::Value) -> Result<u32> {
        let max = f64::from(crate::scenario::MAX_DELAY);
        self.whole("dead_time_periods", periods, (0.0, max))
    }

    /// The observer's tuning, the default where the file has none.
    fn tuning(self, o: Option<&Observer>) -> Result<Tuning> {
        let Some(o) = o else {
            return Ok(Tuning::DEFAULT);
        };
        // A thousandth of a newton or of a metre per second squared at least: below that the
        // observer would trust its model over every reading, and a value is a slip.
        let sd = |field: &str, v: f64| self.check(field, v, (1e-3, 1e4), false);
        if o.accel_sd.len() != 2 {
            return Err(self.refuse(format!(
                "observer.accel_sd: expected 2 numbers (the cart's and the pole's), found {}",
                o.accel_sd.len()
            )));
        }
        Ok(Tuning {
            force_sd: sd("observer.force_sd", o.force_sd)?,
            accel_sd: [
                sd("observer.accel_sd[0]", o.accel_sd[0])?,
                sd("observer.accel_sd[1]", o.accel_sd[1])?,
            ],
        })
    }

    /// The `[identified]` half-widths: relative, so a value off by more than itself (1) is
    /// not an identification. And its misfit's, if any, which widens each to at least
    /// [`MISFIT_HALF_WIDTH`].
    fn uncertainty(self, i: &Identified) -> Result<Uncertainty> {
        let least = match &i.misfit {
            Some(m) => {
                m.check(self)?;
                MISFIT_HALF_WIDTH
            }
            None => 0.0,
        };
        let c = |field: &str, v: f64| {
            let v = self.check(&format!("identified.{field}"), v, (0.0, 1.0), false)?;
            Ok::<f64, weights::Error>(v.max(least))
        };
        Ok(Uncertainty {
            stall_force: c("stall_force", i.stall_force)?,
            damping: c("damping", i.damping)?,
            pole_com: c("pole_com", i.pole_com)?,
        })
    }

    /// How the world advances over periods of `tau`.
    fn integration(self, w: &World, tau: f64) -> Result<Integration> {
        match (w.integration.as_str(), w.substep_s) {
            ("euler", None) => Ok(Integration::Euler),
            ("euler", Some(step)) => Err(self.refuse(format!(
                "world.substep_s: expected none with integration = \"euler\" (one step a \
                 period), found {step}"
            ))),
            // At most the period: a longer step is cut to it, so 0.05 built the same world
            // as 0.02 on a 0.02 s period.
            ("continuous", step) => Ok(Integration::rk4(
                tau,
                self.check(
                    "world.substep_s (at most period_s)",
                    step.unwrap_or(DEFAULT_SUBSTEP_S),
                    (MIN_SUBSTEP_S, tau),
                    false,
                )?,
            )),
            (other, _) => Err(self.refuse(format!(
                "world.integration: expected \"continuous\" or \"euler\", found {}",
                quote(other)
            ))),
        }
    }
}

/// Reads the rig file at `path` (see [the module](self)).
pub fn load(path: &Path) -> Result<Machine> {
    load_startup(path).map(|(machine, _)| machine)
}

/// Parses a rig file's text; `origin` names it in errors.
pub fn parse(text: &str, origin: &str) -> Result<Machine> {
    parse_startup(text, origin).map(|(machine, _)| machine)
}

/// Reads the rig file at `path` with its start-up: its `[startup]` table, the rest suggested
/// from its physics ([`startup`]).
pub fn load_startup(path: &Path) -> Result<(Machine, Startup)> {
    let (text, origin) = read_text(path)?;
    parse_startup(&text, &origin)
}

/// The text of the rig file at `path` (any path: its name need not be text, its contents
/// must be), and how refusals of it name it, for [`parse`].
pub fn read_text(path: &Path) -> Result<(String, String)> {
    let bytes = weights::files::read_capped(path, MAX_RIG_BYTES)?;
    let origin = format!("rig {}", weights::shown(path));
    let text = String::from_utf8(bytes)
        .map_err(|_| Error::Input(format!("{origin}: expected UTF-8 text")))?;
    Ok((text, origin))
}

/// [`parse`] with the start-up, as [`load_startup`] reads it.
pub fn parse_startup(text: &str, origin: &str) -> Result<(Machine, Startup)> {
    let f: File = from_toml(text, origin)?;
    let fields = Fields { origin };
    let machine = machine(&f, fields)?;
    let startup = fields.startup(&f.startup, &machine.rig)?;
    Ok((machine, startup))
}

/// A rig file's text as TOML, refused past a rig file's size wherever the text comes from
/// (a file, a policy file's metadata, a training configuration's `rig`), so that none costs
/// more than a rig file may, and with a number that reads as zero (`1e-400`).
fn from_toml<T: serde::de::DeserializeOwned>(text: &str, origin: &str) -> Result<T> {
    if text.len() as u64 > MAX_RIG_BYTES {
        return Err(Error::Input(format!(
            "{origin}: expected a rig file's text of at most {MAX_RIG_BYTES} bytes, found {}",
            text.len()
        )));
    }
    if let Some(why) = weights::hidden_zero(text) {
        return Err(Error::Input(format!("{origin}: {why}")));
    }
    toml::from_str(text).map_err(|e| {
        let why = weights::located(text, e.span(), e.message());
        Error::Input(format!("{origin}: {why}"))
    })
}

/// The machine file `f` describes.
fn machine(f: &File, fields: Fields<'_>) -> Result<Machine> {
    let (half, margin) = fields.track(f)?;
    let params = fields.params(f, half)?;
    let rig = Rig {
        params,
        encoders: fields.encoders(&f.encoders)?,
        dead_time: fields.dead_time(&f.dead_time_periods)?,
        end_stop_margin: margin,
        tuning: fields.tuning(f.observer.as_ref())?,
    };
    // The firmware's own checks, and the observer's gain, which overflows for some
    // combinations of values each within its range.
    rig.check()
        .and_then(|r| r.observer())
        .map_err(|e| fields.refuse(format!("the board refuses it: {e}")))?;
    let integration = fields.integration(&f.world, params.tau)?;
    crate::machine::check_integrable(&params, integration).map_err(|e| fields.refuse(e))?;
    let uncertainty = fields.uncertainty(&f.identified)?;
    Ok(Machine {
        rig,
        integration,
        uncertainty,
    })
}

mod chosen;
pub use chosen::{METADATA_KEY, OtherRig, choose, choose_warned, recorded, warn};
mod misfit;
mod startup;
pub use startup::given_startup;
mod write;
pub use misfit::{MISFIT_HALF_WIDTH, Misfit, misfit};
use write::radians;
pub use write::to_toml;

#[cfg(test)]
mod tests;
