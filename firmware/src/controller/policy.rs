//! What decides a period: a [`Policy`] scores the sanitised reading, its [`Scores`] choose an
//! output, and the output's duty level drives the motor.

use super::levels::{Duty, Levels, Rises};
use super::reading::Reading;
use crate::network::int::QMlp;
use crate::network::{Mlp, OBS_DIM, argmax};

/// A policy's scores: what the controller records of a period's answer, and which output
/// they choose.
pub trait Scores: Copy + PartialEq + core::fmt::Debug {
    /// What a period records when the policy did not score it (a rejected reading, the
    /// monitor's fallback, a decision handed in).
    const UNSCORED: Self;
    /// The output the scores choose: the largest, a tie to the lower index; `None` when a
    /// score is no number a decision can rest on.
    fn choice(&self) -> Option<usize>;
    /// How far output `i`'s score stands above each neighbour's: what
    /// [`Refined`](super::Refined) reads. `None` where `i` lacks a neighbour on either side,
    /// and for scores that are not values (a baseline's push, no scores).
    fn rises(&self, _i: usize) -> Option<Rises> {
        None
    }
}

impl<const A: usize> Scores for [f32; A] {
    const UNSCORED: [f32; A] = [f32::NAN; A];
    fn choice(&self) -> Option<usize> {
        self.iter().all(|q| q.is_finite()).then(|| argmax(self))
    }
    fn rises(&self, i: usize) -> Option<Rises> {
        Rises::of_floats(self, i)
    }
}

/// Integers are always numbers.
impl<const A: usize> Scores for [i32; A] {
    const UNSCORED: [i32; A] = [0; A];
    fn choice(&self) -> Option<usize> {
        Some(argmax(self))
    }
    fn rises(&self, i: usize) -> Option<Rises> {
        Rises::of_ints(self, i)
    }
}

/// No scores: the record of a controller whose decisions are handed to it.
impl Scores for () {
    const UNSCORED: () = ();
    fn choice(&self) -> Option<usize> {
        None
    }
}

/// Maps a sanitised reading to scores, one per output, and each output to the duty it
/// drives. The Q-network's scores are its Q-values; a baseline's may be anything with that
/// meaning.
pub trait Policy<O: Reading = [f32; OBS_DIM]> {
    /// The scores, one per output.
    type Scores: Scores;
    /// Scores of `obs`.
    fn scores(&mut self, obs: &O) -> Self::Scores;
    /// The duty output `i` drives; `None` beyond the outputs.
    fn duty(&self, i: usize) -> Option<Duty>;
    /// The duty scores `q` drive, having chosen output `i`: its level, unless the policy
    /// refines it ([`Refined`](super::Refined)).
    #[inline]
    fn drive(&self, _q: &Self::Scores, i: usize) -> Option<Duty> {
        self.duty(i)
    }
    /// Whether it has a level between two others, which [`Refined`](super::Refined) moves
    /// its duty between: more than two outputs.
    fn refinable(&self) -> bool {
        self.duty(2).is_some()
    }
}

/// A Q-network choosing among its duty levels: output `i`'s Q-value is the value of driving
/// `levels.duty(i)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Greedy<N, const A: usize> {
    /// The network.
    pub net: N,
    /// The duty of each of its outputs.
    pub levels: Levels<A>,
}

impl<const H: usize, const A: usize> Policy for Greedy<&Mlp<H, A>, A> {
    type Scores = [f32; A];
    #[inline]
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> [f32; A] {
        self.net.forward(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.levels.duty(i)
    }
}

/// The integer network on a fixed-point reading: integer arithmetic from the sensor to the
/// decision.
impl<const H: usize, const A: usize> Policy<[i16; OBS_DIM]> for Greedy<&QMlp<H, A>, A> {
    type Scores = [i32; A];
    #[inline]
    fn scores(&mut self, obs: &[i16; OBS_DIM]) -> [i32; A] {
        self.net.forward(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.levels.duty(i)
    }
}

/// The integer network behind a float sensor: the reading is rounded to Q3.12
/// ([`crate::fixed::from_state`]), the forward pass is integer-only, and the scores are the
/// integer outputs as f32, exact below 2^24 (which every exported network's outputs are, by
/// construction), so they choose as the integers do.
impl<const H: usize, const A: usize> Policy for Greedy<&QMlp<H, A>, A> {
    type Scores = [f32; A];
    #[inline]
    fn scores(&mut self, obs: &[f32; OBS_DIM]) -> [f32; A] {
        self.net
            .forward(&crate::fixed::from_state(obs))
            .map(|q| q as f32)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.levels.duty(i)
    }
}

/// The paper's network on its two levels, full push left and right
/// ([`Levels::BANG_BANG`]).
impl<'n, const H: usize, O: Reading> Policy<O> for &'n Mlp<H>
where
    Greedy<&'n Mlp<H>, 2>: Policy<O>,
{
    type Scores = <Greedy<&'n Mlp<H>, 2> as Policy<O>>::Scores;
    #[inline]
    fn scores(&mut self, obs: &O) -> Self::Scores {
        bang_bang(self).scores(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
}

/// The paper's network in integers on its two levels ([`Levels::BANG_BANG`]).
impl<'n, const H: usize, O: Reading> Policy<O> for &'n QMlp<H>
where
    Greedy<&'n QMlp<H>, 2>: Policy<O>,
{
    type Scores = <Greedy<&'n QMlp<H>, 2> as Policy<O>>::Scores;
    #[inline]
    fn scores(&mut self, obs: &O) -> Self::Scores {
        bang_bang(self).scores(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
}

fn bang_bang<N: Copy>(net: &N) -> Greedy<N, 2> {
    Greedy {
        net: *net,
        levels: Levels::BANG_BANG,
    }
}

/// The policy of a controller whose every decision is handed to it
/// ([`Controller::act_with`](super::Controller::act_with)): its levels alone. It scores
/// nothing; the output it is handed drives its level.
impl<O: Reading, const A: usize> Policy<O> for Levels<A> {
    type Scores = ();
    fn scores(&mut self, _: &O) {}
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::duty(self, i)
    }
}

/// A decision: the scores to record, and the duty they choose (`None` when no duty may
/// rest on them): what [`Monitor::decide`](super::Monitor::decide) asks for.
pub type Answer<Q> = (Q, Option<Duty>);

/// The policy's answer on `seen`: its scores, and the duty of the output they choose. What
/// [`Controller::act`](super::Controller::act) asks of its policy, and a caller of
/// [`Monitor::decide`](super::Monitor::decide) hands it.
#[inline(always)]
pub fn answer<O: Reading, P: Policy<O>>(policy: &mut P, seen: &O) -> Answer<P::Scores> {
    let q = policy.scores(seen);
    let duty = q.choice().and_then(|i| policy.drive(&q, i));
    (q, duty)
}
