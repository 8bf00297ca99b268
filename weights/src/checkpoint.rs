//! Safetensors checkpoints: the trainer's canonical file, and state dicts as PyTorch users
//! save them.
//!
//! A state dict names each tensor `<prefix><layer>.<weight|bias>`: `fc1.weight` for a module
//! with attributes `fc1`, `fc2`, `fc3`; `0.weight`, `2.weight`, `4.weight` for an
//! `nn.Sequential` with ReLUs between; `network.0.weight` for CleanRL's `QNetwork`;
//! `q_net.q_net.0.weight` (and a target net under `q_net_target.q_net.`) for a
//! Stable-Baselines3 DQN policy. [`import`] groups the tensors by prefix and takes the group
//! whose three linear layers, in natural order of their names, chain the shapes
//! `[H, 4] -> [H, H] -> [2, H]` with biases `[H]`, `[H]`, `[2]`. A checkpoint holding two
//! such networks (an online and a target net) is refused with both prefixes named, unless
//! one is chosen; tensors outside the network are refused unless a prefix was chosen
//! explicitly, so nothing is dropped without being asked for.
//!
//! F32 tensors are taken as they are, F16 and BF16 exactly widened, F64 rounded to nearest
//! (the network runs in f32); every value must be finite.

use std::cmp::Ordering;
use std::collections::BTreeMap;
use std::path::Path;

use firmware::network::{N_ACTIONS, OBS_DIM, TENSOR_NAMES};
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use crate::files::{MAX_POLICY_BYTES, read_capped};
use crate::{Error, Result, Weights, quote};

/// Largest safetensors header read. The header is JSON listing every tensor; a few hundred
/// bytes per tensor, so this allows thousands while bounding the memory a hostile file costs.
pub const MAX_HEADER_BYTES: u64 = 1 << 20;

/// A network found in a checkpoint, and where.
#[derive(Clone, Debug, PartialEq)]
pub struct Import {
    /// The network.
    pub weights: Weights,
    /// The tensor-name prefix it was found under (`""` for none, `network.`, `q_net.q_net.`).
    pub prefix: String,
    /// Its three layers' names under the prefix, input side first (`fc1`, `fc2`, `fc3` or
    /// `0`, `2`, `4`).
    pub layers: [String; 3],
    /// Tensors outside the prefix, ignored because the prefix was chosen.
    pub ignored: usize,
    /// The stored dtype, when it was not F32 (F64 values were rounded to f32).
    pub converted_from: Option<String>,
    /// The file's `__metadata__` (the trainer writes its configuration there).
    pub metadata: BTreeMap<String, String>,
}

impl Import {
    /// One line for a log: `fc1, fc2, fc3 under prefix network., width 64`.
    pub fn describe(&self) -> String {
        let mut s = format!(
            "layers {} under {}, hidden width {}",
            self.layers.join(", "),
            show_prefix(&self.prefix),
            self.weights.width()
        );
        if let Some(d) = &self.converted_from {
            s += &format!(", converted from {d}");
        }
        if self.ignored > 0 {
            s += &format!(", {} other tensors ignored", self.ignored);
        }
        s
    }
}

fn show_prefix(p: &str) -> String {
    if p.is_empty() {
        "no prefix".into()
    } else {
        format!("prefix `{p}`")
    }
}

/// The file a policy argument names: `path` itself, or a run directory's
/// `policy.safetensors`.
pub fn policy_file(path: &Path) -> std::path::PathBuf {
    if path.is_dir() {
        path.join("policy.safetensors")
    } else {
        path.to_path_buf()
    }
}

/// Reads the checkpoint at `path` (a `.safetensors` file, or a run directory's
/// `policy.safetensors`) and finds its network; `prefix` chooses among several.
pub fn load(path: &Path, prefix: Option<&str>) -> Result<Import> {
    let file = policy_file(path);
    let bytes = read_capped(&file, MAX_POLICY_BYTES)?;
    import(&bytes, prefix).map_err(|e| match e {
        Error::Input(m) => Error::Input(format!("{}: {m}", file.display())),
        other => other,
    })
}

