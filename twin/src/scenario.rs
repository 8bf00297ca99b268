//! A scenario: the world one episode runs in, as a spec a person can type (`noise+delay=2`,
//! `length=0.8+encoder=1024`; the grammar is [`crate::grammar`]'s), and the named sets of
//! them the tables use.

use firmware::cartpole::Params;
use firmware::controller::predict::MAX_PREDICT;
use firmware::estimator::Encoders;
use firmware::rig::Rig;

use crate::faults::Faults;
use crate::grammar::{self, FACTOR_RANGE, Part, Values};
use crate::machine::{Integration, Machine, check_integrable};

/// Sensor noise standard deviations of the `noise` part, per channel: 1 cm, 5 cm/s,
/// 0.3 degrees, 0.05 rad/s; a cheap encoder and a finite-difference velocity.
pub const NOISE_STD: [f64; 4] = [0.01, 0.05, 0.005, 0.05];

/// Longest scenario or domain spec accepted.
pub const MAX_SPEC_BYTES: usize = 1000;

/// Most periods of actuator dead time a scenario can have: the longest line the firmware's
/// predictor and observer keep.
pub const MAX_DELAY: u32 = MAX_PREDICT as u32;

/// How the controller reads the plant: the link's, which a board's sensor is built from.
pub use firmware::link::Sensing;

/// A disturbance: an extra force of `impulse / tau` for one period, every `every` periods,
/// towards a random side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    /// Size of each push, N*s.
    pub impulse: f64,
    /// Periods between pushes.
    pub every: u32,
}

/// The world one episode runs in: the plant's true physics, the machine as its board knows
/// it, and what goes wrong around them.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Row label, the spec it was parsed from.
    pub name: String,
    /// The machine as the board knows it: the model its observer and predictor run, its
    /// encoders, its dead time (which is also the true one), its end stops.
    pub rig: Rig,
    /// The plant's true physics, friction included: the rig's, perturbed (the controllers are
    /// not told).
    pub params: Params,
    /// Gaussian sensor noise, standard deviation per channel (zero: none). With encoders,
    /// the position channels' noise is added before quantisation and the velocity channels'
    /// is unused (velocities are estimated).
    pub noise_std: [f64; 4],
    /// How the controller reads the plant.
    pub sensing: Sensing,
    /// Push disturbances.
    pub push: Option<Push>,
    /// How far from the period's start the encoders are read, at most, as a share of the
    /// period: each reading early or late by a uniform draw within it (0: on time).
    pub jitter: f64,
    /// How the world advances the plant over a period.
    pub integration: Integration,
    /// What goes wrong in the loop.
    pub faults: Faults,
}

impl Scenario {
    /// Gymnasium's machine: exact sensors, no dead time, no pushes.
    pub fn nominal() -> Scenario {
        Scenario::nominal_on(&Machine::GYMNASIUM)
    }

    /// `machine` as it is: its rig's own physics, exact sensors, its dead time, no pushes.
    pub fn nominal_on(machine: &Machine) -> Scenario {
        let rig = &machine.rig;
        Scenario {
            name: "nominal".into(),
            rig: *rig,
            params: rig.params,
            noise_std: [0.0; 4],
            sensing: Sensing::Exact,
            push: None,
            jitter: 0.0,
            integration: machine.integration,
            faults: Faults::default(),
        }
    }

    /// Periods of actuator dead time: the force in a period is the command of `delay`
    /// periods before (none before the first command).
    pub fn delay(&self) -> u32 {
        self.rig.dead_time
    }

    /// Whether the board reads encoder counts, not the exact state: only then are readings
    /// taken early or late (`jitter`) and the zero errors rounded to whole counts.
    pub fn reads_counts(&self) -> bool {
        self.sensing != Sensing::Exact
    }

    /// The same world with its board modelling another machine, `board`: the physics its
    /// observer, predictor and gains run, its observer's tuning and its end-stop margin
    /// (a policy trained for one rig and run on another; a rig identified from a true one).
    /// The encoders and the dead time stay the world's: the board has them exactly. A board
    /// whose period is not the world's is refused.
    pub fn known_as(mut self, board: &Rig) -> Result<Scenario, String> {
        crate::machine::same_period(&self.rig, board)?;
        self.rig.params = board.params;
        self.rig.tuning = board.tuning;
        self.rig.end_stop_margin = board.end_stop_margin;
        Ok(self)
    }

