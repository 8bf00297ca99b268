//! The `[startup]` table: how a rig starts from power-on (`firmware::startup`), each value
//! optional, the rest [`Startup::suggested`] from the rig's physics.
//!
//! ```toml
//! [startup]
//! zero_window_s = 0.56          # a pole at rest is watched for two windows of this
//! catch_angle_deg = 8.4         # the catch region: angle from upright
//! catch_rate_deg_s = 83         # and the pole's rate
//! catch_periods = 3             # periods inside before the balance controller drives
//! release_angle_deg = 11.4      # past this the motor turns off; at most failure_angle_deg
//! swing_up = true               # or wait for a hand to lift the pole
//! swing_energy_gain_s = 3.0     # the swing-up's gains (firmware::startup::Swing)
//! swing_max_accel_m_s2 = 3.5
//! swing_centring_per_s2 = 6.0
//! swing_centring_per_s = 4.0
//! swing_overshoot = 0.015
//! trim_deg_per_m_s = 0.69       # the zero refined while balancing (integral action); 0: off
//! trim_max_deg = 2.0            # by at most this (above 0; none with the trim off)
//! homing = false                # or drive the cart to the -x end stop, then to the centre
//! homing_duty = 0.3             # at most this duty (firmware::startup::Homing)
//! homing_stall_s = 0.25         # still this long: at the stop, or arrived
//! ```

use std::path::Path;

use firmware::rig::Rig;
use firmware::startup::{Homing, MAX_CATCH_PERIODS, Startup, Swing, periods};
use serde::{Deserialize, Serialize};
use weights::Result;

use super::{Fields, radians};

#[derive(Deserialize, Serialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct Table {
    #[serde(skip_serializing_if = "Option::is_none")]
    zero_window_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    catch_angle_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    catch_rate_deg_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    catch_periods: Option<toml::Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    release_angle_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    swing_up: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    swing_energy_gain_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    swing_max_accel_m_s2: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    swing_centring_per_s2: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    swing_centring_per_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    swing_overshoot: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    trim_deg_per_m_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    trim_max_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    homing: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    homing_duty: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    homing_stall_s: Option<f64>,
}

/// The `[startup]` table of the rig file at `path`, as written to carry it into a rig file
/// made from this one (`host-sim identify`): only the values it gives; empty without any.
pub fn given_startup(path: &Path) -> Result<String> {
    let (text, origin) = super::read_text(path)?;
    let f: super::File = super::from_toml(&text, &origin)?;
    let fields = Fields { origin: &origin };
    let machine = super::machine(&f, fields)?;
    // Checked as a board checks it, so that only a start-up a board takes is carried.
    fields.startup(&f.startup, &machine.rig)?;
    f.startup.to_toml()
}

impl Table {
    /// The table as a rig file's `[startup]`, only the values it was given (the rest are
    /// suggested from a rig's physics, which a rig written from another may not share);
    /// empty when it was given none.
    pub(super) fn to_toml(&self) -> Result<String> {
        #[derive(Serialize)]
        struct Wrapped<'a> {
            startup: &'a Table,
        }
        let text = toml::to_string(&Wrapped { startup: self })
            .map_err(|e| weights::Error::Input(format!("writing [startup]: {e}")))?;
        Ok(if text.trim() == "[startup]" {
            String::new()
        } else {
            format!("\n{text}")
        })
    }
}