/// One linear layer's two tensors, by name.
#[derive(Default)]
struct Layer<'a> {
    weight: Option<&'a str>,
    bias: Option<&'a str>,
    /// Tensors of the layer that are neither (a BatchNorm's `running_mean`, say).
    other: Vec<&'a str>,
}

/// Finds the 4-H-H-2 network in safetensors `bytes`; `prefix` chooses among several.
pub fn import(bytes: &[u8], prefix: Option<&str>) -> Result<Import> {
    let st = parse(bytes)?;
    let metadata = SafeTensors::read_metadata(bytes)
        .ok()
        .and_then(|(_, m)| m.metadata().clone())
        .map(|m| m.into_iter().collect())
        .unwrap_or_default();
    // Sorted, so that messages naming a tensor name the same one every time.
    let mut names = st.names();
    names.sort_unstable();
    // Messages quote names; PyTorch's are short (`q_net_target.q_net.4.weight` is 27 bytes).
    if let Some(long) = names.iter().find(|n| n.len() > crate::QUOTE_MAX) {
        return Err(Error::Input(format!(
            "tensor names must be at most {} bytes, found one of {} bytes: {}",
            crate::QUOTE_MAX,
            long.len(),
            quote(long)
        )));
    }
    let groups = by_prefix(&names);
    let checked: Vec<(&str, std::result::Result<[&str; 3], String>)> = groups
        .iter()
        .map(|(p, layers)| (*p, chain(&st, layers)))
        .collect();
    let (pre, layers) = select(&checked, prefix)?;
    let group = &groups[pre];
    let own: Vec<&str> = layers
        .iter()
        .flat_map(|k| [group[k].weight, group[k].bias])
        .flatten()
        .collect();
    let outside: Vec<&str> = names.iter().copied().filter(|n| !own.contains(n)).collect();
    if prefix.is_none() && !outside.is_empty() {
        return Err(Error::Input(format!(
            "{} tensors are not part of the network under {} (e.g. {}); pass --prefix {} to \
             import that network and ignore them",
            outside.len(),
            show_prefix(pre),
            quote(outside[0]),
            shell_word(pre)
        )));
    }
    let mut tensors: [Vec<f32>; 6] = Default::default();
    let mut converted_from = None;
    for (t, name) in tensors.iter_mut().zip(&own) {
        let view = st
            .tensor(name)
            .map_err(|e| Error::Input(format!("tensor `{name}`: {e}")))?;
        let (values, from) = to_f32(name, &view)?;
        converted_from = converted_from.or(from);
        *t = values;
    }
    let width = tensors[1].len();
    let weights = Weights::new(width, tensors).map_err(|e| match e {
        Error::Input(m) => Error::Input(rename(&m, &own)),
        other => other,
    })?;
    weights.check_outputs()?;
    Ok(Import {
        weights,
        prefix: pre.to_string(),
        layers: layers.map(str::to_string),
        ignored: outside.len(),
        converted_from,
        metadata,
    })
}

/// `names` by prefix, then by layer: `network.0.weight` is layer `0`'s weight under
/// `network.`.
fn by_prefix<'a>(names: &[&'a str]) -> BTreeMap<&'a str, BTreeMap<&'a str, Layer<'a>>> {
    let mut groups: BTreeMap<&str, BTreeMap<&str, Layer>> = BTreeMap::new();
    for &name in names {
        let (stem, param) = name.rsplit_once('.').unwrap_or((name, ""));
        let (pre, layer) = match stem.rfind('.') {
            Some(i) => stem.split_at(i + 1),
            None => ("", stem),
        };
        let l = groups.entry(pre).or_default().entry(layer).or_default();
        match param {
            "weight" => l.weight = Some(name),
            "bias" => l.bias = Some(name),
            _ => l.other.push(name),
        }
    }
    groups
}

