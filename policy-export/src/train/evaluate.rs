//! How good a policy is: greedy episodes on fresh starts, and the paper's "solved" measure
//! on a run's returns.

use firmware::controller::{Greedy, Levels, Policy};
use firmware::estimator::Estimate;
use firmware::network::Mlp;
use firmware::network::int::QMlp;
use host_common::wide::WideMlp;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use twin::lockstep::run_lockstep;
use twin::run::Draws;
use twin::{Domain, Machine, Scenario};
use weights::Weights;
use weights::quant::Granularity;

use super::Stream;
use crate::reward::Prices;

/// A greedy evaluation's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalResult {
    /// Episodes run.
    pub episodes: usize,
    /// Their step limit.
    pub max_steps: u32,
    /// Mean return.
    pub mean: f64,
    /// Worst return.
    pub min: f64,
    /// How far from upright and centred it held the plant, and how hard it drove the motor
    /// doing so: the mean over every step of `lean (theta / theta_max)^2 + distance
    /// (x / x_max)^2 + duty u^2 + change |u - u_prev|` for the period's duty `u` and the
    /// previous period's `u_prev` (0 before the first), at the [`Judge`]'s [`Prices`].
    /// Between snapshots of equal returns, the lower is the better controller: at the plain
    /// prices, of two-level policies (`u^2 = 1` always) the one held closer; with the
    /// learning reward's prices, the one the learner was asked for.
    #[serde(default)]
    pub cost: f64,
}

impl EvalResult {
    /// Whether `self` beats `other`: a higher mean return, or an equal one held closer to
    /// upright and centre.
    pub fn beats(&self, other: &EvalResult) -> bool {
        self.mean > other.mean || (self.mean == other.mean && self.cost < other.cost)
    }
}

/// Where one evaluation's random draws come from: episode `e` draws its world from a stream
/// of its own, and its start, sensor noise and push sides as [`Draws`] say, each indexed by
/// `e` under the run's seed. So every snapshot evaluated with the same streams meets the same
/// worlds, in any order of episodes (in parallel).
#[derive(Clone, Copy, Debug)]
pub struct EvalStreams {
    /// The stream of the episodes' worlds.
    pub world: Stream,
    /// The run's seed and the streams of the starts, the noise and the pushes.
    pub draws: Draws,
}

impl EvalStreams {
    /// The streams of `world`, `start`, `noise` and `pushes` under `seed`.
    fn new(seed: u64, [world, start, noise, pushes]: [Stream; 4]) -> EvalStreams {
        EvalStreams {
            world,
            draws: Draws {
                seed,
                streams: [start, noise, pushes].map(|s| s as u64),
            },
        }
    }

    /// The generator of episode `episode`'s world.
    pub fn world(&self, episode: u64) -> Pcg64Mcg {
        self.draws.rng(episode, self.world as u64)
    }

    /// The streams of evaluation `which` of the run of `seed`.
    pub fn of(seed: u64, which: Eval) -> EvalStreams {
        let streams = match which {
            Eval::Periodic => [
                Stream::EvalWorld,
                Stream::Eval,
                Stream::EvalNoise,
                Stream::EvalPushes,
            ],
            Eval::Trial => [
                Stream::TrialWorld,
                Stream::Trial,
                Stream::TrialNoise,
                Stream::TrialPushes,
            ],
            Eval::Final => [
                Stream::FinalWorld,
                Stream::Final,
                Stream::FinalNoise,
                Stream::FinalPushes,
            ],
        };
        EvalStreams::new(seed, streams)
    }
}

/// Which evaluation a set of streams serves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Eval {
    /// The periodic ones: the same streams every time within a run.
    Periodic,
    /// The finalists' trial: the same streams for every finalist.
    Trial,
    /// The final one, disjoint from everything the run trained or selected on.
    Final,
}

/// How an evaluation runs its episodes and prices their driving.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Judge {
    /// Decide on readings advanced over the world's dead time.
    pub compensate: bool,
    /// What [`EvalResult::cost`] charges.
    pub prices: Prices,
}

