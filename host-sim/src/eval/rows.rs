//! The rows one evaluation asks for, checked before any work by `host-sim eval` and Python's
//! `evaluate` alike: at most [`MAX_ROWS`], and each once (a table showing one row twice is a
//! slip: `--scenario all,noise`, `--controller lqr,lqr`, `noise+delay,delay+noise`). A
//! scenario is compared here by what its spec sets: its parts in any order, its numbers
//! however written, a value left at its default or written out (`noise`, `noise=1`), `-0` as
//! 0, a factor given twice as its product (`length=2+length=2`, `length=4`). What depends on
//! the machine (on a rig with a period of dead time, `delay` builds the nominal world) is
//! judged where the worlds are built on the machine the episodes run on
//! (`twin::Scenario::words_on`), which keeps a named set's rows whole.

use twin::Scenario;

use super::ControllerKind;

/// Most rows of one `eval`.
pub const MAX_ROWS: usize = 10_000;

/// Refuses more than [`MAX_ROWS`] rows of `counts` horizons x scenarios x controllers
/// (counts only, so that it can run before the scenarios are parsed: each spec is a row at
/// least); `names` are the caller's for the three lists (its flags, or keywords).
pub fn check_count(counts: [usize; 3], names: [&str; 3]) -> Result<(), String> {
    let rows = counts.iter().fold(1usize, |n, c| n.saturating_mul(*c));
    if rows > MAX_ROWS {
        return Err(format!(
            "{} must make at most {MAX_ROWS} rows; found {rows}",
            names.join(" x ")
        ));
    }
    Ok(())
}

/// Refuses rows asked for twice, or more than [`MAX_ROWS`]: a horizon by its value, a
/// scenario by what its spec sets ([`canonical`]), a controller by its kind. `names` are the caller's for the three lists (its flags, or keywords).
pub fn check_rows(
    horizons: &[u32],
    scenarios: &[Scenario],
    controllers: &[ControllerKind],
    names: [&str; 3],
) -> Result<(), String> {
    check_count([horizons.len(), scenarios.len(), controllers.len()], names)?;
    let [horizon, scenario, controller] = names;
    if let Some((_, h)) = twice(horizons, |h| *h) {
        return Err(format!(
            "{horizon}: expected each row once, found {h} twice"
        ));
    }
    if let Some((a, b)) = twice(scenarios, |s| canonical(&s.name)) {
        let (a, b) = (weights::quote(&a.name), weights::quote(&b.name));
        let what = if a == b {
            format!("{a} twice")
        } else {
            format!("{a} and {b}, one scenario spelt twice")
        };
        return Err(format!("{scenario}: expected each row once, found {what}"));
    }
    if let Some((_, c)) = twice(controllers, |c| *c) {
        return Err(format!(
            "{controller}: expected each row once, found {c} twice"
        ));
    }
    Ok(())
}

/// What a spec sets, as the grammar reads it: each part's values with their defaults filled
/// in and `-0` as 0 (by their bits, to be hashed), a factor given twice as its product, in
/// the order of the keys. A name that is no spec (none the tools make) is its text.
fn canonical(spec: &str) -> Vec<(String, Vec<Option<u64>>)> {
    let Ok(parts) = twin::grammar::parse(spec, "scenario") else {
        return vec![(spec.to_string(), Vec::new())];
    };
    let mut set: std::collections::BTreeMap<String, Vec<Option<f64>>> = Default::default();
    let mut factors: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
    for part in &parts {
        let given: Vec<Option<f64>> = part.values.iter().map(|v| v.map(|s| s.lo)).collect();
        if part.spec.multiplies() {
            let factor = given[0].unwrap_or(1.0);
            factors
                .entry(part.spec.key.to_string())
                .or_default()
                .push(factor);
            continue;
        }
        let filled = twin::grammar::Values::new(part.spec, &given);
        let values: Vec<Option<f64>> = (0..given.len()).map(|i| filled.get(i)).collect();
        set.insert(part.spec.key.to_string(), values);
    }
    for (key, values) in factors {
        set.insert(key, vec![Some(twin::grammar::product(&values))]);
    }
    set.into_iter()
        .map(|(key, values)| {
            let bits = values.iter().map(|v| v.map(|x| (x + 0.0).to_bits()));
            (key, bits.collect())
        })
        .collect()
}

