//! The paper's ablations with many seeds: Tables 1, 4, 5 and 6, the two choices its prose
//! argues for (Xavier vs N(0, 0.1) initialisation, hard vs soft target updates), and the
//! single changes that might let its preset converge. Each configuration differs from the
//! paper preset in one field; every (configuration, seed) pair is an independent run.

use std::path::Path;

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::Serialize;

use crate::config::{Algo, Config, Init, TargetUpdate, Unit};
use crate::plot::{Curve, line_chart};
use crate::train::{self, EpisodeRecord, solved_episode, trailing_means};
use crate::weights::write_atomic;

/// One configuration of one study.
#[derive(Clone, Debug)]
pub struct Variant {
    /// Which study: `table1`, `table4`, `table5`, `table6`, `init`, `target`, `fix`.
    pub study: &'static str,
    /// Row label, as the paper writes it.
    pub label: String,
    /// The paper's numbers for this row (convergence, final reward), if it gives them.
    pub paper: Option<(&'static str, &'static str)>,
    /// The configuration.
    pub cfg: Config,
}

/// Every study's rows, built from `base` (the paper preset).
pub fn variants(base: &Config) -> Vec<Variant> {
    let v = |study, label: &str, paper, cfg| Variant {
        study,
        label: label.to_string(),
        paper,
        cfg,
    };
    let b = base.clone();
    vec![
        v(
            "table1",
            "width 16",
            Some(("no convergence", "< 100")),
            Config {
                width: 16,
                ..b.clone()
            },
        ),
        v("table1", "width 64", Some(("~160", "196.5")), b.clone()),
        v(
            "table1",
            "width 128",
            Some(("~200", "195.1")),
            Config {
                width: 128,
                ..b.clone()
            },
        ),
        v(
            "table4",
            "DQN",
            Some(("~200", "192.3")),
            Config {
                algo: Algo::Dqn,
                ..b.clone()
            },
        ),
        v("table4", "Double DQN", Some(("~160", "196.5")), b.clone()),
        v(
            "table5",
            "lr 0.0001",
            Some(("> 250", "193.1")),
            Config {
                lr: 1e-4,
                ..b.clone()
            },
        ),
        v("table5", "lr 0.0005", Some(("~160", "196.5")), b.clone()),
        v(
            "table5",
            "lr 0.001",
            Some(("unstable", "< 180")),
            Config {
                lr: 1e-3,
                ..b.clone()
            },
        ),
        v(
            "table6",
            "every 10 ep.",
            Some(("~200", "193.8")),
            Config {
                target_period: 10,
                ..b.clone()
            },
        ),
        v("table6", "every 50 ep.", Some(("~160", "196.5")), b.clone()),
        v(
            "table6",
            "every 100 ep.",
            Some(("~220", "194.2")),
            Config {
                target_period: 100,
                ..b.clone()
            },
        ),
        v("init", "Xavier normal", None, b.clone()),
        v(
            "init",
            "N(0, 0.1)",
            None,
            Config {
                init: Init::Normal01,
                ..b.clone()
            },
        ),
        v("target", "hard, every 50 ep.", None, b.clone()),
        v(
            "target",
            "soft, tau 0.005 per step",
            None,
            Config {
                target_update: TargetUpdate::Soft,
                ..b.clone()
            },
        ),
        v("fix", "paper preset", None, b.clone()),
        v(
            "fix",
            "epsilon per episode (scale 200 ep.)",
            None,
            Config {
                eps_unit: Unit::Episodes,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "slower epsilon (scale 2,000 steps)",
            None,
            Config {
                eps_decay: 2000.0,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "buffer 50,000",
            None,
            Config {
                buffer_size: 50_000,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "hard copy every 100 steps",
            None,
            Config {
                target_period: 100,
                target_period_unit: Unit::Steps,
                ..b.clone()
            },
        ),
        v(
            "fix",
            "500-step episodes",
            None,
            Config {
                max_steps: 500,
                ..b.clone()
            },
        ),
    ]
}

/// Per-run numbers.
#[derive(Clone, Debug, Serialize)]
pub struct RunStats {
    /// Seed.
    pub seed: u64,
    /// First episode whose trailing 100-episode mean reaches 195.
    pub solved_195: Option<usize>,
    /// Mean return of the last 100 episodes.
    pub final_mean100: f64,
    /// Standard deviation of the returns of episodes 101 to 200.
    pub sd_101_200: f64,
    /// Largest fall of the trailing 10-episode mean from its running peak, after that mean
    /// first reaches 150 (0 if it never does).
    pub max_drop_after_150: f64,
    /// Per-episode returns.
    pub returns: Vec<f64>,
    /// Per-episode mean of max-Q over visited states.
    pub mean_max_q: Vec<f64>,
    /// Per-episode mean discounted return actually obtained from those states.
    pub mean_discounted_return: Vec<f64>,
}

impl RunStats {
    /// The numbers of one finished run.
    pub fn of(seed: u64, episodes: &[EpisodeRecord]) -> RunStats {
        let returns: Vec<f64> = episodes.iter().map(|e| e.ret).collect();
        let tail = &returns[returns.len().saturating_sub(100)..];
        let mid = &returns[returns.len().min(100)..returns.len().min(200)];
        RunStats {
            seed,
            solved_195: solved_episode(&returns, 195.0),
            final_mean100: mean(tail),
            sd_101_200: sd(mid),
            max_drop_after_150: max_drop(&returns, 150.0),
            mean_max_q: episodes.iter().map(|e| e.mean_max_q).collect(),
            mean_discounted_return: episodes.iter().map(|e| e.mean_discounted_return).collect(),
            returns,
        }
    }
}

/// The largest fall of the 10-episode trailing mean below its running peak, counted from
/// the first time that mean reaches `gate`.
pub fn max_drop(returns: &[f64], gate: f64) -> f64 {
    let m10: Vec<f64> = trailing_means(returns, 10).collect();
    let Some(start) = m10.iter().position(|&m| m >= gate) else {
        return 0.0;
    };
    let mut peak = f64::NEG_INFINITY;
    let mut drop: f64 = 0.0;
    for &m in &m10[start..] {
        peak = peak.max(m);
        drop = drop.max(peak - m);
    }
    drop
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.iter().sum::<f64>() / v.len() as f64
}

fn sd(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return f64::NAN;
    }
    let m = mean(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

/// Student's t 0.975 quantile with `df` degrees of freedom (the Cornish-Fisher expansion
/// around the normal quantile to third order; within 1e-3 of tables for df >= 9).
pub fn t975(df: usize) -> f64 {
    let (z, d) = (1.959_963_985_f64, df as f64);
    z + (z.powi(3) + z) / (4.0 * d)
        + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * d * d)
        + (3.0 * z.powi(7) + 19.0 * z.powi(5) + 17.0 * z.powi(3) - 15.0 * z) / (384.0 * d.powi(3))
}

/// Mean and 95% half-width (Student t) of `v`.
pub fn mean_ci(v: &[f64]) -> (f64, f64) {
    let n = v.len();
    if n < 2 {
        return (mean(v), f64::NAN);
    }
    (mean(v), t975(n - 1) * sd(v) / (n as f64).sqrt())
}

/// One row of a results table.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Study.
    pub study: String,
    /// Row label.
    pub label: String,
    /// Trainable parameters.
    pub params: usize,
    /// Seeds run.
    pub seeds: usize,
    /// Seeds whose trailing 100-episode mean ever reached 195.
    pub solved_seeds: usize,
    /// Median first episode of those that did.
    pub median_solved_episode: Option<f64>,
    /// Mean of the last 100 episodes, averaged over seeds, and its 95% half-width.
    pub final_mean100: (f64, f64),
    /// SD of returns over episodes 101-200, averaged over seeds, with 95% half-width.
    pub sd_101_200: (f64, f64),
    /// Largest 10-episode-mean drop after 150, averaged over seeds, with 95% half-width.
    pub max_drop_after_150: (f64, f64),
    /// Mean over episodes 101 to the end of (max-Q minus discounted return), averaged over
    /// seeds, with 95% half-width: the overestimation.
    pub overestimation: (f64, f64),
    /// The paper's convergence and final reward for this row.
    pub paper: Option<(String, String)>,
}

/// Aggregates the runs of one variant.
pub fn row(v: &Variant, runs: &[RunStats]) -> Row {
    let mut solved: Vec<f64> = runs
        .iter()
        .filter_map(|r| r.solved_195)
        .map(|e| e as f64)
        .collect();
    solved.sort_by(f64::total_cmp);
    let median = (!solved.is_empty()).then(|| {
        let n = solved.len();
        if n % 2 == 1 {
            solved[n / 2]
        } else {
            0.5 * (solved[n / 2 - 1] + solved[n / 2])
        }
    });
    let per = |f: &dyn Fn(&RunStats) -> f64| -> Vec<f64> { runs.iter().map(f).collect() };
    let over = per(&|r| {
        let gaps: Vec<f64> = r
            .mean_max_q
            .iter()
            .zip(&r.mean_discounted_return)
            .skip(100)
            .map(|(q, g)| q - g)
            .collect();
        mean(&gaps)
    });
    Row {
        study: v.study.to_string(),
        label: v.label.clone(),
        params: params(v.cfg.width),
        seeds: runs.len(),
        solved_seeds: solved.len(),
        median_solved_episode: median,
        final_mean100: mean_ci(&per(&|r| r.final_mean100)),
        sd_101_200: mean_ci(&per(&|r| r.sd_101_200)),
        max_drop_after_150: mean_ci(&per(&|r| r.max_drop_after_150)),
        overestimation: mean_ci(&over),
        paper: v.paper.map(|(a, b)| (a.to_string(), b.to_string())),
    }
}

/// Parameters of a 4-h-h-2 network.
pub fn params(h: usize) -> usize {
    4 * h + h + h * h + h + 2 * h + 2
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
            let r = train::train(firsts[d], seed, &mut |_| {})
                .with_context(|| format!("config {d}, seed {seed}"))?;
            tick();
            Ok(RunStats::of(seed, &r.episodes))
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

/// Per-episode mean over seeds with a 95% band, of `f` smoothed over `w` trailing episodes.
fn curve(
    label: &str,
    runs: &[RunStats],
    f: &dyn Fn(&RunStats) -> &[f64],
    w: usize,
    dashed: bool,
) -> Curve {
    let smoothed: Vec<Vec<f64>> = runs
        .iter()
        .map(|r| {
            let v = f(r);
            (0..v.len())
                .map(|i| mean(&v[i.saturating_sub(w - 1)..=i]))
                .collect()
        })
        .collect();
    let n = smoothed.iter().map(Vec::len).min().unwrap_or(0);
    let (mut m, mut band) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let col: Vec<f64> = smoothed.iter().map(|s| s[i]).collect();
        let (mu, h) = mean_ci(&col);
        m.push(mu);
        band.push((mu - h, mu + h));
    }
    Curve {
        label: label.to_string(),
        mean: m,
        band,
        dashed,
    }
}

/// Writes `results.json`, `tables.md` and the figures into `dir`.
pub fn write(
    dir: &Path,
    variants: &[Variant],
    runs: &[Vec<RunStats>],
    command: &str,
) -> Result<Vec<Row>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let rows: Vec<Row> = variants.iter().zip(runs).map(|(v, r)| row(v, r)).collect();
    let per_seed: Vec<serde_json::Value> = variants
        .iter()
        .zip(runs)
        .map(|(v, rs)| {
            serde_json::json!({
                "study": v.study, "label": v.label, "config": v.cfg,
                "runs": rs.iter().map(|r| serde_json::json!({
                    "seed": r.seed, "solved_195": r.solved_195, "final_mean100": r.final_mean100,
                    "sd_101_200": r.sd_101_200, "max_drop_after_150": r.max_drop_after_150,
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    let json = serde_json::json!({ "command": command, "rows": rows, "per_seed": per_seed });
    write_atomic(
        &dir.join("results.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    write_atomic(&dir.join("tables.md"), tables_md(&rows).as_bytes())?;

    let by = |study: &str| -> Vec<(&Variant, &Vec<RunStats>)> {
        variants
            .iter()
            .zip(runs)
            .filter(|(v, _)| v.study == study)
            .collect()
    };
    let studies = [
        ("table1", "Table 1: hidden width"),
        ("table4", "Table 4 / Figure 3: DQN vs Double DQN"),
        ("table5", "Table 5: learning rate"),
        ("table6", "Table 6: target update period"),
        ("init", "Initialisation"),
        ("target", "Hard vs soft target updates"),
        ("fix", "Single changes to the paper preset"),
    ];
    for (study, title) in studies {
        if by(study).is_empty() {
            continue;
        }
        let curves: Vec<Curve> = by(study)
            .iter()
            .map(|(v, r)| curve(&v.label, r, &|r| &r.returns, 10, false))
            .collect();
        line_chart(
            &dir.join(study),
            &format!(
                "{title} (mean of {} seeds, 95% band, 10-ep. smoothing)",
                runs[0].len()
            ),
            "episode",
            "return",
            &curves,
        )?;
    }
    let mut over = Vec::new();
    for (v, r) in by("table4") {
        over.push(curve(
            &format!("{}: mean max Q", v.label),
            r,
            &|r| &r.mean_max_q,
            10,
            false,
        ));
        over.push(curve(
            &format!("{}: discounted return obtained", v.label),
            r,
            &|r| &r.mean_discounted_return,
            10,
            true,
        ));
    }
    if over.is_empty() {
        return Ok(rows);
    }
    line_chart(
        &dir.join("overestimation"),
        "Q-value overestimation: predicted max Q vs discounted return actually obtained",
        "episode",
        "value",
        &over,
    )?;
    Ok(rows)
}

fn fmt_ci((m, h): (f64, f64), p: usize) -> String {
    if h.is_finite() {
        format!("{m:.p$} ± {h:.p$}")
    } else {
        format!("{m:.p$}")
    }
}

/// The tables in markdown, one per study.
pub fn tables_md(rows: &[Row]) -> String {
    let mut s = String::new();
    let mut last = "";
    for r in rows {
        if r.study != last {
            last = &r.study;
            s += &format!(
                "\n#### {}\n\n| configuration | params | converged (seeds) | median ep. to 195 | final mean100 (95% CI) | SD ep. 101-200 | max drop after 150 | overestimation | paper: conv. / final |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n",
                r.study
            );
        }
        s += &format!(
            "| {} | {} | {}/{} | {} | {} | {} | {} | {} | {} |\n",
            r.label,
            r.params,
            r.solved_seeds,
            r.seeds,
            r.median_solved_episode
                .map_or("-".into(), |m| format!("{m:.0}")),
            fmt_ci(r.final_mean100, 1),
            fmt_ci(r.sd_101_200, 1),
            fmt_ci(r.max_drop_after_150, 1),
            fmt_ci(r.overestimation, 2),
            r.paper
                .as_ref()
                .map_or("-".into(), |(a, b)| format!("{a} / {b}")),
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_match_tables() {
        // Student t 0.975: df 19 -> 2.093, df 9 -> 2.262, df 4 -> 2.776.
        assert!((t975(19) - 2.093).abs() < 1e-3);
        assert!((t975(9) - 2.262).abs() < 1e-3);
        assert!((t975(4) - 2.776).abs() < 1e-2);
    }

    #[test]
    fn drop_is_measured_from_the_running_peak_after_the_gate() {
        // 10-episode means: 100 x10, then 200 x10, then 120 x10.
        let returns: Vec<f64> = [100.0; 10]
            .into_iter()
            .chain([200.0; 10])
            .chain([120.0; 10])
            .collect();
        assert_eq!(max_drop(&returns, 150.0), 80.0);
        assert_eq!(max_drop(&returns, 250.0), 0.0);
    }

    #[test]
    fn run_stats_and_rows() {
        let eps: Vec<EpisodeRecord> = (1..=300)
            .map(|i| EpisodeRecord {
                episode: i,
                ret: if i > 150 { 200.0 } else { 10.0 },
                length: 0,
                epsilon: 0.0,
                mean_loss: None,
                mean_max_q: 30.0,
                mean_discounted_return: 20.0,
                env_steps: 0,
                wall_s: 0.0,
            })
            .collect();
        let r = RunStats::of(1, &eps);
        assert_eq!(r.final_mean100, 200.0);
        // Trailing mean of 100 reaches 195 once at most 2 of them are 10: episode 248.
        assert_eq!(r.solved_195, Some(248));
        let v = &variants(&Config::paper())[1];
        let row = row(v, &[r.clone(), r]);
        assert_eq!((row.params, row.solved_seeds), (4_610, 2));
        assert_eq!(row.median_solved_episode, Some(248.0));
        assert_eq!(row.overestimation.0, 10.0);
    }

    #[test]
    fn every_variant_differs_from_the_paper_preset_in_at_most_one_field() {
        let base = serde_json::to_value(Config::paper()).unwrap();
        for v in variants(&Config::paper()) {
            let cfg = serde_json::to_value(&v.cfg).unwrap();
            let changed: Vec<&String> = base
                .as_object()
                .unwrap()
                .iter()
                .filter(|(k, val)| cfg[k.as_str()] != **val)
                .map(|(k, _)| k)
                .collect();
            // The per-step target row changes the period and its unit.
            assert!(changed.len() <= 2, "{}: {changed:?}", v.label);
            v.cfg.validate().unwrap();
        }
    }

    #[test]
    fn a_short_study_writes_tables_json_and_figures() {
        let base = Config {
            episodes: 20,
            kernel: crate::config::KernelChoice::Portable,
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
        let rows = write(&dir, &vs, &runs, "test").unwrap();
        assert_eq!(rows.len(), 2);
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("results.json")).unwrap()).unwrap();
        assert_eq!(json["rows"][0]["label"], "DQN");
        let md = std::fs::read_to_string(dir.join("tables.md")).unwrap();
        assert!(md.contains("| DQN | 4610 | ") && md.contains("| Double DQN | 4610 | "));
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
}
