//! Checkpoints as PyTorch users save them, and the trainer's canonical file.
//!
//! Four formats, told apart by their first bytes:
//! - safetensors (the trainer's own file, and `safetensors.torch.save_file`);
//! - PyTorch's zip (`torch.save(state_dict)`: `.pt`, `.pth`, CleanRL's `.cleanrl_model`), whose
//!   pickle is read by a restricted reader that runs nothing ([`pickle`]);
//! - Stable-Baselines3's `model.zip`, the same zip inside as `policy.pth`;
//! - ONNX (`torch.onnx.export`), recognised by its graph ([`onnx`]).
//!
//! A state dict names each tensor `<prefix><layer>.<weight|bias>`: `fc1.weight` for a module
//! with attributes `fc1`, `fc2`, `fc3`; `0.weight`, `2.weight`, `4.weight` for an
//! `nn.Sequential` with ReLUs between; `network.0.weight` for CleanRL's `QNetwork`;
//! `q_net.q_net.0.weight` (and a target net under `q_net_target.q_net.`) for a
//! Stable-Baselines3 DQN policy. [`import`] groups the tensors by prefix and takes the group
//! whose three linear layers, in natural order of their names, chain the shapes
//! `[H, 4] -> [H, H] -> [A, H]` with biases `[H]`, `[H]`, `[A]`, one output per duty level
//! (the levels the file records, else those given ([`import_with`]), else the paper's two
//! for `A = 2`: [`crate::levels`]). A checkpoint holding two
//! such networks (an online and a target net) is refused with both prefixes named, unless
//! one is chosen; tensors outside the network are refused unless a prefix was chosen
//! explicitly, so nothing is dropped without being asked for.
//!
//! F32 tensors are taken as they are, F16 and BF16 exactly widened, F64 rounded to nearest
//! (the network runs in f32); every value must be finite.

pub mod onnx;
pub mod pickle;
mod protobuf;
mod safetensors_file;
pub mod state_dict;
mod torch;
mod zip;

use std::cmp::Ordering;
use std::collections::BTreeMap;
use std::path::Path;

use firmware::network::{OBS_DIM, TENSOR_NAMES};

pub use safetensors_file::{MAX_HEADER_BYTES, to_safetensors};
use state_dict::{StateDict, shape_text, to_f32};

use crate::files::{MAX_POLICY_BYTES, read_capped};
use crate::levels::{self, GivenLevels};
use crate::{Error, Result, Weights, check_shape, few, quote};

/// The kind of file a network was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// A safetensors file.
    Safetensors,
    /// PyTorch's zip of a pickled state dict (`torch.save`).
    TorchZip,
    /// Stable-Baselines3's `model.zip`, through its `policy.pth`.
    Sb3Zip,
    /// An ONNX model.
    Onnx,
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Format::Safetensors => "safetensors",
            Format::TorchZip => "PyTorch zip",
            Format::Sb3Zip => "Stable-Baselines3 model.zip",
            Format::Onnx => "ONNX",
        })
    }
}

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
    /// The kind of file it was read from.
    pub format: Format,
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
        if self.format != Format::Safetensors {
            s += &format!(", read from {}", self.format);
        }
        s
    }
}

