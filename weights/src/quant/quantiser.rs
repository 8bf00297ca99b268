//! The quantiser: scales from the calibration set's statistics, weights rounded to int8 for
//! the least output error, and every bound of the integer forward pass checked.

use firmware::fixed::{FRACTION_BITS as OBS_FRACTION_BITS, from_state as fixed_obs};
use firmware::network::OBS_DIM;
use firmware::network::int::Requant;

use super::{Granularity, Quantised};
use crate::{Error, Result, Weights};

/// The output's magnitude bound: integers below 2^24 convert to f32 exactly, so a controller
/// comparing f32 copies of the two outputs decides as the integers do.
const OUTPUT_BOUND: i64 = 1 << 24;

pub(super) fn symmetric(values: &[f32]) -> f64 {
    let m = values.iter().fold(0.0f64, |m, v| m.max(f64::from(v.abs())));
    if m > 0.0 { m / 127.0 } else { 1.0 }
}

pub(super) fn quantise_weights(w: &[f32], scale: f64) -> impl Iterator<Item = i8> + '_ {
    w.iter()
        .map(move |v| (f64::from(*v) / scale).round().clamp(-127.0, 127.0) as i8)
}

pub(super) fn quantise_bias(name: &str, b: f32, scale: f64) -> Result<i32> {
    let q = (f64::from(b) / scale).round();
    if q.abs() >= f64::from(1u32 << 30) {
        return Err(Error::Input(format!(
            "tensor `{name}`: bias {b:?} is {q:e} units of its accumulator, expected under 2^30: \
             the weights of that unit are tiny beside its bias"
        )));
    }
    Ok(q as i32)
}

/// The [`Requant`] closest to multiplying by `factor` (> 0) before clamping to 0..=255.
pub(super) fn requant(factor: f64) -> Requant {
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
/// On the policy shipped when it was chosen, nearest rounding let the cart drift far more
/// than this does (docs/QUANTISATION.md, "Adaptive rounding").
pub(super) fn adaptive_round(w: &[f32], s_w: f64, moments: &[f64]) -> Vec<i8> {
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

/// One hidden layer's integers: int8 weights, int32 biases, a requantisation per unit.
type Hidden = (Vec<i8>, Vec<i32>, Vec<Requant>);

/// Hidden layer `weights` (rows as long as the input) with the input's second moments,
/// input scale `s_x`, output scale `s_y`.
fn hidden(
    name: &str,
    (weights, bias): (&[f32], &[f32]),
    moments: &[f64],
    (s_x, s_y): (f64, f64),
    granularity: Granularity,
) -> Result<Hidden> {
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
}

/// Output `i`'s advantage over the mean of all `a` outputs, `x_i - mean(x)`, for the rows (or
/// biases) `x` of `cols` values each: `sum_j (x_i - x_j) / a` in f64, rounded once to f32.
/// With two outputs that is `(x_1 - x_0) / 2` and its negation, exactly.
fn advantages(x: &[f32], cols: usize, a: usize) -> Vec<f32> {
    let rows: Vec<&[f32]> = x.chunks(cols).collect();
    rows.iter()
        .flat_map(|xi| {
            (0..cols).map(|k| {
                let d: f64 = rows
                    .iter()
                    .map(|xj| f64::from(xi[k]) - f64::from(xj[k]))
                    .sum();
                (d / a as f64) as f32
            })
        })
        .collect()
}

/// The output layer of width-`h` inputs `w3`, `b3` (`a` outputs) as the advantages
/// `Q_i - mean(Q)`: its int8 weights, int32 biases and the advantage per unit of the output,
/// its input scale being `s_x`. One scale serves every row, so the outputs compare as
/// integers and choose as the float advantages, hence the Q-values, do. The Q-values share
/// a common part far larger than their differences (see [the module](super)), which int8
/// weights of each row would resolve so coarsely that it drowns the differences that decide.
///
/// Each row is rounded for the least output error on its own; with two outputs the rows are
/// each other's negation, and the second is rounded and negated for the first, so that the
/// integers are exactly opposite too and a tie between them is a tie.
fn advantage(
    (w3, b3): (&[f32], &[f32]),
    h: usize,
    moments: &[f64],
    s_x: f64,
) -> Result<(Vec<i8>, Vec<i32>, f64)> {
    let a = b3.len();
    let rows = advantages(w3, h, a);
    let s_w3 = symmetric(&rows);
    let q_scale = s_w3 * s_x;
    let biases = advantages(b3, 1, a);
    if a == 2 {
        let half = adaptive_round(&rows[h..], s_w3, moments);
        let fc3_weight = half
            .iter()
            .map(|v| -v)
            .chain(half.iter().copied())
            .collect();
        let b_half = quantise_bias("fc3.bias", biases[1], q_scale)?;
        return Ok((fc3_weight, vec![-b_half, b_half], q_scale));
    }
    let fc3_weight = rows
        .chunks(h)
        .flat_map(|row| adaptive_round(row, s_w3, moments))
        .collect();
    let fc3_bias = biases
        .iter()
        .map(|b| quantise_bias("fc3.bias", *b, q_scale))
        .collect::<Result<_>>()?;
    Ok((fc3_weight, fc3_bias, q_scale))
}

/// Refuses layer `name` if a unit's accumulator can reach `limit` for some input whose
/// values are at most `x_max` in magnitude.
fn bound(
    name: &str,
    (weights, bias): (&[i8], &[i32]),
    cols: usize,
    x_max: i64,
    limit: i64,
) -> Result<()> {
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
    let [m0, m1, m2] = &st.moments;
    let (fc1_weight, fc1_bias, fc1_requant) =
        hidden("fc1", (w1, b1), m0, (s_in, act[0]), granularity)?;
    let (fc2_weight, fc2_bias, fc2_requant) =
        hidden("fc2", (w2, b2), m1, (act[0], act[1]), granularity)?;
    let (fc3_weight, fc3_bias, q_scale) = advantage((w3, b3), h, m2, act[1])?;
    // Worst cases over every input: int16 observations, u8 activations.
    bound("fc1", (&fc1_weight, &fc1_bias), OBS_DIM, 32_768, 1 << 31)?;
    bound("fc2", (&fc2_weight, &fc2_bias), h, 255, 1 << 31)?;
    bound("fc3", (&fc3_weight, &fc3_bias), h, 255, OUTPUT_BOUND)?;
    Ok(Quantised {
        width: h,
        levels: w.levels().to_vec(),
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