/// The group to import: the one `prefix` names, or the only one that is a network.
fn select<'a>(
    checked: &[(&'a str, std::result::Result<[&'a str; 3], String>)],
    prefix: Option<&str>,
) -> Result<(&'a str, [&'a str; 3])> {
    if let Some(p) = prefix {
        return match checked.iter().find(|(q, _)| *q == p) {
            None => {
                let found: Vec<String> = checked.iter().map(|(p, _)| shell_word(p)).collect();
                Err(Error::Input(format!(
                    "no tensors under prefix {} (prefixes found: {})",
                    quote(p),
                    found.join(", ")
                )))
            }
            Some((_, Err(why))) => Err(Error::Input(format!("{}: {why}", show_prefix(p)))),
            Some((p, Ok(layers))) => Ok((*p, *layers)),
        };
    }
    let valid: Vec<(&str, [&str; 3])> = checked
        .iter()
        .filter_map(|(p, r)| r.as_ref().ok().map(|l| (*p, *l)))
        .collect();
    match valid[..] {
        [one] => Ok(one),
        [] => {
            let why: Vec<String> = checked
                .iter()
                .filter_map(|(p, r)| r.as_ref().err().map(|w| format!("{}: {w}", show_prefix(p))))
                .take(8)
                .collect();
            Err(Error::Input(format!(
                "no 4-H-H-2 network found (three linear layers [H, {OBS_DIM}] -> [H, H] -> \
                 [{N_ACTIONS}, H]); {}",
                why.join("; ")
            )))
        }
        ref many => {
            let list: Vec<String> = many.iter().map(|(p, _)| shell_word(p)).collect();
            Err(Error::Input(format!(
                "{} networks found, under the prefixes {}; choose one with --prefix (e.g. \
                 --prefix {})",
                many.len(),
                list.join(", "),
                list[0]
            )))
        }
    }
}

/// `--prefix` as a user would type it in a shell.
fn shell_word(p: &str) -> String {
    if p.is_empty() {
        "\"\"".into()
    } else {
        quote(p).trim_matches('"').to_string()
    }
}

/// Messages from [`Weights::new`] name the canonical tensors; say the checkpoint's names.
fn rename(msg: &str, own: &[&str]) -> String {
    let mut m = msg.to_string();
    for (canonical, name) in TENSOR_NAMES.iter().zip(own) {
        m = m.replace(&format!("`{canonical}`"), &format!("`{name}`"));
    }
    m
}

