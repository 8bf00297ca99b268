//! PyTorch's zip (`torch.save`): `<dir>/data.pkl`, the pickled state dict, and
//! `<dir>/data/<key>`, each storage's raw elements; and Stable-Baselines3's `model.zip`,
//! which holds such a zip as `policy.pth`.

use std::borrow::Cow;
use std::io::{Cursor, Read};

use zip::ZipArchive;

use super::Format;
use super::pickle::{self, TensorRef};
use super::state_dict::{StateDict, Tensor};
use crate::files::MAX_POLICY_BYTES;
use crate::{Error, Result, excerpt, quote};

type Archive<'a> = ZipArchive<Cursor<&'a [u8]>>;

fn refuse<T>(why: String) -> Result<T> {
    Err(Error::Input(why))
}

/// The state dict in a PyTorch or Stable-Baselines3 zip, and which of the two it was.
pub fn read(bytes: &[u8]) -> Result<(StateDict<'static>, Format)> {
    let mut zip = open(bytes)?;
    if let Some(dir) = pickle_dir(&zip)? {
        return Ok((state_dict(&mut zip, &dir)?, Format::TorchZip));
    }
    if zip.index_for_name("policy.pth").is_none() {
        return refuse(format!(
            "a zip file, but neither PyTorch's (no data.pkl) nor a Stable-Baselines3 \
             model.zip (no policy.pth); it holds {}",
            listing(&zip)
        ));
    }
    let inner = entry(&mut zip, "policy.pth")?;
    let mut policy = open(&inner)?;
    let Some(dir) = pickle_dir(&policy)? else {
        return refuse("policy.pth in the model.zip is not a PyTorch zip (no data.pkl)".into());
    };
    let dict = state_dict(&mut policy, &dir)
        .map_err(|e| Error::Input(format!("policy.pth in the model.zip: {e}")))?;
    Ok((dict, Format::Sb3Zip))
}

fn open(bytes: &[u8]) -> Result<Archive<'_>> {
    ZipArchive::new(Cursor::new(bytes)).or_else(|e| {
        refuse(format!(
            "not a readable zip file: {}",
            excerpt(&e.to_string())
        ))
    })
}

/// A few of the archive's names, for a message.
fn listing(zip: &Archive) -> String {
    let names: Vec<String> = zip
        .file_names()
        .take(5)
        .map(|n| n.map_or("(undecodable)".into(), |n| quote(&n)))
        .collect();
    match zip.len() {
        0 => "nothing".into(),
        n if n > 5 => format!("{} and {} more", names.join(", "), n - 5),
        _ => names.join(", "),
    }
}

/// The folder holding `data.pkl` (`archive/` since PyTorch 2.x, the file's stem before),
/// if there is exactly one.
fn pickle_dir(zip: &Archive) -> Result<Option<String>> {
    let dirs: Vec<String> = zip
        .file_names()
        .filter_map(|n| Some(n.ok()?.strip_suffix("data.pkl")?.to_string()))
        .filter(|d| d.is_empty() || d.ends_with('/'))
        .collect();
    match dirs[..] {
        [] => Ok(None),
        [ref one] => Ok(Some(one.clone())),
        _ => refuse(format!(
            "a PyTorch zip with {} data.pkl files, expected one",
            dirs.len()
        )),
    }
}

/// One entry's bytes, at most [`MAX_POLICY_BYTES`] of them whatever its header claims.
fn entry(zip: &mut Archive, name: &str) -> Result<Vec<u8>> {
    let file = zip.by_name(name).or_else(|e| {
        refuse(format!(
            "zip entry {}: {}",
            quote(name),
            excerpt(&e.to_string())
        ))
    })?;
    let mut out = Vec::new();
    file.take(MAX_POLICY_BYTES + 1)
        .read_to_end(&mut out)
        .or_else(|e| {
            refuse(format!(
                "zip entry {}: {}",
                quote(name),
                excerpt(&e.to_string())
            ))
        })?;
    if out.len() as u64 > MAX_POLICY_BYTES {
        return refuse(format!(
            "zip entry {} holds more than {MAX_POLICY_BYTES} bytes",
            quote(name)
        ));
    }
    Ok(out)
}

fn state_dict(zip: &mut Archive, dir: &str) -> Result<StateDict<'static>> {
    let order = format!("{dir}byteorder");
    if zip.index_for_name(&order).is_some() {
        let b = entry(zip, &order)?;
        if b != b"little" {
            return refuse(format!(
                "a PyTorch zip of byte order {}, expected \"little\"",
                quote(&String::from_utf8_lossy(&b))
            ));
        }
    }
    let refs = pickle::state_dict(&entry(zip, &format!("{dir}data.pkl"))?)?;
    let mut storages: Vec<(String, Vec<u8>)> = Vec::new();
    let mut dict = StateDict::new();
    for (name, r) in refs {
        if !storages.iter().any(|(k, _)| *k == r.key) {
            let data = entry(zip, &format!("{dir}data/{}", r.key))?;
            storages.push((r.key.clone(), data));
        }
        let (_, storage) = storages
            .iter()
            .find(|(k, _)| *k == r.key)
            .expect("just read");
        let tensor = gather(&r, storage).map_err(|e| match e {
            Error::Input(m) => Error::Input(format!("tensor {}: {m}", quote(&name))),
            other => other,
        })?;
        if dict.insert(name.clone(), tensor).is_some() {
            return refuse(format!("tensor {} appears twice", quote(&name)));
        }
    }
    Ok(dict)
}

/// The tensor's elements in row-major order, read through its offset and strides.
fn gather(r: &TensorRef, storage: &[u8]) -> Result<Tensor<'static>> {
    let size = r.dtype.size();
    if Some(storage.len())
        != usize::try_from(r.numel)
            .ok()
            .and_then(|n| n.checked_mul(size))
    {
        return refuse(format!(
            "its storage {} holds {} bytes, expected {} elements of {size} bytes",
            quote(&r.key),
            storage.len(),
            r.numel
        ));
    }
    let count = r.shape.iter().try_fold(1u64, |n, &d| n.checked_mul(d));
    let shape: Option<Vec<usize>> = r.shape.iter().map(|&d| usize::try_from(d).ok()).collect();
    let (Some(count), Some(shape)) = (count.filter(|&c| c <= r.numel), shape) else {
        return refuse(format!(
            "shape {:?} has more elements than its storage's {}",
            r.shape, r.numel
        ));
    };
    let mut data = Vec::with_capacity(count as usize * size);
    let mut index = vec![0u64; r.shape.len()];
    for _ in 0..count {
        let at = index
            .iter()
            .zip(&r.stride)
            .try_fold(r.offset, |a, (&i, &s)| a.checked_add(i.checked_mul(s)?))
            .filter(|&a| a < r.numel);
        let Some(at) = at else {
            return refuse(format!(
                "offset {} and strides {:?} reach past its storage of {} elements",
                r.offset, r.stride, r.numel
            ));
        };
        let start = at as usize * size;
        data.extend_from_slice(&storage[start..start + size]);
        // The next row-major index: the last dimension fastest.
        for (i, &d) in index.iter_mut().zip(&r.shape).rev() {
            *i += 1;
            if *i < d {
                break;
            }
            *i = 0;
        }
    }
    Ok(Tensor {
        dtype: Ok(r.dtype),
        shape,
        data: Cow::Owned(data),
    })
}
