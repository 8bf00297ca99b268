//! A Q-network of any supported shape, loaded at run time, as the simulator runs it.

use std::fmt;

use anyhow::Result;
use firmware::controller::{Duty, Levels, Limits, Policy, Rises, Scores};
use firmware::link::digest;
use firmware::network::int::QMlp;
use firmware::network::{MAX_OUTPUTS, Mlp, argmax};
use host_common::wide::WideMlp;
use shipped::envelope::ENVELOPE;
use shipped::policy::POLICY;
use shipped::policy_int::POLICY_INT;
use weights::Weights;
use weights::quant::Granularity;
use weights::shape::{ForShape, by_shape};

/// A Q-network laid out for the host's vector units ([`WideMlp`]: the firmware's forward
/// pass, bit for bit), with its integer version where one was asked for
/// (`firmware::network::int`, as `policy-export export --quant int8` writes it), and the duty
/// level of each output.
#[derive(Debug)]
pub struct Net {
    float: Box<dyn Forward>,
    int: Option<Box<dyn IntForward>>,
    levels: Vec<Duty>,
    envelope: Option<Limits>,
    /// The rig the envelope was measured on ([`digest::rig`]), where that is known.
    envelope_rig: Option<u64>,
    digest: u64,
}

/// The scores of a network whose output count is known only at run time: the first `n`
/// of `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outputs<T> {
    q: [T; MAX_OUTPUTS],
    n: u8,
}

impl<T: Copy + Default> Outputs<T> {
    fn of<const A: usize>(q: [T; A]) -> Outputs<T> {
        let mut all = [T::default(); MAX_OUTPUTS];
        all[..A].copy_from_slice(&q);
        Outputs { q: all, n: A as u8 }
    }

    /// The scores, one per output.
    pub fn values(&self) -> &[T] {
        &self.q[..usize::from(self.n)]
    }
}

impl Scores for Outputs<f32> {
    const UNSCORED: Outputs<f32> = Outputs {
        q: [f32::NAN; MAX_OUTPUTS],
        n: 0,
    };
    fn choice(&self) -> Option<usize> {
        let q = self.values();
        (!q.is_empty() && q.iter().all(|v| v.is_finite())).then(|| argmax(q))
    }
    fn rises(&self, i: usize) -> Option<Rises> {
        Rises::of_floats(self.values(), i)
    }
}

/// As a board's integer network: its largest output, whatever the values.
impl Scores for Outputs<i32> {
    const UNSCORED: Outputs<i32> = Outputs {
        q: [0; MAX_OUTPUTS],
        n: 0,
    };
    fn choice(&self) -> Option<usize> {
        let q = self.values();
        (!q.is_empty()).then(|| argmax(q))
    }
    fn rises(&self, i: usize) -> Option<Rises> {
        Rises::of_ints(self.values(), i)
    }
}

/// A [`QMlp`] of some shape, behind one type.
trait IntForward: fmt::Debug + Send + Sync {
    fn forward(&self, obs: &[i16; 4]) -> Outputs<i32>;
}

impl<const H: usize, const A: usize> IntForward for QMlp<H, A> {
    #[inline]
    fn forward(&self, obs: &[i16; 4]) -> Outputs<i32> {
        Outputs::of(QMlp::forward(self, obs))
    }
}

/// A [`WideMlp`] of some shape, behind one type.
trait Forward: fmt::Debug + Send + Sync {
    fn forward(&self, obs: &[f32; 4]) -> Outputs<f32>;
}

impl<const H: usize, const A: usize> Forward for WideMlp<H, A> {
    #[inline]
    fn forward(&self, obs: &[f32; 4]) -> Outputs<f32> {
        Outputs::of(WideMlp::forward(self, obs))
    }
}

/// Building a [`Net`] for the shape of `weights`.
struct Build<'a> {
    weights: &'a Weights,
    int: Option<&'a weights::quant::Quantised>,
}

impl ForShape for Build<'_> {
    type Output = weights::Result<Net>;
    fn run<const H: usize, const A: usize>(self) -> weights::Result<Net> {
        let mlp: Box<Mlp<H, A>> = self.weights.to_mlp()?;
        let levels: Levels<A> = self.weights.to_levels()?;
        let int: Option<Box<dyn IntForward>> = match self.int {
            Some(q) => Some(q.to_qmlp::<H, A>()?),
            None => None,
        };
        Ok(Net {
            float: WideMlp::new(&mlp, levels),
            int,
            levels: levels.duties().to_vec(),
            envelope: None,
            envelope_rig: None,
            digest: digest::policy(digest::mlp(&mlp), &levels),
        })
    }
}

