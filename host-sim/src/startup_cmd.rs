//! `host-sim startup`: episodes from power-on through the board's start-up
//! (`firmware::startup`): the hanging zero, the swing-up or a hand's lift, the catch, the
//! balance; how often and how fast the pole is up, and what it cost the track.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use firmware::cartpole::unit_f64;
use firmware::controller::Policy;
use firmware::estimator::Estimate;
use firmware::startup::Phase;
use firmware::startup::Startup;
use host_sim::eval::{ControllerKind, IntNet, Net};
use indicatif::{ProgressBar, ProgressStyle};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use twin::Frame;
use twin::startup::{Begin, Events, Knock, Outcome, power_on};
use twin::{Integration, Machine};

use crate::subject::{Monitor, Subject};

mod report;
use report::{Report, summarise, table};

/// Most episodes one run takes.
const MAX_EPISODES: u32 = 1_000_000;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StartArg {
    /// The pole hanging nearly at rest; swung up.
    Hanging,
    /// The pole swinging by up to 30 degrees at power-on; swung up.
    Swinging,
    /// Hanging at rest, lifted by a hand into the catch region; no swing-up.
    Lifted,
}

#[derive(Args)]
pub struct StartupArgs {
    /// How each episode begins.
    #[arg(long, value_enum, default_value = "hanging")]
    start: StartArg,
    /// Episodes.
    #[arg(long, default_value_t = 1000)]
    episodes: u32,
    /// Seconds from power-on within which the pole must be balanced.
    #[arg(long, default_value_t = 10.0)]
    within: f64,
    /// Seconds it must then stay balanced.
    #[arg(long, default_value_t = 60.0)]
    hold: f64,
    /// The board: without --policy, the shipped desk policy on the identified desk rig
    /// (or on --rig). The start-up is --rig's `[startup]` table, the rest suggested from
    /// the rig's physics.
    #[command(flatten)]
    subject: Subject,
    /// The true machine (a rig file), when the board models another.
    #[arg(long)]
    world: Option<PathBuf>,
    /// The pole's zero read this many degrees off once the start-up has taken it (an
    /// encoder that slipped on its shaft, a bent mount), in whole counts of the world's
    /// encoder.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    zero_error: f64,
    /// The cart left anywhere within this many metres of the centre at power-on, rather
    /// than centred by hand (within a centimetre): for a start-up that homes.
    #[arg(long, default_value_t = 0.0)]
    cart_start: f64,
    /// A push that may drop the pole once it is up: NEWTONS held on the cart for one period,
    /// SECONDS after power-on, towards a side drawn per episode. --within then counts from
    /// the push: the pole must be back up (swung up again, or never down) within it.
    #[arg(long, value_name = "NEWTONS@SECONDS", allow_hyphen_values = true)]
    knock: Option<String>,
    /// Seed of the starts and lifts.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Also draw one episode (f32) into this directory: episode.gif and episode.png.
    #[arg(long)]
    render: Option<PathBuf>,
    /// The episode --render draws.
    #[arg(long, default_value_t = 0, requires = "render")]
    episode: u32,
    /// Draw every k-th period in --render's GIF (it plays in real time).
    #[arg(long, default_value_t = crate::render_cmd::DEFAULT_STRIDE, requires = "render")]
    stride: usize,
}

/// The board's machine without --policy or --rig, as messages name it.
const DESK: &str = "the identified desk rig the shipped desk policy runs on";

/// The true world: `--world`, at the board's period and another than the board's, or the
/// board's own rig.
fn world(a: &StartupArgs, board: Machine) -> Result<Machine> {
    let Some(path) = &a.world else {
        return Ok(board);
    };
    let world = twin::rigfile::load(path)?;
    let s = &a.subject;
    let named = crate::world_arg::board_name(s.rig.as_deref(), s.policy.is_some(), DESK);
    crate::world_arg::check(&world, path, &board, &named)?;
    Ok(world)
}

