//! Post-training quantisation: a float policy to the integer network of
//! `firmware::network::int`, calibrated on observations the policy visits.
//!
//! - **Weights**: symmetric int8, `w_q = round(w / s_w)` with `s_w = max|w| / 127`, per
//!   tensor (what the tools use: it balances better in closed loop, docs/QUANTISATION.md) or
//!   per output unit ([`Granularity::PerChannel`]).
//! - **Outputs**: the advantages `Q - mean(Q)`, that is `-A` and `+A` with
//!   `A = (Q_right - Q_left) / 2`, in one scale, so they compare as integers and decide as
//!   the Q-values do. The common part of the two Q-values decides nothing and is some 200
//!   times their difference for the shipped policy: with int8 weights per Q-value row, half
//!   of the visited states' actions flipped (measured on the calibration set), against 6%
//!   with the advantage row alone quantised.
//! - **Activations**: `u8` per hidden layer, `s_h = max h / 255` over the calibration set:
//!   no observation the policy was seen to visit saturates a unit.
//! - **Biases**: int32 in the accumulator's scale, `round(b / (s_w * s_in))`. (Correcting
//!   them for the weights' mean rounding error on the calibration set, as Nagel et al. 2019
//!   do, was tried: nominal success fell from 99.8% to 89.3% over 1,000 episodes.)
//! - **Requantisation**: the factor `s_w * s_in / s_h` as a 16-bit multiplier and shifts
//!   ([`Requant`]), the pre-shift just large enough that the largest accumulator below the
//!   output's saturation fits in 15 bits, the multiplier as large as 16 bits allow.
//!
//! Every bound that keeps the integer forward pass from wrapping is checked here, for any
//! input: a policy whose integers would wrap is refused, not exported. The result is a
//! function of the weights and the calibration set alone, so exporting twice gives the same
//! integers.

use std::fmt::Write;

use firmware::fixed::{FRACTION_BITS as OBS_FRACTION_BITS, from_state as fixed_obs};
use firmware::network::OBS_DIM;
use firmware::network::int::{QMlp, Requant};

use crate::{Error, Result, Weights};

/// How many scales a weight tensor of a hidden layer gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Granularity {
    /// One scale per tensor.
    PerTensor,
    /// One scale per output unit (row): small rows keep their precision.
    PerChannel,
}

/// One scale per unit: for the shipped policy it keeps every robustness row at 100% and the
/// cart as near the centre as the float policy does, where one scale per tensor lets it
/// wander up to 1.2 m RMS over 200 s (`docs/QUANTISATION.md`). The earlier shipped policy
/// measured the other way round, so the better choice depends on the network: check both.
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

/// A quantised 4-H-H-2 network of run-time width: the integers of a [`QMlp`] plus the float
/// scales they stand for.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantised {
    width: usize,
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
    /// Advantage (Q-value minus the mean of the two) per unit of the integer output.
    q_scale: f64,
    calibration_states: usize,
}

/// The output's magnitude bound: integers below 2^24 convert to f32 exactly, so a controller
/// comparing f32 copies of the two outputs decides as the integers do.
const OUTPUT_BOUND: i64 = 1 << 24;

fn symmetric(values: &[f32]) -> f64 {
    let m = values.iter().fold(0.0f64, |m, v| m.max(f64::from(v.abs())));
    if m > 0.0 { m / 127.0 } else { 1.0 }
}

fn quantise_weights(w: &[f32], scale: f64) -> impl Iterator<Item = i8> + '_ {
    w.iter()
        .map(move |v| (f64::from(*v) / scale).round().clamp(-127.0, 127.0) as i8)
}

fn quantise_bias(name: &str, b: f32, scale: f64) -> Result<i32> {
    let q = (f64::from(b) / scale).round();
    if q.abs() >= f64::from(1u32 << 30) {
        return Err(Error::Input(format!(
            "tensor `{name}`: bias {b} is {q:e} units of its accumulator, expected under 2^30: \
             the weights of that unit are tiny beside its bias"
        )));
    }
    Ok(q as i32)
}

