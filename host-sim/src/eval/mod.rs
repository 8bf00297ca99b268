//! Closed-loop evaluation: many seeded episodes per controller, scenario and horizon, and
//! the statistics of the robustness table with 95% confidence intervals.
//!
//! Episode `i` of seed `s` starts from the same state, meets the same noise and the same
//! pushes whichever controller runs it, so rows compare controllers on identical worlds.
//! Episodes run in parallel (rayon) and are gathered in order, so results do not depend on
//! the number of threads.
//!
//! - `net`: a policy of any width, as the simulator runs it.
//! - `table`: the rows and how they are printed.

use std::fmt;

use rayon::prelude::*;
use serde::Serialize;
use std::ops::Range;

use firmware::controller::{Duty, Refined};
use twin::run::{Aids, Stream, episode_rng};
use twin::{EpisodeStats, Frame, Scenario};
use twin::{run_episode, run_episodes};

use crate::baselines::{AngleRule, LinearLqr, Lqr, Random, RoundedLqr};

mod net;
mod rows;
mod table;

pub use net::{IntNet, Net};
pub use rows::{MAX_ROWS, check_count, check_rows};
pub(crate) use table::group;
pub use table::{Motor, Row, WORST, Worst, format_failures, format_table};

/// Which controller drives the cart.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ControllerKind {
    /// The Q-network (shipped, or `--policy FILE`).
    Policy,
    /// Its integer version (int8 weights, no floating point in the forward pass).
    PolicyInt,
    /// The Q-network, its chosen level moved to the peak of its scores between the
    /// neighbouring levels (`firmware::controller::Refined`).
    PolicyRefined,
    /// The integer network, refined alike.
    PolicyIntRefined,
    /// The Q-network under the runtime monitor: LQR outside its envelope, a safe stop
    /// where even LQR cannot recover, frozen encoders watched for.
    Monitored,
    /// Its integer version under the same monitor.
    MonitoredInt,
    /// Bang-bang discrete LQR, Q = I, R = 1, gain for the nominal plant.
    Lqr,
    /// The same LQR, told the dead time and deciding on the predicted state, as `policy`.
    LqrPredict,
    /// Linear LQR: the same gain's command as a duty, continuous PWM saturated at full.
    LqrLinear,
    /// Linear LQR on the predicted state.
    LqrLinearPredict,
    /// Linear LQR rounded to the nearest of the policy's duty levels: what a linear
    /// controller does with only the levels the policy may choose.
    LqrLevels,
    /// The rounded linear LQR on the predicted state.
    LqrLevelsPredict,
    /// Push towards `theta + 0.5 theta_dot`.
    Rule,
    /// A fair coin every period.
    Random,
}

impl ControllerKind {
    /// The controllers a target runs over the link (`eval --pil`): those in which the
    /// Q-network drives.
    pub fn on_target() -> impl Iterator<Item = ControllerKind> {
        let all = <ControllerKind as clap::ValueEnum>::value_variants().iter();
        all.copied().filter(|k| k.runs_policy())
    }

    /// The words that refuse a policy, or its levels, given to controllers none of which
    /// reads it (`eval --policy`, Python's `evaluate(policy)`): which do
    /// ([`Self::needs_policy`]).
    pub fn read_by() -> String {
        let all = <ControllerKind as clap::ValueEnum>::value_variants().iter();
        let readers: Vec<ControllerKind> = all.copied().filter(|k| k.needs_policy()).collect();
        format!(
            "is read by the controllers that run its network or round to its levels ({}) alone",
            names(&readers)
        )
    }

    /// Whether the Q-network drives (in any form).
    pub fn runs_policy(self) -> bool {
        self.int()
            || matches!(
                self,
                ControllerKind::Policy | ControllerKind::PolicyRefined | ControllerKind::Monitored
            )
    }

    /// Whether the policy's duty levels shape its commands: the network drives, or a
    /// baseline is rounded to its levels.
    pub fn needs_policy(self) -> bool {
        self.runs_policy()
            || matches!(
                self,
                ControllerKind::LqrLevels | ControllerKind::LqrLevelsPredict
            )
    }

    /// Whether the integer network drives.
    pub fn int(self) -> bool {
        matches!(
            self,
            ControllerKind::PolicyInt
                | ControllerKind::PolicyIntRefined
                | ControllerKind::MonitoredInt
        )
    }

    /// Whether the chosen level is refined between its neighbours (`policy-refined`,
    /// `policy-int-refined`).
    pub fn refined(self) -> bool {
        matches!(
            self,
            ControllerKind::PolicyRefined | ControllerKind::PolicyIntRefined
        )
    }

