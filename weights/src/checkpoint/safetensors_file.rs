//! Safetensors files: reading one into a state dict, and the trainer's canonical file.

use std::borrow::Cow;
use std::collections::BTreeMap;

use firmware::network::TENSOR_NAMES;
use safetensors::tensor::{Dtype as StDtype, Metadata, SafeTensors, TensorView};

use super::state_dict::{Data, Dtype, StateDict, Tensor};
use crate::levels::LEVELS_KEY;
use crate::{Error, Result, Weights, excerpt};

/// Largest safetensors header read. The header is JSON listing every tensor; a few hundred
/// bytes per tensor, so this allows thousands while bounding the memory a hostile file costs.
pub const MAX_HEADER_BYTES: u64 = 1 << 20;

/// The state dict in safetensors `bytes`, borrowing its data, and the header's
/// `__metadata__` (the trainer writes its configuration there). The header is parsed once:
/// the safetensors crate's parse holds about 16 bytes per header byte while it runs, which
/// [`MAX_HEADER_BYTES`] bounds.
pub fn read(bytes: &[u8]) -> Result<(StateDict<'_>, BTreeMap<String, String>)> {
    let (n, header) = parse(bytes)?;
    let data = &bytes[8 + n..];
    let metadata = header
        .metadata()
        .as_ref()
        .map(|m| m.iter().map(|(k, v)| (k.clone(), v.clone())).collect())
        .unwrap_or_default();
    let dict = header
        .tensors()
        .into_iter()
        .map(|(name, t)| {
            let dtype = match t.dtype {
                StDtype::F32 => Ok(Dtype::F32),
                StDtype::F64 => Ok(Dtype::F64),
                StDtype::F16 => Ok(Dtype::F16),
                StDtype::BF16 => Ok(Dtype::BF16),
                other => Err(format!("{other:?}")),
            };
            let tensor = Tensor {
                dtype,
                shape: t.shape.as_slice().into(),
                data: Data::Dense(Cow::Borrowed(&data[t.data_offsets.0..t.data_offsets.1])),
            };
            (Cow::Owned(name), tensor)
        })
        .collect();
    Ok((dict, metadata))
}

/// Checks the header's size before the safetensors crate parses it (and checks that the
/// tensors' offsets tile the data).
fn parse(bytes: &[u8]) -> Result<(usize, Metadata)> {
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
    // The header is JSON, which the safetensors crate reads into maps where the last of a
    // key given twice (a tensor, `levels`, `rig`) wins without a word: weighed first, such
    // a header is refused.
    let declared = |what: String| {
        Error::Input(format!(
            "not a safetensors file: its header declares {len} bytes, {what}"
        ))
    };
    match bytes.get(8..8 + len as usize).map(std::str::from_utf8) {
        None => {
            let after = bytes.len() - 8;
            return Err(declared(format!("more than the {after} after its length")));
        }
        // The declared length runs past the JSON into the tensors' bytes.
        Some(Err(e)) => {
            let at = e.valid_up_to();
            return Err(declared(format!(
                "and byte {at} of them is not UTF-8 text: expected the header's JSON alone, \
                 found a header whose length runs into the data, or another kind of file"
            )));
        }
        Some(Ok(text)) => {
            crate::json::weight(text)
                .map_err(|e| Error::Input(format!("not a safetensors file: its header: {e}")))?;
        }
    }
    SafeTensors::read_metadata(bytes).map_err(|e| {
        Error::Input(format!(
            "not a safetensors file: {}",
            excerpt(&e.to_string())
        ))
    })
}

/// The trainer's canonical file: tensors `fc1.weight` ... `fc3.bias` in f32, `metadata` in
/// the header's `__metadata__` with the levels under [`LEVELS_KEY`] where they are not the
/// paper's, header keys sorted so the same weights and metadata always give the same bytes.
pub fn to_safetensors(w: &Weights, metadata: &BTreeMap<String, String>) -> Result<Vec<u8>> {
    let shapes = firmware::network::shapes(w.width(), w.outputs());
    let mut metadata = metadata.clone();
    if w.levels() != crate::BANG_BANG {
        let levels = serde_json::to_string(w.levels()).expect("finite floats");
        metadata.insert(LEVELS_KEY.into(), levels);
    }
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
            TensorView::new(StDtype::F32, shape.dims().to_vec(), data)
                .map(|v| (*name, v))
                .map_err(|e| Error::Io(format!("tensor `{name}`: {e}")))
        })
        .collect::<Result<Vec<_>>>()?;
    let meta = (!metadata.is_empty()).then(|| metadata.into_iter().collect());
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
