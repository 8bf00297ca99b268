//! The paper's ablations with many seeds: Tables 1, 4, 5 and 6, the two choices its prose
//! argues for (Xavier vs N(0, 0.1) initialisation, hard vs soft target updates), the single
//! changes that might let its preset converge, the learning rewards and readings of its text
//! that do (`shaping`), and the four tables again on the preset that converges
//! (`paper-fixed`). Every (configuration, seed) pair is an independent run.
//!
//! - `variants`: the studies' configurations.
//! - `stats`: per-run and per-configuration numbers, in the project's interval convention.
//! - `report`: `results.json`, `tables.md` and the figures.

use anyhow::{Context, Result};
use rayon::prelude::*;

use crate::config::{Config, ConfigError};
use crate::train;

mod report;
mod stats;
mod variants;

pub use report::{seed_json, tables_md, write};
pub use stats::{Row, RunStats, max_drop, row};
pub use variants::{STUDIES, Variant, variants};

/// The rows of `all` in `studies` (every row if none is named). A study not in [`STUDIES`]
/// is refused, and so is one named twice: its rows would be run and tabled once, a slip
/// merged without a word.
pub fn chosen(all: Vec<Variant>, studies: &[String]) -> Result<Vec<Variant>, ConfigError> {
    for (i, s) in studies.iter().enumerate() {
        if !STUDIES.iter().any(|(known, _)| known == s) {
            let known: Vec<&str> = STUDIES.iter().map(|(s, _)| *s).collect();
            return Err(ConfigError(format!(
                "--study: expected one of {}, found {}",
                known.join(", "),
                weights::quote(s)
            )));
        }
        if studies[..i].contains(s) {
            return Err(ConfigError(format!(
                "--study: expected each study once, found {s} twice"
            )));
        }
    }
    Ok(all
        .into_iter()
        .filter(|v| studies.is_empty() || studies.iter().any(|s| s == v.study))
        .collect())
}

