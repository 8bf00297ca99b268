//! What the learner is rewarded with. The task's reward is Gymnasium's, +1 for every step
//! (the terminating one included); returns, solve episodes and success are always counted in
//! it. The *learning* reward may be shaped, and only the learner sees it.
//!
//! A spec is parts joined by `+`, applied in this order:
//!
//! - `env`: +1 per step (the default, and the base unless `morvan` is given);
//! - `morvan`: Morvan Zhou's tutorial reward from the next state,
//!   `(x_max - |x|) / x_max - 0.8 + (theta_max - |theta|) / theta_max - 0.5`;
//! - `upright=W`: minus `W * (theta / theta_max)^2`, for holding the pole straighter;
//! - `centre=W`: minus `W * (x / x_max)^2`, for keeping the cart near the middle;
//! - `effort=W`: minus `W * u^2` for the period's duty `u` (a fraction of the full push):
//!   the motor's mean voltage squared, so small levels are preferred where they hold;
//! - `smooth=W`: minus `W * |u - u_prev|`, the change from the previous period's duty: a
//!   reversal at full duty costs `2 W`, the gearbox's full-torque jolt;
//! - `heat=W`: minus `W * i^2`, the motor's current as a share of its stall current
//!   (`Params::current`, at the cart's speed as the period starts): its I^2 R heating,
//!   which back-EMF lowers as the cart moves with the push;
//! - `fail-penalty=V`: the terminating step's reward is V instead;
//! - `scale=K`: everything times K (minimalRL's 1/100 is `scale=0.01`).

use firmware::cartpole::{Params, State};

/// The weights of an evaluation's cost's terms ([`crate::train::EvalResult::cost`]): the
/// pole's lean, the cart's distance, the duty's square and its change between periods. A
/// rig's learning reward sets them (`Reward::prices`), so that the selection judges
/// snapshots at the learner's prices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prices {
    pub lean: f64,
    pub distance: f64,
    pub duty: f64,
    pub change: f64,
}

impl Prices {
    /// Lean, distance and duty alike, changes free: the shipped recipe's selection.
    pub const PLAIN: Prices = Prices {
        lean: 1.0,
        distance: 1.0,
        duty: 1.0,
        change: 0.0,
    };
}

/// What the motor was told in a step, for the effort parts: the period's duty, the previous
/// period's (0 before the first) and the cart's speed as the period started.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Drive {
    /// This period's duty, a fraction of the full push.
    pub duty: f64,
    /// The previous period's duty.
    pub previous: f64,
    /// The cart's speed as the period started, m/s.
    pub x_dot: f64,
}

/// A parsed learning reward; see [the module](self).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reward {
    morvan: bool,
    upright: f64,
    centre: f64,
    effort: f64,
    smooth: f64,
    heat: f64,
    fail: Option<f64>,
    scale: f64,
}

impl Reward {
    /// Parses a spec; `""` is `env`.
    pub fn parse(spec: &str) -> Result<Reward, String> {
        let mut r = Reward {
            morvan: false,
            upright: 0.0,
            centre: 0.0,
            effort: 0.0,
            smooth: 0.0,
            heat: 0.0,
            fail: None,
            scale: 1.0,
        };
        if spec.is_empty() {
            return Ok(r);
        }
        let shown = weights::quote(spec);
        let mut seen = Vec::new();
        for part in spec.split('+') {
            let (key, value) = match part.split_once('=') {
                Some((k, v)) => (k, Some(v)),
                None => (part, None),
            };
            // A part given again would replace the first, which a reader of the spec cannot
            // tell; a weight of 0 or a scale of 1 changes nothing.
            if seen.contains(&key) {
                return Err(format!(
                    "reward {shown}: expected each part once, found {} again",
                    weights::quote(key)
                ));
            }
            seen.push(key);
            // The value a part changes nothing at; fail-penalty's depends on the rest.
            let idle = match key {
                "scale" => Some(1.0),
                "fail-penalty" => None,
                _ => Some(0.0),
            };
            let number = || -> Result<f64, String> {
                value
                    .and_then(|v| v.parse::<f64>().ok())
                    .filter(|v| v.is_finite() && v.abs() <= 1e6 && weights::plain(*v))
                    .filter(|v| idle != Some(*v))
                    .ok_or_else(|| {
                        let other = idle
                            .map(|i| format!(", other than {i} (which changes nothing)"))
                            .unwrap_or_default();
                        format!(
                            "reward {shown}: {key} needs a number in [-1e6, 1e6], zero or \
                             normal{other}, e.g. {key}=2"
                        )
                    })
            };
            match key {
                "env" if value.is_none() => {}
                "morvan" if value.is_none() => r.morvan = true,
                "upright" => r.upright = number()?,
                "centre" => r.centre = number()?,
                "effort" => r.effort = number()?,
                "smooth" => r.smooth = number()?,
                "heat" => r.heat = number()?,
                "fail-penalty" => r.fail = Some(number()?),
                "scale" => r.scale = number()?,
                _ => {
                    return Err(format!(
                        "reward {shown}: unknown part {} (expected env, morvan, upright=W, \
                         centre=W, effort=W, smooth=W, heat=W, fail-penalty=V, scale=K)",
                        weights::quote(part)
                    ));
                }
            }
        }
        r.check_whole(&shown)?;
        Ok(r)
    }