    /// The controller this one runs as where the levels are two ([`unrefinable`] says
    /// which two): refining between them, or rounding the LQR's duty to them, changes
    /// nothing.
    pub fn on_two_levels(self) -> Option<ControllerKind> {
        Some(match self {
            ControllerKind::PolicyRefined => ControllerKind::Policy,
            ControllerKind::PolicyIntRefined => ControllerKind::PolicyInt,
            ControllerKind::LqrLevels => ControllerKind::Lqr,
            ControllerKind::LqrLevelsPredict => ControllerKind::LqrPredict,
            _ => return None,
        })
    }

    /// Whether the runtime monitor decides who drives.
    pub fn monitored(self) -> bool {
        matches!(
            self,
            ControllerKind::Monitored | ControllerKind::MonitoredInt
        )
    }
}

impl fmt::Display for ControllerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ControllerKind::Policy => "policy",
            ControllerKind::PolicyInt => "policy-int",
            ControllerKind::PolicyRefined => "policy-refined",
            ControllerKind::PolicyIntRefined => "policy-int-refined",
            ControllerKind::Monitored => "monitored",
            ControllerKind::MonitoredInt => "monitored-int",
            ControllerKind::Lqr => "lqr",
            ControllerKind::LqrPredict => "lqr-predict",
            ControllerKind::LqrLinear => "lqr-linear",
            ControllerKind::LqrLinearPredict => "lqr-linear-predict",
            ControllerKind::LqrLevels => "lqr-levels",
            ControllerKind::LqrLevelsPredict => "lqr-levels-predict",
            ControllerKind::Rule => "rule",
            ControllerKind::Random => "random",
        })
    }
}

/// The words that refuse a controller among `kinds` whose rows would be another's
/// ([`ControllerKind::on_two_levels`]), bit for bit, for a policy of `levels`: see
/// [`unrefinable`] and [`unrounded`].
pub fn idle_between(kinds: &[ControllerKind], levels: &[Duty]) -> Option<String> {
    unrefinable(kinds, levels.len() > 2).or_else(|| unrounded(kinds, levels))
}

/// The words that refuse a refined controller among `kinds` for a policy that is not
/// `refinable` (two levels: nothing lies between them).
pub fn unrefinable(kinds: &[ControllerKind], refinable: bool) -> Option<String> {
    let c = kinds.iter().find(|k| k.refined()).filter(|_| !refinable)?;
    Some(format!(
        "its two levels are both ends, with nothing between them to refine; found {c}, which \
         would run as {} (run that)",
        c.on_two_levels()?
    ))
}

/// The words that refuse the LQR rounded to `levels` among `kinds` where they are the full
/// push each way: rounding leaves the bang-bang LQR's duty alone (two levels of half the
/// push are another controller).
pub fn unrounded(kinds: &[ControllerKind], levels: &[Duty]) -> Option<String> {
    let c = (kinds.iter())
        .find(|k| !k.refined() && k.on_two_levels().is_some())
        .filter(|_| levels == [Duty::LEFT, Duty::RIGHT])?;
    Some(format!(
        "its two levels are the full push each way, to which rounding leaves the bang-bang \
         LQR's duty alone; found {c}, which would run as {} (run that)",
        c.on_two_levels()?
    ))
}

/// Controllers' names as the command line gives them, in a list.
pub fn names(kinds: &[ControllerKind]) -> String {
    let names: Vec<String> = kinds.iter().map(ToString::to_string).collect();
    names.join(", ")
}

