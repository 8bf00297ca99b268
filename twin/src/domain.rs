//! Domain randomisation: a distribution over scenarios, sampled once per training episode, so
//! that a policy learns a world wider than the one it is judged in.
//!
//! A domain is written like a scenario ([`crate::grammar`]), with ranges: parts joined by
//! `+`, each value `LO..HI` (or a single value), optionally `@P` to apply the part in a
//! share P of episodes only:
//!
//! ```text
//! length=0.5..1.6+polemass=0.5..2+force=0.7..1.3+friction=0..0.08/0..0.002
//! +noise=0..2@0.5+encoder=256..8192@0.5+delay=0..3+push=0..1.2/40..200@0.5
//! ```
//!
//! Real values are drawn uniformly from their ranges; encoder resolutions log-uniformly
//! (each octave as likely); whole numbers uniformly among the whole numbers of their ranges.
//! Every draw comes from the one generator the caller passes, part by part in the spec's
//! order (first the share's coin, then each value given), so a seed gives the same sequence
//! of worlds.

use firmware::cartpole::unit_f64;
use rand_core::Rng;

use crate::grammar::{self, Kind, Part, Span};
use crate::machine::{Machine, check_integrable};
use crate::scenario::{Scenario, check_factors, idle_part};

/// A distribution over scenarios; see [the module](self).
#[derive(Clone, Debug, PartialEq)]
pub struct Domain {
    spec: String,
    machine: Machine,
    parts: Vec<Part>,
}

