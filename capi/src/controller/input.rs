//! What a C caller hands each period, behind the controller's [`StateSensor`]: encoder
//! counts, read through the rig's observer exactly as a Rust board reads them
//! ([`ObserverSensor`]), or the state itself, for a board that measures it.

use core::convert::Infallible;

use firmware::controller::{Command, StateSensor};
use firmware::estimator::{Estimate, ObserverSensor, Zeroed};
use firmware::loopback::Latest;
use firmware::network::{N_ACTIONS, OBS_DIM};

/// One period's input from C.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Handed {
    /// Encoder counts `(cart, pole)`.
    Counts(i32, i32),
    /// `[x, x_dot, theta, theta_dot]` in SI units.
    State([f32; OBS_DIM]),
}

/// Which kind of input an instance reads: the first step decides. Mixing them would feed
/// the observer a stale estimate after a run of states, so the other kind is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reads {
    Undecided,
    Counts,
    State,
}

/// A policy's scores as C's pair of float scores and pair of integer scores: a two-output
/// network's in the pair of its format, zero in the other; a network of more outputs has
/// no pair, and reads zero in both (its scores: its forward pass).
pub(crate) trait CScores {
    fn pairs(self) -> ([f32; N_ACTIONS], [i32; N_ACTIONS]);
}

impl<const A: usize> CScores for [f32; A] {
    fn pairs(self) -> ([f32; N_ACTIONS], [i32; N_ACTIONS]) {
        match self.first_chunk() {
            Some(q) if A == N_ACTIONS => (*q, [0; N_ACTIONS]),
            _ => ([0.0; N_ACTIONS], [0; N_ACTIONS]),
        }
    }
}

impl<const A: usize> CScores for [i32; A] {
    fn pairs(self) -> ([f32; N_ACTIONS], [i32; N_ACTIONS]) {
        match self.first_chunk() {
            Some(q) if A == N_ACTIONS => ([0.0; N_ACTIONS], *q),
            _ => ([0.0; N_ACTIONS], [0; N_ACTIONS]),
        }
    }
}

/// The controller's sensor for C: the encoders through the observer, or the handed state.
pub(crate) struct Input<O> {
    encoders: ObserverSensor<Latest, O>,
    state: [f32; OBS_DIM],
    reads: Reads,
}

impl<O> Input<O> {
    /// Reads through `encoders` once handed counts.
    pub(crate) fn new(encoders: ObserverSensor<Latest, O>) -> Self {
        Input {
            encoders,
            state: [0.0; OBS_DIM],
            reads: Reads::Undecided,
        }
    }

    /// Has the observer watch for frozen encoders from the next period
    /// ([`firmware::estimator::Observer::watching`]).
    pub(crate) fn watch(&mut self) {
        let observer = self.encoders.observer_mut();
        *observer = observer.clone().watching();
    }

    /// Takes this period's input; `false` (and nothing taken) if it is not the kind this
    /// instance has read so far.
    /// Whether the instance has read states: a start-up, which takes its zero from counts,
    /// cannot run on them.
    pub(crate) fn reads_states(&self) -> bool {
        self.reads == Reads::State
    }

    pub(crate) fn hand(&mut self, handed: Handed) -> bool {
        let kind = match handed {
            Handed::Counts(..) => Reads::Counts,
            Handed::State(_) => Reads::State,
        };
        if self.reads != Reads::Undecided && self.reads != kind {
            return false;
        }
        self.reads = kind;
        match handed {
            Handed::Counts(cart, pole) => self.encoders.counter_mut().0 = (cart, pole),
            Handed::State(state) => self.state = state,
        }
        true
    }
}

impl<O: Estimate> StateSensor for Input<O> {
    type Reading = O;
    type Error = Infallible;

    #[inline]
    fn read(&mut self) -> Result<O, Infallible> {
        match self.reads {
            Reads::State => Ok(O::exact(&self.state)),
            Reads::Counts | Reads::Undecided => self.encoders.read(),
        }
    }

    /// Only the observer models the commands; a measured state needs none.
    #[inline]
    fn commanded(&mut self, command: Command) {
        if self.reads == Reads::Counts {
            self.encoders.commanded(command);
        }
    }

    /// Only the observer can find its encoders frozen.
    #[inline]
    fn model_only(&self) -> bool {
        self.reads == Reads::Counts && self.encoders.model_only()
    }
}

impl<O> Zeroed for Input<O> {
    fn zero_at(&mut self, zero: (i32, i32)) {
        self.encoders.zero_at(zero);
    }
    fn trim(&mut self, rad: f32) {
        self.encoders.trim(rad);
    }
}