/// The group's three layers in order if they chain `[H, 4] -> [H, H] -> [2, H]`, or why not.
/// The order is the names' natural order (`fc1 < fc2 < fc10`, `0 < 2 < 4`); names that do not
/// sort that way (`input`, `hidden`, `output`) are ordered by the one chain their shapes form.
fn chain<'a>(
    st: &SafeTensors,
    layers: &BTreeMap<&'a str, Layer<'a>>,
) -> std::result::Result<[&'a str; 3], String> {
    let mut order: Vec<&str> = layers.keys().copied().collect();
    order.sort_by(|a, b| natural(a, b));
    let shown = order.iter().take(6).copied().collect::<Vec<_>>().join(", ");
    let [a, b, c] = order[..] else {
        return Err(format!(
            "{} layers ({shown}{}), expected 3 linear layers",
            order.len(),
            if order.len() > 6 { ", ..." } else { "" }
        ));
    };
    let mut dims = BTreeMap::new();
    for key in [a, b, c] {
        let l = &layers[key];
        if let Some(o) = l.other.first() {
            return Err(format!("`{o}` is not a linear layer's weight or bias"));
        }
        let (Some(w), Some(bias)) = (l.weight, l.bias) else {
            let missing = if l.weight.is_none() { "weight" } else { "bias" };
            return Err(format!("layer `{key}` lacks its {missing}"));
        };
        let shape = |n: &str| st.tensor(n).map(|t| t.shape().to_vec()).unwrap_or_default();
        let (ws, bs) = (shape(w), shape(bias));
        let [out, inp] = ws[..] else {
            return Err(format!("`{w}` has shape {ws:?}, expected [out, in]"));
        };
        if bs != [out] {
            return Err(format!(
                "`{bias}` has shape {bs:?}, expected [{out}] to match `{w}`"
            ));
        }
        dims.insert(key, (w, out, inp));
    }
    let why = |[a, b, c]: [&str; 3]| -> Option<String> {
        let ((w1, h1, i1), (w2, h2, i2), (w3, o3, i3)) = (dims[a], dims[b], dims[c]);
        if i1 != OBS_DIM {
            Some(format!(
                "`{w1}` is [{h1}, {i1}]: the first layer takes the {OBS_DIM} observations"
            ))
        } else if i2 != h1 || i3 != h2 {
            Some(format!(
                "the layers do not chain: `{w1}` [{h1}, {i1}], `{w2}` [{h2}, {i2}], `{w3}` \
                 [{o3}, {i3}]"
            ))
        } else if h1 != h2 {
            Some(format!(
                "hidden widths {h1} and {h2} differ; the network has two hidden layers of one \
                 width"
            ))
        } else if o3 != N_ACTIONS {
            Some(format!(
                "`{w3}` is [{o3}, {i3}]: the output layer has {N_ACTIONS} outputs (left, right)"
            ))
        } else {
            None
        }
    };
    let Some(first) = why([a, b, c]) else {
        return Ok([a, b, c]);
    };
    let others = [[a, c, b], [b, a, c], [b, c, a], [c, a, b], [c, b, a]];
    match others
        .iter()
        .filter(|p| why(**p).is_none())
        .collect::<Vec<_>>()[..]
    {
        [only] => Ok(*only),
        _ => Err(first),
    }
}

/// Orders layer names as a person would: `fc2` before `fc10`, `2` before `10`. Runs of digits
/// compare as numbers, other runs as text, digits after letters.
fn natural(a: &str, b: &str) -> Ordering {
    fn runs(s: &str) -> impl Iterator<Item = (bool, usize, &str)> {
        let b = s.as_bytes();
        let mut start = 0;
        (1..=b.len()).filter_map(move |i| {
            if i < b.len() && b[i].is_ascii_digit() == b[i - 1].is_ascii_digit() {
                return None;
            }
            let run = &s[start..i];
            start = i;
            let digits = run.as_bytes()[0].is_ascii_digit();
            // A number's magnitude first (its length without leading zeros), then its text.
            let len = if digits {
                run.trim_start_matches('0').len()
            } else {
                0
            };
            Some((digits, len, run))
        })
    }
    runs(a).cmp(runs(b))
}

/// Checks the header's size before the safetensors crate parses it.
fn parse(bytes: &[u8]) -> Result<SafeTensors<'_>> {
    let Some(len) = bytes.first_chunk::<8>().map(|b| u64::from_le_bytes(*b)) else {
        return Err(Error::Input(format!(
            "not a safetensors file: {} bytes, shorter than its 8-byte header length",
            bytes.len()
        )));
    };
    if len > MAX_HEADER_BYTES {
        return Err(Error::Input(format!(
            "not a policy checkpoint: its header declares {len} bytes, expected at most {MAX_HEADER_BYTES}"
        )));
    }
    SafeTensors::deserialize(bytes)
        .map_err(|e| Error::Input(format!("not a safetensors file: {e}")))
}

