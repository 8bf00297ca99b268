//! The rows one evaluation asks for, checked before any work by `host-sim eval` and Python's
//! `evaluate` alike: at most [`MAX_ROWS`], and each once (a table showing one row twice is a
//! slip: `--scenario all,noise`, `--controller lqr,lqr`, `noise+delay,delay+noise`). A
//! scenario is compared by its spec, its parts in any order and its numbers however written,
//! not by the world it builds: on a rig with a period of dead time, `delay` builds the
//! nominal world, and the robustness set shows both rows.

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
/// scenario by its spec ([`canonical`]: its parts in any order, its numbers however
/// written), a controller by its kind. `names` are the caller's for the three lists (its flags, or keywords).
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

/// A spec's parts, each with its numbers as `f64` writes them, in order.
fn canonical(spec: &str) -> Vec<String> {
    let number = |v: &str| v.parse::<f64>().map_or(v.to_string(), |x| x.to_string());
    let mut parts: Vec<String> = spec
        .split('+')
        .map(|part| match part.split_once('=') {
            None => part.to_string(),
            Some((key, values)) => {
                let values: Vec<String> = values.split('/').map(number).collect();
                format!("{key}={}", values.join("/"))
            }
        })
        .collect();
    parts.sort();
    parts
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
        Scenario::words_on(&specs, &Machine::GYMNASIUM).unwrap()
    }

    const NAMES: [&str; 3] = ["horizon", "scenario", "controller"];

    #[test]
    fn a_world_asked_for_twice_is_refused_however_it_is_spelt() {
        use ControllerKind::*;
        let ok = parsed(&["nominal", "noise", "noise+delay", "noise=2"]);
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