impl Net {
    /// The shipped policy (the `shipped` crate), its integer version and its envelope compiled
    /// beside it.
    pub fn shipped() -> Net {
        Net {
            float: WideMlp::new(&POLICY, Levels::BANG_BANG),
            int: Some(Box::new(POLICY_INT.clone())),
            levels: Levels::BANG_BANG.duties().to_vec(),
            envelope: Some(ENVELOPE),
            envelope_rig: Some(digest::rig(&shipped::policy::RIG)),
            digest: digest::policy(digest::mlp(&POLICY), &Levels::BANG_BANG),
        }
    }

    /// The gentle nine-level policy trained for the identified desk rig (`shipped::desk`),
    /// with its integer version; no envelope was measured for it.
    pub fn shipped_desk() -> Net {
        Net {
            float: WideMlp::new(&shipped::desk::POLICY, shipped::desk::LEVELS),
            int: Some(Box::new(shipped::desk_int::POLICY_INT.clone())),
            levels: shipped::desk::LEVELS.duties().to_vec(),
            envelope: None,
            envelope_rig: None,
            digest: digest::policy(digest::mlp(&shipped::desk::POLICY), &shipped::desk::LEVELS),
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
        Ok(by_shape(
            w.width(),
            w.outputs(),
            Build {
                weights: w,
                int: q.as_ref(),
            },
        )??)
    }

    /// The envelope the runtime monitor lets this network drive in: measured for the
    /// shipped policy (`shipped::envelope`), none for another until it is given one.
    pub fn envelope(&self) -> Option<Limits> {
        self.envelope
    }

    /// The same network with the envelope `host-sim envelope` measured for it, on the rig
    /// of digest `rig` where the report records it.
    pub fn with_envelope(mut self, envelope: Limits, rig: Option<u64>) -> Net {
        self.envelope = Some(envelope);
        self.envelope_rig = rig;
        self
    }

    /// Refuses the envelope for a board of `rig` when it was measured on another machine
    /// ([`crate::envelope::measured_on`]).
    pub fn check_envelope_on(&self, rig: &firmware::rig::Rig) -> Result<(), String> {
        crate::envelope::measured_on(self.envelope_rig, rig)
    }

    /// The float network's Q-values.
    pub fn forward(&self, obs: &[f32; 4]) -> Outputs<f32> {
        self.float.forward(obs)
    }

    /// The integer network's outputs for a fixed-point observation, if it has one.
    pub fn forward_int(&self, obs: &[i16; 4]) -> Option<Outputs<i32>> {
        self.int.as_ref().map(|n| n.forward(obs))
    }

    /// The duty level of each output.
    pub fn levels(&self) -> &[Duty] {
        &self.levels
    }

    /// The policy as a target's link names it ([`digest::policy`] of the float network):
    /// what an envelope records it was measured for.
    pub fn digest(&self) -> u64 {
        self.digest
    }
}

impl Policy for &Net {
    type Scores = Outputs<f32>;
    #[inline]
    fn scores(&mut self, obs: &[f32; 4]) -> Outputs<f32> {
        self.float.forward(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.levels.get(i).copied()
    }
}

/// The integer network of a [`Net`] as a board's controller runs it: on the reading in
/// Q3.12 (the observer's estimate rounded, then the predictor on it), its scores the
/// integer outputs.
#[derive(Clone, Copy, Debug)]
pub struct IntNet<'a>(&'a dyn IntForward, &'a [Duty]);

impl<'a> IntNet<'a> {
    /// The integer version of `net`, if it was built with one.
    pub fn of(net: &'a Net) -> Option<IntNet<'a>> {
        net.int.as_deref().map(|int| IntNet(int, &net.levels))
    }
}

impl Policy<[i16; 4]> for IntNet<'_> {
    type Scores = Outputs<i32>;
    #[inline]
    fn scores(&mut self, obs: &[i16; 4]) -> Outputs<i32> {
        self.0.forward(obs)
    }
    fn duty(&self, i: usize) -> Option<Duty> {
        self.1.get(i).copied()
    }
}
