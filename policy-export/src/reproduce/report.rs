//! What a reproduction leaves behind: `results.json` (every row and every seed's numbers),
//! `tables.md`, and the learning-curve figures per study.

use std::path::Path;

use anyhow::{Context, Result};
use host_common::plot::{Curve, line_chart};
use host_common::provenance::Provenance;
use host_common::stats::{Estimate, mean};
use weights::files::write_atomic;

use super::stats::{Row, RunStats, row};
use super::variants::{STUDIES, Variant};

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
        let Estimate { mean: mu, ci95: h } = Estimate::of(&col);
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

/// A row drawn in a figure: its variant and its runs.
type Member<'a> = (&'a Variant, &'a Vec<RunStats>);

/// One run's numbers as `results.json`'s `per_seed` lists them.
pub fn seed_json(r: &RunStats) -> serde_json::Value {
    serde_json::json!({
        "seed": r.seed, "solved_195": r.solved_195, "final_mean100": r.final_mean100,
        "sd_101_200": r.sd_101_200, "max_drop_after_150": r.max_drop_after_150,
    })
}

/// Writes `results.json`, `tables.md` and the figures into `dir`.
pub fn write(
    dir: &Path,
    variants: &[Variant],
    runs: &[Vec<RunStats>],
    provenance: &Provenance,
) -> Result<Vec<Row>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", weights::shown(dir)))?;
    let rows: Vec<Row> = variants.iter().zip(runs).map(|(v, r)| row(v, r)).collect();
    let per_seed = variants
        .iter()
        .zip(runs)
        .map(|(v, rs)| {
            Ok(serde_json::json!({
                "study": v.study, "label": v.label, "config": v.cfg.recorded()?,
                "runs": rs.iter().map(seed_json).collect::<Vec<_>>(),
            }))
        })
        .collect::<Result<Vec<serde_json::Value>>>()?;
    let json = serde_json::json!({ "provenance": provenance, "rows": rows, "per_seed": per_seed });
    write_atomic(
        &dir.join("results.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    let page = format!(
        "# The reproduction's tables\n\nWritten by `policy-export reproduce` with `results.json` \
         beside it; do not edit.\n\n{}{}",
        provenance.markdown(),
        tables_md(&rows)
    );
    write_atomic(&dir.join("tables.md"), page.as_bytes())?;

    let by = |study: &str| -> Vec<Member> {
        variants
            .iter()
            .zip(runs)
            .filter(|(v, _)| v.study == study)
            .collect()
    };
    for (study, title) in STUDIES {
        let rows = by(study);
        let Some(&baseline) = rows.first() else {
            continue;
        };
        let mut figures: Vec<((&str, &str), Vec<Member>)> = vec![((study, title), Vec::new())];
        for &row in &rows {
            let key = row.0.figure.unwrap_or((study, title));
            match figures.iter_mut().find(|(k, _)| *k == key) {
                Some((_, members)) => members.push(row),
                None => figures.push((key, vec![baseline, row])),
            }
        }
        for ((name, title), members) in figures {
            let curves: Vec<Curve> = members
                .iter()
                .map(|(v, r)| curve(&v.label, r, &|r| &r.returns, 10, false))
                .collect();
            line_chart(
                &dir.join(name),
                &format!(
                    "{title} (mean of {} seeds, 95% band, 10-ep. smoothing)",
                    runs[0].len()
                ),
                "episode",
                "return",
                &curves,
            )?;
        }
    }
    for (study, name) in [
        ("table4", "overestimation"),
        ("table4-fixed", "overestimation-fixed"),
    ] {
        overestimation(dir, name, &by(study))?;
    }
    Ok(rows)
}

/// Predicted max-Q against the discounted learning return obtained, per row of `rows`.
fn overestimation(dir: &Path, name: &str, rows: &[Member]) -> Result<()> {
    let mut over = Vec::new();
    for (v, r) in rows {
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
        return Ok(());
    }
    line_chart(
        &dir.join(name),
        "Q-value overestimation: predicted max Q vs discounted learning return obtained",
        "episode",
        "value",
        &over,
    )
}

/// The tables in markdown, one per study.
pub fn tables_md(rows: &[Row]) -> String {
    let mut s = String::new();
    let mut last = "";
    for r in rows {
        if r.study != last {
            last = &r.study;
            s += &format!(
                "\n#### {}\n\n| configuration | params | converged (seeds) | by ep. 160 | median ep. to 195 | final mean100 (95% CI) | SD ep. 101-200 | max drop after 150 | overestimation | paper: conv. / final |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n",
                r.study
            );
        }
        s += &format!(
            "| {} | {} | {}/{} | {}/{} | {} | {} | {} | {} | {} | {} |\n",
            r.label,
            r.params,
            r.solved_seeds,
            r.seeds,
            r.solved_by_160,
            r.seeds,
            r.median_solved_episode
                .map_or("-".into(), |m| format!("{m:.0}")),
            r.final_mean100.show(1),
            r.sd_101_200.show(1),
            r.max_drop_after_150.show(1),
            r.overestimation.show(2),
            r.paper
                .as_ref()
                .map_or("-".into(), |(a, b)| format!("{a} / {b}")),
        );
    }
    s
}
