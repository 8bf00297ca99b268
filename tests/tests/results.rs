//! Every committed results file, re-derived in part from today's code. The documents quote
//! these files (`host-sim tables` keeps the quotes equal to them); this test keeps the files
//! equal to what the code computes, so a change to a controller, the world, the statistics or
//! the trainer fails here until `scripts/regenerate.sh` measures the files again.
//!
//! Each file's command is its step's in `docs/results/manifest.toml` (and a file that records
//! its provenance must record that command). Of every file, a few rows run again: the
//! cheapest row of each controller (episodes times mean periods), cheapest first, within a
//! budget of periods per file and at least one; each is the file's command restricted to the
//! row's scenario, controller and horizon (its episodes, seed and every other flag or default
//! left as the command has them: a row depends on nothing else), and its figures must equal
//! the file's bit for bit. A file measured before rows carried `fallback_share` lacks it, which meant no
//! monitor: there it must be 0.
//!
//! What cannot run here, and what stands in for it:
//! - `pil-*.json`: the QEMU target's rows are, by construction, the target's code run on
//!   the host (every answer compared, period by period, with no mismatch: `pil.rs` holds the
//!   target to that code). The rows are re-derived with that code on both ends of the link
//!   in this process; the target's time per period (QEMU's instruction count) is not.
//! - the rig study's files (`rig-*-trained`, `rig-*-bang-bang`, `rig-desk-zero`: their
//!   commands name `runs/rig-study/`): each policy is trained for the
//!   identified rig by a step of about a minute (`runs/rig-study/`, not committed) and
//!   evaluated for 10,000,000 periods a row: too long here. What it was trained for is re-derived instead: the identified rig file,
//!   from the board's experiments simulated on the true rig. The desk policy is the shipped
//!   crate's `desk` too, so one row of its file (the int8 board, refined) runs again from it.
//! - `sb3-dqn.json`: its SB3 rows need Stable-Baselines3's trained `model.zip`, which is not
//!   committed, and PyTorch; only the shipped policy's rows beside them are re-derived.
//! - `docs/reproduction/results.json`: 660 training runs; one seed of each of its two
//!   cheapest configurations runs again, and its numbers must be that seed's in the file.
//! - `envelope.json` runs again whole (a few seconds).
//!
//! `regenerate.rs` holds the script that measures the files again to the same manifest.

use std::path::{Path, PathBuf};
use std::process::Command;

use e2e::{build_tool, repo};
use firmware::link::Format;
use host_sim::eval::{ControllerKind, Row};
use host_sim::manifest::{Manifest, Step};
use host_sim::pil::link::Session;
use host_sim::pil::{Board, handshake, run_row};
use serde_json::Value as Json;
use twin::Scenario;

/// Periods of rows re-run per file beyond its cheapest row.
const BUDGET: f64 = 2e6;

fn manifest() -> Manifest {
    Manifest::load(&repo()).unwrap()
}

fn read_json(path: &Path) -> Json {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Every results file, relative to the root.
fn results_files() -> Vec<String> {
    let mut files: Vec<String> = std::fs::read_dir(repo().join("docs/results"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".json"))
        .map(|n| format!("docs/results/{n}"))
        .collect();
    files.sort();
    files.push("docs/reproduction/results.json".into());
    files
}

/// The manifest's steps that write `file`.
fn steps_of<'m>(m: &'m Manifest, file: &str) -> Vec<&'m Step> {
    let output = file.strip_suffix("/results.json").unwrap_or(file);
    m.producing(output)
}

#[test]
fn every_results_file_has_its_step_and_records_that_command() {
    let m = manifest();
    for file in results_files() {
        let steps = steps_of(&m, &file);
        assert!(
            !steps.is_empty(),
            "{file}: no step of the manifest writes it"
        );
        let doc = read_json(&repo().join(&file));
        let runs = match doc.get("provenance") {
            None => continue,
            Some(Json::Array(runs)) => runs.clone(),
            Some(one) => vec![one.clone()],
        };
        for p in runs {
            let mut recorded = vec![p["tool"].as_str().unwrap()];
            recorded.extend(
                p["argv"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|a| a.as_str().unwrap()),
            );
            let matches = steps.iter().any(|s| {
                let words = s.words().expect("a results step is one plain command");
                // A script runs under `python`; a tool's name is the manifest's first word.
                let command = if words[0] == "python" {
                    &words[1..]
                } else {
                    &words[..]
                };
                command == recorded.as_slice()
            });
            assert!(
                matches,
                "{file} was made by `{}`, which is no step of the manifest",
                recorded.join(" ")
            );
        }
    }
}

