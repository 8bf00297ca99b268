//! The table of parts ([`PARTS`]): each part's key, fields, bounds, defaults, syntax and
//! meaning, and what it does to a scenario.

use super::{
    CART_COUNTS_RANGE, CART_FRICTION_RANGE, FACTOR_RANGE, Fallback, Field, Idle, Kind,
    PIVOT_FRICTION_RANGE, POLE_COUNTS_RANGE, PartSpec, Stretch, field,
};

/// A factor on one of the rig's quantities: the parts that multiply when given twice.
pub(super) const FACTOR: Field = field(
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
        idle: Idle::First(0.0),
        stretch: None,
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
        idle: Idle::Never,
        stretch: None,
    },
    PartSpec {
        key: "force",
        effect: crate::scenario::effects::force,
        fields: &[FACTOR],
        syntax: "force=F",
        doc: "F times the motor's stall force",
        stiff_high: false,
        idle: Idle::First(1.0),
        stretch: None,
    },
    PartSpec {
        key: "damping",
        effect: crate::scenario::effects::damping,
        fields: &[FACTOR],
        syntax: "damping=F",
        doc: "F times the motor's damping (back-EMF and drag, N s/m; none on Gymnasium's \
              machine, where it is refused)",
        stiff_high: true,
        idle: Idle::First(1.0),
        stretch: None,
    },
    PartSpec {
        key: "length",
        effect: crate::scenario::effects::length,
        fields: &[FACTOR],
        syntax: "length=F",
        doc: "F times the pole's length to its centre of mass",
        stiff_high: false,
        idle: Idle::First(1.0),
        stretch: None,
    },
    PartSpec {
        key: "polemass",
        effect: crate::scenario::effects::polemass,
        fields: &[FACTOR],
        syntax: "polemass=F",
        doc: "F times the pole's mass",
        stiff_high: false,
        idle: Idle::First(1.0),
        stretch: None,
    },
    PartSpec {
        key: "cartmass",
        effect: crate::scenario::effects::cartmass,
        fields: &[FACTOR],
        syntax: "cartmass=F",
        doc: "F times the cart's mass",
        stiff_high: false,
        idle: Idle::First(1.0),
        stretch: None,
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
        idle: Idle::Never,
        stretch: None,
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
        idle: Idle::Never,
        stretch: None,
    },
    PartSpec {
        key: "jitter",
        effect: crate::scenario::effects::jitter,
        fields: &[field("share", Kind::Real, 0.0, 0.5, Fallback::Value(0.1))],
        syntax: "jitter[=F]",
        doc: "the encoders are read up to F of a period early or late (an interrupt's \
              latency), uniformly: the positions move on over the offset at the state's \
              velocities; only readings through encoders, so refused without an encoder \
              part",
        stiff_high: false,
        idle: Idle::First(0.0),
        stretch: None,
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
        idle: Idle::First(0.0),
        stretch: None,
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
              and the cart MM mm more than they are (through encoders, in whole counts: \
              refused where both round to none)",
        stiff_high: false,
        idle: Idle::Every(0.0),
        stretch: None,
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
        idle: Idle::Never,
        stretch: None,
    },
    PartSpec {
        key: "stuck",
        effect: crate::faults::stuck,
        fields: &[
            field("periods", Kind::Whole, 1.0, 1e6, Fallback::Value(5.0)),
            interval(200.0),
        ],
        syntax: "stuck[=K[/EVERY]]",
        doc: "the readings freeze for K periods of every EVERY: the last one before repeats \
              (with K = EVERY, the first reading for good, so a glitch or drop that misses \
              the first period is refused beside it)",
        stiff_high: false,
        idle: Idle::Never,
        stretch: Some(Stretch {
            field: 0,
            always: None,
        }),
    },
    PartSpec {
        key: "drop",
        effect: crate::faults::drop,
        fields: &[interval(20.0)],
        syntax: "drop[=EVERY]",
        doc: "every EVERY-th reading never arrives: the sensor returns an error (with EVERY \
              1, none does, so noise, zero, glitch and jitter are refused beside it unless a \
              stuck sensor repeats a reading)",
        stiff_high: false,
        idle: Idle::Never,
        stretch: None,
    },
    PartSpec {
        key: "late",
        effect: crate::faults::late,
        fields: &[interval(50.0)],
        syntax: "late[=EVERY]",
        doc: "every EVERY-th period overruns (counted): its command misses the period and the \
              motor holds the one before",
        stiff_high: false,
        idle: Idle::Never,
        stretch: None,
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
        idle: Idle::First(1.0),
        stretch: Some(Stretch {
            field: 1,
            always: Some("force=F"),
        }),
    },
    PartSpec {
        key: "reset",
        effect: crate::faults::reset,
        fields: &[interval(1000.0)],
        syntax: "reset[=EVERY]",
        doc: "the controller restarts every EVERY periods: its observer starts again from the \
              counts, its predictor empty (its counters go on)",
        stiff_high: false,
        idle: Idle::Never,
        stretch: None,
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
