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

mod choose;
pub mod onnx;
pub mod pickle;
mod protobuf;
mod safetensors_file;
pub mod state_dict;
mod torch;
mod zip;

use std::collections::BTreeMap;
use std::path::Path;

use firmware::network::TENSOR_NAMES;

pub use choose::{Chosen, choose};
pub use safetensors_file::{MAX_HEADER_BYTES, to_safetensors};
use state_dict::{StateDict, to_f32};

use crate::files::{MAX_POLICY_BYTES, read_capped};
use crate::levels::{self, GivenLevels};
use crate::{Error, Result, Weights, quote};

/// The metadata key under which the trainer records its network's hidden width.
pub const WIDTH_KEY: &str = "width";

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
    /// One line for a log: `layers "0", "2", "4" under prefix "network.", hidden width 64`.
    /// The names are the file's, so each is quoted: a layer named with a line break or an
    /// escape sequence cannot forge a line or move a terminal's cursor.
    pub fn describe(&self) -> String {
        let layers: Vec<String> = self.layers.iter().map(|l| quote(l)).collect();
        let mut s = format!(
            "layers {} under {}, hidden width {}",
            layers.join(", "),
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
    let chosen = choose(&names, |n| &dict[n].shape, prefix)?;
    let mut tensors: [Vec<f32>; 6] = Default::default();
    let mut converted_from = None;
    for (t, name) in tensors.iter_mut().zip(&chosen.tensors) {
        let (values, from) = to_f32(name, &dict[*name])?;
        converted_from = converted_from.or(from);
        *t = values;
    }
    let levels = levels::of_file(&metadata, chosen.outputs, given)?;
    let weights = checked_weights(tensors, levels, &chosen.tensors)?;
    width_agrees(&metadata, weights.width())?;
    Ok(Import {
        weights,
        prefix: chosen.prefix.to_string(),
        layers: chosen.layers.map(str::to_string),
        ignored: chosen.ignored,
        converted_from,
        metadata,
        format,
    })
}

/// Refuses a file whose recorded width is not its tensors': a file edited, or put together
/// from two, whose metadata no longer describes its network.
fn width_agrees(metadata: &BTreeMap<String, String>, width: usize) -> Result<()> {
    match metadata.get(WIDTH_KEY) {
        // As the trainer writes it: `+64`, `064` or `64 ` name the same width only by a
        // lenient reading.
        Some(w) if *w != width.to_string() => Err(Error::Input(format!(
            "the file's metadata `{WIDTH_KEY}` is {}, expected {width}, the width of its tensors",
            quote(w)
        ))),
        _ => Ok(()),
    }
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

/// Messages from [`Weights::new`] name the canonical tensors; say the checkpoint's names.
fn rename(msg: &str, own: &[&str]) -> String {
    let mut m = msg.to_string();
    for (canonical, name) in TENSOR_NAMES.iter().zip(own) {
        m = m.replace(&format!("`{canonical}`"), &quote(name));
    }
    m
}

#[cfg(test)]
mod tests;