/// Runs the episodes `a` asks for; the report is printed.
pub fn run(a: &StartupArgs) -> Result<bool> {
    check(a)?;
    let knock = knock(a)?;
    let (board, mut startup, net) = board(&a.subject)?;
    let world = world(a, board)?;
    check_world(a, &world)?;
    let begin = match a.start {
        StartArg::Hanging => Begin::Hanging,
        StartArg::Swinging => Begin::Swinging,
        StartArg::Lifted => Begin::Lifted,
    };
    if begin == Begin::Lifted {
        startup.swing = None;
    }
    let tau = board.rig.params.tau;
    let (within, hold) = (
        periods_of("--within", a.within, tau)?,
        periods_of("--hold", a.hold, tau)?,
    );
    // The clock of --within starts at the knock, if one comes.
    let knock = knock.map(|[force, at]| Knock {
        period: (at / tau).round() as u32,
        force,
    });
    let from = knock.map_or(0, |k| k.period);
    let within = from + within;
    let margin = f64::from(board.rig.limits().map_err(anyhow::Error::msg)?.max_abs()[0]);
    let bar = ProgressBar::new(2 * u64::from(a.episodes)).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} episodes {elapsed}<{eta}")
            .context("the progress bar's template")?,
    );
    let periods = within + hold;
    if a.render.is_some() {
        let from = "the episode --render draws (--within + --hold, after any --knock)";
        crate::render_cmd::bound(periods.into(), a.stride, from)?;
    }
    let runs = Runs {
        begin,
        startup,
        world: &world,
        board: &board,
        periods,
        zero_off: counts_off(a.zero_error, &world),
        cart_start: a.cart_start,
        knock,
        seed: a.seed,
        episodes: a.episodes,
        bar: &bar,
    };
    let summary =
        |name, outcomes: Vec<Outcome>| summarise(name, &outcomes, (from, within), tau, margin);
    let float = summary("f32", runs.all(&net)?);
    let int = IntNet::of(&net).context("the policy has no integer version")?;
    let int = summary("int8", runs.all(int)?);
    bar.finish_and_clear();
    let report = Report {
        start: begin,
        knock: knock.map(|k| [k.force, f64::from(k.period) * tau]),
        seed: a.seed,
        within_s: a.within,
        hold_s: a.hold,
        cart_start_m: a.cart_start,
        zero_error_deg: a.zero_error,
        startup: format!("{startup:?}"),
        rows: vec![float, int],
    };
    if a.json {
        host_common::outln!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        host_common::out!("{}", table(&report));
    }
    // Drawn once the report is out: pictures that cannot be written lose no episodes.
    if let Some(out) = &a.render {
        let (gif, png) = draw(&runs, &net, (a.episode, a.stride), out)?;
        name_pictures(a.json, &gif, &png);
    }
    Ok(true)
}

/// The pictures' paths: on standard error beside the JSON (`json`), on standard output
/// below the table.
fn name_pictures(json: bool, gif: &Path, png: &Path) {
    let names = format!("{}\n{}", weights::shown(gif), weights::shown(png));
    if json {
        host_common::errln!("{names}");
    } else {
        host_common::outln!("{names}");
    }
}

/// `flag`'s `seconds` in periods of `tau`, refused where they round to none: it judged
/// episodes at no time and reported 0%.
fn periods_of(flag: &str, seconds: f64, tau: f64) -> Result<u32> {
    let periods = (seconds / tau).round();
    anyhow::ensure!(
        periods >= 1.0,
        "{flag} {seconds:?} s rounds to no period of {tau:?} s; expected at least half a \
         period ({:?} s)",
        tau / 2.0
    );
    Ok(periods as u32)
}

