//! Post-training quantisation: a float policy to the integer network of
//! `firmware::network::int`, calibrated on observations the policy visits.
//!
//! - **Weights**: symmetric int8, `w_q = round(w / s_w)` with `s_w = max|w| / 127`, per
//!   output unit (the [`Granularity`] the tools use by default) or per tensor
//!   ([`Granularity::PerTensor`], `--granularity per-tensor`).
//! - **Outputs**: the advantages `Q_i - mean(Q)` of the `A` outputs, in one scale for every
//!   row, so they compare as integers and decide as the Q-values do (with the paper's two
//!   outputs, `-D` and `+D` with `D = (Q_right - Q_left) / 2`). The common part of the
//!   Q-values decides nothing and is far larger than their differences: int8 rows of
//!   Q-values resolve the common part and round the differences away, so many more actions
//!   flip than with the advantage rows quantised (docs/QUANTISATION.md, "Why advantages,
//!   not Q-values").
//! - **Activations**: `u8` per hidden layer, `s_h = max h / 255` over the calibration set:
//!   no observation the policy was seen to visit saturates a unit.
//! - **Biases**: int32 in the accumulator's scale, `round(b / (s_w * s_in))`. (Correcting
//!   them for the weights' mean rounding error on the calibration set, as Nagel et al. 2019
//!   do, was tried and balanced worse: docs/QUANTISATION.md, "Adaptive rounding".)
//! - **Requantisation**: the factor `s_w * s_in / s_h` as a 16-bit multiplier and shifts
//!   ([`Requant`]), the pre-shift just large enough that the largest accumulator below the
//!   output's saturation fits in 15 bits, the multiplier as large as 16 bits allow.
//!
//! Every bound that keeps the integer forward pass from wrapping is checked here, for any
//! input: a policy whose integers would wrap is refused, not exported. The result is a
//! function of the weights and the calibration set alone, so exporting twice gives the same
//! integers.

use firmware::network::int::{QMlp, Requant};

use crate::{Error, Result};

mod quantiser;
mod source;
#[cfg(test)]
mod tests;

pub use quantiser::quantise;
pub use source::{c_header, c_struct, rust_module};

/// How many scales a weight tensor of a hidden layer gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Granularity {
    /// One scale per tensor.
    PerTensor,
    /// One scale per output unit (row): small rows keep their precision.
    PerChannel,
}

/// One scale per unit: for the shipped policy it holds the cart as near the centre as the
/// float policy does, where one scale per tensor lets it wander over long episodes
/// (`docs/QUANTISATION.md`, "One scale per unit"). The earlier shipped policy measured the
/// other way round, so the better choice depends on the network: check both.
impl Default for Granularity {
    fn default() -> Granularity {
        Granularity::PerChannel
    }
}

impl Granularity {
    /// The name used on command lines and in provenance lines.
    pub fn name(self) -> &'static str {
        match self {
            Granularity::PerTensor => "per-tensor",
            Granularity::PerChannel => "per-channel",
        }
    }
}

/// A quantised 4-H-H-A network of run-time shape: the integers of a [`QMlp`] plus the float
/// scales they stand for, and the duty level of each output.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantised {
    width: usize,
    /// Each output's duty level, a fraction of the full push (the float policy's).
    levels: Vec<f32>,
    granularity: Granularity,
    fc1_weight: Vec<i8>,
    fc1_bias: Vec<i32>,
    fc1_requant: Vec<Requant>,
    fc2_weight: Vec<i8>,
    fc2_bias: Vec<i32>,
    fc2_requant: Vec<Requant>,
    fc3_weight: Vec<i8>,
    fc3_bias: Vec<i32>,
    /// Activation scales of the two hidden layers (value per unit of `u8`).
    act_scales: [f64; 2],
    /// Advantage (Q-value minus the mean of all outputs') per unit of the integer output.
    q_scale: f64,
    calibration_states: usize,
}
impl Quantised {
    /// Hidden width H.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Per-tensor or per-channel weight scales.
    pub fn granularity(&self) -> Granularity {
        self.granularity
    }

    /// Outputs A: one per duty level.
    pub fn outputs(&self) -> usize {
        self.levels.len()
    }

    /// Each output's duty level, a fraction of the full push.
    pub fn levels(&self) -> &[f32] {
        &self.levels
    }

    /// Advantage (Q-value minus the mean of all outputs') per unit of the integer output.
    pub fn q_scale(&self) -> f64 {
        self.q_scale
    }

    /// Activation per unit of each hidden layer's `u8`.
    pub fn activation_scales(&self) -> [f64; 2] {
        self.act_scales
    }

    /// How many observations the activation ranges were taken from.
    pub fn calibration_states(&self) -> usize {
        self.calibration_states
    }

    /// The network as the firmware runs it, if its shape is `H` x `A`; on the heap.
    pub fn to_qmlp<const H: usize, const A: usize>(&self) -> Result<Box<QMlp<H, A>>> {
        if self.width != H || self.outputs() != A {
            return Err(Error::Input(format!(
                "quantised policy has hidden width {} and {} outputs, expected {H} and {A}",
                self.width,
                self.outputs()
            )));
        }
        let mut q = Box::new(QMlp::<H, A>::zeroed());
        q.fc1_weight
            .as_flattened_mut()
            .copy_from_slice(&self.fc1_weight);
        q.fc1_bias.copy_from_slice(&self.fc1_bias);
        q.fc1_requant.copy_from_slice(&self.fc1_requant);
        q.fc2_weight
            .as_flattened_mut()
            .copy_from_slice(&self.fc2_weight);
        q.fc2_bias.copy_from_slice(&self.fc2_bias);
        q.fc2_requant.copy_from_slice(&self.fc2_requant);
        q.fc3_weight
            .as_flattened_mut()
            .copy_from_slice(&self.fc3_weight);
        q.fc3_bias.copy_from_slice(&self.fc3_bias);
        Ok(q)
    }

    /// Bytes of flash the network occupies.
    pub fn flash_bytes(&self) -> usize {
        firmware::network::int::flash_bytes(self.width, self.outputs())
    }

    /// What the provenance lines of an export say about the quantisation.
    pub fn describe(&self) -> String {
        format!(
            "int8 weights ({}), u8 activations (scales {:.4e}, {:.4e}), calibrated on {} visited \
             states; advantage per output unit {:.6e}",
            self.granularity.name(),
            self.act_scales[0],
            self.act_scales[1],
            self.calibration_states,
            self.q_scale
        )
    }
}