impl Domain {
    /// The empty domain on Gymnasium's machine: every sample is the nominal scenario.
    pub fn nominal() -> Domain {
        Domain {
            spec: String::new(),
            machine: Machine::GYMNASIUM,
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

    /// Parses a spec on Gymnasium's machine (see [`Domain::parse_on`]).
    pub fn parse(spec: &str) -> Result<Domain, String> {
        Domain::parse_on(spec, &Machine::GYMNASIUM)
    }

    /// Parses a spec (see [the module](self)) of worlds around `machine`; `""` and
    /// `nominal` are the machine itself. The extremes must make valid worlds, whichever
    /// corner a sample lands in.
    pub fn parse_on(spec: &str, machine: &Machine) -> Result<Domain, String> {
        let rig = &machine.rig;
        let d = Domain {
            spec: spec.to_string(),
            machine: *machine,
            parts: grammar::parse(spec, "domain")?,
        };
        // A part changes nothing if every world the sampler builds of it runs as the world
        // without it (`delay=1` on a rig of one period's dead time, `length=2+length=0.5`,
        // `jitter` without an encoder part): the judgement of a scenario's parts.
        if let Some((key, why)) = idle_part(&d.parts, machine) {
            return Err(format!(
                "domain {}: {key} changes nothing {why}",
                weights::quote(spec)
            ));
        }
        // Every low end, every high end, and the stiffest corner: the most damping and
        // friction on the lightest, shortest pole and cart.
        let stiff = |p: &Part| p.spec.stiff_high;
        let corners: [&dyn Fn(&Part) -> bool; 3] = [&|_| false, &|_| true, &stiff];
        for high in corners {
            let mut s = Scenario::nominal_on(machine);
            for part in &d.parts {
                s.apply(part, &part.ends(high(part)));
            }
            check_factors(&s.params, &rig.params)
                .and_then(|()| check_integrable(&s.params, s.integration))
                .map_err(|e| format!("domain {}: {e}", weights::quote(spec)))?;
        }
        Ok(d)
    }

    /// The most periods of dead time a world drawn has: the delay part's high end (its
    /// default where the value is left out) in the worlds it applies to, the machine's own
    /// in the others (all of them, without the part).
    pub fn most_dead_time(&self) -> u32 {
        let own = self.machine.rig.dead_time;
        let Some(part) = self.parts.iter().find(|p| p.spec.key == "delay") else {
            return own;
        };
        let mut s = Scenario::nominal_on(&self.machine);
        s.apply(part, &part.ends(true));
        if part.share < 1.0 {
            s.delay().max(own)
        } else {
            s.delay()
        }
    }

    /// One world of the distribution.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Scenario {
        let mut s = Scenario::nominal_on(&self.machine);
        s.name = "sampled".into();
        for part in &self.parts {
            // The share's coin is drawn even when it is 1, so parts keep their streams.
            if unit_f64(rng) >= part.share {
                continue;
            }
            let values: Vec<Option<f64>> = part
                .values
                .iter()
                .zip(part.spec.fields)
                .map(|(v, f)| v.map(|v| draw(&v, f.kind, rng)))
                .collect();
            s.apply(part, &values);
        }
        s
    }
}

/// One value from `span`, drawn as `kind` says.
fn draw<R: Rng + ?Sized>(span: &Span, kind: Kind, rng: &mut R) -> f64 {
    let u = unit_f64(rng);
    match kind {
        Kind::Real => span.lo + (span.hi - span.lo) * u,
        Kind::Whole => {
            let width = span.hi - span.lo;
            span.lo + (u * (width + 1.0)).floor().min(width)
        }
        Kind::LogWhole => {
            let (a, b) = (span.lo.ln(), span.hi.ln());
            (a + (b - a) * u).exp().round()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_pcg::Pcg64Mcg;

    #[test]
    fn a_domain_draws_faults_too() {
        let d = Domain::parse("encoder+stuck=1..10/100..200@0.5+weak=0..0.5/20/100..400").unwrap();
        let mut rng = Pcg64Mcg::new(3);
        let mut stuck = 0;
        for _ in 0..2000 {
            let f = d.sample(&mut rng).faults;
            if let Some(w) = f.stuck {
                stuck += 1;
                assert!((1..=10).contains(&w.periods) && (100..=200).contains(&w.every));
            }
            let (factor, w) = f.weak.expect("every sample is weak");
            assert!((0.0..=0.5).contains(&factor) && w.periods == 20);
            assert!((100..=400).contains(&w.every), "{w:?}");
        }
        assert!((850..1150).contains(&stuck), "{stuck}");
    }

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
            let e = s.rig.encoders;
            assert!((256..=4096).contains(&e.pole_counts_per_rev));
            noisy += usize::from(s.noise_std != [0.0; 4]);
            pushed += usize::from(s.push.is_some());
            if let Some(p) = s.push {
                assert!((50..=60).contains(&p.every) && p.impulse <= 1.0);
            }
            delays[s.delay() as usize] += 1;
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
            let n = d.sample(&mut rng).rig.encoders.pole_counts_per_rev;
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
            ("length", "length needs a value"),
            ("length=2..1", "needs LO..HI with LO <= HI"),
            ("wind=1", "unknown part"),
            (
                "nominal+length=1.1",
                "expected nominal alone (no parts) or parts joined by +",
            ),
            ("noise=0..1@2", "needs a share in (0, 1]"),
            ("noise=0..1@0", "needs a share in (0, 1]"),
            ("noise=1@-0", "needs a share in (0, 1]"),
            (
                "delay=0..40",
                "delay must be a whole number in [0, 16], found \"40\"",
            ),
            (
                "length=500+length=500",
                "length comes to 2.5e5 times nominal",
            ),
            // Gymnasium's motor has no damping to scale: any range of it draws nothing.
            (
                "noise=0..1+damping=0.5..2",
                "domain \"noise=0..1+damping=0.5..2\": damping changes nothing on a machine \
                 without motor damping; expected another part, or a rig that has some",
            ),
        ] {
            let e = Domain::parse(spec).unwrap_err();
            assert!(e.contains(want), "{spec}: {e}");
        }
    }

    #[test]
    fn a_part_that_draws_only_the_machines_own_world_is_refused() {
        let desk = crate::rigfile::parse(include_str!("../../rigs/desk.toml"), "desk").unwrap();
        for (spec, want) in [
            (
                "noise=0..1+delay=1@0.5",
                "domain \"noise=0..1+delay=1@0.5\": delay changes nothing on this machine, \
                 whose own dead time is 1 period",
            ),
            (
                "friction=0/0",
                "friction changes nothing on this machine, which has it",
            ),
        ] {
            let e = Domain::parse_on(spec, &desk).unwrap_err();
            assert!(e.contains(want), "{spec}: {e}");
        }
        // A range reaching past the machine's own value, at either end, draws other worlds.
        for spec in ["delay=0..1", "delay=1..2", "length=1..1.2", "delay=2"] {
            Domain::parse_on(spec, &desk).unwrap();
        }
        Domain::parse("delay=1").unwrap();
        let e = Domain::parse("delay=0").unwrap_err();
        assert!(e.contains("own dead time is 0 periods"), "{e}");
    }

    /// A factor's parts are judged together, as the sampler applies them: all at once where
    /// each is always drawn, apart where a share's coin may fall alone.
    #[test]
    fn the_parts_of_one_factor_are_judged_together() {
        let desk = crate::rigfile::parse(include_str!("../../rigs/desk.toml"), "desk").unwrap();
        for machine in [Machine::GYMNASIUM, desk] {
            for spec in ["length=2+length=0.5", "noise+length=2+length=0.25+length=2"] {
                let e = Domain::parse_on(spec, &machine).unwrap_err();
                let want = format!(
                    "domain {}: length changes nothing on this machine: its factors multiply \
                     to 1",
                    weights::quote(spec)
                );
                assert!(e.contains(&want), "{spec}: {e}");
            }
            for spec in [
                "length=2@0.5+length=0.5@0.5",
                "length=2+length=0.5@0.5",
                "length=1..2+length=0.5",
                "length=2..4+length=0.25..0.5",
            ] {
                let d = Domain::parse_on(spec, &machine).unwrap();
                let mut rng = Pcg64Mcg::new(2);
                let own = machine.rig.params.length;
                let other = (0..50).any(|_| d.sample(&mut rng).params.length != own);
                assert!(other, "{spec} drew only the machine's length");
            }
        }
    }

    /// A part that needs another is judged beside the domain's other parts, drawn or not.
    #[test]
    fn a_part_that_needs_another_is_judged_beside_the_others() {
        for (spec, want) in [
            (
                "noise=0..1+jitter=0..0.1",
                "jitter changes nothing under exact sensing, where no encoder is read early or \
                 late; expected an encoder part beside it",
            ),
            (
                "zero=0.01..0.02+encoder=256..8192",
                "zero changes nothing through encoders of 8192 counts per revolution and 40960 \
                 per metre",
            ),
        ] {
            let e = Domain::parse(spec).unwrap_err();
            assert!(e.contains(want), "{spec}: {e}");
        }
        // An encoder part drawn in some worlds, or fine enough at its high end; an exact
        // sensor where the encoder's coin falls.
        for spec in [
            "jitter=0..0.1@0.3+encoder=256..8192@0.3",
            "encoder+jitter=0.2",
            "zero=0.01..0.02+encoder=256..65536",
            "zero=0.01+encoder=1024@0.5",
        ] {
            Domain::parse(spec).unwrap();
        }
    }

    #[test]
    fn a_damping_range_is_drawn_on_a_motor_that_has_damping() {
        let desk = crate::rigfile::parse(include_str!("../../rigs/desk.toml"), "desk").unwrap();
        let d = Domain::parse_on("damping=0.5..2", &desk).unwrap();
        let s = d.sample(&mut Pcg64Mcg::new(5));
        let f = s.params.motor_damping / desk.rig.params.motor_damping;
        assert!((0.5..=2.0).contains(&f) && f != 1.0, "{f}");
    }
}
