//! Encoders behind a controller: a [`Counter`] gives the two counts, an estimator turns them
//! into the reading, and the commands the controller sends reach the estimator.

use core::marker::PhantomData;

use super::{AlphaBeta, Observer};
use crate::controller::{Command, Reading, StateSensor};
use crate::network::OBS_DIM;

/// Where a board's encoder counts come from, once a period: `(cart, pole)`. A closure
/// returning the pair is one (a board reads its timers or PIO counters there).
pub trait Counter {
    /// This period's counts.
    fn counts(&mut self) -> (i32, i32);
}

impl<F: FnMut() -> (i32, i32)> Counter for F {
    #[inline]
    fn counts(&mut self) -> (i32, i32) {
        self()
    }
}

/// A sensor on encoder counts whose zero a start-up takes after power-on
/// ([`crate::startup`]): until then it reads the counts as they come.
pub trait Zeroed {
    /// From the next reading on, reads the counts about `zero` (the raw counts of the cart's
    /// centre and of the pole upright) and estimates afresh from them.
    fn zero_at(&mut self, zero: (i32, i32));
    /// From the next reading on, reads the pole `rad` further from upright than its counts
    /// about the zero say: the zero refined finer than a count, while balancing
    /// ([`crate::startup::Startup::trim_rate`]).
    fn trim(&mut self, rad: f32);
}

/// The counts `(cart, pole)` about `zero`, wrapping as a counter does.
fn about((cart, pole): (i32, i32), zero: (i32, i32)) -> (i32, i32) {
    (cart.wrapping_sub(zero.0), pole.wrapping_sub(zero.1))
}

/// The encoders read through the model-based [`Observer`], which is told every command:
/// the sensor every encoder-read controller runs (the twin's, the loopback's, a board's).
/// `O` is the reading's format: `[f32; 4]`, or `[i16; 4]` (Q3.12) for the integer network.
pub struct ObserverSensor<C, O = [f32; OBS_DIM]> {
    counter: C,
    observer: Observer,
    zero: (i32, i32),
    format: PhantomData<O>,
}

impl<C: Counter, O> ObserverSensor<C, O> {
    /// `observer` reading `counter` (for a rig, `rig.observer()`).
    pub fn new(observer: Observer, counter: C) -> Self {
        ObserverSensor {
            counter,
            observer,
            zero: (0, 0),
            format: PhantomData,
        }
    }

    /// The observer.
    pub fn observer(&self) -> &Observer {
        &self.observer
    }

    /// The observer, to change it in place (to watch for frozen encoders,
    /// [`Observer::watching`]).
    pub fn observer_mut(&mut self) -> &mut Observer {
        &mut self.observer
    }

    /// The counter, to hand it the next period's counts where the caller owns them.
    pub fn counter_mut(&mut self) -> &mut C {
        &mut self.counter
    }

    /// Restarts the observer: the next reading starts from the counts at rest.
    pub fn reset(&mut self) {
        self.observer.reset();
    }
}

impl<C: Counter, O: Estimate> StateSensor for ObserverSensor<C, O> {
    type Reading = O;
    type Error = core::convert::Infallible;
    #[inline]
    fn read(&mut self) -> Result<O, Self::Error> {
        let (cart, pole) = about(self.counter.counts(), self.zero);
        self.observer.update(cart, pole);
        Ok(O::observed(&self.observer))
    }
    #[inline]
    fn commanded(&mut self, command: Command) {
        self.observer.command(command.level());
    }
    #[inline]
    fn model_only(&self) -> bool {
        self.observer.frozen()
    }
}

impl<C, O> Zeroed for ObserverSensor<C, O> {
    fn zero_at(&mut self, zero: (i32, i32)) {
        self.zero = zero;
        self.observer.reset();
        self.observer.trim(0.0);
    }
    fn trim(&mut self, rad: f32) {
        self.observer.trim(rad);
    }
}

/// The encoders read through the model-free [`AlphaBeta`] filter, which needs no commands.
/// With `O = [i16; 4]` the whole path from counts to the integer network's decision is
/// integer arithmetic.
pub struct AlphaBetaSensor<C, O = [f32; OBS_DIM]> {
    counter: C,
    filter: AlphaBeta,
    zero: (i32, i32),
    format: PhantomData<O>,
}

impl<C: Counter, O> AlphaBetaSensor<C, O> {
    /// `filter` reading `counter`.
    pub fn new(filter: AlphaBeta, counter: C) -> Self {
        AlphaBetaSensor {
            counter,
            filter,
            zero: (0, 0),
            format: PhantomData,
        }
    }

    /// Restarts the filter.
    pub fn reset(&mut self) {
        self.filter.reset();
    }

    /// The counter, to hand it the next period's counts where the caller owns them.
    pub fn counter_mut(&mut self) -> &mut C {
        &mut self.counter
    }
}

/// The formats the estimators hand their estimate out in.
pub trait Estimate: Reading {
    /// An exact state, `[x, x_dot, theta, theta_dot]`, in this format.
    fn exact(state: &[f32; OBS_DIM]) -> Self;
    /// The observer's estimate in this format.
    fn observed(observer: &Observer) -> Self;
    /// The alpha-beta filter's estimate in this format.
    fn filtered(filter: &AlphaBeta) -> Self;
}

impl Estimate for [f32; OBS_DIM] {
    fn exact(state: &[f32; OBS_DIM]) -> Self {
        *state
    }
    fn observed(observer: &Observer) -> Self {
        observer.state()
    }
    fn filtered(filter: &AlphaBeta) -> Self {
        filter.state()
    }
}

impl Estimate for [i16; OBS_DIM] {
    /// A NaN channel reads as saturated, which the integer format rejects as a value unknown:
    /// rounded, it would read as 0, a plausible state the policy would act on.
    fn exact(state: &[f32; OBS_DIM]) -> Self {
        state.map(|v| {
            if v.is_nan() {
                i16::MAX
            } else {
                crate::fixed::from_f32(v)
            }
        })
    }
    fn observed(observer: &Observer) -> Self {
        observer.fixed_state()
    }
    fn filtered(filter: &AlphaBeta) -> Self {
        filter.fixed_state()
    }
}

impl<C: Counter, O: Estimate> StateSensor for AlphaBetaSensor<C, O> {
    type Reading = O;
    type Error = core::convert::Infallible;
    #[inline]
    fn read(&mut self) -> Result<O, Self::Error> {
        let (cart, pole) = about(self.counter.counts(), self.zero);
        self.filter.update(cart, pole);
        Ok(O::filtered(&self.filter))
    }
}

impl<C, O> Zeroed for AlphaBetaSensor<C, O> {
    fn zero_at(&mut self, zero: (i32, i32)) {
        self.zero = zero;
        self.filter.reset();
        self.filter.trim(0.0);
    }
    fn trim(&mut self, rad: f32) {
        self.filter.trim(rad);
    }
}
