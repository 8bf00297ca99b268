//! What identification hands back: the estimates as a table, the identified rig as a rig
//! file (the intervals in its comments), and each log's measured and simulated counts
//! drawn against each other.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use host_common::plot::{Curve, line_chart};
use twin::Machine;
use weights::files::check_output;

use super::fit::{Fit, MAX_DEAD_TIME};
use super::log::Log;
use super::misfit;
use crate::batch::Batch;

/// Each shared unknown's rig-file field and unit, in the fit's order.
pub const FIELDS: [(&str, &str); 5] = [
    ("actuator.stall_force_n", "N"),
    ("actuator.damping_n_s_per_m", "N s/m"),
    ("friction.cart_coulomb", ""),
    ("friction.pivot_viscous_n_m_s", "N m s/rad"),
    ("pole_com_m", "m"),
];

/// The assumption the intervals rest on, as the report states it.
pub const ASSUMPTION: &str = "95% intervals from the Jacobian at the optimum: the residuals \
    taken as independent with one variance per log and the model's equations as right, the \
    dead time held at its value; residuals that are correlated in time make them too narrow";

/// The estimates, one line each, with their intervals and the dead time's search.
pub fn lines(fit: &Fit) -> Vec<String> {
    let mut out: Vec<String> = FIELDS
        .iter()
        .zip(&fit.estimates)
        .map(|(&(field, unit), e)| {
            let interval = match e.half_width {
                Some(h) => format!("+- {h:.3e}"),
                None => "(at its bound, or not identifiable: no interval)".into(),
            };
            format!("{field:<30} = {:<12.6} {interval} {unit}", e.value)
        })
        .collect();
    let best = fit.dead_time_sse[fit.dead_time as usize];
    let ratios: Vec<String> = fit
        .dead_time_sse
        .iter()
        .enumerate()
        .map(|(d, s)| format!("{d}: {:.3}", s / best))
        .collect();
    out.push(format!(
        "{:<30} = {:<12} (sum of squares against the best, by dead time 0 to {MAX_DEAD_TIME}: {})",
        "dead_time_periods",
        fit.dead_time,
        ratios.join(", ")
    ));
    out
}

/// The report printed on standard output.
pub fn format(fit: &Fit, logs: &[Log]) -> String {
    let mut s = String::new();
    for l in lines(fit) {
        let _ = writeln!(s, "{l}");
    }
    for trace in &fit.traces {
        let log = &logs[trace.log];
        let rms: Vec<String> = trace
            .channels
            .iter()
            .map(|c| {
                format!(
                    "{} {:.3} (lag-1 autocorrelation {:.2})",
                    c.name, c.rms, c.autocorrelation
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "{} (line {}, {}): RMS residual, counts: {} over {} periods",
            log.origin,
            log.line,
            log.experiment.name(),
            rms.join(", "),
            trace.channels[0].measured.len()
        );
    }
    let _ = writeln!(s, "{ASSUMPTION}");
    s
}

/// A warning for each encoder of a log the fit does not explain ([`misfit`]).
pub fn warnings(fit: &Fit, logs: &[Log]) -> Vec<String> {
    misfit::findings(fit)
        .into_iter()
        .map(|(trace, channel)| misfit::warning(&logs[trace.log], trace, channel))
        .collect()
}

/// The identified rig as a rig file: the estimates and their intervals as comments, then
/// the file [`twin::rigfile::to_toml`] writes.
pub fn rig_file(machine: &Machine, fit: &Fit, logs: &[Log]) -> String {
    let mut names: Vec<&str> = logs.iter().map(|l| l.origin.as_str()).collect();
    names.dedup();
    let mut s = format!(
        "# Identified from {} by host-sim identify.\n",
        names.join(", ")
    );
    for l in lines(fit) {
        let _ = writeln!(s, "# {l}");
    }
    let _ = writeln!(s, "# {ASSUMPTION}.");
    let found = warnings(fit, logs);
    for w in &found {
        let line: String = w
            .chars()
            .map(|c| if c.is_control() { ' ' } else { c })
            .collect();
        let _ = writeln!(s, "# Misfit: {line}");
    }
    s += &twin::rigfile::to_toml(machine);
    if let Some(m) = misfit::record(fit) {
        s += &m.to_toml();
    }
    s
}

/// The plots' paths, two a log: `DIR/identify-N-EXPERIMENT.png` (and `.svg`) for the N-th
/// log given, its measured and simulated counts, and `identify-N-EXPERIMENT-residuals.png`,
/// their differences.
pub fn plot_paths(dir: &Path, logs: &[Log]) -> Vec<[PathBuf; 2]> {
    logs.iter()
        .enumerate()
        .map(|(i, l)| {
            let stem = format!("identify-{}-{}", i + 1, l.experiment.name());
            [
                dir.join(format!("{stem}.png")),
                dir.join(format!("{stem}-residuals.png")),
            ]
        })
        .collect()
}

/// Checks that the plots can be written: `dir` a directory or a new path, each plot a
/// regular file or none, none of them an input.
pub fn check_plots(dir: &Path, logs: &[Log], inputs: &[&Path]) -> weights::Result<()> {
    weights::files::check_dir_name("--plots", dir)?;
    weights::files::outside_runs(dir).map_err(|e| match e {
        weights::Error::Input(m) => weights::Error::Input(format!("--plots {m}")),
        other => other,
    })?;
    if let Ok(m) = std::fs::symlink_metadata(dir)
        && !m.is_dir()
    {
        return Err(weights::Error::Input(format!(
            "--plots {}: expected a directory (or a new path), found {}",
            weights::shown(dir),
            weights::files::kind(&m.file_type())
        )));
    }
    let ours: Vec<PathBuf> = plot_paths(dir, logs)
        .into_iter()
        .flatten()
        .flat_map(|png| [png.with_extension("svg"), png])
        .collect();
    for path in &ours {
        check_output(path, inputs)?;
    }
    others(dir, &ours)
}

/// Whether `name` is one [`plot_paths`] gives some fit: `identify-N-...` as a PNG or SVG
/// (a user's `identify-setup.png` is not).
fn drawn_by_a_fit(name: &str) -> bool {
    let Some((n, _)) = name
        .strip_prefix("identify-")
        .and_then(|rest| rest.split_once('-'))
    else {
        return false;
    };
    let numbered = !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit());
    numbered && (name.ends_with(".png") || name.ends_with(".svg"))
}

/// Refuses a plots directory holding another fit's plots that this one would leave beside
/// its own (a fit of four logs, then of two: the directory described both).
fn others(dir: &Path, ours: &[PathBuf]) -> weights::Result<()> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    let ours: std::collections::HashSet<&std::ffi::OsStr> =
        ours.iter().filter_map(|p| p.file_name()).collect();
    let mut theirs: Vec<String> = entries
        .filter_map(|e| e.ok().map(|e| e.file_name()))
        .filter(|n| !ours.contains(n.as_os_str()))
        .map(|n| n.to_string_lossy().into_owned())
        .filter(|n| drawn_by_a_fit(n))
        .collect();
    theirs.sort();
    if theirs.is_empty() {
        return Ok(());
    }
    Err(weights::Error::Input(format!(
        "--plots {}: expected a directory without another fit's plots, found {}, which this \
         fit does not replace: remove them or give another directory",
        weights::shown(dir),
        weights::few(theirs.iter().map(|n| weights::quote(n)), 3)
    )))
}