/// The [`Requant`] closest to multiplying by `factor` (> 0) before clamping to 0..=255.
fn requant(factor: f64) -> Requant {
    // The accumulator at which the output reaches 255.5 (saturation): shift it into 15 bits.
    let saturating = 255.5 / factor;
    let mut pre = 0u8;
    while pre < 31 && saturating / f64::from(1u32 << pre) >= 32_767.0 {
        pre += 1;
    }
    let mut post = 31u8;
    loop {
        let m = (factor * 2f64.powi(i32::from(pre) + i32::from(post))).round();
        if m <= 65_535.0 || post == 0 {
            return Requant {
                multiplier: m.clamp(0.0, 65_535.0) as u16,
                pre_shift: pre,
                post_shift: post,
            };
        }
        post -= 1;
    }
}

/// What the calibration set says about each layer's input (the observation, then the two
/// hidden layers' activations) in the float network, each state first rounded to the integer
/// network's input format: the largest activation of each hidden layer, and each input's
/// second moments `E[x x^T]`, row-major.
struct Stats {
    maxima: [f64; 2],
    moments: [Vec<f64>; 3],
}

fn stats(w: &Weights, states: &[[f32; OBS_DIM]]) -> Stats {
    let h = w.width();
    let [w1, b1, w2, b2, _, _] = w.tensors();
    let layer = |weights: &[f32], bias: &[f32], x: &[f64], y: &mut [f64]| {
        for ((y, row), b) in y.iter_mut().zip(weights.chunks(x.len())).zip(bias) {
            let v = f64::from(*b)
                + row
                    .iter()
                    .zip(x)
                    .map(|(w, x)| f64::from(*w) * x)
                    .sum::<f64>();
            *y = v.max(0.0);
        }
    };
    let mut st = Stats {
        maxima: [0.0; 2],
        moments: [
            vec![0.0; OBS_DIM * OBS_DIM],
            vec![0.0; h * h],
            vec![0.0; h * h],
        ],
    };
    let (mut h1, mut h2) = (vec![0.0f64; h], vec![0.0f64; h]);
    for s in states {
        let x = fixed_obs(s).map(|v| f64::from(v) / f64::from(1u32 << OBS_FRACTION_BITS));
        layer(w1, b1, &x, &mut h1);
        layer(w2, b2, &h1, &mut h2);
        st.maxima[0] = h1.iter().fold(st.maxima[0], |m, v| m.max(*v));
        st.maxima[1] = h2.iter().fold(st.maxima[1], |m, v| m.max(*v));
        for (m, v) in st.moments.iter_mut().zip([&x[..], &h1, &h2]) {
            for (row, a) in m.chunks_mut(v.len()).zip(v) {
                if *a != 0.0 {
                    for (m, b) in row.iter_mut().zip(v) {
                        *m += a * b;
                    }
                }
            }
        }
    }
    for m in st.moments.iter_mut().flatten() {
        *m /= states.len() as f64;
    }
    st
}

/// The int8 weights of one unit, `w / s_w` rounded up or down so as to minimise the mean
/// squared error this unit's output takes from them over the calibration set,
/// `e^T M e` with `e = w - s_w w_q` and `M = E[x x^T]`, rather than each weight's own error:
/// rounding to nearest, then flipping single weights to the other side while that lowers the
/// error (at most 8 sweeps). The idea is AdaRound's (Nagel et al., "Up or Down? Adaptive
/// Rounding for Post-Training Quantization", ICML 2020), solved greedily instead of learnt.
/// Measured on the shipped policy with per-unit scales (docs/QUANTISATION.md): nearest
/// rounding doubles the cart's RMS drift; this keeps it within a fifth.
fn adaptive_round(w: &[f32], s_w: f64, moments: &[f64]) -> Vec<i8> {
    let n = w.len();
    let mut q: Vec<i8> = quantise_weights(w, s_w).collect();
    let mut e: Vec<f64> = w
        .iter()
        .zip(&q)
        .map(|(w, q)| f64::from(*w) - s_w * f64::from(*q))
        .collect();
    // g = M e, kept up to date as weights flip.
    let mut g: Vec<f64> = moments
        .chunks(n)
        .map(|row| row.iter().zip(&e).map(|(m, e)| m * e).sum())
        .collect();
    for _ in 0..8 {
        let mut improved = false;
        for i in 0..n {
            // The other side of w_i / s_w: one step away from nearest, towards w_i.
            let step: i8 = if e[i] > 0.0 { 1 } else { -1 };
            let Some(flipped) = q[i].checked_add(step).filter(|v| (-127..=127).contains(v)) else {
                continue;
            };
            let d = -s_w * f64::from(step);
            let m_ii = moments[i * n + i];
            if 2.0 * d * g[i] + d * d * m_ii < -1e-15 {
                q[i] = flipped;
                e[i] += d;
                for (g, m) in g.iter_mut().zip(&moments[i * n..(i + 1) * n]) {
                    // M is symmetric: column i is row i.
                    *g += m * d;
                }
                improved = true;
            }
        }
        if !improved {
            break;
        }
    }
    q
}