/// A row's name and its cost in periods.
fn key(row: &Json) -> (String, String, u64) {
    let s = |k: &str| row[k].as_str().unwrap().to_string();
    (
        s("controller"),
        s("scenario"),
        row["horizon"].as_u64().unwrap(),
    )
}

fn cost(row: &Json) -> f64 {
    row["episodes"].as_f64().unwrap() * row["mean_steps"].as_f64().unwrap()
}

/// The rows re-run of `rows` (those `keep` allows): the cheapest of each controller,
/// cheapest first, within [`BUDGET`] beyond the first.
fn sample(rows: &[Json], keep: impl Fn(&Json) -> bool) -> Vec<&Json> {
    let mut sorted: Vec<&Json> = rows.iter().filter(|r| keep(r)).collect();
    sorted.sort_by(|a, b| cost(a).total_cmp(&cost(b)).then(key(a).cmp(&key(b))));
    let (mut picked, mut spent): (Vec<&Json>, f64) = (Vec::new(), 0.0);
    for r in sorted {
        let taken = picked.iter().any(|p| p["controller"] == r["controller"]);
        if taken || (!picked.is_empty() && spent + cost(r) > BUDGET) {
            continue;
        }
        spent += cost(r);
        picked.push(r);
    }
    picked
}

/// The file's row and today's are equal in every figure the file holds.
fn assert_same_row(file: &str, committed: &Json, today: &Json) {
    let (c, t) = (committed.as_object().unwrap(), today.as_object().unwrap());
    let what = format!("{file}: {:?}", key(committed));
    for (k, v) in t {
        match c.get(k) {
            Some(was) => assert_eq!(was, v, "{what}: `{k}` is no longer what the file holds"),
            None if k == "fallback_share" => assert_eq!(v, &Json::from(0.0), "{what}: {k}"),
            None => panic!("{what}: the file lacks `{k}`: measure it again"),
        }
    }
    let gone: Vec<&String> = c.keys().filter(|k| !t.contains_key(*k)).collect();
    assert!(gone.is_empty(), "{what}: today's row lacks {gone:?}");
}

/// `words` (an `eval` command) for one row: its scenario, controller and horizon; every other
/// flag, and every default, the command's.
fn restricted(file: &str, words: &[&str], row: &Json) -> Vec<String> {
    let (controller, scenario, horizon) = key(row);
    let mut out = Vec::new();
    let mut rest = words.iter();
    while let Some(&w) = rest.next() {
        if w == "--json" || !w.starts_with("--") {
            out.push(w.to_string());
            continue;
        }
        let value = *rest
            .next()
            .unwrap_or_else(|| panic!("{file}: `{w}` without a value"));
        if !["--scenario", "--controller", "--horizon"].contains(&w) {
            out.extend([w.to_string(), value.to_string()]);
        }
    }
    let row_flags = [
        ("--scenario", scenario),
        ("--controller", controller),
        ("--horizon", horizon.to_string()),
    ];
    out.extend(row_flags.into_iter().flat_map(|(f, v)| [f.to_string(), v]));
    out
}

fn run_host_sim(exe: &Path, args: &[String]) -> Json {
    let o = Command::new(exe)
        .args(args)
        .current_dir(repo())
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "host-sim {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn eval_rows_are_what_todays_code_computes() {
    let exe = build_tool("host-sim");
    let m = manifest();
    let mut ran = 0;
    for file in results_files() {
        let steps = steps_of(&m, &file);
        let words = steps[0].words().unwrap();
        let doc = read_json(&repo().join(&file));
        let rows = doc["rows"].as_array().cloned().unwrap_or_default();
        let episodes = rows.first().map(|r| r["episodes"].to_string());
        let (words, keep): (Vec<&str>, fn(&Json) -> bool) = match words[..2] {
            // The policies trained for the rigs are not committed (the module's documentation).
            _ if words.iter().any(|w| w.starts_with("runs/rig-study/")) => continue,
            ["host-sim", "eval"] if !words.contains(&"--pil") => (words, |_| true),
            // The shipped policy's rows of the SB3 comparison: `host-sim eval` as the script
            // runs it, with its episodes a row (its --episodes).
            ["python", "examples/sb3_dqn.py"] => {
                let e = episodes.as_deref().unwrap();
                let words = vec!["host-sim", "eval", "--json", "--episodes", e];
                (words, |r| r["controller"] == "policy")
            }
            _ => continue,
        };
        for row in sample(&rows, keep) {
            let args = restricted(&file, &words[1..], row);
            let today = run_host_sim(&exe, &args);
            let today = today["rows"].as_array().unwrap();
            assert_eq!(today.len(), 1, "{file}: {args:?}");
            assert_same_row(&file, row, &today[0]);
            ran += 1;
        }
    }
    assert!(ran >= 20, "only {ran} rows re-derived");
}

