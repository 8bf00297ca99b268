//! A scenario: the world one episode runs in, as a spec a person can type (`noise+delay=2`,
//! `length=0.8+encoder=1024`), and the named sets of them the tables use.

use firmware::cartpole::Params;
use firmware::controller::predict::MAX_PREDICT;
use firmware::estimator::Encoders;

/// Sensor noise standard deviations of the `noise` part, per channel: 1 cm, 5 cm/s,
/// 0.3 degrees, 0.05 rad/s; a cheap encoder and a finite-difference velocity.
pub const NOISE_STD: [f64; 4] = [0.01, 0.05, 0.005, 0.05];

/// The range a physical quantity of a scenario may take, as a factor on its nominal value:
/// wide enough for any robustness study, narrow enough that the plant's arithmetic stays
/// finite.
pub const FACTOR_RANGE: (f64, f64) = (1e-3, 1e3);

/// Longest scenario spec accepted.
pub const MAX_SPEC_BYTES: usize = 1000;

/// Most periods of actuator dead time a scenario can have: the longest line the firmware's
/// predictor and observer keep.
pub const MAX_DELAY: u32 = MAX_PREDICT as u32;

/// How an `encoder` scenario's board turns counts into the state (`firmware::estimator`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Estimation {
    /// The model-based observer, told the commands sent and the dead time (the default).
    Observer,
    /// The model-free alpha-beta filter with this discount (`encoder=N/M/D`).
    AlphaBeta(f32),
}

/// A disturbance: an extra force of `impulse / tau` for one period, every `every` periods,
/// towards a random side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    /// Size of each push, N*s.
    pub impulse: f64,
    /// Periods between pushes.
    pub every: u32,
}

/// The world one episode runs in: the plant's physics and what goes wrong around it.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Row label, the spec it was parsed from.
    pub name: String,
    /// The plant's physics, friction included (the controllers are not told).
    pub params: Params,
    /// Gaussian sensor noise, standard deviation per channel (zero: none). With encoders,
    /// the position channels' noise is added before quantisation and the velocity channels'
    /// is unused (velocities are estimated).
    pub noise_std: [f64; 4],
    /// Encoders instead of a state sensor: positions quantised to counts, velocities from
    /// `firmware::estimator`, as a board must do it.
    pub encoders: Option<Encoders>,
    /// Which estimator reads the encoders.
    pub estimation: Estimation,
    /// Periods of actuator dead time: the force in a period is the command of `delay`
    /// periods before (none before the first command).
    pub delay: u32,
    /// Push disturbances.
    pub push: Option<Push>,
}

impl Scenario {
    /// The nominal plant, exact sensors, no dead time, no pushes.
    pub fn nominal() -> Scenario {
        Scenario {
            name: "nominal".into(),
            params: Params::default(),
            noise_std: [0.0; 4],
            encoders: None,
            estimation: Estimation::Observer,
            delay: 0,
            push: None,
        }
    }