/// Runs every distinct configuration of `variants` for `seeds` seeds in parallel; rows that
/// share a configuration (the paper preset appears in every study) share its runs.
/// `tick` is called once per finished run.
pub fn run(
    variants: &[Variant],
    seeds: u64,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<Vec<RunStats>>> {
    let mut distinct: Vec<String> = Vec::new();
    let keys: Vec<usize> = variants
        .iter()
        .map(|v| {
            let key = serde_json::to_string(&v.cfg).expect("configs serialise");
            distinct.iter().position(|k| *k == key).unwrap_or_else(|| {
                distinct.push(key);
                distinct.len() - 1
            })
        })
        .collect();
    let firsts: Vec<&Config> = (0..distinct.len())
        .map(|d| {
            &variants[keys
                .iter()
                .position(|&k| k == d)
                .expect("every key has a row")]
            .cfg
        })
        .collect();
    let jobs: Vec<(usize, u64)> = (0..firsts.len())
        .flat_map(|d| (0..seeds).map(move |s| (d, s)))
        .collect();
    let done: Vec<Result<RunStats>> = jobs
        .par_iter()
        .map(|&(d, seed)| {
            let episodes = train::episodes(firsts[d], seed)
                .with_context(|| format!("config {d}, seed {seed}"))?;
            tick();
            Ok(RunStats::of(seed, &episodes))
        })
        .collect();
    let mut by_config: Vec<Vec<RunStats>> = vec![Vec::new(); firsts.len()];
    for ((d, _), r) in jobs.iter().zip(done) {
        by_config[*d].push(r?);
    }
    Ok(keys.iter().map(|&k| by_config[k].clone()).collect())
}

/// Number of distinct training runs `run` will do.
pub fn distinct_runs(variants: &[Variant], seeds: u64) -> u64 {
    let mut keys: Vec<String> = variants
        .iter()
        .map(|v| serde_json::to_string(&v.cfg).expect("configs serialise"))
        .collect();
    keys.sort();
    keys.dedup();
    keys.len() as u64 * seeds
}

#[cfg(test)]
mod tests {
    use super::*;
    use host_common::provenance::Provenance;

    fn provenance() -> Provenance {
        Provenance::new("policy-export", vec!["reproduce".into()])
    }

    #[test]
    fn studies_are_chosen_each_once() {
        let studies =
            |names: &[&str]| -> Vec<String> { names.iter().map(|s| s.to_string()).collect() };
        let all = variants(&Config::paper());
        let some = chosen(all.clone(), &studies(&["table4", "init"])).unwrap();
        assert!(some.iter().all(|v| ["table4", "init"].contains(&v.study)));
        assert!(some.iter().any(|v| v.study == "init") && some.iter().any(|v| v.study == "table4"));
        assert_eq!(chosen(all.clone(), &[]).unwrap().len(), all.len());
        let e = chosen(all, &studies(&["table1", "table4", "table1"])).unwrap_err();
        assert_eq!(e.0, "--study: expected each study once, found table1 twice");
    }

    #[test]
    fn a_short_study_writes_tables_json_and_figures() {
        let base = Config {
            episodes: 20,
            ..Config::paper()
        };
        let vs: Vec<Variant> = variants(&base)
            .into_iter()
            .filter(|v| v.study == "table4")
            .collect();
        assert_eq!(distinct_runs(&vs, 2), 4);
        let runs = run(&vs, 2, &|| {}).unwrap();
        assert_eq!(runs.iter().map(Vec::len).collect::<Vec<_>>(), [2, 2]);
        // Same seed and flags, same numbers.
        let again = run(&vs, 2, &|| {}).unwrap();
        assert_eq!(runs[0][1].returns, again[0][1].returns);
        let dir = std::env::temp_dir().join(format!("reproduce-{}", std::process::id()));
        let rows = write(&dir, &vs, &runs, &provenance()).unwrap();
        assert_eq!(rows.len(), 2);
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("results.json")).unwrap()).unwrap();
        assert_eq!(json["rows"][0]["label"], "DQN");
        assert_eq!(json["provenance"]["argv"], serde_json::json!(["reproduce"]));
        let md = std::fs::read_to_string(dir.join("tables.md")).unwrap();
        assert!(md.contains("| DQN | 4610 | ") && md.contains("| Double DQN | 4610 | "));
        assert!(
            md.contains("- command: `policy-export reproduce`\n"),
            "{md}"
        );
        for f in [
            "table4.svg",
            "table4.png",
            "overestimation.svg",
            "overestimation.png",
        ] {
            assert!(std::fs::metadata(dir.join(f)).unwrap().len() > 1000, "{f}");
        }
        assert!(!dir.join("table1.svg").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_shaping_study_draws_its_readings_apart_beside_its_baseline() {
        let base = Config {
            episodes: 3,
            ..Config::paper()
        };
        let vs: Vec<Variant> = variants(&base)
            .into_iter()
            .filter(|v| v.study == "shaping")
            .collect();
        assert_eq!((vs.len(), distinct_runs(&vs, 2)), (14, 28));
        let runs = run(&vs, 2, &|| {}).unwrap();
        let dir = std::env::temp_dir().join(format!("reproduce-shaping-{}", std::process::id()));
        write(&dir, &vs, &runs, &provenance()).unwrap();
        let svg = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
        let (rewards, readings) = (svg("shaping.svg"), svg("shaping-readings.svg"));
        assert!(rewards.contains("paper preset") && readings.contains("paper preset"));
        assert!(rewards.contains("-100 on failing") && !readings.contains("-100 on failing"));
        assert!(readings.contains("paper-fixed") && !rewards.contains("paper-fixed"));
        assert!(readings.contains("P(greedy)") && !rewards.contains("P(greedy)"));
        let md = std::fs::read_to_string(dir.join("tables.md")).unwrap();
        assert_eq!(md.matches("| reading: ").count(), 3);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