/// The value of `flag` in `words`, or `default`.
fn flag<'a>(words: &[&'a str], flag: &str, default: &'a str) -> &'a str {
    words
        .iter()
        .position(|w| *w == flag)
        .map_or(default, |i| words[i + 1])
}

/// The desk policy of the rig study is the shipped crate's `desk` (the manifest exports one
/// to the other), so one row of its file runs again from that: the int8 board refined
/// between its levels through the encoders, its quantisation and refinement both.
#[test]
fn the_shipped_desk_policys_refined_board_row_is_todays() {
    let (m, file, run) = (
        manifest(),
        "docs/results/rig-desk-trained.json",
        "runs/rig-study/desk-policy",
    );
    let export = &m.producing("shipped/src/desk.rs")[0];
    assert!(export.words().unwrap().contains(&run), "{export:?}");
    let w = weights::Weights::from_mlp(&shipped::desk::POLICY, &shipped::desk::LEVELS).unwrap();
    let rig = std::fs::read_to_string(repo().join("rigs/desk-identified.toml")).unwrap();
    let meta = [(twin::rigfile::METADATA_KEY.to_string(), rig)].into();
    let policy = scratch("desk").join("policy.safetensors");
    std::fs::write(
        &policy,
        weights::checkpoint::to_safetensors(&w, &meta).unwrap(),
    )
    .unwrap();
    let words = steps_of(&m, file)[0].words().unwrap();
    let shown = policy.display().to_string();
    let words: Vec<&str> = words
        .iter()
        .map(|w| if *w == run { shown.as_str() } else { w })
        .collect();
    let doc = read_json(&repo().join(file));
    let is = |r: &&Json| r["controller"] == "policy-int-refined" && r["scenario"] == "encoder";
    let row = doc["rows"].as_array().unwrap().iter().find(is).unwrap();
    let today = run_host_sim(&build_tool("host-sim"), &restricted(file, &words[1..], row));
    assert_same_row(file, row, &today["rows"][0]);
    std::fs::remove_dir_all(policy.parent().unwrap()).unwrap();
}

#[test]
fn processor_in_the_loop_rows_are_the_targets_code_run_here() {
    let m = manifest();
    let mut ran = 0;
    for file in results_files() {
        let words = steps_of(&m, &file)[0].words().unwrap();
        if !words.contains(&"--pil") {
            continue;
        }
        let doc = read_json(&repo().join(&file));
        let seed = doc["seed"].as_u64().unwrap();
        let checks = doc["pil"].as_array().unwrap();
        for row in sample(doc["rows"].as_array().unwrap(), |_| true) {
            let (controller, scenario, horizon) = key(row);
            // The command gives its episodes; its seed is the file's.
            let episodes = row["episodes"].as_u64().unwrap();
            assert_eq!(
                flag(&words, "--episodes", ""),
                episodes.to_string(),
                "{file}"
            );
            let kind = ControllerKind::on_target()
                .find(|k| k.to_string() == controller)
                .unwrap_or_else(|| panic!("{file}: `{controller}` runs on no target"));
            let s = Scenario::parse(&scenario).unwrap();
            let here = || Session::new(Board::Shipped.reference());
            let (mut target, mut reference) = (here(), here());
            let format = if kind.int() {
                Format::Int8
            } else {
                Format::F32
            };
            let info = handshake(
                &mut target,
                &mut reference,
                format,
                std::slice::from_ref(&s),
                Board::Shipped,
            )
            .unwrap();
            let run = (&info, kind);
            let h = u32::try_from(horizon).unwrap();
            let (eps, check) = run_row(
                &mut target,
                &mut reference,
                run,
                &s,
                h,
                seed,
                episodes,
                || (),
            )
            .unwrap();
            let today = Row::from_episodes(&controller, &s.name, (h, s.params.tau), seed, &eps);
            assert_same_row(&file, row, &serde_json::to_value(today).unwrap());
            let committed = checks
                .iter()
                .find(|c| {
                    (c["controller"].as_str(), c["scenario"].as_str())
                        == (Some(&controller[..]), Some(&scenario[..]))
                })
                .unwrap_or_else(|| panic!("{file}: no check of {controller} on {scenario}"));
            assert_eq!(committed["periods"], check.periods, "{file}: {scenario}");
            assert_eq!(committed["mismatches"], 0, "{file}: {scenario}");
            ran += 1;
        }
    }
    assert!(ran >= 11, "only {ran} rows re-derived");
}

