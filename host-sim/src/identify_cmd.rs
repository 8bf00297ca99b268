//! `host-sim identify`: the rig's unknowns fitted to the board's logs (`host_sim::identify`),
//! the estimates printed with their intervals, the identified rig file written whole through
//! a temporary file, and, if asked, each log's measured and simulated counts drawn. And
//! `host-sim simulate-logs`: the logs a board would stream from a machine the twin simulates,
//! to try the identification (and what follows it) on a rig whose truth is known.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Result;
use clap::Args;
use host_sim::batch::Batch;
use host_sim::identify::{self, Log, fit, log, report};
use indicatif::{ProgressBar, ProgressStyle};
use weights::files::{read_capped, remove_stale, write_atomic};

#[derive(Args)]
pub struct IdentifyArgs {
    /// The board's logs (`firmware::identify`'s text; a file may hold several): at least one
    /// cart and one swing experiment.
    #[arg(required = true)]
    logs: Vec<PathBuf>,
    /// The rig as its builder measured it (a rig file, `rigs/`): masses, lengths, encoders,
    /// track and period are taken as they are; its motor, friction, pole length and dead
    /// time are only where the fit starts.
    #[arg(long)]
    rig: PathBuf,
    /// Where the identified rig file is written.
    #[arg(long)]
    out: PathBuf,
    /// A directory for the plots of measured against simulated counts
    /// (`identify-N-EXPERIMENT.png` and `.svg`, one per log).
    #[arg(long)]
    plots: Option<PathBuf>,
}

/// The logs in `paths`, each read whole (up to [`log::MAX_LOG_BYTES`], and
/// [`log::MAX_TOTAL_LOG_BYTES`] all together) and parsed, each experiment once
/// ([`log::check_each_once`]).
fn read_logs(paths: &[PathBuf]) -> Result<Vec<Log>> {
    let mut logs = Vec::new();
    let mut total = 0;
    for path in paths {
        let bytes = read_capped(path, log::MAX_LOG_BYTES)?;
        let origin = weights::shown(path);
        total += bytes.len() as u64;
        if total > log::MAX_TOTAL_LOG_BYTES {
            return Err(weights::Error::Input(format!(
                "LOG {origin}: expected at most {} bytes of logs in all, found {total} up to \
                 this file's end",
                log::MAX_TOTAL_LOG_BYTES
            ))
            .into());
        }
        let text = std::str::from_utf8(&bytes)
            .map_err(|e| weights::Error::Input(format!("{origin}: expected UTF-8 text, {e}")))?;
        logs.extend(log::parse(text, &origin)?);
    }
    log::check_each_once(&logs)?;
    Ok(logs)
}

/// Fits the rig `a` asks for; every input is checked, and every output's place, before the
/// fit starts.
pub fn run(a: &IdentifyArgs) -> Result<()> {
    if a.logs.len() > log::MAX_LOG_FILES {
        return Err(weights::Error::Input(format!(
            "LOG: expected at most {} log files, found {}",
            log::MAX_LOG_FILES,
            a.logs.len()
        ))
        .into());
    }
    let mut labelled: Vec<(&str, PathBuf)> = a.logs.iter().map(|l| ("LOG", l.clone())).collect();
    labelled.push(("--rig", a.rig.clone()));
    crate::check_io(&labelled, &[("--out", &a.out)])?;
    let machine = twin::rigfile::load(&a.rig)?;
    // Identification fits the physics alone; how the rig starts is the builder's, carried.
    let startup = twin::rigfile::given_startup(&a.rig)?;
    let logs = read_logs(&a.logs)?;
    let inputs: Vec<&Path> = labelled.iter().map(|(_, p)| p.as_path()).collect();
    if let Some(dir) = &a.plots {
        report::check_plots(dir, &logs, &inputs)?;
        let plots: Vec<PathBuf> = report::plot_paths(dir, &logs)
            .into_iter()
            .flatten()
            .flat_map(|png| [png.with_extension("svg"), png])
            .collect();
        let mut files = vec![("--out", a.out.as_path())];
        files.extend(plots.iter().map(|p| ("--plots", p.as_path())));
        weights::files::check_apart(&files, &[("--plots", dir)])?;
    }
    identify::check(&logs, &machine)?;
    let bar = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("static template"),
    );
    bar.set_message(format!(
        "fitting {} logs: the swing, each dead time from 0 to {}, then all together",
        logs.len(),
        fit::MAX_DEAD_TIME
    ));
    bar.enable_steady_tick(Duration::from_millis(100));
    let found = identify::fitted(&logs, &machine);
    bar.finish_and_clear();
    let found = found?;
    let identified = identify::identified(&machine, &found);
    let text = report::rig_file(&identified, &found, &logs) + &startup;
    // What is written must be a rig file every tool reads back.
    twin::rigfile::parse(&text, "the identified rig")?;
    let plots = write(a, &text, &found, &logs)?;
    for path in plots {
        host_common::errln!("{}", weights::shown(&path));
    }
    host_common::out!("{}", report::format(&found, &logs));
    for w in report::warnings(&found, &logs) {
        host_common::errln!("warning: {w}");
    }
    host_common::errln!("{}", weights::shown(&a.out));
    Ok(())
}

