//! Domain randomisation: a distribution over scenarios, sampled once per training episode, so
//! that a policy learns a world wider than the one it is judged in.
//!
//! A domain is written like a scenario, with ranges: parts joined by `+`, each `KEY=LO..HI`
//! (or a single value), optionally `@P` to apply the part in a share P of episodes only:
//!
//! ```text
//! length=0.5..1.6+polemass=0.5..2+force=0.7..1.3+friction=0..0.08/0..0.002
//! +noise=0..2@0.5+encoder=256..8192@0.5+delay=0..3+push=0..1.2/40..200@0.5
//! ```
//!
//! Factors, noise scales, friction coefficients and impulses are drawn uniformly from their
//! ranges; encoder resolutions log-uniformly (each octave as likely); dead time and push
//! intervals uniformly among the whole numbers of their ranges. Every draw comes from the one
//! generator the caller passes, part by part in the spec's order, so a seed gives the same
//! sequence of worlds.

use firmware::cartpole::unit_f64;
use firmware::estimator::Encoders;
use rand_core::Rng;

use crate::scenario::{MAX_DELAY, MAX_SPEC_BYTES, NOISE_STD, Push, Scenario, check_factors};

/// One randomised quantity.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Part {
    Force(Span),
    Length(Span),
    PoleMass(Span),
    CartMass(Span),
    Friction(Span, Span),
    Noise(Span),
    Encoder(Span),
    Delay(Span),
    Push(Span, Span),
}

/// A closed range `[lo, hi]`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Span {
    lo: f64,
    hi: f64,
}

impl Span {
    fn uniform<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        self.lo + (self.hi - self.lo) * unit_f64(rng)
    }

    fn whole<R: Rng + ?Sized>(&self, rng: &mut R) -> u32 {
        let (lo, hi) = (self.lo as u32, self.hi as u32);
        lo + ((unit_f64(rng) * f64::from(hi - lo + 1)) as u32).min(hi - lo)
    }

    fn log_uniform<R: Rng + ?Sized>(&self, rng: &mut R) -> u32 {
        let (a, b) = (self.lo.ln(), self.hi.ln());
        (a + (b - a) * unit_f64(rng)).exp().round() as u32
    }
}

/// A distribution over scenarios; see [the module](self).
#[derive(Clone, Debug, PartialEq)]
pub struct Domain {
    spec: String,
    parts: Vec<(Part, f64)>,
}

impl Domain {
    /// The empty domain: every sample is the nominal scenario.
    pub fn nominal() -> Domain {
        Domain {
            spec: String::new(),
            parts: Vec::new(),
        }
    }

    /// Whether every sample is nominal.
    pub fn is_nominal(&self) -> bool {
        self.parts.is_empty()
    }

    /// The spec it was parsed from.
    pub fn spec(&self) -> &str {
        &self.spec
    }

    /// Parses a spec (see [the module](self)); `""` and `nominal` are the nominal domain.
    pub fn parse(spec: &str) -> Result<Domain, String> {
        let shown = weights::quote(spec);
        if spec.len() > MAX_SPEC_BYTES {
            return Err(format!(
                "domain: expected at most {MAX_SPEC_BYTES} bytes, found {} ({shown})",
                spec.len()
            ));
        }
        let mut d = Domain {
            spec: spec.to_string(),
            parts: Vec::new(),
        };
        if spec.is_empty() || spec == "nominal" {
            return Ok(d);
        }
        for raw in spec.split('+') {
            let err = |what: String| format!("domain {shown}: {} {what}", weights::quote(raw));
            let (part, share) = match raw.split_once('@') {
                None => (raw, 1.0),
                Some((p, s)) => match s.parse::<f64>() {
                    Ok(v) if (0.0..=1.0).contains(&v) => (p, v),
                    _ => return Err(err("needs a share in [0, 1] after @".into())),
                },
            };
            let (key, value) = part
                .split_once('=')
                .ok_or_else(|| err("needs KEY=LO..HI".into()))?;
            let span = |v: &str, lo: f64, hi: f64| -> Result<Span, String> {
                let (a, b) = v.split_once("..").unwrap_or((v, v));
                match (a.parse::<f64>(), b.parse::<f64>()) {
                    (Ok(a), Ok(b)) if lo <= a && a <= b && b <= hi => Ok(Span { lo: a, hi: b }),
                    _ => Err(err(format!("needs LO..HI with {lo} <= LO <= HI <= {hi}"))),
                }
            };
            let pair = |v: &str, (l1, h1): (f64, f64), (l2, h2): (f64, f64)| {
                let (a, b) = v.split_once('/').unwrap_or((v, "0"));
                Ok::<_, String>((span(a, l1, h1)?, span(b, l2, h2)?))
            };
            let factor = (1e-3, 1e3);
            let p = match key {
                "force" => Part::Force(span(value, factor.0, factor.1)?),
                "length" => Part::Length(span(value, factor.0, factor.1)?),
                "polemass" => Part::PoleMass(span(value, factor.0, factor.1)?),
                "cartmass" => Part::CartMass(span(value, factor.0, factor.1)?),
                "friction" => {
                    let (c, p) = pair(value, (0.0, 1.0), (0.0, 0.1))?;
                    Part::Friction(c, p)
                }
                "noise" => Part::Noise(span(value, 0.0, 1000.0)?),
                "encoder" => Part::Encoder(span(value, 16.0, f64::from(1u32 << 24))?),
                "delay" => Part::Delay(span(value, 0.0, f64::from(MAX_DELAY))?),
                "push" => {
                    let (i, k) = value.split_once('/').unwrap_or((value, "100"));
                    Part::Push(span(i, 0.0, 1000.0)?, span(k, 1.0, 1e9)?)
                }
                _ => {
                    return Err(err(
                        "is not a domain part (force, length, polemass, cartmass, friction, \
                         noise, encoder, delay, push)"
                            .into(),
                    ));
                }
            };
            d.parts.push((p, share));
        }
        // The extremes must make a valid world, whichever corner a sample lands in.
        for corner in [false, true] {
            let mut s = Scenario::nominal();
            for (p, _) in &d.parts {
                let v = |sp: &Span| if corner { sp.hi } else { sp.lo };
                match p {
                    Part::Force(f) => s.params.force_mag *= v(f),
                    Part::Length(f) => s.params.length *= v(f),
                    Part::PoleMass(f) => s.params.masspole *= v(f),
                    Part::CartMass(f) => s.params.masscart *= v(f),
                    _ => {}
                }
            }
            check_factors(&s.params).map_err(|e| format!("domain {shown}: {e}"))?;
        }
        Ok(d)
    }

