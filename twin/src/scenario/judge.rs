//! Whether a part of a scenario or a domain changes nothing, judged on the worlds its parts
//! build on a machine, not on the spec. A part's effect can depend on the machine
//! (`delay=1` is one rig's own dead time and another rig's change, `damping` scales a
//! damping one motor does not have), and factors of one quantity can multiply to 1. A
//! scenario is the domain whose every value is a point, so one judgement serves both.

use super::Scenario;
use super::words::world_of;
use crate::grammar::{Part, PartSpec, Span};
use crate::machine::Machine;

/// Refuses a part of `parts` (a factor's values all at once) that `s`, the world they build
/// on `machine`, is the same without.
pub(super) fn refuse_idle_on(
    s: &Scenario,
    parts: &[Part],
    machine: &Machine,
) -> Result<(), String> {
    match idle_part(parts, machine) {
        Some((key, why)) => Err(format!(
            "scenario {}: {key} changes nothing {why}",
            weights::quote(&s.name)
        )),
        None => Ok(()),
    }
}

/// The first key of `parts` whose parts change nothing in any world a sampler of them
/// builds on `machine` (for a scenario, its one world): its key, and why.
pub(crate) fn idle_part(parts: &[Part], machine: &Machine) -> Option<(&'static str, String)> {
    let mut judged: Vec<&PartSpec> = Vec::new();
    for part in parts {
        if judged.contains(&part.spec) {
            continue;
        }
        judged.push(part.spec);
        if let Some(why) = idle_key(part.spec, parts, machine) {
            return Some((part.spec.key, why));
        }
    }
    None
}

/// Why the parts of `key` change nothing in the worlds a sampler of `parts` builds on
/// `machine`, or `None` where one of them is another world without those parts. The sampler
/// draws each value within its range and each share's coin alone, so the worlds looked at
/// are: the key's parts at the low ends of their ranges and at the high ends, all at once
/// (a factor's values multiply, and their product is 1 at both ends only if it is 1
/// throughout); those of share 1 together, with each of a lower share beside them or alone
/// (its coin may fall without the others'); and the other parts at either end, all of
/// them or only those of share 1.
fn idle_key(key: &PartSpec, parts: &[Part], machine: &Machine) -> Option<String> {
    let ranged = parts
        .iter()
        .any(|p| p.values.iter().flatten().any(|v| !v.is_point()));
    let ends: &[bool] = if ranged { &[false, true] } else { &[false] };
    let shared = parts.iter().any(|p| p.share < 1.0);
    let beside: &[bool] = if shared { &[true, false] } else { &[true] };
    let (always, sometimes): (Vec<usize>, Vec<usize>) = (0..parts.len())
        .filter(|&i| parts[i].spec == key)
        .partition(|&i| parts[i].share == 1.0);
    let mut sets: Vec<Vec<usize>> = Vec::new();
    if !always.is_empty() {
        sets.push(always.clone());
    }
    sets.extend(sometimes.iter().map(|&i| [&always[..], &[i]].concat()));
    let mut why = None;
    for &all in beside {
        let other = |i: usize| parts[i].spec != key && (all || parts[i].share == 1.0);
        for (&around, &high) in ends.iter().flat_map(|a| ends.iter().map(move |h| (a, h))) {
            for set in &sets {
                // In the spec's order, as a sampler applies them.
                let at = |i: usize| end(&parts[i], if set.contains(&i) { high } else { around });
                let with: Vec<Part> = (0..parts.len())
                    .filter(|&i| other(i) || set.contains(&i))
                    .map(at)
                    .collect();
                let without: Vec<Part> = (0..parts.len()).filter(|&i| other(i)).map(at).collect();
                let (with, without) = (
                    world_of(with.iter(), machine),
                    world_of(without.iter(), machine),
                );
                if !with.same_world(&without) {
                    return None;
                }
                why.get_or_insert_with(|| reason(key, set.len(), machine));
            }
        }
    }
    why
}

/// `part` with each range at its low end, or its high.
fn end(part: &Part, high: bool) -> Part {
    Part {
        values: (part.ends(high).into_iter())
            .map(|v| v.map(|x| Span { lo: x, hi: x }))
            .collect(),
        ..part.clone()
    }
}

/// Why a part of `key` (`factors` of them at once) changes nothing on `machine`.
fn reason(key: &PartSpec, factors: usize, machine: &Machine) -> String {
    if let Some(why) = scales_nothing(key, machine) {
        return why.to_string();
    }
    if key.key == "delay" {
        return format!(
            "on this machine, whose own dead time is {}; expected another value, or the part \
             left out",
            crate::machine::periods(machine.rig.dead_time)
        );
    }
    if factors > 1 {
        return "on this machine: its factors multiply to 1; expected other values, or the \
                part left out"
            .to_string();
    }
    "on this machine, which has it already; expected another value, or the part left out"
        .to_string()
}

/// Why a part of `spec` changes nothing on `machine` at any value, if it does: a factor on a
/// damping the motor does not have (Gymnasium's).
pub(crate) fn scales_nothing(spec: &PartSpec, machine: &Machine) -> Option<&'static str> {
    (spec.key == "damping" && machine.rig.params.motor_damping == 0.0).then_some(
        "on a machine without motor damping; expected another part, or a rig that has some",
    )
}
