//! `host-sim render`: one episode drawn as an animated GIF and a time-series PNG, written
//! under temporary names and put in place together, so a failure leaves no half-written
//! picture, and never a new one beside an old one.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use firmware::cartpole::Params;
use host_sim::batch::Batch;
use host_sim::eval::{self, ControllerKind};
use host_sim::render;
use twin::{Frame, Scenario};

use crate::subject::{Monitor, Subject};

/// Longest episode drawn (`render`, `startup --render`): it keeps every period (40 bytes)
/// and draws each `--stride`-th into the GIF.
const MAX_RENDER_HORIZON: u64 = 100_000;
/// Most frames of one animation: drawing them is the costly part (`docs/HOSTILE_INPUT.md`),
/// so the most periods need a stride of 10.
const MAX_FRAMES: u64 = 10_000;
/// Longest `--stride`.
const MAX_STRIDE: usize = 1000;
/// The `--stride` a drawing takes unless told: the GIF at half the periods.
pub const DEFAULT_STRIDE: usize = 2;

/// Refuses, before any episode runs, a drawing of `periods` periods (`periods_from` names
/// the flags they come from) at every `stride`-th past what one may cost: at most
/// [`MAX_RENDER_HORIZON`] periods kept, a stride of 1 to [`MAX_STRIDE`], at most
/// [`MAX_FRAMES`] frames. Both commands that draw check here, so neither draws unbounded.
pub fn bound(periods: u64, stride: usize, periods_from: &str) -> Result<()> {
    anyhow::ensure!(
        (1..=MAX_RENDER_HORIZON).contains(&periods),
        "{periods_from} must be in [1, {MAX_RENDER_HORIZON}] periods to draw, got {periods}"
    );
    anyhow::ensure!(
        (1..=MAX_STRIDE).contains(&stride),
        "--stride must be in [1, {MAX_STRIDE}], got {stride}"
    );
    let frames = periods.div_ceil(stride as u64);
    anyhow::ensure!(
        frames <= MAX_FRAMES,
        "{periods_from} / --stride must make at most {MAX_FRAMES} frames of the animation, \
         got {frames} ({periods} / {stride})"
    );
    Ok(())
}

#[derive(Args)]
pub struct RenderArgs {
    /// Output directory; gets episode.gif and episode.png.
    #[arg(long, default_value = "render")]
    out: PathBuf,
    /// Which controller drives.
    #[arg(long, default_value = "policy")]
    controller: ControllerKind,
    #[command(flatten)]
    subject: Subject,
    #[command(flatten)]
    monitor: Monitor,
    /// One scenario spec (see `eval`).
    #[arg(long, default_value = "nominal")]
    scenario: String,
    /// Periods to run at most.
    #[arg(long, default_value_t = 500)]
    horizon: u32,
    /// Seed and episode number of the start (as in `eval`).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[arg(long, default_value_t = 0)]
    episode: u64,
    /// Draw every k-th period in the GIF (it plays in real time).
    #[arg(long, default_value_t = DEFAULT_STRIDE)]
    stride: usize,
}

/// Draws the episode `a` asks for.
pub fn run(a: &RenderArgs) -> Result<()> {
    let (horizon, stride, out) = (a.horizon, a.stride, a.out.as_path());
    bound(horizon.into(), stride, "--horizon")?;
    let (gif, png) = pictures("--out", out)?;
    let inputs: Vec<_> = a
        .subject
        .inputs()
        .into_iter()
        .chain(a.monitor.inputs())
        .collect();
    crate::check_io(&inputs, &[("--out", &gif), ("--out", &png)])?;
    // Built and judged once, on the machine the episode runs on (`--rig`, or the policy's
    // own rig), not read first on another one.
    let (machine, net) = a.subject.load_for(&[a.controller], &a.monitor)?;
    let scenario = Scenario::parse_on(&a.scenario, &machine).map_err(anyhow::Error::msg)?;
    let (controller, seed, episode) = (a.controller, a.seed, a.episode);
    let mut frames = Vec::new();
    let stats = eval::episode(controller, &net, &scenario, horizon, seed, episode, |f| {
        frames.push(f)
    });
    let title = format!("{controller}, {}", scenario.name);
    let caption = format!(
        "{title}: {} of {horizon} periods, {}",
        stats.steps,
        if stats.success { "balanced" } else { "fell" }
    );
    let at = ("--out", out);
    let (gif, png) = draw(at, &frames, &scenario.params, stride, (&title, &caption))?;
    host_common::outln!("{}\n{}", weights::shown(&gif), weights::shown(&png));
    Ok(())
}

/// The two pictures' paths in `out` (`flag`'s), once `out` is found to be a directory or a new path:
/// checked before the work, and replaced whole.
pub fn pictures(flag: &str, out: &Path) -> Result<(PathBuf, PathBuf)> {
    weights::files::check_dir_name(flag, out)?;
    let (gif, png) = (out.join("episode.gif"), out.join("episode.png"));
    if let Ok(m) = std::fs::symlink_metadata(out)
        && !m.is_dir()
    {
        anyhow::bail!(
            "{flag} {}: expected a directory (or a new path), found {}",
            weights::shown(out),
            weights::files::kind(&m.file_type())
        );
    }
    Ok((gif, png))
}

/// Draws `frames` into `out`'s (`flag`'s) `episode.gif` (every `stride`-th period, titled
/// `title`) and `episode.png` (titled `caption`), each under a temporary name, and puts both in
/// place together ([`Batch`]): a failure leaves the old pair (or none, and no
/// directory it created) and names the picture that failed; their paths.
pub fn draw(
    (flag, out): (&str, &Path),
    frames: &[Frame],
    params: &Params,
    stride: usize,
    (title, caption): (&str, &str),
) -> Result<(PathBuf, PathBuf)> {
    let (gif, png) = pictures(flag, out)?;
    let mut batch = Batch::default();
    batch.dir(out)?;
    let gif_tmp = batch.file(&gif)?;
    render::gif(&gif_tmp, frames, params, stride, title)
        .map_err(|e| render::failed_writing(&gif, &e))?;
    let png_tmp = batch.file(&png)?;
    render::timeseries(&png_tmp, frames, params, caption)
        .map_err(|e| render::failed_writing(&png, &e))?;
    batch.commit()?;
    Ok((gif, png))
}