    /// One world of the distribution.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Scenario {
        let mut s = Scenario::nominal();
        s.name = "sampled".into();
        for (part, share) in &self.parts {
            // The share's coin is drawn even when it is 1, so parts keep their streams.
            if unit_f64(rng) >= *share {
                continue;
            }
            match part {
                Part::Force(f) => s.params.force_mag *= f.uniform(rng),
                Part::Length(f) => s.params.length *= f.uniform(rng),
                Part::PoleMass(f) => s.params.masspole *= f.uniform(rng),
                Part::CartMass(f) => s.params.masscart *= f.uniform(rng),
                Part::Friction(c, p) => {
                    s.params.cart_friction = c.uniform(rng);
                    s.params.pole_friction = p.uniform(rng);
                }
                Part::Noise(k) => {
                    let k = k.uniform(rng);
                    s.noise_std = NOISE_STD.map(|v| v * k);
                }
                Part::Encoder(n) => {
                    let n = n.log_uniform(rng).max(16);
                    s.encoders = Some(Encoders {
                        cart_counts_per_m: n.saturating_mul(5),
                        pole_counts_per_rev: n,
                    });
                }
                Part::Delay(d) => s.delay = d.whole(rng),
                Part::Push(i, k) => {
                    s.push = Some(Push {
                        impulse: i.uniform(rng),
                        every: k.whole(rng).max(1),
                    })
                }
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_pcg::Pcg64Mcg;

    #[test]
    fn samples_stay_in_their_ranges_and_shares_hold() {
        let d = Domain::parse(
            "length=0.5..1.5+polemass=2+friction=0..0.1/0..0.002+noise=0..2@0.5+encoder=256..4096\
             +delay=0..3+push=0..1/50..60@0.25",
        )
        .unwrap();
        let mut rng = Pcg64Mcg::new(9);
        let (mut noisy, mut pushed) = (0, 0);
        let mut delays = [0; 4];
        for _ in 0..4000 {
            let s = d.sample(&mut rng);
            let f = s.params.length / 0.5;
            assert!((0.5..=1.5).contains(&f), "{f}");
            assert!((s.params.masspole - 0.2).abs() < 1e-15);
            assert!((0.0..=0.1).contains(&s.params.cart_friction));
            let e = s.encoders.unwrap();
            assert!((256..=4096).contains(&e.pole_counts_per_rev));
            noisy += usize::from(s.noise_std != [0.0; 4]);
            pushed += usize::from(s.push.is_some());
            if let Some(p) = s.push {
                assert!((50..=60).contains(&p.every) && p.impulse <= 1.0);
            }
            delays[s.delay as usize] += 1;
        }
        assert!((1800..2200).contains(&noisy), "{noisy}");
        assert!((850..1150).contains(&pushed), "{pushed}");
        assert!(
            delays.iter().all(|&n| (850..1150).contains(&n)),
            "{delays:?}"
        );
        // Log-uniform: each octave about as likely.
        let mut octaves = [0; 4];
        for _ in 0..4000 {
            let n = d.sample(&mut rng).encoders.unwrap().pole_counts_per_rev;
            octaves[((f64::from(n).log2() - 8.0).floor() as usize).min(3)] += 1;
        }
        assert!(
            octaves.iter().all(|&n| (850..1150).contains(&n)),
            "{octaves:?}"
        );
    }

    #[test]
    fn a_seed_gives_the_same_worlds_and_nominal_is_nominal() {
        let d = Domain::parse("length=0.5..1.5+noise=0..2").unwrap();
        let draw = |seed| {
            (0..5)
                .map(|_| 0)
                .scan(Pcg64Mcg::new(seed), |r, _| Some(d.sample(r)))
                .collect::<Vec<_>>()
        };
        assert_eq!(draw(3), draw(3));
        assert_ne!(draw(3), draw(4));
        let mut n = Domain::parse("").unwrap().sample(&mut Pcg64Mcg::new(1));
        n.name = "nominal".into();
        assert_eq!(n, Scenario::nominal());
    }

    #[test]
    fn bad_domains_say_why() {
        for (spec, want) in [
            ("length", "needs KEY=LO..HI"),
            ("length=2..1", "needs LO..HI with 0.001 <= LO <= HI <= 1000"),
            ("wind=1", "is not a domain part"),
            ("noise=0..1@2", "needs a share in [0, 1]"),
            ("delay=0..40", "LO <= HI <= 16"),
            (
                "length=500+length=500",
                "length comes to 2.5e5 times nominal",
            ),
        ] {
            let e = Domain::parse(spec).unwrap_err();
            assert!(e.contains(want), "{spec}: {e}");
        }
    }
}
