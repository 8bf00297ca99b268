//! A trained policy's six tensors, independent of the compile-time width, and their
//! safetensors form (PyTorch names and shapes, f32, so `torch` and `safetensors` load it).

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use anyhow::{Context, Result, bail, ensure};
use firmware::network::{Mlp, N_ACTIONS, OBS_DIM, TENSOR_NAMES};
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

/// The parameters of a 4-H-H-2 network as flat row-major tensors in [`TENSOR_NAMES`] order.
#[derive(Clone, Debug, PartialEq)]
pub struct Weights {
    /// Hidden width H.
    pub width: usize,
    /// `fc1.weight`, `fc1.bias`, `fc2.weight`, `fc2.bias`, `fc3.weight`, `fc3.bias`.
    pub tensors: [Vec<f32>; 6],
}

impl Weights {
    /// Copies a network's parameters.
    pub fn from_mlp<const H: usize>(net: &Mlp<H>) -> Weights {
        Weights {
            width: H,
            tensors: net.tensors().map(<[f32]>::to_vec),
        }
    }

    /// The network, if the width is `H`.
    pub fn to_mlp<const H: usize>(&self) -> Result<Box<Mlp<H>>> {
        ensure!(
            self.width == H,
            "policy has hidden width {}, expected {H}",
            self.width
        );
        let mut net = Box::new(Mlp::<H>::zeroed());
        for (dst, src) in net.tensors_mut().into_iter().zip(&self.tensors) {
            dst.copy_from_slice(src);
        }
        Ok(net)
    }

    /// Shapes of the six tensors at this width.
    pub fn shapes(&self) -> [Vec<usize>; 6] {
        shapes(self.width)
    }

    /// Serialises to safetensors bytes; `metadata` lands in the header's `__metadata__`.
    pub fn to_safetensors(&self, metadata: &HashMap<String, String>) -> Result<Vec<u8>> {
        let shapes = self.shapes();
        let bytes: Vec<Vec<u8>> = self
            .tensors
            .iter()
            .map(|t| t.iter().flat_map(|v| v.to_le_bytes()).collect())
            .collect();
        let views = TENSOR_NAMES
            .iter()
            .zip(shapes)
            .zip(&bytes)
            .map(|((name, shape), data)| Ok((*name, TensorView::new(Dtype::F32, shape, data)?)))
            .collect::<Result<Vec<_>>>()?;
        let meta = (!metadata.is_empty()).then(|| metadata.clone());
        canonical_header(&safetensors::serialize(views, meta)?)
    }

    /// Parses safetensors bytes, checking every tensor's presence, dtype, shape and values.
    /// The width is read from `fc1.weight`.
    pub fn from_safetensors(bytes: &[u8]) -> Result<Weights> {
        let st = SafeTensors::deserialize(bytes).context("not a safetensors file")?;
        let fc1 = st.tensor("fc1.weight").map_err(|_| {
            anyhow::anyhow!("tensor `fc1.weight` is missing (expected f32 [H, {OBS_DIM}])")
        })?;
        let width = match fc1.shape() {
            [h, i] if *i == OBS_DIM && *h > 0 => *h,
            s => bail!("tensor `fc1.weight`: expected shape [H, {OBS_DIM}], found {s:?}"),
        };
        let expected = shapes(width);
        let mut tensors: [Vec<f32>; 6] = Default::default();
        for ((name, shape), out) in TENSOR_NAMES.iter().zip(&expected).zip(&mut tensors) {
            let t = st.tensor(name).map_err(|_| {
                anyhow::anyhow!("tensor `{name}` is missing (expected f32 {shape:?})")
            })?;
            ensure!(
                t.dtype() == Dtype::F32,
                "tensor `{name}`: expected dtype F32, found {:?}",
                t.dtype()
            );
            ensure!(
                t.shape() == shape.as_slice(),
                "tensor `{name}`: expected shape {shape:?}, found {:?}",
                t.shape()
            );
            *out = t
                .data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            if let Some(i) = out.iter().position(|v| !v.is_finite()) {
                bail!(
                    "tensor `{name}`: element {i} is {}, expected a finite value",
                    out[i]
                );
            }
        }
        Ok(Weights { width, tensors })
    }

    /// Reads a `.safetensors` file, or `policy.safetensors` inside a run directory.
    pub fn load(path: &Path) -> Result<Weights> {
        let file = if path.is_dir() {
            path.join("policy.safetensors")
        } else {
            path.to_path_buf()
        };
        let bytes = std::fs::read(&file).with_context(|| format!("reading {}", file.display()))?;
        Weights::from_safetensors(&bytes).with_context(|| format!("{}", file.display()))
    }
}

/// PyTorch shapes of the six tensors at hidden width `h`.
pub fn shapes(h: usize) -> [Vec<usize>; 6] {
    [
        vec![h, OBS_DIM],
        vec![h],
        vec![h, h],
        vec![h],
        vec![N_ACTIONS, h],
        vec![N_ACTIONS],
    ]
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so
/// a crash leaves either the old file or the new one, never half of one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let name = path.file_name().context("output path has no file name")?;
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("renaming onto {}", path.display()))
}

