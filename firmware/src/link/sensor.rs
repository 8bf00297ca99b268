//! The sensor of a controller whose readings come from a simulated world, period by
//! period: a host's world over the link (on the target), or the twin's in the same
//! process. One code for both sides, so a measurement means the same reading on either.

use crate::config::ConfigError;
use crate::controller::{Command, StateSensor};
use crate::estimator::{AlphaBeta, AlphaBetaSensor, Estimate, Observer, ObserverSensor};
use crate::loopback::Latest;
use crate::network::OBS_DIM;

use super::{Measurement, Sensing};

/// A reading that never arrived ([`Measurement::Missing`]), or one of the other kind than
/// the sensor reads (which the session refuses before it gets here).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Missing;

/// Reads the last [`Measurement`] handed to it, in the format `O`: the exact state, or
/// encoder counts through the observer or the alpha-beta filter.
pub struct LinkSensor<O = [f32; OBS_DIM]> {
    reader: Reader<O>,
    missing: bool,
}

enum Reader<O> {
    Exact(O),
    Observer(ObserverSensor<Latest, O>),
    AlphaBeta(AlphaBetaSensor<Latest, O>),
}

impl<O: Estimate> LinkSensor<O> {
    /// The exact state.
    pub fn exact() -> Self {
        LinkSensor::of(Reader::Exact(O::ZERO))
    }

    /// Counts through `observer` (which starts from the first counts).
    pub fn observer(observer: Observer) -> Self {
        LinkSensor::of(Reader::Observer(ObserverSensor::new(
            observer,
            Latest::default(),
        )))
    }

    /// Counts through `filter`.
    pub fn alpha_beta(filter: AlphaBeta) -> Self {
        LinkSensor::of(Reader::AlphaBeta(AlphaBetaSensor::new(
            filter,
            Latest::default(),
        )))
    }

    /// The sensor of `sensing` on a machine whose observer is `observer` (built only when
    /// asked for: it solves a Riccati equation) and whose encoders and period the
    /// alpha-beta filter takes from `rig`; refused as the observer or filter is.
    pub fn new(
        sensing: Sensing,
        rig: &crate::rig::Rig,
        observer: impl FnOnce() -> Result<Observer, ConfigError>,
    ) -> Result<Self, ConfigError> {
        Ok(match sensing {
            Sensing::Exact => LinkSensor::exact(),
            Sensing::Observer => LinkSensor::observer(observer()?),
            Sensing::AlphaBeta(d) => {
                LinkSensor::alpha_beta(AlphaBeta::new(rig.encoders, d, rig.params.tau as f32)?)
            }
        })
    }

    fn of(reader: Reader<O>) -> Self {
        LinkSensor {
            reader,
            missing: false,
        }
    }

    /// Hands the sensor this period's measurement. One of the other kind than it reads
    /// reads as missing.
    pub fn set(&mut self, m: Measurement) {
        self.missing = match (&mut self.reader, m) {
            (Reader::Exact(s), Measurement::State(v)) => {
                *s = O::exact(&v);
                false
            }
            (Reader::Observer(o), Measurement::Counts(c, p)) => {
                o.counter_mut().0 = (c, p);
                false
            }
            (Reader::AlphaBeta(a), Measurement::Counts(c, p)) => {
                a.counter_mut().0 = (c, p);
                false
            }
            _ => true,
        };
    }
}

impl<O: Estimate> StateSensor for LinkSensor<O> {
    type Reading = O;
    type Error = Missing;
    #[inline]
    fn read(&mut self) -> Result<O, Missing> {
        if self.missing {
            return Err(Missing);
        }
        Ok(match &mut self.reader {
            Reader::Exact(s) => *s,
            Reader::Observer(o) => o.read().unwrap_or_else(|e| match e {}),
            Reader::AlphaBeta(a) => a.read().unwrap_or_else(|e| match e {}),
        })
    }
    #[inline]
    fn commanded(&mut self, command: Command) {
        if let Reader::Observer(o) = &mut self.reader {
            o.commanded(command);
        }
    }
    #[inline]
    fn model_only(&self) -> bool {
        match &self.reader {
            Reader::Observer(o) => !self.missing && o.model_only(),
            _ => false,
        }
    }
}