/// The first item whose `key` an earlier one has, with that earlier one: one lookup an item,
/// so ten thousand scenarios from Python cost ten thousand keys, not fifty million pairs.
fn twice<T, K: std::hash::Hash + Eq>(items: &[T], key: impl Fn(&T) -> K) -> Option<(&T, &T)> {
    let mut seen = std::collections::HashMap::new();
    items
        .iter()
        .find_map(|b| seen.insert(key(b), b).map(|a| (a, b)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use twin::Machine;

    fn parsed(specs: &[&str]) -> Vec<Scenario> {
        let specs: Vec<String> = specs.iter().map(|s| s.to_string()).collect();
        Scenario::words_built_on(&specs, &Machine::GYMNASIUM).unwrap()
    }

    const NAMES: [&str; 3] = ["horizon", "scenario", "controller"];

    #[test]
    fn a_world_asked_for_twice_is_refused_however_it_is_spelt() {
        use ControllerKind::*;
        let ok = parsed(&[
            "nominal",
            "noise",
            "noise+delay",
            "noise=2",
            "length=2+length=3",
            "length=2",
            "zero=0/1",
            "zero=0/-1",
            "encoder",
            "encoder=64",
            "encoder=64/64",
        ]);
        assert_eq!(
            check_rows(&[500, 10_000], &ok, &[Policy, Lqr], NAMES),
            Ok(())
        );
        for (specs, found) in [
            (
                &["noise+delay", "delay+noise"][..],
                "\"noise+delay\" and \"delay+noise\"",
            ),
            (
                &["length=2", "length=2.0"],
                "\"length=2\" and \"length=2.0\"",
            ),
            (&["noise", "noise=1"], "\"noise\" and \"noise=1\""),
            (&["delay", "delay=1"], "\"delay\" and \"delay=1\""),
            (&["push", "push=0.5/100"], "\"push\" and \"push=0.5/100\""),
            (
                &["friction=0.1", "friction=0.1/0"],
                "\"friction=0.1\" and \"friction=0.1/0\"",
            ),
            (&["zero=0/1", "zero=-0/1"], "\"zero=0/1\" and \"zero=-0/1\""),
            (
                &["length=2+length=2", "length=4"],
                "\"length=2+length=2\" and \"length=4\"",
            ),
            // Multiplied in the order given, these two products differ in the last bit.
            (
                &[
                    "length=0.9+length=1.6+length=1.5",
                    "length=1.5+length=1.6+length=0.9",
                ],
                "\"length=0.9+length=1.6+length=1.5\" and \"length=1.5+length=1.6+length=0.9\"",
            ),
            (
                &["encoder=64", "encoder=64/320"],
                "\"encoder=64\" and \"encoder=64/320\"",
            ),
        ] {
            let e = check_rows(&[500], &parsed(specs), &[Policy], NAMES).unwrap_err();
            assert!(
                e.contains(found) && e.contains("one scenario spelt twice"),
                "{e}"
            );
        }
        // On a rig with a period of dead time, `delay` builds the nominal world: the
        // robustness set shows both rows all the same.
        let desk = twin::rigfile::parse(include_str!("../../../rigs/desk.toml"), "desk").unwrap();
        let set = Scenario::words_on(&["all".to_string()], &desk).unwrap();
        assert_eq!(check_rows(&[500], &set, &[Policy], NAMES), Ok(()));
        let e = check_rows(&[500, 500], &ok, &[Policy], NAMES).unwrap_err();
        assert_eq!(e, "horizon: expected each row once, found 500 twice");
        let e = check_rows(&[500], &ok, &[Lqr, Policy, Lqr], NAMES).unwrap_err();
        assert_eq!(e, "controller: expected each row once, found lqr twice");
        let e = check_count([10_001, 1, 1], NAMES).unwrap_err();
        assert_eq!(
            e,
            "horizon x scenario x controller must make at most 10000 rows; found 10001"
        );
        assert!(check_count([usize::MAX, 2, 2], NAMES).is_err());
    }
}
