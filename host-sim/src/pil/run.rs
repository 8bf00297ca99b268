//! Episodes over the link: the twin's world measured and moved by what the target
//! commands, the software-in-the-loop reference fed the same frames, and what the two say
//! compared period by period.

use anyhow::{Context, Result, bail, ensure};
use firmware::controller::FaultFlags;
use firmware::link::{Format, Info, Reply, Scores, Start, digest};
use firmware::loopback::command_duty;
use firmware::rig::Rig;
use serde::Serialize;
use twin::run::{Draws, Tally};
use twin::{EpisodeStats, Scenario};

use super::Board;
use super::link::{Remote, Session};
use crate::eval::ControllerKind;

/// What the comparison with the software-in-the-loop reference and the target's clock
/// found over a row's episodes.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Check {
    /// Periods run.
    pub periods: u64,
    /// Periods whose command, scores (bit for bit) or fault flags differ from the
    /// reference's.
    pub mismatches: u64,
    /// The first of them.
    pub first: Option<Mismatch>,
    /// The target's time per period, ns: median, 99th percentile, worst.
    pub time_ns: [u64; 3],
    /// Periods whose time exceeded the control period.
    pub overruns: u64,
}

/// One period where the target and the reference differ.
#[derive(Clone, Debug, Serialize)]
pub struct Mismatch {
    /// Episode.
    pub episode: u64,
    /// Period of the episode.
    pub period: u32,
    /// What the target answered.
    pub target: String,
    /// What the reference answered.
    pub reference: String,
}

/// Whether two answers say the same: the command, the scores bit for bit, the flags.
fn same(a: &Reply, b: &Reply) -> bool {
    let scores = match (a.scores, b.scores) {
        (Scores::F32(x), Scores::F32(y)) => x
            .as_slice()
            .iter()
            .map(|v| v.to_bits())
            .eq(y.as_slice().iter().map(|v| v.to_bits())),
        (x, y) => x == y,
    };
    a.command == b.command && scores && a.faults == b.faults
}

/// Checks that `target` holds what the reference holds for `format` (the application of
/// `board`), and runs `scenario`'s board (its rig less the dead time, which Start sets);
/// the target's `Info`.
pub fn handshake(
    target: &mut Session<impl Remote>,
    reference: &mut Session<impl Remote>,
    format: Format,
    scenarios: &[Scenario],
    board: Board,
) -> Result<Info> {
    let got = target.hello(format).context("the handshake")?;
    let want = reference.hello(format)?;
    let differs = |what: &str| {
        anyhow::anyhow!(
            "the target holds another {what} than this build of the firmware's {board} \
             policy ({format:?}: target {got:?}, here {want:?}); rebuild the {} application, \
             or give the --pil-policy it holds",
            board.app()
        )
    };
    ensure!(
        got.hidden == want.hidden && got.policy == want.policy,
        differs("policy")
    );
    ensure!(
        got.rig == want.rig && got.period_ns == want.period_ns,
        differs("rig")
    );
    ensure!(got.clock_hz > 0, "the target's clock runs at 0 Hz");
    for s in scenarios {
        let built = Rig {
            dead_time: board.rig().dead_time,
            ..s.rig
        };
        if digest::rig(&built) != got.rig {
            bail!(
                "scenario {}: its board's rig differs from the target's in more than the dead \
                 time (a rig file or encoder of its own); the target runs the rig it was built \
                 with (--rig gives the scenarios that machine)",
                s.name
            );
        }
        ensure!(
            s.delay() <= u32::from(u8::MAX),
            "scenario {}: a dead time of {} periods does not fit the link's Start",
            s.name,
            s.delay()
        );
    }
    Ok(got)
}