fn show_prefix(p: &str) -> String {
    if p.is_empty() {
        "no prefix".into()
    } else {
        format!("prefix {}", quote(p))
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
    load_with(path, prefix, None)
}

/// [`load`], with the duty levels `given` for a network whose file records none
/// ([`levels`](crate::levels)).
pub fn load_with(path: &Path, prefix: Option<&str>, given: Option<&GivenLevels>) -> Result<Import> {
    let file = policy_file(path);
    let bytes = read_capped(&file, MAX_POLICY_BYTES)?;
    import_with(&bytes, prefix, given).map_err(|e| match e {
        Error::Input(m) => Error::Input(format!("{}: {m}", crate::shown(&file))),
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

/// Finds the 4-H-H-A network in a checkpoint's `bytes` (any of the module's formats);
/// `prefix` chooses among several.
pub fn import(bytes: &[u8], prefix: Option<&str>) -> Result<Import> {
    import_with(bytes, prefix, None)
}

/// [`import`], with the duty levels `given` for a network whose file records none
/// ([`levels`](crate::levels)).
pub fn import_with(
    bytes: &[u8],
    prefix: Option<&str>,
    given: Option<&GivenLevels>,
) -> Result<Import> {
    let found = Found {
        prefix,
        given,
        metadata: BTreeMap::new(),
    };
    if bytes.starts_with(b"PK") {
        let (dict, format) = torch::read(bytes)?;
        return from_dict(&dict, found, format);
    }
    if let [0x80, 2..=5, 0x8a, ..] = bytes {
        return Err(Error::Input(
            "a PyTorch file in the legacy format (before PyTorch 1.6); save it again with \
             torch.save, whose zip format is read"
                .into(),
        ));
    }
    // Safetensors' JSON header starts at byte 8; an ONNX model with its IR version (field 1,
    // varint: byte 0x08).
    if bytes.first() == Some(&0x08) && bytes.get(8) != Some(&b'{') {
        if let Some(p) = prefix.filter(|p| !p.is_empty()) {
            return Err(Error::Input(format!(
                "an ONNX model holds one network; --prefix {} does not apply",
                quote(p)
            )));
        }
        return onnx::import(bytes, given);
    }
    let (dict, metadata) = safetensors_file::read(bytes).map_err(|e| match e {
        Error::Input(m) if bytes.get(8) != Some(&b'{') => Error::Input(format!(
            "expected a safetensors file, a PyTorch zip (torch.save: .pt, .pth, \
             .cleanrl_model), a Stable-Baselines3 model.zip or an ONNX model; {m}"
        )),
        other => other,
    })?;
    from_dict(&dict, Found { metadata, ..found }, Format::Safetensors)
}

/// What finding a network in a state dict goes by: the prefix asked for, the levels given,
/// the file's metadata.
struct Found<'a> {
    prefix: Option<&'a str>,
    given: Option<&'a GivenLevels>,
    metadata: BTreeMap<String, String>,
}

/// Finds the 4-H-H-A network among a state dict's tensors.
fn from_dict(dict: &StateDict, found: Found, format: Format) -> Result<Import> {
    let Found {
        prefix,
        given,
        metadata,
    } = found;
    let names: Vec<&str> = dict.keys().map(|k| k.as_ref()).collect();
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
        .map(|(p, layers)| (*p, chain(dict, layers)))
        .collect();
    let (pre, layers) = select(&checked, prefix)?;
    let group = &groups[pre];
    let own: Vec<&str> = layers
        .iter()
        .flat_map(|k| [group[k].weight, group[k].bias])
        .flatten()
        .collect();
    let outside: Vec<&str> = names.iter().copied().filter(|n| !own.contains(n)).collect();
    // The chain's first layer is [H, 4]: a width no network has is refused before any
    // tensor is converted, so no view is materialised beyond the largest network's.
    let (width, outputs) = (dict[own[0]].shape[0], dict[own[4]].shape[0]);
    check_shape(width, outputs).map_err(|e| match e {
        Error::Input(m) => Error::Input(format!("{}: {m}", show_prefix(pre))),
        other => other,
    })?;
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
        let (values, from) = to_f32(name, &dict[*name])?;
        converted_from = converted_from.or(from);
        *t = values;
    }
    let levels = levels::of_file(&metadata, outputs, given)?;
    let weights = checked_weights(tensors, levels, &own)?;
    Ok(Import {
        weights,
        prefix: pre.to_string(),
        layers: layers.map(str::to_string),
        ignored: outside.len(),
        converted_from,
        metadata,
        format,
    })
}

/// The network of `tensors` (canonical order, named `names` in the file) on `levels`, with
/// finite Q-values.
fn checked_weights(tensors: [Vec<f32>; 6], levels: Vec<f32>, names: &[&str]) -> Result<Weights> {
    let width = tensors[1].len();
    let weights = Weights::new(width, levels, tensors).map_err(|e| match e {
        Error::Input(m) => Error::Input(rename(&m, names)),
        other => other,
    })?;
    weights.check_outputs()?;
    Ok(weights)
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
            None => Err(Error::Input(format!(
                "no tensors under prefix {} (prefixes found: {})",
                quote(p),
                few(checked.iter().map(|(p, _)| shell_word(p)), 8)
            ))),
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
                "no 4-H-H-A network found (three linear layers [H, {OBS_DIM}] -> [H, H] -> \
                 [A, H], A one output per duty level); {}",
                why.join("; ")
            )))
        }
        ref many => Err(Error::Input(format!(
            "{} networks found, under the prefixes {}; choose one with --prefix (e.g. \
             --prefix {})",
            many.len(),
            few(many.iter().map(|(p, _)| shell_word(p)), 8),
            shell_word(many[0].0)
        ))),
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
        m = m.replace(&format!("`{canonical}`"), &quote(name));
    }
    m
}