    /// Refuses what the parts (`shown`) make together of nothing: every reward 0, or a
    /// fail penalty of 1 where the terminating step's reward is 1 already.
    fn check_whole(&self, shown: &str) -> Result<(), String> {
        if self.scale == 0.0 {
            return Err(format!(
                "reward {shown}: scale=0 makes every reward 0, leaving nothing to learn; \
                 expected a scale other than 0 and 1"
            ));
        }
        // Without morvan or a weight, every step's reward is 1, the terminating one's too.
        let weights = [
            self.upright,
            self.centre,
            self.effort,
            self.smooth,
            self.heat,
        ];
        let shaped = self.morvan || weights != [0.0; 5];
        if self.fail == Some(1.0) && !shaped {
            return Err(format!(
                "reward {shown}: fail-penalty=1 changes nothing where no other part shapes the \
                 reward (the terminating step's is 1 already); expected another value"
            ));
        }
        Ok(())
    }

    /// Whether the learner sees the task's own reward.
    pub fn is_env(&self) -> bool {
        *self == Reward::parse("").expect("the empty spec parses")
    }

    /// The prices a selection judges snapshots at: a reward that prices the motor's effort
    /// (`effort`, `smooth` or `heat`) judges by its own weights of the lean, the distance,
    /// the duty and its change, so the snapshot shipped is the one the learner was asked
    /// for; any other keeps the plain prices (the shipped recipe's, which keeps its bits).
    pub fn prices(&self) -> Prices {
        if self.effort == 0.0 && self.smooth == 0.0 && self.heat == 0.0 {
            return Prices::PLAIN;
        }
        Prices {
            lean: self.upright,
            distance: self.centre,
            duty: self.effort,
            change: self.smooth,
        }
    }

