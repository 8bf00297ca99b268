//! The one grammar of worlds: a scenario (`noise+delay=2`) and a domain of them
//! (`length=0.75..1.25+delay=0..4@0.5`) are written alike, and a scenario is a domain whose
//! every value is a single point. [`PARTS`] is the one table of parts: their fields, bounds
//! and defaults and what each means; the parser, the errors, the command-line help, the
//! bounds a rig file's encoders and friction keep, and the table of parts in
//! `docs/SCENARIOS.md` (`host-sim parts`) are all made from it.
//!
//! A spec is `nominal`, or parts joined by `+`; a part is `KEY`, or `KEY=V[/V...]`, each value
//! a number or (in a domain) a range `LO..HI`, and (in a domain) `@P` applies the part in a
//! share P of samples only.

use crate::scenario::{MAX_SPEC_BYTES, Scenario};

mod help;
mod parts;
mod values;
pub use help::{markdown_table, scenario_help, syntax_list};
use parts::FACTOR;
pub use parts::PARTS;
pub use values::Values;

/// How a field's values are read and, in a domain, drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A real number, drawn uniformly.
    Real,
    /// A whole number, drawn uniformly among the whole numbers of the range.
    Whole,
    /// A whole number drawn log-uniformly: each octave as likely (encoder resolutions).
    LogWhole,
}

/// What a field is when a spec leaves it out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fallback {
    /// It may not be left out.
    Required,
    /// This value.
    Value(f64),
    /// Five times the part's first field (a cart encoder on a 20 cm pulley: 5 counts per
    /// metre for each count per revolution).
    FiveTimesFirst,
    /// Absent: the part means something else without it.
    Absent,
}

/// One number of a part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Field {
    /// What it is, as errors name it.
    pub name: &'static str,
    /// How it is read and drawn.
    pub kind: Kind,
    /// Smallest accepted value.
    pub lo: f64,
    /// Largest accepted value.
    pub hi: f64,
    /// Its value when left out.
    pub fallback: Fallback,
}

/// One kind of part: its key, its fields, its meaning.
#[derive(Clone, Copy, Debug)]
pub struct PartSpec {
    /// The key, before `=`.
    pub key: &'static str,
    /// What it does to a scenario, given its values.
    pub effect: fn(&mut Scenario, &Values),
    /// The values after `=`, separated by `/`, in order; the first is required unless its
    /// fallback says otherwise (then the part may be written as its key alone).
    pub fields: &'static [Field],
    /// The part's syntax as the help shows it.
    pub syntax: &'static str,
    /// What it does.
    pub doc: &'static str,
    /// Whether its high end makes a world stiffer to integrate (more damping, more
    /// friction), where the other parts' low ends do (a lighter, shorter pole and cart):
    /// a domain checks that corner too.
    pub stiff_high: bool,
    /// The values at which it changes nothing.
    pub idle: Idle,
    /// Its stretch of periods within an interval, if it has one.
    pub stretch: Option<Stretch>,
}

/// A part's stretch of K periods of every EVERY (`stuck=K/EVERY`, `weak=F/K/EVERY`). A
/// stretch as long as its interval holds in every period, whatever K, so K past EVERY is
/// refused: it reads as more than K = EVERY and builds the same world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stretch {
    /// The field of K; EVERY is the next.
    pub field: usize,
    /// The part that builds this part's world in every period, if another does (`force=F`
    /// for a weak motor): then K = EVERY, given as single values, is refused too, one world
    /// having one spelling (a domain's ranges that meet there draw it among others).
    pub always: Option<&'static str>,
}

/// The values at which a part changes nothing (`noise=0`, `length=1`, `zero=0/0`): written,
/// such a part is a slip, a spec that reads as a world it is not (and beside `nominal`, one
/// row asked for twice), so it is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Idle {
    /// It always changes something.
    Never,
    /// Its first field at this value makes the rest moot (a push of no impulse).
    First(f64),
    /// Every field at this value.
    Every(f64),
}

impl PartSpec {
    /// Whether it is a factor, which multiplies when given again (`length=2+length=2` is
    /// `length=4`); any other part is taken once.
    pub fn multiplies(&self) -> bool {
        self.fields == [FACTOR]
    }

    /// The fields that decide whether the part changes nothing, and the value at which each
    /// does ([`Idle`]); `None` for a part that always changes something.
    pub fn idle_fields(&self) -> Option<(&'static [Field], f64)> {
        match self.idle {
            Idle::Never => None,
            Idle::First(v) => Some((&self.fields[..1], v)),
            Idle::Every(v) => Some((self.fields, v)),
        }
    }
}

/// A part is known by its key.
impl PartialEq for PartSpec {
    fn eq(&self, other: &PartSpec) -> bool {
        self.key == other.key
    }
}

