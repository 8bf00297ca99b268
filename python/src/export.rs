//! `policy-export export` for Python: the same steps as the command, from a policy file or
//! from tensors handed over in memory (a state dict's arrays, serialised as safetensors and
//! read by the same `weights::checkpoint` code as a file), written atomically. Of a state
//! dict only the network's six tensors are converted: the importer chooses them from the
//! names and shapes alone.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use policy_export::export::{self as exporter, Language};
use pyo3::prelude::*;
use safetensors::tensor::{Dtype, TensorView};
use weights::checkpoint::{self, Import};
use weights::files::{check_io, write_atomic};
use weights::levels::GivenLevels;
use weights::quant::Granularity;

use crate::{file_error, value_error};

/// One tensor handed over from Python: safetensors dtype name, shape, little-endian bytes.
type Tensor = (String, Vec<usize>, Vec<u8>);

/// A state dict's tensors' shapes, by name.
type Shapes = BTreeMap<String, Vec<usize>>;

/// Writes the network of `path` (a policy file or run directory) or of a state dict to
/// `out` as Rust (`fmt` `rust`) or C (`c`) source, int8-quantised with `quant` `int8`, under
/// `name` (the command's defaults), for the rig file `rig` (without one, the rig the file
/// records, or Gymnasium's). A state dict is its tensors' `shapes`, and `tensor`, which gives
/// one by name as a [`Tensor`]. `label` names a state dict in the provenance comment, as a
/// file's name does; `levels` are the duty levels of a network whose source records none
/// (`weights::levels`). Returns the provenance's description of the network.
#[pyfunction]
#[pyo3(signature = (out, fmt, path=None, shapes=None, tensor=None, label=None, quant=None, name=None, rig=None, prefix=None, granularity=None, levels=None))]
// One argument per keyword of the Python function (`cartpole_ddqn.export`).
#[allow(clippy::too_many_arguments)]
pub fn export(
    py: Python<'_>,
    out: PathBuf,
    fmt: &str,
    path: Option<PathBuf>,
    shapes: Option<Shapes>,
    tensor: Option<Bound<'_, PyAny>>,
    label: Option<&str>,
    quant: Option<&str>,
    name: Option<String>,
    rig: Option<PathBuf>,
    prefix: Option<&str>,
    granularity: Option<&str>,
    levels: Option<Vec<f64>>,
) -> PyResult<String> {
    let (lang, int, granularity) = arithmetic(fmt, quant, granularity)?;
    let name = name.unwrap_or_else(|| exporter::default_name(lang, int).to_string());
    exporter::check_name(lang, &name).map_err(value_error)?;
    let levels = crate::given_levels(levels)?;
    let found = Found {
        prefix,
        levels: levels.as_ref(),
        rig: rig.as_deref(),
        out: &out,
    };
    let label = label.unwrap_or("state dict");
    let (import, provenance, source) = match (&path, shapes, tensor) {
        (Some(p), None, None) => {
            let (import, provenance) = from_file(p, &found)?;
            (import, provenance, format!("source {}", weights::shown(p)))
        }
        (None, Some(s), Some(t)) => {
            let (import, provenance) = from_tensors(&s, &t, label, &found)?;
            (import, provenance, weights::quote(label))
        }
        _ => {
            return Err(value_error(
                "expected a policy file's path or a state dict as the source",
            ));
        }
    };
    let (machine, other) = exporter::machine(&import, &source, rig.as_deref())
        .map_err(|e| value_error(format!("{e:#}")))?;
    crate::warn_other_rig(py, other)?;
    let r = exporter::render(
        &import,
        &provenance,
        &machine,
        lang,
        int.then_some(granularity),
        &name,
    )
    .map_err(|e| value_error(format!("{e:#}")))?;
    // What the command line warns of a run's policy; before writing, so that a warning
    // raised as an error (`-W error`) leaves no file behind.
    for w in path
        .as_deref()
        .map(policy_export::run::board_warnings)
        .unwrap_or_default()
    {
        crate::warn(py, w.strip_prefix("warning: ").unwrap_or(&w))?;
    }
    write_atomic(&out, r.text.as_bytes()).map_err(file_error)?;
    Ok(import.describe())
}