/// Writes the rig file `text` to `--out` and the plots of `found` into `--plots`, all or
/// none: the plots drawn first, the rig file last, each under a temporary name, then all
/// put in place together ([`Batch`]), so a failure (a full disk) leaves no rig file
/// without its plots, nor plots of a fit whose rig file is the old one; the plots' paths.
fn write(
    a: &IdentifyArgs,
    text: &str,
    found: &identify::Fit,
    logs: &[Log],
) -> Result<Vec<PathBuf>> {
    let mut batch = Batch::default();
    let plots = match &a.plots {
        Some(dir) => report::plots(&mut batch, dir, found, logs)?,
        None => Vec::new(),
    };
    let out = a.out.as_path();
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        batch.dir(dir)?;
    }
    // A killed writer's probe of the place's check.
    remove_stale(out, &["probe"]);
    let tmp = batch.file(out)?;
    weights::files::write_new(&tmp, text.as_bytes())
        .map_err(|e| weights::Error::Io(format!("writing {}: {e}", weights::shown(out))))?;
    batch.commit()?;
    Ok(plots)
}

/// The longest experiment `simulate-logs` runs, s: as long as the fit takes in all.
const MAX_SIMULATED_S: f64 = log::MAX_TOTAL_SECONDS;

#[derive(Args)]
pub struct SimulateLogsArgs {
    /// The true machine the experiments run on (a rig file): its motor, friction, pole and
    /// dead time are what an identification should find.
    #[arg(long)]
    world: PathBuf,
    /// The rig as its builder measured it, the board's (a rig file): its encoders, track and
    /// period run the experiments.
    #[arg(long)]
    rig: PathBuf,
    /// The cart experiment's sequence, and the encoders' jitter: a whole number in [0,
    /// 4294967295], the 32 bits the board's sequence takes.
    #[arg(long, default_value_t = 1, value_parser = seed32)]
    seed: u32,
    /// The standard deviation of a vibration or an edge's jitter on each reading, counts.
    #[arg(long, default_value_t = 0.5)]
    jitter: f64,
    /// How long the cart experiment runs, s.
    #[arg(long, default_value_t = identify::synthetic::CART_S)]
    cart_s: f64,
    /// How long the swing is logged after the release, s.
    #[arg(long, default_value_t = identify::synthetic::SWING_S)]
    swing_s: f64,
    /// Where the two logs (cart, then swing) are written, as the board streams them.
    #[arg(long)]
    out: PathBuf,
}

/// A `--seed` of the cart experiment's sequence, which the board takes in 32 bits: std's
/// "number too large to fit in target type" said no range.
fn seed32(text: &str) -> Result<u32, String> {
    weights::whole::<u32>(text).ok_or_else(|| {
        format!(
            "expected a whole number in [0, {}] (the board's sequence takes a 32-bit seed), \
             found {}",
            u32::MAX,
            weights::quote(text)
        )
    })
}

/// Writes the cart and swing experiments' logs `a` asks for; the inputs are checked, and the
/// output's place, before anything runs.
pub fn simulate(a: &SimulateLogsArgs) -> Result<()> {
    crate::check_io(
        &[("--world", a.world.clone()), ("--rig", a.rig.clone())],
        &[("--out", &a.out)],
    )?;
    let truth = twin::rigfile::load(&a.world)?;
    let board = twin::rigfile::load(&a.rig)?;
    let named = crate::world_arg::board_name(Some(&a.rig), false, "");
    crate::world_arg::same_period(&truth, &a.world, &board, &named)?;
    if !((0.0..=100.0).contains(&a.jitter) && weights::plain(a.jitter)) {
        return Err(weights::Error::Input(format!(
            "--jitter: expected counts in [0, 100], zero or normal, found {:?}",
            a.jitter
        ))
        .into());
    }
    for (flag, seconds) in [("--cart-s", a.cart_s), ("--swing-s", a.swing_s)] {
        if !(log::MIN_SECONDS..=MAX_SIMULATED_S).contains(&seconds) {
            return Err(weights::Error::Input(format!(
                "{flag}: expected seconds in [{}, {MAX_SIMULATED_S}], found {seconds:?}",
                log::MIN_SECONDS
            ))
            .into());
        }
    }
    let reading = identify::synthetic::Reading {
        jitter_counts: a.jitter,
        seed: u64::from(a.seed),
        ..Default::default()
    };
    let logs = identify::synthetic::experiments_lasting(
        &truth,
        &board.rig,
        (a.seed, reading),
        [a.cart_s, a.swing_s],
    );
    write_atomic(&a.out, logs.concat().as_bytes())?;
    host_common::errln!("{}", weights::shown(&a.out));
    Ok(())
}