    /// Parses a spec: `nominal`, or parts joined by `+`, each one of
    ///
    /// - `noise[=SCALE]`: Gaussian sensor noise, SCALE times [`NOISE_STD`];
    /// - `delay[=N]`: N periods of actuator dead time (1 without `=N`), at most [`MAX_DELAY`];
    /// - `force=F`, `length=F`, `polemass=F`, `cartmass=F`: F times the nominal value;
    /// - `friction=C[/P]`: Coulomb friction coefficient C between cart and track, viscous
    ///   friction P (N m s/rad, default 0) at the pivot (Florian's model, `firmware::cartpole`);
    /// - `encoder=N[/M[/D]]`: encoders with N counts per revolution on the pole and M counts
    ///   per metre on the cart (default 5N: the same encoder on a 20 cm drive pulley), read
    ///   through the observer, or with D through the alpha-beta filter of discount D (0 is the
    ///   plain backward difference);
    /// - `push[=IMPULSE[/EVERY]]`: pushes of IMPULSE N s (default 0.5) every EVERY periods
    ///   (default 100).
    ///
    /// Factors of one quantity multiply; every quantity must end within [`FACTOR_RANGE`] of
    /// nominal. Numbers lie in `[0, 1000]`.
    pub fn parse(spec: &str) -> Result<Scenario, String> {
        let shown = weights::quote(spec);
        if spec.len() > MAX_SPEC_BYTES {
            return Err(format!(
                "scenario: expected at most {MAX_SPEC_BYTES} bytes, found {} ({shown})",
                spec.len()
            ));
        }
        let mut s = Scenario::nominal();
        s.name = spec.to_string();
        if spec == "nominal" {
            return Ok(s);
        }
        for part in spec.split('+') {
            let (key, value) = match part.split_once('=') {
                Some((k, v)) => (k, Some(v)),
                None => (part, None),
            };
            let number = |v: &str| -> Result<f64, String> {
                match v.parse::<f64>() {
                    Ok(x) if x.is_finite() && (0.0..=1000.0).contains(&x) => Ok(x),
                    _ => Err(format!(
                        "scenario {shown}: {key} needs a number in [0, 1000], found {}",
                        weights::quote(v)
                    )),
                }
            };
            let whole = |v: &str, lo: u32, hi: u32, what: &str| -> Result<u32, String> {
                v.parse::<u32>()
                    .ok()
                    .filter(|n| (lo..=hi).contains(n))
                    .ok_or_else(|| {
                        format!(
                            "scenario {shown}: {what} must be a whole number in [{lo}, {hi}], \
                             found {}",
                            weights::quote(v)
                        )
                    })
            };
            let needed = || -> Result<&str, String> {
                value
                    .ok_or_else(|| format!("scenario {shown}: {key} needs a value, e.g. {key}=1.2"))
            };
            match key {
                "noise" => {
                    let scale = value.map(number).transpose()?.unwrap_or(1.0);
                    s.noise_std = NOISE_STD.map(|v| v * scale);
                }
                "delay" => {
                    s.delay = match value {
                        None => 1,
                        Some(v) => whole(v, 0, MAX_DELAY, "delay")?,
                    }
                }
                "force" => s.params.force_mag *= number(needed()?)?,
                "length" => s.params.length *= number(needed()?)?,
                "polemass" => s.params.masspole *= number(needed()?)?,
                "cartmass" => s.params.masscart *= number(needed()?)?,
                "friction" => {
                    let (c, p) = match needed()?.split_once('/') {
                        None => (needed()?, "0"),
                        Some(cp) => cp,
                    };
                    let (c, p) = (number(c)?, number(p)?);
                    if c > 1.0 || p > 0.1 {
                        return Err(format!(
                            "scenario {shown}: friction needs a cart coefficient in [0, 1] and \
                             a pivot coefficient in [0, 0.1] N m s/rad, found {c} and {p}"
                        ));
                    }
                    s.params.cart_friction = c;
                    s.params.pole_friction = p;
                }
                "encoder" => {
                    let v = needed()?;
                    let (v, d) = match v.splitn(3, '/').nth(2) {
                        None => (v, None),
                        Some(d) => (&v[..v.len() - d.len() - 1], Some(d)),
                    };
                    let (n, m) = match v.split_once('/') {
                        None => (v, None),
                        Some((n, m)) => (n, Some(m)),
                    };
                    if let Some(d) = d {
                        let d = number(d)?;
                        if !(0.0..=0.99).contains(&d) {
                            return Err(format!(
                                "scenario {shown}: the estimator's discount must lie in [0, 0.99], \
                                 found {d}"
                            ));
                        }
                        s.estimation = Estimation::AlphaBeta(d as f32);
                    }
                    let n = whole(n, 16, 1 << 24, "encoder counts per revolution")?;
                    let m = match m {
                        None => n.saturating_mul(5),
                        Some(m) => whole(m, 16, 1 << 26, "encoder counts per metre")?,
                    };
                    s.encoders = Some(Encoders {
                        cart_counts_per_m: m,
                        pole_counts_per_rev: n,
                    });
                }
                "push" => {
                    let (impulse, every) = match value {
                        None => (0.5, 100),
                        Some(v) => match v.split_once('/') {
                            None => (number(v)?, 100),
                            Some((i, k)) => (number(i)?, whole(k, 1, u32::MAX, "push interval")?),
                        },
                    };
                    s.push = Some(Push { impulse, every });
                }
                _ => {
                    return Err(format!(
                        "scenario {shown}: unknown part {} (expected nominal, noise[=S], \
                         delay[=N], force=F, length=F, polemass=F, cartmass=F, \
                         friction=C[/P], encoder=N[/M[/D]], push[=I[/K]])",
                        weights::quote(part)
                    ));
                }
            }
        }
        check_factors(&s.params).map_err(|e| format!("scenario {shown}: {e}"))?;
        Ok(s)
    }

