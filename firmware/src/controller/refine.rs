//! A duty between the levels: a Q-network scores a few duty levels, but the value of a
//! duty varies smoothly between them. [`Refined`] fits the parabola through the chosen
//! level's score and its two neighbours' and drives the duty at its peak, so a policy
//! trained on nine levels can hold the pole with the finer duty a linear controller would
//! give, without being trained again.
//!
//! The peak always lies between the midpoints the chosen level shares with its neighbours
//! (the chosen score is the largest of the three), so the refined duty is one that rounding
//! to the nearest level would give back as the chosen level: it refines the choice, never
//! overturns it.

use super::levels::{Duty, between};
use super::policy::{Policy, Scores};
use super::reading::Reading;
use super::{Actuator, Controller, StateSensor};

/// `P`, its chosen level moved to the peak of the parabola through the scores of that level
/// and its two neighbours ([`between`]). An end level (full push, or the lowest or highest
/// of the levels) drives itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refined<P>(pub P);

impl<O: Reading, P: Policy<O>> Policy<O> for Refined<P> {
    type Scores = P::Scores;
    #[inline]
    fn scores(&mut self, obs: &O) -> P::Scores {
        self.0.scores(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.0.duty(i)
    }
    fn drive(&self, q: &P::Scores, i: usize) -> Option<Duty> {
        refine(&self.0, q, i)
    }
}

/// `P`, refined ([`Refined`]) or not as chosen while it runs: what a controller holds whose
/// user chooses after it is built, as C does (`cartpole_controller_refine`) and a link
/// target does for each episode's Start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refinable<P> {
    /// The policy.
    pub policy: P,
    /// Whether its chosen level is refined.
    pub refine: bool,
}

impl<O: Reading, P: Policy<O>> Policy<O> for Refinable<P> {
    type Scores = P::Scores;
    #[inline]
    fn scores(&mut self, obs: &O) -> P::Scores {
        self.policy.scores(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.policy.duty(i)
    }
    fn drive(&self, q: &P::Scores, i: usize) -> Option<Duty> {
        if self.refine {
            refine(&self.policy, q, i)
        } else {
            self.policy.drive(q, i)
        }
    }
}

/// Why a controller refused to refine its policy's chosen level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefineRefused {
    /// The policy has no level between two others (two outputs, both ends).
    NoInnerLevel,
    /// The runtime monitor runs: its envelope is measured for the policy's plain levels
    /// (`host-sim envelope`), and says nothing of refined ones.
    Monitored,
}

impl<P, S, A, const N: usize> Controller<Refinable<P>, S, A, N>
where
    P: Policy<S::Reading>,
    S: StateSensor,
    A: Actuator,
{
    /// Refines the policy's chosen level from the next period on, or (`on` false) drives
    /// its levels again; refused, changing nothing, as [`RefineRefused`] says.
    pub fn refine(&mut self, on: bool) -> Result<(), RefineRefused> {
        if on && !self.policy.policy.refinable() {
            return Err(RefineRefused::NoInnerLevel);
        }
        if on && self.mode().is_some() {
            return Err(RefineRefused::Monitored);
        }
        self.policy.refine = on;
        Ok(())
    }

    /// Whether the policy's chosen level is refined.
    pub fn refines(&self) -> bool {
        self.policy.refine
    }
}

/// What `p` drives having chosen output `i` of scores `q`, moved to the peak of the
/// parabola through `i`'s score and its neighbours'.
fn refine<O: Reading, P: Policy<O>>(p: &P, q: &P::Scores, i: usize) -> Option<Duty> {
    let level = p.drive(q, i)?;
    let lower = i.checked_sub(1).and_then(|k| p.duty(k));
    match (lower, p.duty(i + 1), q.rises(i)) {
        (Some(lo), Some(hi), Some(rise)) => Some(between([lo, level, hi], rise)),
        _ => Some(level),
    }
}

#[cfg(test)]
mod tests;