/// The language, whether int8, and the int8 weights' granularity `export`'s keywords ask for.
fn arithmetic(
    fmt: &str,
    quant: Option<&str>,
    granularity: Option<&str>,
) -> PyResult<(Language, bool, Granularity)> {
    let lang = match fmt {
        "rust" => Language::Rust,
        "c" => Language::C,
        _ => {
            return Err(value_error(format!(
                "fmt must be \"rust\" or \"c\"; found {fmt:?}"
            )));
        }
    };
    let int = match quant {
        None => false,
        Some("int8") => true,
        Some(q) => {
            return Err(value_error(format!(
                "quant must be None or \"int8\"; found {q:?}"
            )));
        }
    };
    let granularity = match (granularity, int) {
        (None, _) => Granularity::default(),
        // It chooses how int8 weights share a scale: without quant it would change nothing,
        // and the command refuses --granularity without --quant.
        (Some(g), false) => {
            return Err(value_error(format!(
                "granularity needs quant=\"int8\" (it chooses how int8 weights share a \
                 scale); found granularity={g:?} without quant"
            )));
        }
        (Some("per-channel"), true) => Granularity::PerChannel,
        (Some("per-tensor"), true) => Granularity::PerTensor,
        (Some(g), true) => {
            return Err(value_error(format!(
                "granularity must be \"per-channel\" or \"per-tensor\"; found {g:?}"
            )));
        }
    };
    Ok((lang, int, granularity))
}

/// What finding the network goes by: the prefix and levels given, and the rig and output
/// files, checked before it is read.
struct Found<'a> {
    prefix: Option<&'a str>,
    levels: Option<&'a GivenLevels>,
    rig: Option<&'a Path>,
    out: &'a Path,
}

/// The network of a policy file and its provenance, the inputs and `out` checked first.
fn from_file(src: &Path, f: &Found) -> PyResult<(Import, Vec<String>)> {
    let read = policy_export::run::export_inputs(src);
    let mut inputs: Vec<(&str, &Path)> = read.iter().map(|p| ("source", p.as_path())).collect();
    inputs.extend(f.rig.map(|r| ("rig", r)));
    check_io(&inputs, &[("out", f.out)]).map_err(file_error)?;
    let import = checkpoint::load_with(src, f.prefix, f.levels).map_err(file_error)?;
    // As the command's exit status tells them apart: a summary refused, or one the system
    // failed to read.
    let provenance = policy_export::run::source_provenance(src, &import).map_err(|e| {
        match e.downcast::<weights::Error>() {
            Ok(e) => file_error(e),
            Err(e) => value_error(format!("{e:#}")),
        }
    })?;
    Ok((import, provenance))
}

/// The network of a state dict and its provenance, as a file named `label` would give. The
/// importer's own rules choose the network from the names and shapes alone
/// (`weights::checkpoint::choose`); only its six tensors are asked of `tensor` and imported,
/// so a tensor outside the network is never converted, however large.
fn from_tensors(
    shapes: &Shapes,
    tensor: &Bound<'_, PyAny>,
    label: &str,
    f: &Found,
) -> PyResult<(Import, Vec<String>)> {
    let inputs: Vec<(&str, &Path)> = f.rig.map(|r| ("rig", r)).into_iter().collect();
    check_io(&inputs, &[("out", f.out)]).map_err(file_error)?;
    let names: Vec<&str> = shapes.keys().map(String::as_str).collect();
    let chosen =
        checkpoint::choose(&names, |n| shapes[n].as_slice(), f.prefix).map_err(value_error)?;
    let mut tensors = BTreeMap::new();
    for name in chosen.tensors {
        let t: Tensor = tensor.call1((name,))?.extract()?;
        tensors.insert(name.to_string(), t);
    }
    let import = checkpoint::import_with(&safetensors(&tensors)?, Some(chosen.prefix), f.levels)
        .map_err(value_error)?;
    // The tensors outside the network were left out of the second choice, not of the first.
    let import = Import {
        ignored: chosen.ignored,
        ..import
    };
    let provenance = vec![format!("source: {label} ({})", import.describe())];
    Ok((import, provenance))
}

/// `tensors` as a safetensors file, which the importer reads as it reads one from disk.
fn safetensors(tensors: &BTreeMap<String, Tensor>) -> PyResult<Vec<u8>> {
    let views = tensors
        .iter()
        .map(|(n, (dtype, shape, data))| {
            let dtype = match dtype.as_str() {
                "F32" => Dtype::F32,
                "F64" => Dtype::F64,
                "F16" => Dtype::F16,
                "BF16" => Dtype::BF16,
                d => {
                    return Err(value_error(format!(
                        "tensor {}: expected a float dtype (F32, F64, F16, BF16); found {}",
                        weights::quote(n),
                        weights::quote(d)
                    )));
                }
            };
            let view = TensorView::new(dtype, shape.clone(), data).map_err(|e| {
                value_error(format!(
                    "tensor {}: {}",
                    weights::quote(n),
                    weights::excerpt(&e.to_string())
                ))
            })?;
            Ok((n.as_str(), view))
        })
        .collect::<PyResult<Vec<_>>>()?;
    safetensors::tensor::serialize(views, None)
        .map_err(|e| value_error(weights::excerpt(&e.to_string())))
}