    /// The robustness table's rows: nominal, each perturbation alone, and all three kinds of
    /// trouble at once.
    pub fn default_set() -> Vec<Scenario> {
        parse_all(&[
            "nominal",
            "noise",
            "delay",
            "force=0.8",
            "force=1.2",
            "length=0.8",
            "length=1.2",
            "polemass=0.8",
            "polemass=1.2",
            "cartmass=0.8",
            "cartmass=1.2",
            "push",
            "noise+delay+push",
        ])
    }

    /// The `hard` set: perturbations beyond the default set's under which bang-bang LQR with
    /// its nominal gain fails (see [`HARD`] and `docs/CONTROL.md`).
    pub fn hard_set() -> Vec<Scenario> {
        parse_all(HARD)
    }

    /// The candidates the `hard` set is chosen from ([`HARD_CANDIDATES`]).
    pub fn hard_candidates() -> Vec<Scenario> {
        parse_all(HARD_CANDIDATES)
    }
}

/// The specs of [`Scenario::hard_set`]: the [`HARD_CANDIDATES`] under which bang-bang LQR
/// with its nominal gain fails in part or whole over 10,000 steps, encoders read through the
/// observer: long dead time, short poles with dead time, friction with dead time, coarse
/// encoders with noise, strong pushes, with exact sensing or read through encoders
/// (`docs/CONTROL.md` has every candidate's figure).
pub const HARD: &[&str] = &[
    "delay=6",
    "delay=8",
    "length=0.4+delay=2",
    "length=0.7+delay=4+noise",
    "friction=0.1/0.002+delay=5",
    "encoder=128+noise",
    "push=1.1/50",
    "push=1.3/50",
    "push=1.5/100",
    "push=1.1/50+noise",
    "length=0.7+push=1/50",
    "noise+delay=2+push=0.8/50",
    "encoder=512+push=1.1/50",
];

/// Perturbations beyond the default set's, one to three kinds at a time and stronger than its
/// +-20%, one period and 0.5 N s: every kind the twin models, each at levels from mild to
/// severe. [`HARD`] is those under which bang-bang LQR fails in part or whole
/// (`host-sim eval --scenario hard-candidates --controller lqr --horizon 10000`).
pub const HARD_CANDIDATES: &[&str] = &[
    "delay=2",
    "delay=3",
    "delay=4",
    "delay=6",
    "delay=8",
    "length=0.3",
    "length=0.4",
    "length=0.5",
    "length=3",
    "length=0.4+delay=2",
    "length=0.5+delay=2",
    "length=0.7+delay=4+noise",
    "polemass=3",
    "polemass=5",
    "cartmass=0.3",
    "cartmass=3",
    "force=0.5",
    "force=0.4",
    "force=2",
    "noise=2",
    "noise=3",
    "noise=2+delay=2",
    "friction=0.1/0.002",
    "friction=0.2/0.005",
    "friction=0.1/0.002+delay=5",
    "friction=0.2+delay=2",
    "encoder=64",
    "encoder=128",
    "encoder=128+noise",
    "encoder=128+delay=2",
    "encoder=512+delay=2",
    "length=0.5+encoder=256",
    "push=1/50",
    "push=1.1/50",
    "push=1.3/50",
    "push=1.5/100",
    "push=0.8/25",
    "push=1.1/50+noise",
    "length=0.7+push=1/50",
    "noise+delay=2+push=0.8/50",
    "encoder=512+push=0.8/50",
    "encoder=512+push=1.1/50",
];

fn parse_all(specs: &[&str]) -> Vec<Scenario> {
    specs
        .iter()
        .map(|s| Scenario::parse(s).expect("built-in scenario specs parse"))
        .collect()
}

