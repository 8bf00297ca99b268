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
mod values;
pub use help::{markdown_table, scenario_help, syntax_list};
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

const FACTOR: Field = field(
    "factor",
    Kind::Real,
    FACTOR_RANGE.0,
    FACTOR_RANGE.1,
    Fallback::Required,
);

/// Every part, in the order the help lists them.
pub const PARTS: &[PartSpec] = &[
    PartSpec {
        key: "noise",
        effect: crate::scenario::effects::noise,
        fields: &[field(
            "scale",
            Kind::Real,
            0.0,
            1000.0,
            Fallback::Value(1.0),
        )],
        syntax: "noise[=SCALE]",
        doc: "Gaussian sensor noise, SCALE times 1 cm, 5 cm/s, 0.3 degrees, 0.05 rad/s \
              (on the positions before quantisation when read through encoders)",
        stiff_high: false,
    },
    PartSpec {
        key: "delay",
        effect: crate::scenario::effects::delay,
        fields: &[field(
            "delay",
            Kind::Whole,
            0.0,
            crate::scenario::MAX_DELAY as f64,
            Fallback::Value(1.0),
        )],
        syntax: "delay[=N]",
        doc: "N periods of actuator dead time, known to the controller",
        stiff_high: false,
    },
    PartSpec {
        key: "force",
        effect: crate::scenario::effects::force,
        fields: &[FACTOR],
        syntax: "force=F",
        doc: "F times the motor's stall force",
        stiff_high: false,
    },
    PartSpec {
        key: "damping",
        effect: crate::scenario::effects::damping,
        fields: &[FACTOR],
        syntax: "damping=F",
        doc: "F times the motor's damping (back-EMF and drag, N s/m; none on Gymnasium's \
              machine, so nothing to scale there)",
        stiff_high: true,
    },
    PartSpec {
        key: "length",
        effect: crate::scenario::effects::length,
        fields: &[FACTOR],
        syntax: "length=F",
        doc: "F times the pole's length to its centre of mass",
        stiff_high: false,
    },
    PartSpec {
        key: "polemass",
        effect: crate::scenario::effects::polemass,
        fields: &[FACTOR],
        syntax: "polemass=F",
        doc: "F times the pole's mass",
        stiff_high: false,
    },
    PartSpec {
        key: "cartmass",
        effect: crate::scenario::effects::cartmass,
        fields: &[FACTOR],
        syntax: "cartmass=F",
        doc: "F times the cart's mass",
        stiff_high: false,
    },
    PartSpec {
        key: "friction",
        effect: crate::scenario::effects::friction,
        fields: &[
            field(
                "cart coefficient",
                Kind::Real,
                CART_FRICTION_RANGE.0,
                CART_FRICTION_RANGE.1,
                Fallback::Required,
            ),
            field(
                "pivot coefficient",
                Kind::Real,
                PIVOT_FRICTION_RANGE.0,
                PIVOT_FRICTION_RANGE.1,
                Fallback::Value(0.0),
            ),
        ],
        syntax: "friction=C[/P]",
        doc: "Coulomb friction C of the cart on the track and viscous friction P (N m s/rad) \
              at the pivot (Florian 2007's corrected equations)",
        stiff_high: true,
    },
    PartSpec {
        key: "encoder",
        effect: crate::scenario::effects::encoder,
        fields: &[
            field(
                "counts per revolution",
                Kind::LogWhole,
                POLE_COUNTS_RANGE.0,
                POLE_COUNTS_RANGE.1,
                Fallback::Absent,
            ),
            field(
                "counts per metre",
                Kind::Whole,
                CART_COUNTS_RANGE.0,
                CART_COUNTS_RANGE.1,
                Fallback::FiveTimesFirst,
            ),
            field("discount", Kind::Real, 0.0, 0.99, Fallback::Absent),
        ],
        syntax: "encoder[=N[/M[/D]]]",
        doc: "positions read by encoders of N counts per revolution and M per metre (the \
              rig's own if both are omitted) through the board's observer, or with D through \
              the model-free alpha-beta filter of discount D",
        stiff_high: false,
    },
    PartSpec {
        key: "jitter",
        effect: crate::scenario::effects::jitter,
        fields: &[field("share", Kind::Real, 0.0, 0.5, Fallback::Value(0.1))],
        syntax: "jitter[=F]",
        doc: "the encoders are read up to F of a period early or late (an interrupt's \
              latency), uniformly: the positions move on over the offset at the state's \
              velocities; only readings through encoders",
        stiff_high: false,
    },
    PartSpec {
        key: "push",
        effect: crate::scenario::effects::push,
        fields: &[
            field("impulse", Kind::Real, 0.0, 1000.0, Fallback::Value(0.5)),
            field(
                "interval",
                Kind::Whole,
                1.0,
                u32::MAX as f64,
                Fallback::Value(100.0),
            ),
        ],
        syntax: "push[=IMPULSE[/EVERY]]",
        doc: "a push of IMPULSE N s every EVERY periods, to a random side",
        stiff_high: false,
    },
    PartSpec {
        key: "zero",
        effect: crate::faults::zero,
        fields: &[
            field("pole degrees", Kind::Real, -5.0, 5.0, Fallback::Required),
            field("cart mm", Kind::Real, -100.0, 100.0, Fallback::Value(0.0)),
        ],
        syntax: "zero=DEG[/MM]",
        doc: "the encoders' zeros are off for the whole episode: the pole reads DEG degrees \
              and the cart MM mm more than they are (through encoders, in whole counts)",
        stiff_high: false,
    },
    PartSpec {
        key: "glitch",
        effect: crate::faults::glitch,
        fields: &[
            field("counts", Kind::Whole, 1.0, 1e6, Fallback::Value(100.0)),
            interval(100.0),
        ],
        syntax: "glitch[=N[/EVERY]]",
        doc: "the pole encoder reads N counts off for one period every EVERY periods (with \
              exact sensing, the angle is off by N of the rig's pole counts)",
        stiff_high: false,
    },
    PartSpec {
        key: "stuck",
        effect: crate::faults::stuck,
        fields: &[
            field("periods", Kind::Whole, 1.0, 1e6, Fallback::Value(5.0)),
            interval(200.0),
        ],
        syntax: "stuck[=K[/EVERY]]",
        doc: "the readings freeze for K periods of every EVERY: the last one before repeats",
        stiff_high: false,
    },
    PartSpec {
        key: "drop",
        effect: crate::faults::drop,
        fields: &[interval(20.0)],
        syntax: "drop[=EVERY]",
        doc: "every EVERY-th reading never arrives: the sensor returns an error",
        stiff_high: false,
    },
    PartSpec {
        key: "late",
        effect: crate::faults::late,
        fields: &[interval(50.0)],
        syntax: "late[=EVERY]",
        doc: "every EVERY-th period overruns (counted): its command misses the period and the \
              motor holds the one before",
        stiff_high: false,
    },
    PartSpec {
        key: "weak",
        effect: crate::faults::weak,
        fields: &[
            field("factor", Kind::Real, 0.0, 1.0, Fallback::Required),
            field("periods", Kind::Whole, 1.0, 1e6, Fallback::Value(50.0)),
            interval(500.0),
        ],
        syntax: "weak=F[/K[/EVERY]]",
        doc: "the motor gives F times its force for K periods of every EVERY",
        stiff_high: false,
    },
    PartSpec {
        key: "reset",
        effect: crate::faults::reset,
        fields: &[interval(1000.0)],
        syntax: "reset[=EVERY]",
        doc: "the controller restarts every EVERY periods: its observer starts again from the \
              counts, its predictor empty (its counters go on)",
        stiff_high: false,
    },
];

/// How many periods a fault recurs after, defaulting to `default`.
const fn interval(default: f64) -> Field {
    field(
        "interval",
        Kind::Whole,
        1.0,
        u32::MAX as f64,
        Fallback::Value(default),
    )
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
        if p.spec.fields != [FACTOR] && parts[..k].iter().any(|q| q.spec == p.spec) {
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
        Some((b, s)) => match s.parse::<f64>() {
            Ok(v) if (0.0..=1.0).contains(&v) => (b, v),
            _ => {
                return Err(format!(
                    "{} needs a share in [0, 1] after @, found {}",
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
    Ok(Part {
        spec,
        values,
        share,
    })
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
            // A subnormal is no setting anyone means: a slip, lost in the physics.
            Kind::Real => t.parse::<f64>().ok().filter(|v| *v == 0.0 || v.is_normal()),
            Kind::Whole | Kind::LogWhole => t.parse::<u64>().ok().map(|v| v as f64),
        };
        v.filter(|v| (f.lo..=f.hi).contains(v)).ok_or_else(|| {
            let kind = match f.kind {
                Kind::Real => "zero or a normal number",
                Kind::Whole | Kind::LogWhole => "a whole number",
            };
            format!(
                "{name} must be {kind} in [{}, {}], found {}",
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