    /// Parses a spec on Gymnasium's machine (see [`Scenario::parse_on`]).
    pub fn parse(spec: &str) -> Result<Scenario, String> {
        Scenario::parse_on(spec, &Machine::GYMNASIUM)
    }

    /// Parses a spec ([`crate::grammar`], every value a single number) into a world around
    /// `machine`, as [`Scenario::build_on`] does, and refuses a part that changes nothing on
    /// it: one the world is the same without (`delay=1` on a rig of one period's dead time,
    /// `length=2+length=0.5`, `damping` on a motor without damping), which is the world
    /// without it under another name.
    pub fn parse_on(spec: &str, machine: &Machine) -> Result<Scenario, String> {
        let (s, parts) = Scenario::built(spec, machine)?;
        judge::refuse_idle_on(&s, &parts, machine)?;
        Ok(s)
    }

    /// Builds a spec into a world around `machine` without judging what each part changes
    /// on it: for the named sets, whose rows are the same specs on every machine, and for a
    /// check of a spec before the machine its episodes run on is known. Factors of one
    /// quantity multiply ([`words::world_of`]); every quantity must end within
    /// [`FACTOR_RANGE`] of the rig's.
    pub fn build_on(spec: &str, machine: &Machine) -> Result<Scenario, String> {
        Scenario::built(spec, machine).map(|(s, _)| s)
    }

    /// [`Scenario::build_on`]'s world, and the parts it was built from.
    fn built(spec: &str, machine: &Machine) -> Result<(Scenario, Vec<Part>), String> {
        if spec.is_empty() {
            // An empty `--scenario` (or a comma with nothing after it) is a slip, not a
            // request for the nominal world, which has a name.
            return Err(
                "scenario: expected a spec (`nominal` for the nominal world); found \
                        an empty one"
                    .into(),
            );
        }
        let shown = weights::quote(spec);
        let parts = grammar::parse(spec, "scenario")?;
        if let Some(part) = parts
            .iter()
            .find(|p| p.share != 1.0 || p.values.iter().flatten().any(|v| !v.is_point()))
        {
            return Err(format!(
                "scenario {shown}: {} takes single values, not ranges or shares (those \
                 are a domain's)",
                part.spec.key
            ));
        }
        let mut s = words::world_of(parts.iter(), machine);
        s.name = spec.to_string();
        check_factors(&s.params, &machine.rig.params)
            .and_then(|()| check_integrable(&s.params, s.integration))
            .map_err(|e| format!("scenario {shown}: {e}"))?;
        s.check_board()
            .map_err(|e| format!("scenario {shown}: the board refuses it: {e}"))?;
        Ok((s, parts))
    }

    /// Sets what `part` says with `values` (one per field, `None` where left out).
    pub(crate) fn apply(&mut self, part: &Part, values: &[Option<f64>]) {
        (part.spec.effect)(self, &Values::new(part.spec, values));
    }

    /// The robustness table's rows: nominal, each perturbation alone, and all three kinds of
    /// trouble at once.
    pub fn default_set() -> Vec<Scenario> {
        Scenario::default_set_on(&Machine::GYMNASIUM)
    }

    /// [`Scenario::default_set`] around `machine`.
    pub fn default_set_on(machine: &Machine) -> Vec<Scenario> {
        parse_all(
            machine,
            &[
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
            ],
        )
    }

    /// The `hard` set: perturbations beyond the default set's under which bang-bang LQR with
    /// its nominal gain fails (see [`HARD`] and `docs/CONTROL.md`).
    pub fn hard_set() -> Vec<Scenario> {
        Scenario::hard_set_on(&Machine::GYMNASIUM)
    }

    /// [`Scenario::hard_set`] around `machine`.
    pub fn hard_set_on(machine: &Machine) -> Vec<Scenario> {
        parse_all(machine, HARD)
    }

    /// The `faults` set around `machine` ([`FAULTS`]).
    pub fn faults_set_on(machine: &Machine) -> Vec<Scenario> {
        parse_all(machine, FAULTS)
    }

    /// The candidates the `hard` set is chosen from ([`HARD_CANDIDATES`]), on Gymnasium's
    /// machine, where the choice was made: the `--scenario` word is refused on any other.
    pub fn hard_candidates() -> Vec<Scenario> {
        parse_all(&Machine::GYMNASIUM, HARD_CANDIDATES)
    }
}

