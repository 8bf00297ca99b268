//! The worlds the tools' `--scenario` words build on a machine, and which of them are one
//! world asked for twice.

use std::collections::hash_map::{Entry, HashMap};

use super::Scenario;
use super::judge::in_effect;
use crate::grammar::{self, Part, PartSpec};
use crate::machine::Machine;

impl Scenario {
    /// What the tools' `--scenario` words name on `machine`: a named set (`all`, `hard`,
    /// `hard-candidates`, `faults`) or one spec each ([`Scenario::parse_on`]), in order. A
    /// spec that builds the world another row builds on `machine` is refused: one row asked
    /// for twice. The named sets keep their rows on every machine, even two of one world (on
    /// a rig with a period of dead time, the default set's `delay` builds its `nominal`);
    /// `hard-candidates` is refused off Gymnasium's machine ([`Scenario::hard_candidates`]).
    pub fn words_on(words: &[String], machine: &Machine) -> Result<Vec<Scenario>, String> {
        let (rows, typed) = expand(words, machine, Scenario::parse_on)?;
        refuse_same_world(&rows, &typed)?;
        Ok(rows)
    }

    /// The words' rows as [`Scenario::build_on`] builds them, without judging what they
    /// change on `machine`: for a check of their specs before the machine the episodes run
    /// on is known.
    pub fn words_built_on(words: &[String], machine: &Machine) -> Result<Vec<Scenario>, String> {
        expand(words, machine, Scenario::build_on).map(|(rows, _)| rows)
    }

    /// Whether `other` runs as this world does, under whatever name: a field that changes
    /// nothing in its episodes (`jitter` under exact sensing) aside.
    pub fn same_world(&self, other: &Scenario) -> bool {
        let named = Scenario {
            name: other.name.clone(),
            ..in_effect(self)
        };
        named == in_effect(other)
    }
}

/// The rows `words` name, each spec built by `spec`, and whether each row was a spec (not a
/// named set's).
type Rows = (Vec<Scenario>, Vec<bool>);

fn expand(
    words: &[String],
    machine: &Machine,
    spec: fn(&str, &Machine) -> Result<Scenario, String>,
) -> Result<Rows, String> {
    let (mut rows, mut typed) = (Vec::new(), Vec::new());
    for word in words {
        let set = match word.as_str() {
            "all" => Scenario::default_set_on(machine),
            "hard" => Scenario::hard_set_on(machine),
            "hard-candidates" if *machine == Machine::GYMNASIUM => Scenario::hard_candidates(),
            "hard-candidates" => return Err(HARD_CANDIDATES_OFF_GYMNASIUM.into()),
            "faults" => Scenario::faults_set_on(machine),
            _ => {
                rows.push(spec(word, machine)?);
                typed.push(true);
                continue;
            }
        };
        typed.extend(set.iter().map(|_| false));
        rows.extend(set);
    }
    Ok((rows, typed))
}

/// Why `hard-candidates` is refused off Gymnasium's machine: its rows are the pool the
/// `hard` set was chosen from by runs there, built on Gymnasium's plant; on another machine
/// they would be neither that pool nor the machine's own worlds.
const HARD_CANDIDATES_OFF_GYMNASIUM: &str = "scenario: expected `hard-candidates` on \
     Gymnasium's machine, where the `hard` set was chosen from its rows; found another rig or \
     world: name the specs wanted, or `hard`, which builds on every machine";

/// Refuses a spec's row whose world another row builds ([`Scenario::same_world`]). Worlds
/// are compared by their fields as `Debug` writes them (every number in its shortest exact
/// form), so that ten thousand rows cost ten thousand keys, not fifty million pairs.
fn refuse_same_world(rows: &[Scenario], typed: &[bool]) -> Result<(), String> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    for (b, row) in rows.iter().enumerate() {
        let world = Scenario {
            name: String::new(),
            ..in_effect(row)
        };
        match seen.entry(format!("{world:?}")) {
            Entry::Vacant(e) => {
                e.insert(b);
            }
            Entry::Occupied(e) if typed[*e.get()] || typed[b] => {
                return Err(format!(
                    "scenario: expected each row once, found {} and {}, which build one world \
                     on this machine",
                    weights::quote(&rows[*e.get()].name),
                    weights::quote(&row.name)
                ));
            }
            Entry::Occupied(_) => {}
        }
    }
    Ok(())
}

/// The world `parts` build around `machine`, in the spec's order, but that the values of a
/// factor given again multiply into one factor ([`grammar::product`]), applied where the
/// factor first appears: however the spec orders them, the same bits.
pub(super) fn world_of<'a>(
    parts: impl Iterator<Item = &'a Part> + Clone,
    machine: &Machine,
) -> Scenario {
    let mut factors: Vec<(&PartSpec, Vec<f64>)> = Vec::new();
    for part in parts.clone().filter(|p| p.spec.multiplies()) {
        let value = part.values[0].map_or(1.0, |v| v.lo);
        match factors.iter_mut().find(|(spec, _)| *spec == part.spec) {
            Some((_, values)) => values.push(value),
            None => factors.push((part.spec, vec![value])),
        }
    }
    let mut s = Scenario::nominal_on(machine);
    for part in parts {
        if !part.spec.multiplies() {
            let values: Vec<Option<f64>> = part.values.iter().map(|v| v.map(|v| v.lo)).collect();
            s.apply(part, &values);
        } else if let Some(k) = factors.iter().position(|(spec, _)| *spec == part.spec) {
            let (_, values) = factors.swap_remove(k);
            s.apply(part, &[Some(grammar::product(&values))]);
        }
    }
    s
}