/// Runs episode `episode` with controller `kind`; `on_frame` sees every period.
pub fn episode(
    kind: ControllerKind,
    net: &Net,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episode: u64,
    on_frame: impl FnMut(Frame),
) -> EpisodeStats {
    let (s, h) = (scenario, horizon);
    match kind {
        // The policy is told the dead time, as a board knows its own.
        ControllerKind::Policy => run_episode(net, s, h, seed, episode, true, on_frame),
        ControllerKind::Monitored => {
            run_episode(net, s, h, seed, episode, monitored(net), on_frame)
        }
        ControllerKind::PolicyInt => run_episode(int(net), s, h, seed, episode, true, on_frame),
        ControllerKind::PolicyRefined => {
            run_episode(Refined(net), s, h, seed, episode, true, on_frame)
        }
        ControllerKind::PolicyIntRefined => {
            run_episode(Refined(int(net)), s, h, seed, episode, true, on_frame)
        }
        ControllerKind::MonitoredInt => {
            run_episode(int(net), s, h, seed, episode, monitored(net), on_frame)
        }
        ControllerKind::Lqr => run_episode(Lqr::of(&s.rig), s, h, seed, episode, false, on_frame),
        ControllerKind::LqrPredict => {
            run_episode(Lqr::of(&s.rig), s, h, seed, episode, true, on_frame)
        }
        ControllerKind::LqrLinear | ControllerKind::LqrLinearPredict => {
            let predict = kind == ControllerKind::LqrLinearPredict;
            run_episode(
                LinearLqr::of(&s.rig),
                s,
                h,
                seed,
                episode,
                predict,
                on_frame,
            )
        }
        ControllerKind::LqrLevels | ControllerKind::LqrLevelsPredict => {
            let predict = kind == ControllerKind::LqrLevelsPredict;
            let lqr = RoundedLqr::of(&s.rig, net.levels());
            run_episode(lqr, s, h, seed, episode, predict, on_frame)
        }
        ControllerKind::Rule => run_episode(AngleRule, s, h, seed, episode, false, on_frame),
        ControllerKind::Random => run_episode(
            Random(episode_rng(seed, episode, Stream::Policy)),
            s,
            h,
            seed,
            episode,
            false,
            on_frame,
        ),
    }
}

/// Episodes `episodes` of controller `kind`, side by side (`twin::run_episodes`).
pub fn episodes(
    kind: ControllerKind,
    net: &Net,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episodes: Range<u64>,
) -> Vec<EpisodeStats> {
    let (s, h, e) = (scenario, horizon, episodes);
    match kind {
        ControllerKind::Policy => run_episodes(|_| net, s, h, seed, e, true),
        ControllerKind::Monitored => run_episodes(|_| net, s, h, seed, e, monitored(net)),
        ControllerKind::PolicyInt => run_episodes(|_| int(net), s, h, seed, e, true),
        ControllerKind::PolicyRefined => run_episodes(|_| Refined(net), s, h, seed, e, true),
        ControllerKind::PolicyIntRefined => {
            run_episodes(|_| Refined(int(net)), s, h, seed, e, true)
        }
        ControllerKind::MonitoredInt => run_episodes(|_| int(net), s, h, seed, e, monitored(net)),
        ControllerKind::Lqr => run_episodes(|_| Lqr::of(&s.rig), s, h, seed, e, false),
        ControllerKind::LqrPredict => run_episodes(|_| Lqr::of(&s.rig), s, h, seed, e, true),
        ControllerKind::LqrLinear | ControllerKind::LqrLinearPredict => {
            let predict = kind == ControllerKind::LqrLinearPredict;
            run_episodes(|_| LinearLqr::of(&s.rig), s, h, seed, e, predict)
        }
        ControllerKind::LqrLevels | ControllerKind::LqrLevelsPredict => {
            let predict = kind == ControllerKind::LqrLevelsPredict;
            let lqr = RoundedLqr::of(&s.rig, net.levels());
            run_episodes(|_| lqr.clone(), s, h, seed, e, predict)
        }
        ControllerKind::Rule => run_episodes(|_| AngleRule, s, h, seed, e, false),
        ControllerKind::Random => run_episodes(
            |i| Random(episode_rng(seed, i, Stream::Policy)),
            s,
            h,
            seed,
            e,
            false,
        ),
    }
}

/// The integer version of `net`.
fn int(net: &Net) -> IntNet<'_> {
    IntNet::of(net).expect("the caller built the net with its integer version")
}

/// What a monitored policy's board knows: its dead time and its envelope.
fn monitored(net: &Net) -> Aids {
    Aids {
        predict: true,
        envelope: Some(net.envelope().expect(NO_ENVELOPE)),
    }
}

/// Why a monitored run may take the network's envelope as given.
/// Most episodes per row of `eval`: a row keeps each episode's statistics
/// ([`EPISODE_BYTES`]) and little besides, so 720 MB at the limit.
pub const MAX_EPISODES: u64 = 10_000_000;
/// What a row keeps per episode while its statistics are taken: the episode's
/// [`EpisodeStats`], in one list allocated once (`docs/HOSTILE_INPUT.md`).
pub const EPISODE_BYTES: usize = size_of::<EpisodeStats>();
/// Longest episode `eval` runs, in periods (about 5.6 hours of control).
pub const MAX_HORIZON: u32 = 1_000_000;

const NO_ENVELOPE: &str = "the caller refused `monitored` for a network without an envelope";

/// Episodes a thread runs side by side, enough to keep the lanes full as episodes end.
const CHUNK: u64 = 64;