const fn field(name: &'static str, kind: Kind, lo: f64, hi: f64, fallback: Fallback) -> Field {
    Field {
        name,
        kind,
        lo,
        hi,
        fallback,
    }
}

/// The range a physical quantity's factor may take: wide enough for any robustness study,
/// narrow enough that the plant's arithmetic stays finite.
pub const FACTOR_RANGE: (f64, f64) = (1e-3, 1e3);

/// The cart's Coulomb friction coefficient a world (and a rig file) may have.
pub const CART_FRICTION_RANGE: (f64, f64) = (0.0, 1.0);

/// The pivot's viscous friction a world (and a rig file) may have, N m s/rad.
pub const PIVOT_FRICTION_RANGE: (f64, f64) = (0.0, 0.1);

/// The pole encoder's counts per revolution a world (and a rig file) may have.
pub const POLE_COUNTS_RANGE: (f64, f64) = (16.0, (1u32 << 24) as f64);

/// The cart encoder's counts per metre of travel a world (and a rig file) may have.
pub const CART_COUNTS_RANGE: (f64, f64) = (16.0, (1u32 << 26) as f64);

/// The product of a factor's values given again (`length=2+length=3+length=0.5`), taken in
/// ascending order: the same bits however a spec orders them.
pub fn product(factors: &[f64]) -> f64 {
    let mut sorted = factors.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.iter().product()
}

/// A closed range `[lo, hi]`; a point when `lo == hi`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Its low end.
    pub lo: f64,
    /// Its high end.
    pub hi: f64,
}

impl Span {
    /// Whether it holds one value.
    pub fn is_point(&self) -> bool {
        self.lo == self.hi
    }
}

/// One parsed part: which, its values (`None` where a field was left out) and its share.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// Its kind.
    pub spec: &'static PartSpec,
    /// One per field of `spec`.
    pub values: Vec<Option<Span>>,
    /// The share of samples it applies in (1 in a scenario).
    pub share: f64,
}

impl Part {
    /// Each field's value at the low ends of its range, or the high (`None` where left out).
    pub fn ends(&self, high: bool) -> Vec<Option<f64>> {
        let end = |v: Span| if high { v.hi } else { v.lo };
        self.values.iter().map(|v| v.map(end)).collect()
    }
}

/// Splits `spec` into parts (`nominal` and `""` are none), checking every value against its
/// field. `what` names the spec in errors (`scenario` or `domain`).
pub fn parse(spec: &str, what: &str) -> Result<Vec<Part>, String> {
    let shown = weights::quote(spec);
    if spec.len() > MAX_SPEC_BYTES {
        return Err(format!(
            "{what}: expected at most {MAX_SPEC_BYTES} bytes, found {} ({shown})",
            spec.len()
        ));
    }
    if spec.is_empty() || spec == "nominal" {
        return Ok(Vec::new());
    }
    if spec.split('+').any(|raw| raw == "nominal") {
        return Err(format!(
            "{what} {shown}: expected nominal alone (no parts) or parts joined by +, found \
             nominal joined with parts"
        ));
    }
    let parts: Vec<Part> = spec
        .split('+')
        .map(|raw| parse_part(raw).map_err(|e| format!("{what} {shown}: {e}")))
        .collect::<Result<_, _>>()?;
    // A factor given twice multiplies; any other part given again would replace the first,
    // which a reader of the spec cannot tell.
    for (k, p) in parts.iter().enumerate() {
        if !p.spec.multiplies() && parts[..k].iter().any(|q| q.spec == p.spec) {
            return Err(format!(
                "{what} {shown}: expected each part once (only factors multiply), found {} \
                 again",
                p.spec.key
            ));
        }
    }
    Ok(parts)
}

fn parse_part(raw: &str) -> Result<Part, String> {
    let (body, share) = match raw.split_once('@') {
        None => (raw, 1.0),
        // A share of 0 applies the part in no sample: the domain would claim a
        // randomisation it never draws.
        Some((b, s)) => match s.parse::<f64>() {
            Ok(v) if v > 0.0 && v <= 1.0 && weights::plain(v) => (b, v),
            _ => {
                return Err(format!(
                    "{} needs a share in (0, 1], normal, after @, found {}",
                    weights::quote(raw),
                    weights::quote(s)
                ));
            }
        },
    };
    let (key, text) = match body.split_once('=') {
        Some((k, v)) => (k, Some(v)),
        None => (body, None),
    };
    let spec = PARTS.iter().find(|p| p.key == key).ok_or_else(|| {
        format!(
            "unknown part {} (expected nominal, or parts joined by + from {})",
            weights::quote(body),
            syntax_list()
        )
    })?;
    let texts: Vec<&str> = match text {
        None => Vec::new(),
        Some(t) => t.split('/').collect(),
    };
    if texts.len() > spec.fields.len() {
        return Err(format!(
            "{key} takes at most {} values ({}), found {}",
            spec.fields.len(),
            spec.syntax,
            weights::quote(text.unwrap_or(""))
        ));
    }
    let mut values = Vec::with_capacity(spec.fields.len());
    for (i, f) in spec.fields.iter().enumerate() {
        values.push(match texts.get(i) {
            Some(t) => Some(parse_span(key, f, t)?),
            None if f.fallback == Fallback::Required => {
                return Err(format!("{key} needs a value, e.g. {}", spec.syntax));
            }
            None => None,
        });
    }
    refuse_idle(spec, &values)?;
    refuse_stretch(spec, &values)?;
    Ok(Part {
        spec,
        values,
        share,
    })
}