/// A scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("results-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_envelope_is_todays_measurement() {
    let exe = build_tool("host-sim");
    let m = manifest();
    let words = steps_of(&m, "docs/results/envelope.json")[0]
        .words()
        .unwrap();
    assert_eq!(words[..2], ["host-sim", "envelope"]);
    let args: Vec<String> = words[1..].iter().map(|w| w.to_string()).collect();
    let mut today = run_host_sim(&exe, &args);
    let mut committed = read_json(&repo().join("docs/results/envelope.json"));
    for doc in [&mut today, &mut committed] {
        doc.as_object_mut().unwrap().remove("provenance");
    }
    assert_eq!(
        committed, today,
        "docs/results/envelope.json is no longer the measurement"
    );
}

#[test]
fn the_rigs_trained_for_are_identified_again() {
    let exe = build_tool("host-sim");
    let m = manifest();
    let dir = scratch("rigs");
    for rig in ["desk", "desk-100hz", "lab"] {
        let committed = format!("rigs/{rig}-identified.toml");
        // The logs step and the identification step, their outputs moved to the scratch dir.
        let log = format!("runs/rig-study/{rig}.log");
        let moved = |w: &str| {
            if w == log || w == committed {
                dir.join(Path::new(w).file_name().unwrap())
                    .display()
                    .to_string()
            } else {
                w.to_string()
            }
        };
        for output in [log.as_str(), committed.as_str()] {
            let words = m.producing(output)[0].words().unwrap();
            assert_eq!(words[0], "host-sim", "{output}");
            let args: Vec<String> = words[1..].iter().map(|w| moved(w)).collect();
            let o = Command::new(&exe)
                .args(&args)
                .current_dir(repo())
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{args:?}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        // Its header names the log it was identified from.
        let today = std::fs::read_to_string(moved(&committed))
            .unwrap()
            .replacen(&moved(&log), &log, 1);
        let file = std::fs::read_to_string(repo().join(&committed)).unwrap();
        assert_eq!(
            file, today,
            "{committed} is no longer what identification gives"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_reproductions_cheapest_runs_are_todays() {
    use policy_export::config::Config;
    use policy_export::reproduce::{RunStats, seed_json, variants};
    let m = manifest();
    let words = steps_of(&m, "docs/reproduction/results.json")[0]
        .words()
        .unwrap();
    assert_eq!(words[..2], ["policy-export", "reproduce"]);
    assert!(
        !words.contains(&"--kernel") && !words.contains(&"--study"),
        "{words:?}"
    );
    let seeds: u64 = flag(&words, "--seeds", "20").parse().unwrap();
    let doc = read_json(&repo().join("docs/reproduction/results.json"));
    let per_seed = doc["per_seed"].as_array().unwrap();
    let mut all = variants(&Config::paper());
    assert_eq!(
        all.len(),
        per_seed.len(),
        "the studies' rows are not the file's"
    );
    for (v, recorded) in all.iter().zip(per_seed) {
        assert_eq!(
            (recorded["study"].as_str(), recorded["label"].as_str()),
            (Some(v.study), Some(&v.label[..]))
        );
        assert_eq!(
            recorded["config"],
            v.cfg.recorded().unwrap(),
            "{}: {}",
            v.study,
            v.label
        );
        assert_eq!(recorded["runs"].as_array().unwrap().len() as u64, seeds);
    }
    // The two cheapest distinct configurations: fewest periods at most, then narrowest.
    let cheap = |c: &Config| (c.episodes as u64 * u64::from(c.max_steps), c.width);
    all.sort_by_key(|v| cheap(&v.cfg));
    let config = |v: &policy_export::reproduce::Variant| v.cfg.recorded().unwrap();
    all.dedup_by(|a, b| config(a) == config(b));
    for v in &all[..2] {
        let recorded = per_seed.iter().find(|p| p["config"] == config(v)).unwrap();
        let episodes = policy_export::train::episodes(&v.cfg, 0).unwrap();
        let today = seed_json(&RunStats::of(0, &episodes));
        assert_eq!(
            recorded["runs"][0], today,
            "{}: {}, seed 0",
            v.study, v.label
        );
    }
}

/// Every committed results file is one the tools read back: within the generic reader's
/// weight (`weights::json::MAX_WEIGHT`) and as `results moved` checks it (no row twice,
/// whole counts, no more failures than episodes, rates in [0, 1]).
#[test]
fn the_committed_results_files_are_ones_the_readers_take() {
    for file in results_files() {
        let text = std::fs::read_to_string(repo().join(&file)).unwrap();
        let doc = weights::json::value(&text).unwrap_or_else(|e| panic!("{file}: {e}"));
        host_sim::moved::check(&doc).unwrap_or_else(|e| panic!("{file}: {e}"));
    }
}