/// Quantises `w`, taking the activation ranges from `states` (observations the float
/// policy visits; at least one).
pub fn quantise(
    w: &Weights,
    states: &[[f32; OBS_DIM]],
    granularity: Granularity,
) -> Result<Quantised> {
    if states.is_empty() {
        return Err(Error::Input(
            "quantisation needs at least one calibration state, found none".into(),
        ));
    }
    let h = w.width();
    let [w1, b1, w2, b2, w3, b3] = w.tensors();
    let st = stats(w, states);
    let act = st.maxima.map(|m| if m > 0.0 { m / 255.0 } else { 1.0 });
    let s_in = 1.0 / f64::from(1u32 << OBS_FRACTION_BITS);

    // Hidden layer `weights` (rows as long as the input) with the input's second moments,
    // input scale `s_x`, output scale `s_y`.
    // Hidden layer `weights` (rows as long as the input) with the input's second moments,
    // input scale `s_x`, output scale `s_y`.
    let hidden = |name: &str,
                  weights: &[f32],
                  bias: &[f32],
                  moments: &[f64],
                  s_x: f64,
                  s_y: f64|
     -> Result<(Vec<i8>, Vec<i32>, Vec<Requant>)> {
        let tensor = symmetric(weights);
        let (mut wq, mut bq, mut rq) = (Vec::new(), Vec::new(), Vec::new());
        let cols = moments.len().isqrt();
        for (row, b) in weights.chunks(cols).zip(bias) {
            let s_w = match granularity {
                Granularity::PerTensor => tensor,
                Granularity::PerChannel => symmetric(row),
            };
            wq.extend(adaptive_round(row, s_w, moments));
            bq.push(quantise_bias(&format!("{name}.bias"), *b, s_w * s_x)?);
            rq.push(requant(s_w * s_x / s_y));
        }
        Ok((wq, bq, rq))
    };
    let [m0, m1, m2] = &st.moments;
    let (fc1_weight, fc1_bias, fc1_requant) = hidden("fc1", w1, b1, m0, s_in, act[0])?;
    let (fc2_weight, fc2_bias, fc2_requant) = hidden("fc2", w2, b2, m1, act[0], act[1])?;
    // The output layer computes the advantages `Q - mean(Q)`, `-A` and `+A` with
    // `A = (Q_right - Q_left) / 2`: the two Q-values share a large common part (about 76
    // against differences of a few tenths for the shipped policy) that int8 weights of each
    // row would resolve only to about 1%, drowning the difference that decides the action.
    let advantage: Vec<f32> = w3[h..]
        .iter()
        .zip(&w3[..h])
        .map(|(r, l)| ((f64::from(*r) - f64::from(*l)) / 2.0) as f32)
        .collect();
    let s_w3 = symmetric(&advantage);
    let half = adaptive_round(&advantage, s_w3, m2);
    let fc3_weight: Vec<i8> = half
        .iter()
        .map(|v| -v)
        .chain(half.iter().copied())
        .collect();
    let q_scale = s_w3 * act[1];
    let b_adv = (f64::from(b3[1]) - f64::from(b3[0])) / 2.0;
    let b_half = quantise_bias("fc3.bias", b_adv as f32, q_scale)?;
    let fc3_bias = vec![-b_half, b_half];

    // Worst cases over every input: int16 observations, u8 activations.
    let bound = |weights: &[i8], bias: &[i32], cols: usize, x_max: i64, limit: i64, name: &str| {
        for (o, (row, b)) in weights.chunks(cols).zip(bias).enumerate() {
            let worst =
                row.iter().map(|w| i64::from(*w).abs() * x_max).sum::<i64>() + i64::from(*b).abs();
            if worst >= limit {
                return Err(Error::Input(format!(
                    "tensor `{name}`: unit {o} can reach {worst} in its accumulator, expected \
                     under {limit}"
                )));
            }
        }
        Ok(())
    };
    bound(&fc1_weight, &fc1_bias, OBS_DIM, 32_768, 1 << 31, "fc1")?;
    bound(&fc2_weight, &fc2_bias, h, 255, 1 << 31, "fc2")?;
    bound(&fc3_weight, &fc3_bias, h, 255, OUTPUT_BOUND, "fc3")?;
    Ok(Quantised {
        width: h,
        granularity,
        fc1_weight,
        fc1_bias,
        fc1_requant,
        fc2_weight,
        fc2_bias,
        fc2_requant,
        fc3_weight,
        fc3_bias,
        act_scales: act,
        q_scale,
        calibration_states: states.len(),
    })
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

    /// Advantage (Q-value minus the mean of the two) per unit of the integer output.
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

    /// The network as the firmware runs it, if its width is `H`; on the heap.
    pub fn to_qmlp<const H: usize>(&self) -> Result<Box<QMlp<H>>> {
        if self.width != H {
            return Err(Error::Input(format!(
                "quantised policy has hidden width {}, expected {H}",
                self.width
            )));
        }
        let mut q = Box::new(QMlp::<H>::zeroed());
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
        firmware::network::int::flash_bytes(self.width)
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

/// One field's values, for the source writers.
enum Values<'a> {
    Ints(&'a [i32]),
    Bytes(&'a [i8], usize),
    Requants(&'a [Requant]),
}

impl Quantised {
    /// The arrays in [`QMlp`]'s field order.
    fn fields(&self) -> [(&'static str, Values<'_>); 8] {
        let h = self.width;
        [
            ("fc1_bias", Values::Ints(&self.fc1_bias)),
            ("fc2_bias", Values::Ints(&self.fc2_bias)),
            ("fc3_bias", Values::Ints(&self.fc3_bias)),
            ("fc1_requant", Values::Requants(&self.fc1_requant)),
            ("fc2_requant", Values::Requants(&self.fc2_requant)),
            ("fc1_weight", Values::Bytes(&self.fc1_weight, OBS_DIM)),
            ("fc2_weight", Values::Bytes(&self.fc2_weight, h)),
            ("fc3_weight", Values::Bytes(&self.fc3_weight, h)),
        ]
    }
}

fn join<T: ToString>(v: &[T]) -> String {
    v.iter().map(T::to_string).collect::<Vec<_>>().join(", ")
}

/// The Rust module: `pub static NAME: ::firmware::network::int::QMlp<H>`, with a doc header
/// that says what it is, its formats and where it came from (`provenance`, one line each).
pub fn rust_module(q: &Quantised, name: &str, provenance: &[String]) -> Result<String> {
    crate::source::check_rust_name(name)?;
    let h = q.width;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "//! `{name}`: a 4-{h}-{h}-2 cart-pole balance policy in integers, for cores without an\n\
         //! FPU: int8 weights, int32 accumulators, no floating-point operation.\n\
         //!\n\
         //! Generated by `policy-export export --quant int8`; do not edit. Compile it into any\n\
         //! crate that depends on `firmware` (`mod policy_int;`) and call\n\
         //! `policy_int::{name}.forward(&obs)` with `obs` in Q3.12\n\
         //! (`firmware::network::int`, `Observer::fixed_state`); push right iff\n\
         //! `q[1] > q[0]`. `q` holds the advantages `Q - mean(Q)` (`q[0] == -q[1]` as exported);\n\
         //! one unit is {:.6e} of the float policy's Q-value.\n//!",
        q.q_scale
    );
    for line in provenance {
        let _ = writeln!(s, "//! - {line}");
    }
    let _ = writeln!(s, "//! - {}", q.describe());
    let _ = writeln!(
        s,
        "\n/// {} bytes of flash (int8 weights, int32 biases, a requantisation per hidden unit).",
        q.flash_bytes()
    );
    s.push_str("#[rustfmt::skip]\n");
    let _ = writeln!(
        s,
        "pub static {name}: ::firmware::network::int::QMlp<{h}> = ::firmware::network::int::QMlp {{"
    );
    for (field, values) in q.fields() {
        match values {
            Values::Ints(v) => {
                let _ = writeln!(s, "    {field}: [{}],", join(v));
            }
            Values::Bytes(v, cols) => {
                let _ = writeln!(s, "    {field}: [");
                for row in v.chunks(cols) {
                    let _ = writeln!(s, "        [{}],", join(row));
                }
                s.push_str("    ],\n");
            }
            Values::Requants(v) => {
                let _ = writeln!(s, "    {field}: [");
                for r in v {
                    let _ = writeln!(
                        s,
                        "        ::firmware::network::int::Requant::new({}, {}, {}),",
                        r.multiplier, r.pre_shift, r.post_shift
                    );
                }
                s.push_str("    ],\n");
            }
        }
    }
    s.push_str("};\n");
    Ok(s)
}

/// The guarded definitions of `struct cartpole_requant` and `struct cartpole_qmlpH` and the
/// declaration of `cartpole_qmlpH_forward`: what every integer header for width `h` shares
/// with `cartpole_policy.h`.
pub fn c_struct(h: usize) -> String {
    let mut s = String::new();
    s.push_str(
        "#ifndef CARTPOLE_REQUANT_DEFINED\n#define CARTPOLE_REQUANT_DEFINED\n#include <stdint.h>\n\
         /* acc -> u8 activation: t = min(max(acc, 0) >> pre_shift, 32767);\n \
         * y = min((t * multiplier + (2^post_shift >> 1)) >> post_shift, 255), in uint32_t. */\n\
         struct cartpole_requant {\n    uint16_t multiplier;\n    uint8_t pre_shift;\n    \
         uint8_t post_shift;\n};\n#endif\n",
    );
    let _ = writeln!(
        s,
        "#ifndef CARTPOLE_QMLP{h}_DEFINED\n#define CARTPOLE_QMLP{h}_DEFINED\n\
         /* A 4-{h}-{h}-2 Q-network in integers (weight[out][in]); the layout of Rust's\n \
         * firmware::network::int::QMlp<{h}>. */\nstruct cartpole_qmlp{h} {{\n    \
         int32_t fc1_bias[{h}];\n    int32_t fc2_bias[{h}];\n    int32_t fc3_bias[2];\n    \
         struct cartpole_requant fc1_requant[{h}];\n    struct cartpole_requant fc2_requant[{h}];\n    \
         int8_t fc1_weight[{h}][4];\n    int8_t fc2_weight[{h}][{h}];\n    int8_t fc3_weight[2][{h}];\n}};\n\
         /* q = the two outputs of w (exported policies: the advantages Q - mean(Q)) in its\n \
         * integer scale, obs = {{x, x_dot, theta, theta_dot}} in Q3.12 (SI units times 4096);\n \
         * push right iff q[1] > q[0]. No floating point. From libcartpole_policy.a; a NULL\n \
         * argument makes it write nothing. */\n\
         #ifdef __cplusplus\nextern \"C\"\n#endif\n\
         void cartpole_qmlp{h}_forward(const struct cartpole_qmlp{h} *w, const int16_t obs[4], int32_t q[2]);\n\
         #endif"
    );
    s
}

/// The C header: `static const struct cartpole_qmlpH NAME`, with a comment that says what
/// it is, how to use it and where it came from.
pub fn c_header(q: &Quantised, name: &str, provenance: &[String]) -> Result<String> {
    crate::source::check_c_name(name)?;
    let h = q.width;
    let guard = format!("CARTPOLE_POLICY_{}_H", name.to_ascii_uppercase());
    let mut s = String::new();
    let _ = writeln!(
        s,
        "/* {name}: a 4-{h}-{h}-2 cart-pole balance policy in integers, for cores without an FPU.\n \
         *\n \
         * Generated by policy-export export --quant int8; do not edit. Run it with the Rust\n \
         * forward pass, bit for bit: cartpole_qmlp{h}_forward(&{name}, obs, q), linking\n \
         * libcartpole_policy.a. q holds the advantages Q - mean(Q), one unit being {:.6e}\n \
         * of the float policy's Q-value.",
        q.q_scale
    );
    for line in provenance {
        let _ = writeln!(s, " * - {line}");
    }
    let _ = writeln!(s, " * - {}", q.describe());
    let _ = writeln!(s, " */\n#ifndef {guard}\n#define {guard}\n");
    s.push_str(&c_struct(h));
    let _ = writeln!(
        s,
        "\n/* {} bytes. */\nstatic const struct cartpole_qmlp{h} {name} = {{",
        q.flash_bytes()
    );
    for (field, values) in q.fields() {
        match values {
            Values::Ints(v) => {
                let _ = writeln!(s, "    .{field} = {{{}}},", join(v));
            }
            Values::Bytes(v, cols) => {
                let _ = writeln!(s, "    .{field} = {{");
                for row in v.chunks(cols) {
                    let _ = writeln!(s, "        {{{}}},", join(row));
                }
                s.push_str("    },\n");
            }
            Values::Requants(v) => {
                let _ = writeln!(s, "    .{field} = {{");
                for r in v {
                    let _ = writeln!(
                        s,
                        "        {{{}, {}, {}}},",
                        r.multiplier, r.pre_shift, r.post_shift
                    );
                }
                s.push_str("    },\n");
            }
        }
    }
    let _ = writeln!(s, "}};\n\n#endif /* {guard} */");
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::fixed::from_state as fixed_obs;
    use firmware::policy::POLICY;

    #[test]
    fn a_requantisation_applies_its_factor_to_16_bits_and_saturates_late() {
        // From the smallest factor whose saturating accumulator fits in an i32.
        let mut factor = 2e-7;
        while factor < 10.0 {
            let r = requant(factor);
            let applied = f64::from(r.multiplier)
                / 2f64.powi(i32::from(r.pre_shift) + i32::from(r.post_shift));
            assert!((applied / factor - 1.0).abs() < 2e-5, "{factor}: {r:?}");
            // The largest accumulator below saturation keeps 14 bits after the pre-shift.
            let t = (255.0 / factor) / 2f64.powi(i32::from(r.pre_shift));
            assert!(
                (16_383.0..32_767.0).contains(&t) || r.pre_shift == 0,
                "{factor}: {t}"
            );
            // And the output saturates where the real product reaches 255.5.
            let acc = (255.5 / factor).ceil() as i32;
            assert_eq!(r.apply(acc), 255, "{factor}");
            factor *= 1.37;
        }
    }

    /// `e^T M e` for the rounding of `w` to `q` at scale `s`.
    fn output_error(w: &[f32], q: &[i8], s: f64, m: &[f64]) -> f64 {
        let e: Vec<f64> = w
            .iter()
            .zip(q)
            .map(|(w, q)| f64::from(*w) - s * f64::from(*q))
            .collect();
        m.chunks(e.len())
            .zip(&e)
            .map(|(row, ei)| ei * row.iter().zip(&e).map(|(m, e)| m * e).sum::<f64>())
            .sum()
    }

    #[test]
    fn adaptive_rounding_lowers_the_output_error_and_stays_beside_nearest() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for n in [4usize, 16, 64] {
            // Correlated inputs: M = A A^T / k for random A, as activations give.
            let k = 3 * n;
            let a: Vec<f64> = (0..n * k).map(|_| next()).collect();
            let mut m = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    m[i * n + j] =
                        (0..k).map(|c| a[i * k + c] * a[j * k + c]).sum::<f64>() / k as f64;
                }
            }
            let w: Vec<f32> = (0..n).map(|_| (next() * 2.0 - 1.0) as f32).collect();
            let s = symmetric(&w);
            let nearest: Vec<i8> = quantise_weights(&w, s).collect();
            let adaptive = adaptive_round(&w, s, &m);
            assert!(output_error(&w, &adaptive, s, &m) <= output_error(&w, &nearest, s, &m));
            assert!(
                adaptive
                    .iter()
                    .zip(&nearest)
                    .all(|(a, b)| (i16::from(*a) - i16::from(*b)).abs() <= 1)
            );
            // Uncorrelated inputs: each weight's own error is all there is, and nearest is best.
            let diagonal: Vec<f64> = (0..n * n)
                .map(|i| if i % (n + 1) == 0 { 1.0 } else { 0.0 })
                .collect();
            assert_eq!(adaptive_round(&w, s, &diagonal), nearest);
        }
    }

    #[test]
    fn the_shipped_policy_keeps_its_decisions_where_they_matter() {
        let w = Weights::from_mlp(&POLICY).unwrap();
        // A calibration set of its own: states along a swinging, drifting trajectory.
        let states: Vec<[f32; 4]> = (0..4000)
            .map(|i| {
                let t = i as f32 * 0.01;
                [
                    0.8 * (0.3 * t).sin(),
                    0.5 * (0.7 * t).cos(),
                    0.05 * (2.1 * t).sin(),
                    0.4 * (1.3 * t).cos(),
                ]
            })
            .collect();
        for g in [Granularity::PerChannel, Granularity::PerTensor] {
            let q = quantise(&w, &states, g).unwrap();
            let net = q.to_qmlp::<64>().unwrap();
            let (mut big, mut kept, mut err, mut size) = (0, 0, 0.0f64, 0.0f64);
            for s in &states {
                let f = POLICY.forward(s);
                let a = f64::from(f[1] - f[0]) / 2.0;
                let qi = net.forward(&fixed_obs(s));
                err += (f64::from(qi[1]) * q.q_scale() - a).abs();
                size += a.abs();
                // A clear preference (a margin of 0.3 and more) must survive, but for a few
                // states away from where the policy goes (`host-sim agree` measures it on
                // visited states: 3 of 493,030 flip).
                if a.abs() >= 0.15 {
                    big += 1;
                    kept += u32::from((qi[1] > qi[0]) == (f[1] > f[0]));
                }
            }
            assert!(
                big > 500 && kept * 100 >= big * 98,
                "{g:?}: {kept} of {big}"
            );
            // Measured: 11.5% per channel, 13.3% per tensor; 99.2% and 99.5% kept.
            assert!(
                err < 0.2 * size,
                "{g:?}: advantage error {err} against {size}"
            );
        }
    }

    #[test]
    fn what_cannot_be_represented_is_refused() {
        let w = Weights::from_mlp(&POLICY).unwrap();
        let e = quantise(&w, &[], Granularity::PerChannel).unwrap_err();
        assert!(e.is_input() && e.to_string().contains("calibration"), "{e}");
        // A unit with tiny weights and a large bias: its bias does not fit its accumulator.
        let mut t = w.tensors().clone();
        for v in &mut t[0][..4] {
            *v = 1e-30;
        }
        t[1][0] = 5.0;
        let odd = Weights::new(64, t).unwrap();
        let e = quantise(&odd, &[[0.0; 4]], Granularity::PerChannel).unwrap_err();
        assert!(e.to_string().contains("`fc1.bias`"), "{e}");
    }

    #[test]
    fn sources_name_their_scale_and_size() {
        let w = Weights::from_mlp(&POLICY).unwrap();
        let q = quantise(&w, &[[0.01, 0.0, 0.02, 0.0]], Granularity::PerTensor).unwrap();
        let rust = rust_module(&q, "P_INT", &["source: a test".into()]).unwrap();
        assert!(rust.contains("pub static P_INT: ::firmware::network::int::QMlp<64>"));
        assert!(rust.contains("5512 bytes of flash") && rust.contains("per-tensor"));
        let c = c_header(&q, "p_int", &[]).unwrap();
        assert!(c.contains("static const struct cartpole_qmlp64 p_int = {"));
        assert!(rust_module(&q, "lower", &[]).unwrap_err().is_input());
        assert!(c_header(&q, "int", &[]).unwrap_err().is_input());
    }
}
