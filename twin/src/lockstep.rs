//! Episodes run to their end ([`run_episode`], [`run_episodes`]), side by side: several
//! episodes advanced period by period together, so that their worlds' Runge-Kutta
//! integrations, each one long chain of dependent operations, run interleaved
//! ([`crate::machine::rk4_lanes`]). Every episode's periods are the ones it has alone, bit
//! for bit; only the time changes.

use firmware::cartpole::{State, Transition};
use firmware::controller::{Command, Policy};
use firmware::estimator::Estimate;
use firmware::loopback::duty;
use rand_core::Rng;

use crate::machine::{Lane, rk4_lanes};
use crate::run::{Aids, Draws, Episode, EpisodeStats, Frame, Tally};
use crate::scenario::Scenario;
use crate::world::Drive;

/// How many episodes [`run_lockstep`] keeps in flight: enough worlds to fill the widest
/// block of lanes.
pub const LANES: usize = 8;

/// Runs episodes `0..n` side by side, [`LANES`] at a time: `start(i)` begins episode `i`, and
/// `each(i, &episode, command, &transition)` sees every period of it, after the period. An
/// episode ends with its transition's `terminated` or `truncated`, and the next takes its
/// place. Each episode's periods are the ones it has alone ([`Episode::decide`], then
/// [`Episode::apply`]), bit for bit.
pub fn run_lockstep<'s, P: Policy<O>, R: Rng, O: Estimate>(
    n: usize,
    mut start: impl FnMut(usize) -> Episode<'s, P, R, O>,
    mut each: impl FnMut(usize, &Episode<'s, P, R, O>, Command, &Transition),
) {
    let mut slots: Vec<(usize, Episode<'s, P, R, O>)> = Vec::with_capacity(LANES.min(n));
    let mut scratch = Scratch::default();
    let mut next = 0;
    loop {
        while slots.len() < LANES && next < n {
            slots.push((next, start(next)));
            next += 1;
        }
        if slots.is_empty() {
            return;
        }
        scratch.commands.clear();
        scratch
            .commands
            .extend(slots.iter_mut().map(|(_, ep)| ep.decide()));
        apply(&mut slots, &mut scratch);
        let transitions = scratch
            .transitions
            .iter()
            .map(|t| t.expect("every slot applied"));
        for ((i, ep), (command, t)) in slots.iter().zip(scratch.commands.iter().zip(transitions)) {
            each(*i, ep, *command, &t);
        }
        let mut ended = (scratch.transitions.iter().flatten()).map(|t| t.terminated || t.truncated);
        slots.retain(|_| !ended.next().expect("one transition a slot"));
    }
}

/// The buffers of one lockstep run, kept from period to period.
#[derive(Default)]
struct Scratch {
    commands: Vec<Command>,
    drives: Vec<Option<Drive>>,
    next: Vec<Option<State>>,
    rk4: Vec<(u32, usize)>,
    /// Slot `k`'s transition, once its world has been through the period.
    transitions: Vec<Option<Transition>>,
}

/// Every slot's world through its period: Euler worlds alone, Runge-Kutta worlds of one step
/// count in blocks of lanes.
fn apply<P: Policy<O>, R: Rng, O: Estimate>(
    slots: &mut [(usize, Episode<'_, P, R, O>)],
    s: &mut Scratch,
) {
    s.drives.clear();
    s.next.clear();
    s.rk4.clear();
    s.transitions.clear();
    s.transitions.resize(slots.len(), None);
    for (k, (_, ep)) in slots.iter_mut().enumerate() {
        let duty = duty(ep.controller.actuator());
        match ep.world.substeps() {
            Some(n) => {
                s.drives.push(Some(ep.world.drive(duty)));
                s.rk4.push((n, k));
            }
            None => {
                s.drives.push(None);
                s.transitions[k] = Some(ep.world.apply(duty));
            }
        }
        s.next.push(None);
    }
    // A domain's worlds share their rig's period, so this is almost always one group.
    s.rk4.sort_unstable();
    let mut rest = &s.rk4[..];
    while let Some(&(n, _)) = rest.first() {
        let same = rest.iter().take_while(|(m, _)| *m == n).count();
        let (group, tail) = rest.split_at(same);
        integrate(group, n, slots, &s.drives, &mut s.next);
        rest = tail;
    }
    for (k, (_, ep)) in slots.iter_mut().enumerate() {
        if let Some(state) = s.next[k] {
            s.transitions[k] = Some(ep.world.land(state));
        }
    }
}

/// The slots `group` (`(steps, slot)`, one step count `n`) integrated in blocks of 8, 4, 2
/// and 1 lanes.
fn integrate<P: Policy<O>, R: Rng, O: Estimate>(
    group: &[(u32, usize)],
    n: u32,
    slots: &[(usize, Episode<'_, P, R, O>)],
    drives: &[Option<Drive>],
    next: &mut [Option<State>],
) {
    let lane = |k: usize| {
        slots[k]
            .1
            .world
            .lane(drives[k].expect("a Runge-Kutta slot"))
    };
    fn block<const N: usize>(
        ks: &[(u32, usize)],
        n: u32,
        lane: &impl Fn(usize) -> Lane,
        next: &mut [Option<State>],
    ) {
        let out = rk4_lanes::<N>(n, core::array::from_fn(|j| lane(ks[j].1)));
        for (&(_, k), s) in ks.iter().zip(out) {
            next[k] = Some(s);
        }
    }
    let mut rest = group;
    while !rest.is_empty() {
        let take = [8, 4, 2, 1]
            .into_iter()
            .find(|&b| b <= rest.len())
            .expect("a block of 1 fits");
        let (ks, tail) = rest.split_at(take);
        match take {
            8 => block::<8>(ks, n, &lane, next),
            4 => block::<4>(ks, n, &lane, next),
            2 => block::<2>(ks, n, &lane, next),
            _ => block::<1>(ks, n, &lane, next),
        }
        rest = tail;
    }
}

/// Runs one episode of `policy` under `scenario` for at most `horizon` periods from the
/// Gymnasium-style random start of (`seed`, `episode`), with the board's `aids` ([`Aids`]; a
/// `bool` says whether the controller is told the scenario's dead time and decides on the
/// state its command will meet, [`firmware::controller::predict`]). `on_frame` sees every
/// period.
pub fn run_episode<P: Policy<O>, O: Estimate>(
    policy: P,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episode: u64,
    aids: impl Into<Aids>,
    mut on_frame: impl FnMut(Frame),
) -> EpisodeStats {
    let aids = aids.into();
    let mut policy = Some(policy);
    let mut tally = Tally::default();
    run_lockstep(
        1,
        |_| {
            let p = policy.take().expect("one episode");
            Draws::of(seed).episode(p, scenario, horizon, episode, aids)
        },
        |_, ep, command, t| {
            let state = ep.world().state();
            let p = &ep.world().scenario().params;
            tally.period(p, (command, ep.fallback()), &state, t);
            let reading = ep.controller().last().map_or([0.0; 4], |r| r.obs.state());
            on_frame(Frame {
                state,
                command,
                reading,
            });
        },
    );
    tally.stats()
}

/// [`run_episode`] for every episode of `episodes`, side by side
/// ([`crate::lockstep::run_lockstep`]), each
/// with the policy `policy(episode)` makes; the statistics in the episodes' order.
pub fn run_episodes<P: Policy<O>, O: Estimate>(
    mut policy: impl FnMut(u64) -> P,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episodes: core::ops::Range<u64>,
    aids: impl Into<Aids>,
) -> Vec<EpisodeStats> {
    let aids = aids.into();
    let first = episodes.start;
    let n = (episodes.end.saturating_sub(first)) as usize;
    let mut tallies: Vec<Tally> = (0..n).map(|_| Tally::default()).collect();
    run_lockstep(
        n,
        |i| {
            let e = first + i as u64;
            Draws::of(seed).episode(policy(e), scenario, horizon, e, aids)
        },
        |i, ep, command, t| {
            let (p, s) = (&ep.world().scenario().params, ep.world().state());
            tallies[i].period(p, (command, ep.fallback()), &s, t)
        },
    );
    tallies.into_iter().map(|t| t.stats()).collect()
}