/// Episodes `0..episodes` of `seed` under `scenario`, `horizon` periods at most, with the
/// target's commands moving the world, as the row's controller `kind` asks (under the runtime
/// monitor, refined between the levels; its format is `info`'s); each
/// period compared with `reference`'s answer and timed on `info`'s clock. `progress` sees
/// every finished episode.
#[allow(clippy::too_many_arguments)]
pub fn run_row(
    target: &mut Session<impl Remote>,
    reference: &mut Session<impl Remote>,
    (info, kind): (&Info, ControllerKind),
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episodes: u64,
    mut progress: impl FnMut(),
) -> Result<(Vec<EpisodeStats>, Check)> {
    let start = Start {
        sensing: scenario.sensing,
        // As `eval`'s policy rows: the board is told its dead time.
        predict: true,
        monitor: kind.monitored(),
        refine: kind.refined(),
        dead_time: scenario.delay() as u8,
    };
    let mut check = Check::default();
    let mut times = Vec::new();
    let mut stats = Vec::with_capacity(episodes as usize);
    for e in 0..episodes {
        let mut world = Draws::of(seed).world(scenario, horizon, e);
        let mut tally = Tally::default();
        for k in 0.. {
            let at = || format!("{}, episode {e}, period {k}", scenario.name);
            if k == 0 || scenario.faults.resets(k) {
                target.start(start).with_context(at)?;
                reference.start(start).with_context(at)?;
            }
            let m = world.measure();
            let got = target.period(m).with_context(at)?;
            let want = reference.period(m).with_context(at)?;
            if !same(&got, &want) {
                check.mismatches += 1;
                check.first.get_or_insert_with(|| Mismatch {
                    episode: e,
                    period: k,
                    target: format!("{got:?}"),
                    reference: format!("{want:?}"),
                });
            }
            times.push(u64::from(got.ticks) * 1_000_000_000 / u64::from(info.clock_hz));
            let t = world.apply(command_duty(got.command));
            let fallback = got.faults.contains(FaultFlags::FALLBACK);
            tally.period(
                &scenario.params,
                (got.command, fallback),
                &world.state(),
                &t,
            );
            if t.terminated || t.truncated {
                break;
            }
        }
        stats.push(tally.stats());
        progress();
    }
    check.periods = times.len() as u64;
    check.overruns = times
        .iter()
        .filter(|&&t| t > u64::from(info.period_ns))
        .count() as u64;
    times.sort_unstable();
    let at =
        |q: f64| times.get(((times.len() as f64 * q) as usize).min(times.len().saturating_sub(1)));
    check.time_ns = [at(0.5), at(0.99), times.last()].map(|t| t.copied().unwrap_or(0));
    Ok((stats, check))
}

#[cfg(test)]
mod tests {
    use firmware::controller::{Command, Duty};
    use firmware::link::Values;

    use super::*;

    fn reply(scores: Scores) -> Reply {
        Reply {
            command: Command::Drive(Duty::LEFT),
            scores,
            faults: FaultFlags(0),
            ticks: 7,
        }
    }

    #[test]
    fn answers_are_the_same_when_their_scores_match_in_count_and_bits() {
        let f = |q: &[f32]| reply(Scores::F32(Values::new(q).unwrap()));
        let nan = f32::from_bits(0x7FC0_0001);
        assert!(same(&f(&[1.0, nan]), &f(&[1.0, nan])));
        assert!(!same(&f(&[1.0, nan]), &f(&[1.0, f32::NAN])));
        assert!(!same(&f(&[0.0, 1.0]), &f(&[-0.0, 1.0])));
        // A policy of more outputs is another answer, whatever its first scores.
        assert!(!same(&f(&[1.0, 2.0]), &f(&[1.0, 2.0, 3.0])));
        let i = |q: &[i32]| reply(Scores::I32(Values::new(q).unwrap()));
        assert!(same(&i(&[3; 9]), &i(&[3; 9])));
        assert!(!same(&i(&[3; 9]), &i(&[3; 8])));
        assert!(!same(&i(&[0, 1]), &f(&[0.0, 1.0])));
    }
}