/// The specs of [`Scenario::hard_set`]: the [`HARD_CANDIDATES`] under which bang-bang LQR
/// with its nominal gain fails in part or whole over 10,000 steps, encoders read through the
/// observer: long dead time, short poles with dead time, friction with dead time, coarse
/// encoders with noise, strong pushes, with exact sensing or read through encoders
/// (`docs/results/eval-hard-candidates.md` has every candidate's figures).
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

/// The `faults` set: each transient fault of a real loop alone (not `zero`, a lasting
/// error: `docs/RIGS.md`), at its default and a severe level
/// (half a revolution of glitch, half a second stuck, every other reading lost or period
/// late, the motor dead for 0.2 s every 5 s, a restart every third period), read through
/// the encoders and the observer where the fault is the sensor's, and all of them at once
/// with noise and dead time (`docs/FAULTS.md`).
pub const FAULTS: &[&str] = &[
    "encoder+glitch",
    "encoder+glitch=2000/50",
    "encoder+stuck",
    "encoder+stuck=25/500",
    "encoder+drop",
    "encoder+drop=2",
    "late",
    "late=2",
    "delay+late=5",
    "weak=0.5",
    "weak=0/10/250",
    "encoder+reset",
    "encoder+reset=3",
    "noise+delay+encoder+glitch+stuck+drop+late+weak=0.5+reset",
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

fn parse_all(machine: &Machine, specs: &[&str]) -> Vec<Scenario> {
    specs
        .iter()
        .map(|s| Scenario::build_on(s, machine).expect("built-in scenario specs build"))
        .collect()
}

/// Every perturbed quantity within [`FACTOR_RANGE`] of `nominal`'s.
pub(crate) fn check_factors(p: &Params, nominal: &Params) -> Result<(), String> {
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

/// What each part of a world does to a scenario ([`grammar::PARTS`] names each beside its
/// fields); the faults' are [`crate::faults`]'.
pub(crate) mod effects {
    use super::*;

    /// `noise=SCALE`.
    pub(crate) fn noise(s: &mut Scenario, v: &Values) {
        s.noise_std = NOISE_STD.map(|sd| sd * v.first());
    }

    /// `delay=N`.
    pub(crate) fn delay(s: &mut Scenario, v: &Values) {
        s.rig.dead_time = v.first() as u32;
    }

    /// `force=F`.
    pub(crate) fn force(s: &mut Scenario, v: &Values) {
        s.params.force_mag *= v.first();
    }

    /// `damping=F`.
    pub(crate) fn damping(s: &mut Scenario, v: &Values) {
        s.params.motor_damping *= v.first();
    }

    /// `length=F`.
    pub(crate) fn length(s: &mut Scenario, v: &Values) {
        s.params.length *= v.first();
    }

    /// `polemass=F`.
    pub(crate) fn polemass(s: &mut Scenario, v: &Values) {
        s.params.masspole *= v.first();
    }

    /// `cartmass=F`.
    pub(crate) fn cartmass(s: &mut Scenario, v: &Values) {
        s.params.masscart *= v.first();
    }

    /// `friction=C/P`.
    pub(crate) fn friction(s: &mut Scenario, v: &Values) {
        s.params.cart_friction = v.first();
        s.params.pole_friction = v.get(1).unwrap_or(0.0);
    }

    /// `encoder=N/M/D`: the rig's own encoders unless counts are given.
    pub(crate) fn encoder(s: &mut Scenario, v: &Values) {
        if let Some(n) = v.get(0) {
            let n = (n as u32).max(16);
            s.rig.encoders = Encoders {
                cart_counts_per_m: v.get(1).map_or(n.saturating_mul(5), |m| m as u32),
                pole_counts_per_rev: n,
            };
        }
        s.sensing = match v.get(2) {
            Some(d) => Sensing::AlphaBeta(d as f32),
            None => Sensing::Observer,
        };
    }

    /// `jitter=F`.
    pub(crate) fn jitter(s: &mut Scenario, v: &Values) {
        s.jitter = v.first();
    }

    /// `push=IMPULSE/EVERY`.
    pub(crate) fn push(s: &mut Scenario, v: &Values) {
        s.push = Some(Push {
            impulse: v.first(),
            every: v.get(1).map_or(100, |k| (k as u32).max(1)),
        });
    }
}

mod judge;
mod words;
pub(crate) use judge::idle_part;

#[cfg(test)]
mod tests;