/// `episodes` seeded episodes of one controller in one scenario, in parallel, in order.
pub fn evaluate(
    kind: ControllerKind,
    net: &Net,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episodes: u64,
) -> Row {
    let eps = par_episodes(kind, net, scenario, horizon, seed, 0..episodes);
    row(kind, scenario, horizon, seed, &eps)
}

/// Episodes `episodes` of one controller in one scenario, in parallel, in order: a caller
/// may run a row's episodes range by range (and stop between ranges) and get the same row.
/// Each chunk's episodes are written into their place in one list allocated once, where a
/// parallel collect held every episode twice at its end.
pub fn par_episodes(
    kind: ControllerKind,
    net: &Net,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episodes: Range<u64>,
) -> Vec<EpisodeStats> {
    let first = episodes.start;
    let n = episodes.end.saturating_sub(first);
    let mut eps = vec![EpisodeStats::default(); n as usize];
    eps.par_chunks_mut(CHUNK as usize)
        .enumerate()
        .for_each(|(c, out)| {
            let start = first + c as u64 * CHUNK;
            let range = start..start + out.len() as u64;
            out.copy_from_slice(&self::episodes(kind, net, scenario, horizon, seed, range));
        });
    eps
}

/// The row of controller `kind`'s episodes `eps` (episode `i` of `seed` at `eps[i]`).
pub fn row(
    kind: ControllerKind,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    eps: &[EpisodeStats],
) -> Row {
    let period = (horizon, scenario.params.tau);
    Row::from_episodes(&kind.to_string(), &scenario.name, period, seed, eps)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Several chunks, on a pool of one thread and on one of four, give the same row bit for
    /// bit (its floats by their shortest exact representations, its worst episodes by
    /// index): episodes are gathered in order, whichever thread ran a chunk and whenever it
    /// ended. Pushes make some episodes fail, so the row's worst list has entries to order.
    #[test]
    fn results_do_not_depend_on_threads() {
        let net = Net::shipped();
        let s = Scenario::parse("noise+push=2").unwrap();
        // Four full chunks and part of a fifth.
        let episodes = 4 * CHUNK + 17;
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                assert_eq!(rayon::current_num_threads(), threads);
                evaluate(ControllerKind::Policy, &net, &s, 200, 3, episodes)
            })
        };
        let (one, four) = (run(1), run(4));
        assert_eq!(one.episodes, episodes as usize);
        assert!(one.success_rate < 1.0, "no episode failed: {one:?}");
        assert_eq!(format!("{one:?}"), format!("{four:?}"));
    }

    /// A row's episodes run in ranges that cut across the chunks give the row of one run.
    #[test]
    fn ranges_of_episodes_give_the_same_row() {
        let (net, kind) = (Net::shipped(), ControllerKind::Policy);
        let s = Scenario::parse("noise+push=2").unwrap();
        let whole = evaluate(kind, &net, &s, 200, 3, 2 * CHUNK + 9);
        let mut eps = Vec::new();
        for r in [0..5, 5..CHUNK + 3, CHUNK + 3..2 * CHUNK + 9] {
            eps.extend(par_episodes(kind, &net, &s, 200, 3, r));
        }
        assert!(whole.failures > 0, "no episode failed: {whole:?}");
        assert_eq!(
            format!("{whole:?}"),
            format!("{:?}", row(kind, &s, 200, 3, &eps))
        );
    }

    /// Refining drives a two-level policy as it was, float and integer (both its levels are
    /// ends, `firmware::controller::Refined`), and moves a nine-level one off its levels: the
    /// simulator's scores reach the refinement (they once lacked the rises it reads).
    #[test]
    fn refining_moves_only_a_policy_with_levels_between_its_ends() {
        let s = Scenario::parse("noise").unwrap();
        let run = |kind, net: &Net| format!("{:?}", par_episodes(kind, net, &s, 200, 3, 0..8));
        let two = Net::shipped();
        assert_eq!(
            run(ControllerKind::Policy, &two),
            run(ControllerKind::PolicyRefined, &two)
        );
        assert_eq!(
            run(ControllerKind::PolicyInt, &two),
            run(ControllerKind::PolicyIntRefined, &two)
        );
        let nine = Net::shipped_desk();
        let mut off = 0;
        episode(ControllerKind::PolicyRefined, &nine, &s, 200, 3, 0, |f| {
            let duty = match f.command {
                firmware::controller::Command::Drive(d) => Some(d),
                firmware::controller::Command::Coast => None,
            };
            off += usize::from(duty.is_some_and(|d| !nine.levels().contains(&d)));
        });
        assert!(off > 0, "no refined duty left the levels");
    }
}