/// `a`'s values, and its picture's paths, before any work.
fn check(a: &StartupArgs) -> Result<()> {
    anyhow::ensure!(
        (1..=MAX_EPISODES).contains(&a.episodes),
        "--episodes must be 1 to {MAX_EPISODES}, found {}",
        a.episodes
    );
    anyhow::ensure!(
        a.zero_error.abs() <= 10.0 && weights::plain(a.zero_error),
        "--zero-error must be degrees in [-10, 10], zero or normal, found {:?}",
        a.zero_error
    );
    anyhow::ensure!(
        (0.0..=10.0).contains(&a.cart_start) && weights::plain(a.cart_start),
        "--cart-start must be metres in [0, 10], zero or normal, found {:?}",
        a.cart_start
    );
    // A millisecond at least: less is no duration a board's period can count.
    for (flag, s) in [("--within", a.within), ("--hold", a.hold)] {
        anyhow::ensure!(
            (0.001..=3600.0).contains(&s),
            "{flag} must be seconds in [0.001, 3600], found {s:?}"
        );
    }
    if let Some(out) = &a.render {
        anyhow::ensure!(
            a.episode < a.episodes,
            "--episode must be below --episodes ({}), found {}",
            a.episodes,
            a.episode
        );
        let (gif, png) = crate::render_cmd::pictures("--render", out)?;
        let mut inputs = a.subject.inputs();
        inputs.extend(a.world.clone().map(|w| ("--world", w)));
        crate::check_io(&inputs, &[("--render", &gif), ("--render", &png)])?;
    }
    Ok(())
}

/// The force, N, and time, s, of the knock `a` asks for, if one.
fn knock(a: &StartupArgs) -> Result<Option<[f64; 2]>> {
    let Some(spec) = &a.knock else {
        return Ok(None);
    };
    anyhow::ensure!(
        a.start != StartArg::Lifted,
        "--knock needs a swing-up to bring the pole back: --start hanging or swinging, found \
         --start lifted"
    );
    let parsed = spec
        .split_once('@')
        .and_then(|(f, t)| Some([f.parse::<f64>().ok()?, t.parse::<f64>().ok()?]));
    match parsed {
        Some([force, at])
            if force > 0.0
                && force <= 1000.0
                && at > 0.0
                && at <= 3600.0
                && weights::plain(force)
                && weights::plain(at) =>
        {
            Ok(Some([force, at]))
        }
        _ => anyhow::bail!(
            "--knock expects NEWTONS@SECONDS, newtons in (0, 1000] and seconds in (0, 3600], \
             normal numbers (e.g. 40@20), found '{}'",
            weights::excerpt(spec)
        ),
    }
}

/// Draws episode `k` of `runs` with the float network into `out`, every `stride`-th period
/// into the GIF; the pictures' paths.
fn draw(
    runs: &Runs<'_>,
    net: &Net,
    (k, stride): (u32, usize),
    out: &std::path::Path,
) -> Result<(PathBuf, PathBuf)> {
    let mut frames = Vec::new();
    let o = runs.episode(k, net, |f, _| frames.push(*f))?;
    let title = format!("start-up from {:?}, episode {k}", runs.begin);
    let tau = runs.world.rig.params.tau;
    let caption = match o.balanced_from {
        Some(b) => format!("{title}: balanced from {:.2} s", f64::from(b) * tau),
        None => format!("{title}: not balanced at the end"),
    };
    let params = &runs.world.rig.params;
    crate::render_cmd::draw(
        ("--render", out),
        &frames,
        params,
        stride,
        (&title, &caption),
    )
}

/// What every episode of a run shares.
struct Runs<'a> {
    begin: Begin,
    startup: Startup,
    world: &'a Machine,
    board: &'a Machine,
    periods: u32,
    /// The zero's error once taken, pole counts ([`Events::zero_off`]).
    zero_off: i32,
    /// The cart's start drawn within this of the centre, m (0: as the start draws it).
    cart_start: f64,
    /// The push, towards +x; each episode draws its side.
    knock: Option<Knock>,
    seed: u64,
    episodes: u32,
    bar: &'a ProgressBar,
}