/// `bytes` with its JSON header's keys sorted. The safetensors crate writes the metadata (and
/// may write the tensor entries) in `HashMap` order, which differs from run to run; sorted,
/// the same weights and metadata always give the same file. The header stays padded with
/// spaces to a multiple of 8 bytes, as the format recommends; tensor offsets are relative to
/// the data, so they do not change.
fn canonical_header(bytes: &[u8]) -> Result<Vec<u8>> {
    let (len, rest) = bytes
        .split_first_chunk::<8>()
        .context("safetensors output shorter than its length prefix")?;
    let len = usize::try_from(u64::from_le_bytes(*len))?;
    let (header, data) = rest
        .split_at_checked(len)
        .context("safetensors header longer than the output")?;
    let mut fields: BTreeMap<String, serde_json::Value> = serde_json::from_slice(header)?;
    if let Some(meta) = fields.remove("__metadata__") {
        let meta: BTreeMap<String, String> = serde_json::from_value(meta)?;
        fields.insert("__metadata__".into(), serde_json::to_value(meta)?);
    }
    let mut header = serde_json::to_vec(&fields)?;
    header.resize(header.len().next_multiple_of(8), b' ');
    let mut out = Vec::with_capacity(8 + header.len() + data.len());
    out.extend_from_slice(&(header.len() as u64).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(data);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(width: usize) -> Weights {
        let tensors = shapes(width).map(|s| {
            let n: usize = s.iter().product();
            (0..n)
                .map(|i| (i as f32 * 0.37).sin() * 1e-3 + f32::from_bits(i as u32 + 1))
                .collect()
        });
        Weights { width, tensors }
    }

    #[test]
    fn the_same_weights_and_metadata_give_the_same_bytes() {
        let w = sample(16);
        // Each map hashes with its own random state, so its iteration order varies.
        let meta = || -> HashMap<String, String> {
            (0..12)
                .map(|i| (format!("key{i}"), format!("{i}")))
                .collect()
        };
        let first = w.to_safetensors(&meta()).unwrap();
        for _ in 0..10 {
            assert_eq!(w.to_safetensors(&meta()).unwrap(), first);
        }
        assert_eq!(u64::from_le_bytes(first[..8].try_into().unwrap()) % 8, 0);
        let st = SafeTensors::deserialize(&first).unwrap();
        assert_eq!(st.tensor("fc3.bias").unwrap().data().len(), 8);
        let (_, header) = SafeTensors::read_metadata(&first).unwrap();
        let keys: Vec<_> = header
            .metadata()
            .as_ref()
            .unwrap()
            .keys()
            .cloned()
            .collect();
        assert_eq!(keys.len(), 12);
        assert_eq!(
            Weights::from_safetensors(&first).unwrap().tensors,
            w.tensors
        );
    }

    #[test]
    fn safetensors_round_trip_is_bit_exact() {
        let w = sample(16);
        let bytes = w.to_safetensors(&HashMap::new()).unwrap();
        let back = Weights::from_safetensors(&bytes).unwrap();
        let bits = |w: &Weights| {
            w.tensors
                .clone()
                .map(|t| t.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
        };
        assert_eq!(bits(&back), bits(&w));
        assert_eq!(
            back.to_mlp::<16>().unwrap().tensors().map(<[f32]>::to_vec),
            w.tensors
        );
        assert!(back.to_mlp::<64>().is_err());
    }

    fn rewrite(f: impl FnOnce(&mut Vec<(String, Dtype, Vec<usize>, Vec<u8>)>)) -> String {
        let w = sample(8);
        let mut list: Vec<_> = TENSOR_NAMES
            .iter()
            .zip(w.shapes())
            .zip(&w.tensors)
            .map(|((n, s), t)| {
                (
                    n.to_string(),
                    Dtype::F32,
                    s,
                    t.iter().flat_map(|v| v.to_le_bytes()).collect(),
                )
            })
            .collect();
        f(&mut list);
        let views: Vec<_> = list
            .iter()
            .map(|(n, d, s, b)| (n.clone(), TensorView::new(*d, s.clone(), b).unwrap()))
            .collect();
        let bytes = safetensors::serialize(views, None).unwrap();
        format!("{:#}", Weights::from_safetensors(&bytes).unwrap_err())
    }

    #[test]
    fn bad_files_name_the_tensor_and_what_was_expected() {
        let e = rewrite(|l| {
            l.remove(3);
        });
        assert!(
            e.contains("`fc2.bias` is missing") && e.contains("[8]"),
            "{e}"
        );
        let e = rewrite(|l| {
            l[2].2 = vec![4, 16];
        });
        assert!(
            e.contains("`fc2.weight`: expected shape [8, 8], found [4, 16]"),
            "{e}"
        );
        let e = rewrite(|l| {
            l[5].1 = Dtype::I32;
        });
        assert!(
            e.contains("`fc3.bias`: expected dtype F32, found I32"),
            "{e}"
        );
        let e = rewrite(|l| {
            l[4].3[8..12].copy_from_slice(&f32::NAN.to_le_bytes());
        });
        assert!(e.contains("`fc3.weight`: element 2 is NaN"), "{e}");
        let e = rewrite(|l| {
            l[0].2 = vec![8, 5];
            l[0].3.extend_from_slice(&[0; 32]);
        });
        assert!(
            e.contains("`fc1.weight`: expected shape [H, 4], found [8, 5]"),
            "{e}"
        );
        assert!(Weights::from_safetensors(b"garbage").is_err());
    }

    #[test]
    fn atomic_write_replaces_whole_files() {
        let dir = std::env::temp_dir().join(format!("atomic-{}", std::process::id()));
        let p = dir.join("x.bin");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "no temporary left behind"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