/// Episodes one task of an evaluation runs through [`twin::lockstep`] at most: enough to
/// keep its lanes full as episodes end.
const CHUNK: usize = 32;

/// Runs `episodes` greedy episodes of at most `max_steps` through the firmware's controller,
/// each in a world of `domain`, run and priced as `judge` says. Episodes run in parallel and are summed in order, so the result does
/// not depend on the number of threads.
pub fn evaluate<const H: usize, const A: usize>(
    (net, levels): (&Mlp<H, A>, Levels<A>),
    episodes: usize,
    max_steps: u32,
    domain: &Domain,
    judge: Judge,
    streams: EvalStreams,
) -> EvalResult {
    let wide = WideMlp::new(net, levels);
    evaluate_policy::<_, [f32; 4]>(&*wide, episodes, max_steps, domain, judge, streams)
}

/// `net` quantised as `policy-export export --quant int8` quantises the policy file of it for
/// `machine` (the default granularity, calibrated on `machine`'s worlds): the integers an
/// int8 board runs.
pub fn quantised<const H: usize, const A: usize>(
    (net, levels): (&Mlp<H, A>, Levels<A>),
    machine: &Machine,
) -> weights::Result<Box<QMlp<H, A>>> {
    let w = Weights::from_mlp(net, &levels)?;
    twin::calibrate::quantise_policy(&w, Granularity::default(), machine)?.to_qmlp::<H, A>()
}

/// [`evaluate`] with the integer network `q` on `levels`, on the same episodes, as an
/// integer board runs it: its sensor hands over the estimate in Q3.12, and the predictor
/// and the network run on that reading. The same streams give the same worlds, starts,
/// noise and pushes as the float network met.
pub fn evaluate_int<const H: usize, const A: usize>(
    (q, levels): (&QMlp<H, A>, Levels<A>),
    episodes: usize,
    max_steps: u32,
    domain: &Domain,
    judge: Judge,
    streams: EvalStreams,
) -> EvalResult {
    let policy = Greedy { net: q, levels };
    evaluate_policy::<_, [i16; 4]>(policy, episodes, max_steps, domain, judge, streams)
}

/// [`evaluate`]'s episodes with any policy a controller runs, on readings of format `O`.
fn evaluate_policy<P: Policy<O> + Copy + Send + Sync, O: Estimate>(
    policy: P,
    episodes: usize,
    max_steps: u32,
    domain: &Domain,
    judge: Judge,
    streams: EvalStreams,
) -> EvalResult {
    // Chunks as equal as they can be, so that 50 episodes keep two threads busy alike (25
    // and 25, not 32 and 18); an episode's figures do not depend on the chunk it runs in.
    let size = episodes.div_ceil(episodes.div_ceil(CHUNK).max(1)).max(1);
    let per_episode: Vec<(f64, f64, u64)> = (0..episodes.div_ceil(size))
        .into_par_iter()
        .flat_map_iter(|c| {
            let first = c * size;
            let n = size.min(episodes - first);
            let e = |i: usize| (first + i) as u64;
            let scenarios: Vec<Scenario> = (0..n)
                .map(|i| domain.sample(&mut streams.world(e(i))))
                .collect();
            // Each episode's return, cost, steps and previous duty.
            let mut sums = vec![(0.0, 0.0, 0u64, 0.0); n];
            run_lockstep(
                n,
                |i| {
                    let draws = &streams.draws;
                    draws.episode(policy, &scenarios[i], max_steps, e(i), judge.compensate)
                },
                |i, ep, command, t| {
                    let (p, s) = (&scenarios[i].params, ep.world().state());
                    let (ret, cost, steps, previous) = &mut sums[i];
                    let duty = f64::from(command.level());
                    *ret += f64::from(t.reward);
                    let w = judge.prices;
                    *cost += w.lean * (s.theta / p.theta_threshold_radians).powi(2)
                        + w.distance * (s.x / p.x_threshold).powi(2)
                        + w.duty * duty.powi(2)
                        + w.change * (duty - *previous).abs();
                    *previous = duty;
                    *steps += 1;
                },
            );
            sums.into_iter().map(|(r, c, n, _)| (r, c, n))
        })
        .collect();
    let (mut sum, mut min, mut cost, mut steps) = (0.0, f64::INFINITY, 0.0, 0u64);
    for (r, c, n) in per_episode {
        sum += r;
        min = f64::min(min, r);
        cost += c;
        steps += n;
    }
    EvalResult {
        episodes,
        max_steps,
        mean: sum / episodes as f64,
        min,
        cost: cost / steps.max(1) as f64,
    }
}