/// The tensor's values as f32, and the dtype they were converted from, if not F32.
fn to_f32(name: &str, t: &TensorView) -> Result<(Vec<f32>, Option<String>)> {
    let d = t.data();
    let v: Vec<f32> = match t.dtype() {
        Dtype::F32 => d
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        Dtype::F64 => d
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("chunks of 8")) as f32)
            .collect(),
        Dtype::BF16 => d
            .chunks_exact(2)
            .map(|c| f32::from_bits(u32::from(u16::from_le_bytes([c[0], c[1]])) << 16))
            .collect(),
        Dtype::F16 => d
            .chunks_exact(2)
            .map(|c| f16_to_f32(u16::from_le_bytes([c[0], c[1]])))
            .collect(),
        other => {
            return Err(Error::Input(format!(
                "tensor `{name}`: expected dtype F32 (or F64, F16, BF16), found {other:?}"
            )));
        }
    };
    let from = (t.dtype() != Dtype::F32).then(|| format!("{:?}", t.dtype()));
    Ok((v, from))
}

/// IEEE binary16 to binary32, exactly (every f16 is an f32).
fn f16_to_f32(h: u16) -> f32 {
    let sign = u32::from(h >> 15) << 31;
    let exp = u32::from((h >> 10) & 0x1f);
    let man = u32::from(h & 0x3ff);
    let bits = match (exp, man) {
        (0, 0) => sign,
        // Subnormal: value man * 2^-24, normalised for f32.
        (0, m) => {
            let shift = m.leading_zeros() - 21;
            sign | ((127 - 15 - shift + 1) << 23) | ((m << shift) & 0x3ff) << 13
        }
        (0x1f, m) => sign | 0x7f80_0000 | (m << 13),
        (e, m) => sign | ((e + 127 - 15) << 23) | (m << 13),
    };
    f32::from_bits(bits)
}

/// The trainer's canonical file: tensors `fc1.weight` ... `fc3.bias` in f32, `metadata` in
/// the header's `__metadata__`, header keys sorted so the same weights and metadata always
/// give the same bytes.
pub fn to_safetensors(w: &Weights, metadata: &BTreeMap<String, String>) -> Result<Vec<u8>> {
    let shapes = firmware::network::shapes(w.width());
    let bytes: Vec<Vec<u8>> = w
        .tensors()
        .iter()
        .map(|t| t.iter().flat_map(|v| v.to_le_bytes()).collect())
        .collect();
    let views = TENSOR_NAMES
        .iter()
        .zip(shapes)
        .zip(&bytes)
        .map(|((name, shape), data)| {
            TensorView::new(Dtype::F32, shape.dims().to_vec(), data)
                .map(|v| (*name, v))
                .map_err(|e| Error::Io(format!("tensor `{name}`: {e}")))
        })
        .collect::<Result<Vec<_>>>()?;
    let meta = (!metadata.is_empty()).then(|| metadata.clone().into_iter().collect());
    let raw = safetensors::serialize(views, meta)
        .map_err(|e| Error::Io(format!("serialising safetensors: {e}")))?;
    Ok(canonical_header(&raw))
}

/// `bytes` with its JSON header's keys sorted. The safetensors crate writes the metadata (and
/// may write the tensor entries) in `HashMap` order, which differs from run to run. The
/// header stays padded with spaces to a multiple of 8 bytes, as the format recommends; tensor
/// offsets are relative to the data, so they do not change.
fn canonical_header(bytes: &[u8]) -> Vec<u8> {
    let len = u64::from_le_bytes(*bytes.first_chunk::<8>().expect("serialised header")) as usize;
    let (header, data) = bytes[8..].split_at(len);
    let mut fields: BTreeMap<String, serde_json::Value> =
        serde_json::from_slice(header).expect("the safetensors crate writes JSON");
    if let Some(serde_json::Value::Object(meta)) = fields.remove("__metadata__") {
        let sorted: BTreeMap<String, serde_json::Value> = meta.into_iter().collect();
        fields.insert(
            "__metadata__".into(),
            serde_json::to_value(sorted).expect("strings"),
        );
    }
    let mut header = serde_json::to_vec(&fields).expect("JSON values serialise");
    header.resize(header.len().next_multiple_of(8), b' ');
    let mut out = Vec::with_capacity(8 + header.len() + data.len());
    out.extend_from_slice(&(header.len() as u64).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(data);
    out
}

#[cfg(test)]
mod tests;