    /// The learning reward of a step that drove the motor as `drive` and led to `next`
    /// (terminated or not), for a plant of physics `p`.
    pub fn of(&self, p: &Params, drive: &Drive, next: &State, terminated: bool) -> f32 {
        if self.is_env() {
            return 1.0;
        }
        let (xr, tr) = (
            next.x / p.x_threshold,
            next.theta / p.theta_threshold_radians,
        );
        let mut r = if self.morvan {
            (1.0 - xr.abs() - 0.8) + (1.0 - tr.abs() - 0.5)
        } else {
            1.0
        };
        r -= self.upright * tr * tr + self.centre * xr * xr;
        let current = p.current(drive.duty, drive.x_dot);
        r -= self.effort * drive.duty * drive.duty
            + self.smooth * (drive.duty - drive.previous).abs()
            + self.heat * current * current;
        if terminated && let Some(v) = self.fail {
            r = v;
        }
        (r * self.scale) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_part_does_what_it_says() {
        let p = Params::default();
        let s = State {
            x: 1.2,
            theta: p.theta_threshold_radians / 2.0,
            ..State::default()
        };
        let still = Drive::default();
        let of = |spec: &str, term| Reward::parse(spec).unwrap().of(&p, &still, &s, term);
        assert_eq!(of("", false), 1.0);
        assert_eq!(of("env", true), 1.0);
        // Morvan: (1 - 0.5 - 0.8) + (1 - 0.5 - 0.5) = -0.3.
        assert!((of("morvan", false) - -0.3).abs() < 1e-6);
        // 1 - 2 * 0.25 - 4 * 0.25 = -0.5.
        assert!((of("upright=2+centre=4", false) - -0.5).abs() < 1e-6);
        assert_eq!(of("fail-penalty=-100", true), -100.0);
        assert_eq!(of("fail-penalty=-100", false), 1.0);
        assert_eq!(of("scale=0.01+fail-penalty=-10", true), -0.1);
        assert!(Reward::parse("env").unwrap().is_env());
        assert!(!Reward::parse("effort=0.1").unwrap().is_env());

        assert!(!Reward::parse("scale=1.5").unwrap().is_env());
    }

    #[test]
    fn a_reward_that_prices_the_motor_is_the_selections_price_list() {
        let prices = |spec: &str| Reward::parse(spec).unwrap().prices();
        assert_eq!(prices(""), Prices::PLAIN);
        assert_eq!(prices("upright=20+centre=5"), Prices::PLAIN);
        let rig = Prices {
            lean: 20.0,
            distance: 5.0,
            duty: 1.0,
            change: 4.0,
        };
        assert_eq!(prices("upright=20+centre=5+effort=1+smooth=4"), rig);
        // Heat alone prices the motor too, and the duty's square is then free.
        let heat = prices("upright=3+heat=1");
        assert_eq!((heat.lean, heat.duty, heat.change), (3.0, 0.0, 0.0));
    }

    #[test]
    fn the_effort_parts_price_the_duty_its_change_and_the_current() {
        let p = Params {
            motor_damping: 2.0,
            ..Params::default()
        };
        let s = State::default();
        // A reversal from full left to half right while the cart runs left at 1 m/s.
        let drive = Drive {
            duty: 0.5,
            previous: -1.0,
            x_dot: -1.0,
        };
        let of = |spec: &str| Reward::parse(spec).unwrap().of(&p, &drive, &s, false);
        // 1 - 4 * 0.25
        assert!((of("effort=4") - 0.0).abs() < 1e-6);
        // 1 - 2 * 1.5
        assert!((of("smooth=2") - -2.0).abs() < 1e-6);
        // Current 0.5 - 2 * (-1) / 10 = 0.7: 1 - 10 * 0.49.
        assert!((of("heat=10") - -3.9).abs() < 1e-5);
        // Parts add: 1 - 1 - 3 - 4.9.
        assert!((of("effort=4+smooth=2+heat=10") - -7.9).abs() < 1e-5);
    }

    #[test]
    fn bad_specs_say_why() {
        for (spec, want) in [
            ("bonus", "unknown part \"bonus\""),
            ("scale", "scale needs a number"),
            ("upright=nan", "upright needs a number"),
            ("morvan=2", "unknown part"),
            // Given again, the last replaced the first; at a value that changes nothing, or a
            // subnormal, it was a slip taken without a word.
            (
                "upright=1+upright=2",
                "expected each part once, found \"upright\" again",
            ),
            ("env+env", "found \"env\" again"),
            ("smooth=0", "other than 0 (which changes nothing)"),
            ("scale=1", "other than 1"),
            // Every reward 0, the failing step's too: nothing to learn, without a word.
            ("env+scale=0", "scale=0 makes every reward 0"),
            ("upright=1+scale=-0", "scale=0 makes every reward 0"),
            ("fail-penalty=5e-324", "zero or normal, e.g."),
            ("upright=1e-40", "zero or normal"),
            // Every step's reward is 1 here, the terminating one's too.
            ("fail-penalty=1", "fail-penalty=1 changes nothing"),
        ] {
            let e = Reward::parse(spec).unwrap_err();
            assert!(e.contains(want), "{spec}: {e}");
        }
        // 0 takes the terminating step's 1 away; 1 does change a shaped reward's.
        for spec in [
            "fail-penalty=0",
            "upright=1+fail-penalty=1",
            "morvan+fail-penalty=1",
        ] {
            Reward::parse(spec).unwrap();
        }
    }
}