/// First episode (1-based) whose trailing 100-episode mean return reaches `threshold`.
pub fn solved_episode(returns: &[f64], threshold: f64) -> Option<usize> {
    trailing_means(returns, 100)
        .position(|m| m >= threshold)
        .map(|i| i + 100)
}

/// Means of every full window of `w` consecutive values, in order.
pub fn trailing_means(values: &[f64], w: usize) -> impl Iterator<Item = f64> + '_ {
    values
        .windows(w)
        .map(move |win| win.iter().sum::<f64>() / w as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shipped::policy::POLICY;
    use shipped::policy_int::POLICY_INT;
    use twin::Episode;

    /// The trial's quantisation is the exporter's: the shipped policy's committed int8 module
    /// (`policy-export export --quant int8` of it on Gymnasium's machine) is what the trial
    /// makes of the float policy.
    #[test]
    fn the_trial_quantises_as_export_does() {
        let q = quantised((&POLICY, Levels::BANG_BANG), &Machine::GYMNASIUM).unwrap();
        assert!(*q == POLICY_INT);
    }

    /// The returns of the committed int8 network's episodes of the trial's streams under
    /// `streams`' seed, one at a time, on readings of format `O`.
    fn by_hand<O: Estimate>(
        domain: &Domain,
        streams: EvalStreams,
        episodes: usize,
        max_steps: u32,
    ) -> Vec<f64>
    where
        &'static QMlp<64>: Policy<O>,
    {
        (0..episodes as u64)
            .map(|e| {
                // The trial's streams by name, not read back from the streams under test.
                let rng = |s: Stream| host_common::seed::rng(streams.draws.seed, e, s as u64);
                let scenario = domain.sample(&mut rng(Stream::TrialWorld));
                let [start, noise, pushes] =
                    [Stream::Trial, Stream::TrialNoise, Stream::TrialPushes].map(rng);
                let mut ep = Episode::<_, _, O>::start(
                    &POLICY_INT,
                    &scenario,
                    max_steps,
                    &mut { start },
                    (noise, pushes),
                    true,
                );
                let mut ret = 0.0;
                loop {
                    ep.decide();
                    let t = ep.apply();
                    ret += f64::from(t.reward);
                    if t.terminated || t.truncated {
                        return ret;
                    }
                }
            })
            .collect()
    }

    /// The int8 trial's episodes, one at a time and by hand: each world, start, noise and
    /// pushes drawn from the streams the float network's trial draws them from, the
    /// committed int8 network deciding on the estimate its sensor hands over in Q3.12.
    #[test]
    fn the_int8_trial_runs_the_integer_board_on_the_float_trials_worlds() {
        let cfg = crate::config::Config::deploy();
        // With a period of dead time, so that the predictor runs on the reading.
        let spec = format!("{}+delay=1", cfg.finalist_domain);
        let domain = Domain::parse_on(&spec, &Machine::GYMNASIUM).unwrap();
        let streams = EvalStreams::of(7, Eval::Trial);
        let (episodes, max_steps) = (40, 400);
        let int = (&POLICY_INT, Levels::BANG_BANG);
        let judge = Judge {
            compensate: true,
            prices: Prices::PLAIN,
        };
        let res = evaluate_int(int, episodes, max_steps, &domain, judge, streams);
        // Cut into other chunks (33 episodes run as 17 and 16), the first 33 episodes give
        // the figures of the same 33 run one at a time below.
        let first = evaluate_int(int, 33, max_steps, &domain, judge, streams);
        let returns = by_hand::<[i16; 4]>(&domain, streams, episodes, max_steps);
        let figures = |r: &[f64]| {
            let mean = r.iter().sum::<f64>() / r.len() as f64;
            (mean, r.iter().copied().fold(f64::INFINITY, f64::min))
        };
        let (mean, min) = figures(&returns);
        assert_eq!(
            (res.mean.to_bits(), res.min.to_bits()),
            (mean.to_bits(), min.to_bits())
        );
        let (mean33, min33) = figures(&returns[..33]);
        assert_eq!(
            (first.mean.to_bits(), first.min.to_bits()),
            (mean33.to_bits(), min33.to_bits())
        );
        // Hard enough that some episodes fall and some hold, and not the float board's.
        assert!(min < f64::from(max_steps) && mean > min, "{res:?}");
        let float = evaluate(
            (&POLICY, Levels::BANG_BANG),
            episodes,
            max_steps,
            &domain,
            judge,
            streams,
        );
        assert_ne!(float, res);
        // A reading rounded after the predictor, as a float board hands it over, is not
        // what the integer board decides on.
        assert_ne!(
            by_hand::<[f32; 4]>(&domain, streams, episodes, max_steps),
            returns
        );
    }

    /// A change of duty costs what the judge prices it at: the cost with a price of 2 is the
    /// plain cost plus twice the mean change per period, counted here episode by episode
    /// (the first period's change from 0).
    #[test]
    fn the_cost_prices_each_change_of_duty() {
        let domain = Domain::parse_on("noise=0..1+push=1.1/50", &Machine::GYMNASIUM).unwrap();
        let order = [
            Stream::EvalWorld,
            Stream::Eval,
            Stream::EvalNoise,
            Stream::EvalPushes,
        ];
        let streams = EvalStreams::new(3, order);
        let (episodes, max_steps) = (20, 300);
        let int = (&POLICY_INT, Levels::BANG_BANG);
        let judged = |change| {
            let judge = Judge {
                compensate: false,
                prices: Prices {
                    change,
                    ..Prices::PLAIN
                },
            };
            evaluate_int(int, episodes, max_steps, &domain, judge, streams)
        };
        let (free, priced) = (judged(0.0), judged(2.0));
        let (mut changes, mut steps) = (0.0, 0u64);
        for e in 0..episodes as u64 {
            let rng = |i: usize| host_common::seed::rng(3, e, order[i] as u64);
            let scenario = domain.sample(&mut rng(0));
            let (start, pair) = (&mut rng(1), (rng(2), rng(3)));
            let mut ep: Episode<_, _, [i16; 4]> =
                Episode::start(&POLICY_INT, &scenario, max_steps, start, pair, false);
            let mut previous = 0.0;
            loop {
                let duty = f64::from(ep.decide().level());
                changes += (duty - previous).abs();
                previous = duty;
                steps += 1;
                let t = ep.apply();
                if t.terminated || t.truncated {
                    break;
                }
            }
        }
        let mean_change = changes / steps as f64;
        // A bang-bang policy reverses often: the price is not lost in the rounding.
        assert!(mean_change > 0.1, "{mean_change}");
        assert_eq!(free.mean, priced.mean);
        let expected = free.cost + 2.0 * mean_change;
        assert!(
            (priced.cost - expected).abs() < 1e-9,
            "{priced:?} {expected}"
        );
    }

    #[test]
    fn solved_episode_is_the_first_full_window_reaching_the_threshold() {
        let mut r = vec![100.0; 150];
        r.extend(vec![200.0; 100]);
        // Window ending at episode e has (e - 150) returns of 200: mean 100 + (e - 150).
        assert_eq!(solved_episode(&r, 195.0), Some(245));
        assert_eq!(solved_episode(&r[..99], 0.0), None);
    }
}