impl Fields<'_> {
    /// The start-up `t` gives for `rig`, each value checked and the whole as the board
    /// checks it (the catch region inside the release angle, the release angle at most the
    /// failure angle).
    pub(super) fn startup(self, t: &Table, rig: &Rig) -> Result<Startup> {
        let refused = |e| self.refuse(format!("the board refuses its start-up: {e}"));
        let mut s = Startup::suggested(rig).map_err(refused)?;
        let value = |field: &str, v: Option<f64>, hi: f64| self.start_value(field, v, hi);
        let narrow = |field: &str, v: f64| self.narrow(field, v);
        if let Some(w) = value("zero_window_s", t.zero_window_s, 60.0)? {
            s.zero_periods = periods(w, rig.params.tau);
        }
        if let Some(a) = value("catch_angle_deg", t.catch_angle_deg, 90.0)? {
            s.catch_angle = narrow("catch_angle_deg", radians(a))?;
        }
        if let Some(r) = value("catch_rate_deg_s", t.catch_rate_deg_s, 1e4)? {
            s.catch_rate = narrow("catch_rate_deg_s", radians(r))?;
        }
        if let Some(v) = &t.catch_periods {
            let n = v.as_integer().and_then(|n| u16::try_from(n).ok());
            s.catch_periods = n
                .filter(|n| (1..=MAX_CATCH_PERIODS).contains(n))
                .ok_or_else(|| {
                    self.refuse(format!(
                    "startup.catch_periods: expected 1 to {MAX_CATCH_PERIODS} periods, found {}",
                    weights::excerpt(&v.to_string())
                ))
                })?;
        }
        if let Some(a) = value("release_angle_deg", t.release_angle_deg, 90.0)? {
            s.release_angle = narrow("release_angle_deg", radians(a))?;
        }
        self.trim(t, &mut s)?;
        let tuned = t.homing_duty.is_some() || t.homing_stall_s.is_some();
        if tuned && t.homing != Some(true) {
            return Err(self.refuse(
                "startup.homing_duty, startup.homing_stall_s: given, but homing is not true".into(),
            ));
        }
        if t.homing == Some(true) {
            let mut h = Homing::suggested(rig.params.tau);
            if let Some(d) = value("homing_duty", t.homing_duty, 1.0)? {
                h.duty = narrow("homing_duty", d)?;
            }
            if let Some(w) = value("homing_stall_s", t.homing_stall_s, 60.0)? {
                h.stall_periods = periods(w, rig.params.tau);
            }
            s.homing = Some(h);
        }
        s.swing = self.swing(t, s.swing)?;
        s.check(rig).map_err(refused)
    }

    /// The trim `t` asks for, into `s`. A rate of zero turns it off, and a limit is then
    /// refused, as are swing-up values without a swing-up: a trim that never runs reads
    /// none. A limit of zero is refused too: it would leave the rate read by nothing.
    fn trim(self, t: &Table, s: &mut Startup) -> Result<()> {
        if let Some(r) = t.trim_deg_per_m_s {
            let r = self.check("startup.trim_deg_per_m_s", r, (0.0, 90.0), false)?;
            s.trim_rate = self.narrow("trim_deg_per_m_s", radians(r))?;
        }
        if let Some(m) = self.start_value("trim_max_deg", t.trim_max_deg, 90.0)? {
            if s.trim_rate == 0.0 {
                return Err(self.refuse(
                    "startup.trim_max_deg: given, but the trim is off (trim_deg_per_m_s = 0)"
                        .into(),
                ));
            }
            s.trim_max = self.narrow("trim_max_deg", radians(m))?;
        }
        Ok(())
    }

    /// `startup.FIELD`'s value `v`, if given: in (0, `hi`].
    fn start_value(self, field: &str, v: Option<f64>, hi: f64) -> Result<Option<f64>> {
        v.map(|v| self.check(&format!("startup.{field}"), v, (0.0, hi), true))
            .transpose()
    }

    /// `v` as the board holds it, in f32: a value that narrows to a subnormal there (`1e-40`)
    /// is as much a slip as one in f64.
    fn narrow(self, field: &str, v: f64) -> Result<f32> {
        if weights::plain(v) {
            return Ok(v as f32);
        }
        Err(self.refuse(format!(
            "startup.{field}: expected zero or a number the board's f32 holds as a normal \
             one, found {v:e}"
        )))
    }

    /// The swing-up `t` asks for, from the one the rig's physics suggests (`None` where its
    /// motor cannot swing the pole up).
    fn swing(self, t: &Table, suggested: Option<Swing>) -> Result<Option<Swing>> {
        let value = |field: &str, v: Option<f64>, hi: f64| self.start_value(field, v, hi);
        let narrow = |field: &str, v: f64| self.narrow(field, v);
        let swing_values = [
            ("swing_energy_gain_s", t.swing_energy_gain_s, 1e3),
            ("swing_max_accel_m_s2", t.swing_max_accel_m_s2, 1e3),
            ("swing_centring_per_s2", t.swing_centring_per_s2, 1e3),
            ("swing_centring_per_s", t.swing_centring_per_s, 1e3),
            ("swing_overshoot", t.swing_overshoot, 2.0),
        ];
        Ok(match (t.swing_up, suggested) {
            (Some(false), _) | (_, None) => {
                // As homing's: a value of a swing-up that will not run is a slip, not a
                // setting to drop without a word.
                let given: Vec<&str> = swing_values
                    .iter()
                    .filter(|v| v.1.is_some())
                    .map(|v| v.0)
                    .collect();
                if !given.is_empty() {
                    return Err(self.refuse(format!(
                        "startup.{}: given, but no swing-up runs (swing_up is false)",
                        given.join(", startup.")
                    )));
                }
                None
            }
            (_, Some(mut w)) => {
                let mut set = [None; 5];
                for (slot, (field, v, hi)) in set.iter_mut().zip(swing_values) {
                    if let Some(v) = value(field, v, hi)? {
                        *slot = Some(narrow(field, v)?);
                    }
                }
                let [gain, accel, spring, damper, over] = set;
                w.energy_gain = gain.unwrap_or(w.energy_gain);
                w.max_accel = accel.unwrap_or(w.max_accel);
                w.centring[0] = spring.unwrap_or(w.centring[0]);
                w.centring[1] = damper.unwrap_or(w.centring[1]);
                w.overshoot = over.unwrap_or(w.overshoot);
                Some(w)
            }
        })
    }
}

#[cfg(test)]
mod tests;
