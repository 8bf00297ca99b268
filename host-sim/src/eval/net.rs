//! A Q-network of any supported width, loaded at run time, as the simulator runs it.

use std::fmt;

use anyhow::Result;
use firmware::controller::{Limits, Policy};
use firmware::envelope::ENVELOPE;
use firmware::network::Mlp;
use firmware::network::int::QMlp;
use firmware::policy::POLICY;
use firmware::policy_int::POLICY_INT;
use host_common::wide::WideMlp;
use weights::Weights;
use weights::quant::Granularity;
use weights::width::{ForWidth, by_width};

/// A Q-network laid out for the host's vector units ([`WideMlp`]: the firmware's forward
/// pass, bit for bit), with its integer version where one was asked for
/// (`firmware::network::int`, as `policy-export export --quant int8` writes it).
#[derive(Debug)]
pub struct Net {
    float: Box<dyn Forward>,
    int: Option<Box<dyn IntForward>>,
    envelope: Option<Limits>,
}

/// A [`QMlp`] of some width, behind one type.
trait IntForward: fmt::Debug + Send + Sync {
    fn forward(&self, obs: &[i16; 4]) -> [i32; 2];
}

impl<const H: usize> IntForward for QMlp<H> {
    #[inline]
    fn forward(&self, obs: &[i16; 4]) -> [i32; 2] {
        QMlp::forward(self, obs)
    }
}

/// A [`WideMlp`] of some width, behind one type.
trait Forward: fmt::Debug + Send + Sync {
    fn forward(&self, obs: &[f32; 4]) -> [f32; 2];
}

impl<const H: usize> Forward for WideMlp<H> {
    #[inline]
    fn forward(&self, obs: &[f32; 4]) -> [f32; 2] {
        WideMlp::forward(self, obs)
    }
}

/// Building a [`Net`] for the width of `weights`.
struct Build<'a> {
    weights: &'a Weights,
    int: Option<&'a weights::quant::Quantised>,
}

impl ForWidth for Build<'_> {
    type Output = weights::Result<Net>;
    fn run<const H: usize>(self) -> weights::Result<Net> {
        let mlp: Box<Mlp<H>> = self.weights.to_mlp()?;
        let int: Option<Box<dyn IntForward>> = match self.int {
            Some(q) => Some(q.to_qmlp::<H>()?),
            None => None,
        };
        Ok(Net {
            float: WideMlp::new(&mlp),
            int,
            envelope: None,
        })
    }
}

impl Net {
    /// The policy compiled into `firmware`, its integer version and its envelope compiled
    /// beside it.
    pub fn shipped() -> Net {
        Net {
            float: WideMlp::new(&POLICY),
            int: Some(Box::new(POLICY_INT.clone())),
            envelope: Some(ENVELOPE),
        }
    }

    /// A network from checked weights of any supported width; with `int`, also its integer
    /// version, quantised as `policy-export export --quant int8` does by default on that
    /// machine (the same granularity and calibration). Without `int`, a float policy the
    /// quantiser would refuse still loads.
    pub fn from_weights(w: &Weights, int: Option<&twin::Machine>) -> Result<Net> {
        let q = if let Some(machine) = int {
            Some(twin::calibrate::quantise_policy(
                w,
                Granularity::default(),
                machine,
            )?)
        } else {
            None
        };
        Ok(by_width(
            w.width(),
            Build {
                weights: w,
                int: q.as_ref(),
            },
        )??)
    }

    /// The envelope the runtime monitor lets this network drive in: measured for the
    /// shipped policy (`firmware::envelope`), none for another until it is given one.
    pub fn envelope(&self) -> Option<Limits> {
        self.envelope
    }

    /// The same network with the envelope `host-sim envelope` measured for it.
    pub fn with_envelope(mut self, envelope: Limits) -> Net {
        self.envelope = Some(envelope);
        self
    }

    /// The float network's Q-values.
    pub fn forward(&self, obs: &[f32; 4]) -> [f32; 2] {
        self.float.forward(obs)
    }

    /// The integer network's outputs for a fixed-point observation, if it has one.
    pub fn forward_int(&self, obs: &[i16; 4]) -> Option<[i32; 2]> {
        self.int.as_ref().map(|n| n.forward(obs))
    }
}

impl Policy for &Net {
    #[inline]
    fn scores(&mut self, obs: &[f32; 4]) -> [f32; 2] {
        self.float.forward(obs)
    }
}

/// The integer network of a [`Net`] as a controller's policy: the reading rounded to Q3.12,
/// the scores the integer outputs (exact in f32, see `firmware::controller`).
#[derive(Clone, Copy, Debug)]
pub struct IntNet<'a>(&'a dyn IntForward);

impl<'a> IntNet<'a> {
    /// The integer version of `net`, if it was built with one.
    pub fn of(net: &'a Net) -> Option<IntNet<'a>> {
        net.int.as_deref().map(IntNet)
    }
}

impl Policy for IntNet<'_> {
    #[inline]
    fn scores(&mut self, obs: &[f32; 4]) -> [f32; 2] {
        self.0
            .forward(&firmware::fixed::from_state(obs))
            .map(|q| q as f32)
    }
}