/// The group's three layers in order if they chain `[H, 4] -> [H, H] -> [2, H]`, or why not.
/// The order is the names' natural order (`fc1 < fc2 < fc10`, `0 < 2 < 4`); names that do not
/// sort that way (`input`, `hidden`, `output`) are ordered by the one chain their shapes form.
fn chain<'a>(
    dict: &StateDict,
    layers: &BTreeMap<&'a str, Layer<'a>>,
) -> std::result::Result<[&'a str; 3], String> {
    let mut order: Vec<&str> = layers.keys().copied().collect();
    order.sort_by(|a, b| natural(a, b));
    let [a, b, c] = order[..] else {
        return Err(format!(
            "{} layers ({}), expected 3 linear layers",
            order.len(),
            few(order.iter().map(|l| quote(l)), 6)
        ));
    };
    let mut dims = BTreeMap::new();
    for key in [a, b, c] {
        let l = &layers[key];
        if let Some(o) = l.other.first() {
            return Err(format!(
                "{} is not a linear layer's weight or bias",
                quote(o)
            ));
        }
        let (Some(w), Some(bias)) = (l.weight, l.bias) else {
            let missing = if l.weight.is_none() { "weight" } else { "bias" };
            return Err(format!("layer {} lacks its {missing}", quote(key)));
        };
        let (ws, bs) = (&dict[w].shape, &dict[bias].shape);
        let [out, inp] = ws[..] else {
            return Err(format!(
                "{} has shape {}, expected [out, in]",
                quote(w),
                shape_text(ws)
            ));
        };
        if bs[..] != [out] {
            return Err(format!(
                "{} has shape {}, expected [{out}] to match {}",
                quote(bias),
                shape_text(bs),
                quote(w)
            ));
        }
        dims.insert(key, (w, out, inp));
    }
    let why = |[a, b, c]: [&str; 3]| unchained([dims[a], dims[b], dims[c]]);
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

/// Why three linear layers `(weight name, out, in)`, in this order, are not a 4-H-H-2
/// network, if they are not.
fn unchained(layers: [(&str, usize, usize); 3]) -> Option<String> {
    let [(w1, h1, i1), (w2, h2, i2), (w3, o3, i3)] = layers;
    let (w1, w2, w3) = (quote(w1), quote(w2), quote(w3));
    if i1 != OBS_DIM {
        Some(format!(
            "{w1} is [{h1}, {i1}]: the first layer takes the {OBS_DIM} observations"
        ))
    } else if i2 != h1 || i3 != h2 {
        Some(format!(
            "the layers do not chain: {w1} [{h1}, {i1}], {w2} [{h2}, {i2}], {w3} [{o3}, {i3}]"
        ))
    } else if h1 != h2 {
        Some(format!(
            "hidden widths {h1} and {h2} differ; the network has two hidden layers of one \
             width"
        ))
    } else if o3 < 2 {
        Some(format!(
            "{w3} is [{o3}, {i3}]: the output layer has one output per duty level, at least two"
        ))
    } else {
        None
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

#[cfg(test)]
mod tests;