/// Every perturbed quantity within [`FACTOR_RANGE`] of nominal.
pub(crate) fn check_factors(p: &Params) -> Result<(), String> {
    let nominal = Params::default();
    for (name, v, n) in [
        ("force", p.force_mag, nominal.force_mag),
        ("length", p.length, nominal.length),
        ("polemass", p.masspole, nominal.masspole),
        ("cartmass", p.masscart, nominal.masscart),
    ] {
        let f = v / n;
        if !(FACTOR_RANGE.0..=FACTOR_RANGE.1).contains(&f) {
            return Err(format!(
                "{name} comes to {f:e} times nominal, expected a factor in [{}, {}] (factors \
                 of one quantity multiply)",
                FACTOR_RANGE.0, FACTOR_RANGE.1
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_set_what_they_say() {
        let s = Scenario::parse("force=1.2+length=0.8+polemass=1.2+cartmass=0.8").unwrap();
        let d = Params::default();
        assert_eq!(s.params.force_mag, d.force_mag * 1.2);
        assert_eq!(s.params.length, d.length * 0.8);
        assert_eq!(s.params.masspole, d.masspole * 1.2);
        assert_eq!(s.params.masscart, d.masscart * 0.8);
        assert_eq!(
            Scenario::parse("push=0.3/40").unwrap().push,
            Some(Push {
                impulse: 0.3,
                every: 40
            })
        );
        assert_eq!(Scenario::parse("delay").unwrap().delay, 1);
        assert_eq!(Scenario::parse("delay=3").unwrap().delay, 3);
        let f = Scenario::parse("friction=0.05/0.001").unwrap().params;
        assert_eq!((f.cart_friction, f.pole_friction), (0.05, 0.001));
        assert_eq!(
            Scenario::parse("friction=0.05")
                .unwrap()
                .params
                .pole_friction,
            0.0
        );
        let e = Scenario::parse("encoder=1024").unwrap().encoders.unwrap();
        assert_eq!((e.pole_counts_per_rev, e.cart_counts_per_m), (1024, 5120));
        let e = Scenario::parse("encoder=4096/20000")
            .unwrap()
            .encoders
            .unwrap();
        assert_eq!((e.pole_counts_per_rev, e.cart_counts_per_m), (4096, 20000));
        assert_eq!(Scenario::nominal(), Scenario::parse("nominal").unwrap());
        assert_eq!(Scenario::default_set().len(), 13);
        assert_eq!(Scenario::hard_set().len(), HARD.len());
        // The hard set is chosen from the candidates, whose every spec parses.
        assert_eq!(Scenario::hard_candidates().len(), HARD_CANDIDATES.len());
        for h in HARD {
            assert!(HARD_CANDIDATES.contains(h), "{h}");
        }
    }

    #[test]
    fn an_encoder_spec_reads_through_the_observer_or_a_filter_of_its_discount() {
        assert_eq!(
            Scenario::parse("encoder=1024").unwrap().estimation,
            Estimation::Observer
        );
        let s = Scenario::parse("encoder=2400/16000/0").unwrap();
        assert_eq!(s.estimation, Estimation::AlphaBeta(0.0));
        assert_eq!(s.encoders.unwrap().cart_counts_per_m, 16_000);
        let e = Scenario::parse("encoder=2400/16000/1.5").unwrap_err();
        assert!(
            e.contains("discount must lie in [0, 0.99], found 1.5"),
            "{e}"
        );
        assert!(Scenario::parse("encoder=2400/16000/x").is_err());
    }

    #[test]
    fn bad_specs_are_rejected_with_the_reason() {
        for (spec, needle) in [
            ("wind", "unknown part"),
            ("force", "needs a value"),
            ("force=-1", "needs a number in [0, 1000], found \"-1\""),
            ("push=0.5/0", "push interval must be a whole number in [1,"),
            ("noise=x", "needs a number in [0, 1000]"),
            ("force=0", "force comes to 0e0 times nominal"),
            // One quantity's factors multiply: each is fine, their product is not.
            ("length=999+length=999", "length comes to 9.98"),
            (
                "length=1e300+length=1e300",
                "needs a number in [0, 1000], found \"1e300\"",
            ),
            ("push=1e9", "needs a number in [0, 1000]"),
            ("delay=17", "delay must be a whole number in [0, 16]"),
            ("delay=-1", "delay must be a whole number"),
            (
                "encoder=8",
                "encoder counts per revolution must be a whole number in [16,",
            ),
            ("encoder", "needs a value"),
            ("friction=2", "a cart coefficient in [0, 1]"),
            ("friction=0.1/0.5", "a pivot coefficient in [0, 0.1]"),
        ] {
            let e = Scenario::parse(spec).unwrap_err();
            assert!(e.contains(needle), "{spec}: {e}");
        }
        let long = "noise+".repeat(10_000);
        let e = Scenario::parse(&long).unwrap_err();
        assert!(
            e.contains("expected at most 1000 bytes") && e.len() < 400,
            "{e}"
        );
    }
}
