//! Whether a part of a scenario or a domain changes nothing, judged on the worlds its parts
//! build on a machine and on how those worlds run, not on the spec. A part's effect can
//! depend on the machine (`delay=1` is one rig's own dead time and another rig's change,
//! `damping` scales a damping one motor does not have), on the parts beside it (`jitter`
//! moves only readings taken through encoders), and factors of one quantity can multiply
//! to 1. A scenario is the domain whose every value is a point, so one judgement serves both.

use super::Scenario;
use super::words::world_of;
use crate::faults::{Window, zero_counts, zero_read};
use crate::grammar::{Part, PartSpec, Span};
use crate::machine::Machine;

/// Refuses a part of `parts` (a factor's values all at once) that `s`, the world they build
/// on `machine`, runs the same without.
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
/// `machine`, or `None` where one of them runs otherwise without those parts. The sampler
/// draws each value within its range and each share's coin alone, so the worlds looked at
/// are: the key's parts at the low ends of their ranges and at the high ends, all at once
/// (a factor's values multiply, and their product is 1 at both ends only if it is 1
/// throughout); those of share 1 together, with each of a lower share beside them or alone
/// (its coin may fall without the others'); and the other parts at either end, all of
/// them or only those of share 1 (an encoder part of a lower share, which `jitter` needs,
/// or whose coarse counts hide a `zero`).
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
                // Read at the high ends last, where a part that needs another sets the most
                // (a jitter range's low end may be 0, which needs nothing).
                why = Some(reason(key, &with, set.len(), machine));
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

/// Why a part of `key` (`factors` of them at once) changes nothing in `with`, a world it
/// runs the same without, on `machine`.
fn reason(key: &PartSpec, with: &Scenario, factors: usize, machine: &Machine) -> String {
    if let Some(why) = scales_nothing(key, machine) {
        return why.to_string();
    }
    if let Some(need) = (NEEDS.iter()).find(|n| n.keys.contains(&key.key) && (n.moot)(with)) {
        return (need.why)(with);
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

/// Parts whose effect needs something beside them: in a world where `moot` holds, the
/// fields `keys` set change nothing in any episode, and `clear` takes them out.
struct Need {
    keys: &'static [&'static str],
    moot: fn(&Scenario) -> bool,
    clear: fn(&mut Scenario),
    why: fn(&Scenario) -> String,
}

/// Every part a world can hold without effect ([`crate::world::World`]'s sensors). Left
/// out, as the controller's rather than the world's: a `reset` under exact sensing without
/// dead time, which restarts nothing in the twin's episodes but restarts the monitor of a
/// board in the loop; a `glitch` of whole revolutions, which the observer reads as none
/// and the alpha-beta filter does not.
const NEEDS: &[Need] = &[
    Need {
        keys: &["jitter"],
        moot: |s| s.jitter > 0.0 && !s.reads_counts(),
        clear: |s| s.jitter = 0.0,
        why: |_| {
            "under exact sensing, where no encoder is read early or late; expected an encoder \
             part beside it"
                .into()
        },
    },
    Need {
        keys: &["zero"],
        moot: |s| {
            let encoders = &s.rig.encoders;
            s.reads_counts() && (s.faults.zero).is_some_and(|z| zero_counts(z, encoders) == (0, 0))
        },
        clear: |s| s.faults.zero = None,
        why: |s| {
            let e = &s.rig.encoders;
            format!(
                "through encoders of {} counts per revolution and {} per metre, which round \
                 its errors to no count; expected an error of half a count or more",
                e.pole_counts_per_rev, e.cart_counts_per_m
            )
        },
    },
    // Every reading lost: what a reading would have held reaches nothing. A stuck sensor
    // repeats a reading the drop did not reach ([`crate::world::World::measure`]).
    Need {
        keys: &["noise", "zero", "glitch", "jitter"],
        moot: |s| s.faults.drop.is_some_and(|w| w.always()) && s.faults.stuck.is_none(),
        clear: |s| {
            s.noise_std = [0.0; 4];
            s.faults.zero = None;
            s.faults.glitch = None;
            s.jitter = 0.0;
        },
        why: |_| {
            "where every reading is lost (drop=1, and no stuck sensor to repeat one); expected \
             a drop that lets some through, or the part left out"
                .into()
        },
    },
    // Readings frozen for good at the first: a fault of later periods reaches nothing.
    Need {
        keys: &["glitch"],
        moot: |s| frozen(s) && (s.faults.glitch).is_some_and(|(_, w)| !w.holds(0)),
        clear: |s| s.faults.glitch = None,
        why: |_| FROZEN.into(),
    },
    Need {
        keys: &["drop"],
        moot: |s| frozen(s) && (s.faults.drop).is_some_and(|w| !w.holds(0)),
        clear: |s| s.faults.drop = None,
        why: |_| FROZEN.into(),
    },
];

/// Why a sensing fault that misses the first period changes nothing in a [`frozen`] world.
const FROZEN: &str = "where the readings freeze for good at the first (stuck with K = EVERY), \
     a period it misses; expected EVERY 1, or the part left out";

/// Whether `s`'s readings freeze for good at the first period's: a stuck sensor in every
/// period repeats the reading before, and the first has none before it.
fn frozen(s: &Scenario) -> bool {
    s.faults.stuck.is_some_and(|w| w.always())
}

/// `s` as its episodes run, in one form: a field a part sets without effect there
/// ([`NEEDS`]) taken out, a stuck sensor in every period written as one stuck every
/// period, a zero error read through encoders as the whole counts it adds.
pub(super) fn in_effect(s: &Scenario) -> Scenario {
    let mut out = s.clone();
    for need in NEEDS.iter().filter(|n| (n.moot)(s)) {
        (need.clear)(&mut out);
    }
    out.faults.stuck = (out.faults.stuck).map(|w| if w.always() { Window::every(1) } else { w });
    if out.reads_counts() {
        out.faults.zero = (out.faults.zero).map(|z| zero_read(z, &out.rig.encoders));
    }
    out
}

#[cfg(test)]
mod tests;