/// Field `i`'s value or range, its fallback where it was left out (`None` where that is
/// not a value).
fn filled(spec: &PartSpec, values: &[Option<Span>], i: usize) -> Option<Span> {
    values
        .get(i)
        .copied()
        .flatten()
        .or(match spec.fields[i].fallback {
            Fallback::Value(v) => Some(Span { lo: v, hi: v }),
            _ => None,
        })
}

/// Refuses a part whose every value is a point at which it changes nothing ([`Idle`]).
fn refuse_idle(spec: &PartSpec, values: &[Option<Span>]) -> Result<(), String> {
    let point = |i: usize| filled(spec, values, i).filter(Span::is_point).map(|s| s.lo);
    let Some((fields, at)) = spec.idle_fields() else {
        return Ok(());
    };
    if !(0..fields.len()).all(|i| point(i) == Some(at)) {
        return Ok(());
    }
    let names: Vec<&str> = fields.iter().map(|f| f.name).collect();
    Err(format!(
        "{} changes nothing with {} {at}: expected another value, or the part left out",
        spec.key,
        names.join(" and ")
    ))
}

/// Refuses a stretch that can be longer than its interval in a world drawn, and one as
/// long as its interval where another part builds that world ([`Stretch`]).
fn refuse_stretch(spec: &PartSpec, values: &[Option<Span>]) -> Result<(), String> {
    let Some(stretch) = spec.stretch else {
        return Ok(());
    };
    let span = |i: usize| filled(spec, values, i).expect("a stretch's fields have defaults");
    let (k, every) = (span(stretch.field), span(stretch.field + 1));
    let shown = |s: Span| match s.is_point() {
        true => format!("{}", s.lo),
        false => format!("{}..{}", s.lo, s.hi),
    };
    let (key, found) = (
        spec.key,
        format!("K {} and EVERY {}", shown(k), shown(every)),
    );
    match stretch.always {
        Some(instead) if k.is_point() && every.is_point() && k.lo >= every.lo => Err(format!(
            "{key} takes K periods of every EVERY: expected K below EVERY (K = EVERY is every \
             period, the world {instead} builds: write that), found {found}"
        )),
        _ if k.hi > every.lo => Err(format!(
            "{key} takes K periods of every EVERY: expected K at most EVERY in every world (K \
             = EVERY is every period), found {found}"
        )),
        _ => Ok(()),
    }
}

/// One value or range of field `f` of part `key`.
fn parse_span(key: &str, f: &Field, text: &str) -> Result<Span, String> {
    let name = if f.name == key {
        key.to_string()
    } else {
        format!("{key} {}", f.name)
    };
    let (a, b) = text.split_once("..").unwrap_or((text, text));
    let read = |t: &str| -> Result<f64, String> {
        let v = match f.kind {
            // `-0` reads as 0: the two build one world, and a world's key (its `Debug`
            // text, `words::refuse_same_world`) must not tell them apart.
            // `1e-400` too is a zero in disguise, wherever the spec came from (Python's
            // `scenario=`, a TOML escape), not only on a command line.
            Kind::Real => t
                .parse::<f64>()
                .ok()
                .filter(|v| weights::plain(*v) && !weights::reads_as_zero(t))
                .map(|v| v + 0.0),
            Kind::Whole | Kind::LogWhole => weights::whole::<u64>(t).map(|v| v as f64),
        };
        v.filter(|v| (f.lo..=f.hi).contains(v)).ok_or_else(|| {
            let kind = match f.kind {
                Kind::Real => "zero or a normal number",
                Kind::Whole | Kind::LogWhole => "a whole number",
            };
            // `delay=+2` and `noise=1e+0` arrive cut at their `+`, which joins parts.
            let joins = if t.is_empty() || t.ends_with(['e', 'E']) {
                " (a `+` joins a spec's parts: write numbers without one)"
            } else {
                ""
            };
            format!(
                "{name} must be {kind} in [{}, {}], found {}{joins}",
                f.lo,
                f.hi,
                weights::quote(t)
            )
        })
    };
    let (lo, hi) = (read(a)?, read(b)?);
    if lo > hi {
        return Err(format!(
            "{name} needs LO..HI with LO <= HI, found {}",
            weights::quote(text)
        ));
    }
    Ok(Span { lo, hi })
}