/// `degrees` in whole counts of `world`'s pole encoder.
/// `a`'s values that only the world can judge: a cart started on its track, and a zero
/// error the pole's encoder counts (the `zero` scenario part is judged alike).
fn check_world(a: &StartupArgs, world: &Machine) -> Result<()> {
    let track = world.rig.params.x_threshold;
    anyhow::ensure!(
        a.cart_start <= track,
        "--cart-start must be at most the world's track half-length, {track} m, found {:?}",
        a.cart_start
    );
    let rev = world.rig.encoders.pole_counts_per_rev;
    anyhow::ensure!(
        a.zero_error == 0.0 || counts_off(a.zero_error, world) != 0,
        "--zero-error {:?} degrees rounds to no count of the pole's encoder ({rev} counts a \
         turn, {:.3} degrees a count); expected half a count or more, or 0",
        a.zero_error,
        360.0 / f64::from(rev)
    );
    Ok(())
}

/// The pole counts a zero `degrees` off adds to what `world`'s encoder reads, as the `zero`
/// scenario part adds them.
fn counts_off(degrees: f64, world: &Machine) -> i32 {
    twin::faults::zero_counts((degrees.to_radians(), 0.0), &world.rig.encoders).1
}

impl Runs<'_> {
    /// Every episode with the policy `p`, on all cores, in episode order.
    fn all<O: Estimate, P: Policy<O> + Copy + Send + Sync>(&self, p: P) -> Result<Vec<Outcome>> {
        (0..self.episodes)
            .into_par_iter()
            .map(|k| {
                let o = self.episode(k, p, |_, _| {});
                self.bar.inc(1);
                o
            })
            .collect()
    }

    /// Episode `k` with `policy`, `each` shown every period: the start drawn from the
    /// episode's own stream of the seed.
    fn episode<O: Estimate, P: Policy<O>>(
        &self,
        k: u32,
        policy: P,
        each: impl FnMut(&Frame, Phase),
    ) -> Result<Outcome> {
        let tau = self.board.rig.params.tau;
        let mut rng = Pcg64Mcg::new((u128::from(self.seed) << 64) | u128::from(k));
        let (mut start, lift) = self.begin.draw(&mut rng, &self.startup, tau);
        if self.cart_start > 0.0 {
            start.x = self.cart_start * (2.0 * unit_f64(&mut rng) - 1.0);
        }
        let knocks: Vec<Knock> = self
            .knock
            .iter()
            .map(|k| Knock {
                force: if unit_f64(&mut rng) < 0.5 {
                    -k.force
                } else {
                    k.force
                },
                ..*k
            })
            .collect();
        let events = Events {
            periods: self.periods,
            lift,
            knocks: &knocks,
            zero_off: self.zero_off,
        };
        let (world, rig) = (self.world, &self.board.rig);
        power_on::<O, _>(world, rig, self.startup, (policy, start), events, each)
            .map_err(anyhow::Error::msg)
    }
}

/// The board's machine, its start-up and its policy: --policy on its rig (or --rig), or the
/// shipped desk policy on the identified desk rig it was trained for (or --rig).
fn board(s: &Subject) -> Result<(Machine, Startup, Net)> {
    let given = s
        .rig
        .as_deref()
        .map(twin::rigfile::load_startup)
        .transpose()?;
    let (machine, net) = match &s.policy {
        Some(_) => s.load_for(
            &[ControllerKind::Policy, ControllerKind::PolicyInt],
            &Monitor::default(),
        )?,
        None => {
            let rig = shipped::desk::RIG;
            let desk = Machine {
                rig,
                integration: Integration::rk4(rig.params.tau, twin::rigfile::DEFAULT_SUBSTEP_S),
                uncertainty: Default::default(),
            };
            (given.map_or(desk, |(m, _)| m), Net::shipped_desk())
        }
    };
    let startup = match given {
        Some((m, startup)) if m == machine => startup,
        _ => Startup::suggested(&machine.rig).map_err(anyhow::Error::msg)?,
    };
    Ok((machine, startup, net))
}