fn curve(label: String, mean: Vec<f64>, dashed: bool) -> Curve {
    Curve {
        label,
        mean,
        band: Vec::new(),
        dashed,
    }
}

/// Draws `curves` into temporaries of `png` and its `.svg`, which `batch` puts in place
/// with everything else it writes.
fn draw(
    batch: &mut Batch,
    png: &Path,
    title: &str,
    y_label: &str,
    curves: &[Curve],
) -> anyhow::Result<()> {
    let svg = png.with_extension("svg");
    let tmp = batch.file(png)?;
    batch.beside(&tmp, &svg);
    line_chart(&tmp, title, "period", y_label, curves).map_err(|e| {
        // The chart draws its SVG first: a PNG begun means that the SVG was written.
        let failed = if tmp.with_extension("png").exists() {
            png
        } else {
            &svg
        };
        let reason = anyhow::anyhow!(crate::render::reason(&e.to_string()));
        crate::render::failed_writing(failed, &reason).into()
    })
}

/// Draws each log's measured and simulated counts into `dir`, and their differences beside
/// the band a fit that holds stays in ([`misfit::MAX_RMS_COUNTS`]): under temporary names,
/// put in place by `batch`'s commit (`dir` created through it); the plots' paths.
pub fn plots(
    batch: &mut Batch,
    dir: &Path,
    fit: &Fit,
    logs: &[Log],
) -> anyhow::Result<Vec<PathBuf>> {
    batch.dir(dir)?;
    let paths = plot_paths(dir, logs);
    for trace in &fit.traces {
        let (log, [counts, residuals]) = (&logs[trace.log], &paths[trace.log]);
        let title = format!(
            "{} ({}), from period {}",
            log.origin,
            log.experiment.name(),
            trace.start
        );
        let curves: Vec<Curve> = trace
            .channels
            .iter()
            .flat_map(|c| {
                [
                    curve(format!("{} measured", c.name), c.measured.clone(), false),
                    curve(format!("{} simulated", c.name), c.simulated.clone(), true),
                ]
            })
            .collect();
        draw(batch, counts, &title, "counts", &curves)?;
        let n = trace.channels.first().map_or(0, |c| c.measured.len());
        let limit = misfit::MAX_RMS_COUNTS;
        let mut differences = vec![Curve {
            label: format!("+-{limit} counts, the most RMS of a fit that holds"),
            mean: vec![0.0; n],
            band: vec![(-limit, limit); n],
            dashed: true,
        }];
        differences.extend(trace.channels.iter().map(|c| {
            let e = c.measured.iter().zip(&c.simulated).map(|(a, b)| a - b);
            curve(
                format!("{} measured - simulated", c.name),
                e.collect(),
                false,
            )
        }));
        draw(
            batch,
            residuals,
            &format!("{title}: residuals"),
            "counts",
            &differences,
        )?;
    }
    Ok(paths.into_iter().flatten().collect())
}
