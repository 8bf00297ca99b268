//! PyTorch's zip (`torch.save`): `<dir>/data.pkl`, the pickled state dict, and
//! `<dir>/data/<key>`, each storage's raw elements; and Stable-Baselines3's `model.zip`,
//! which holds such a zip as `policy.pth`. Everything is read in place: a tensor is a view
//! of its storage's bytes in the file until the network's six are converted.

use std::borrow::Cow;

use super::Format;
use super::pickle;
use super::state_dict::{Data, Dtype, StateDict, Tensor};
use super::zip::Zip;
use crate::{Error, QUOTE_MAX, Result, quote};

fn refuse<T>(why: String) -> Result<T> {
    Err(Error::Input(why))
}

/// The state dict in a PyTorch or Stable-Baselines3 zip, and which of the two it was.
pub fn read(bytes: &[u8]) -> Result<(StateDict<'_>, Format)> {
    let zip = Zip::open(bytes)?;
    if let Some(dir) = pickle_dir(&zip)? {
        return Ok((state_dict(&zip, dir)?, Format::TorchZip));
    }
    if !zip.has(&["policy.pth"]) {
        return refuse(format!(
            "a zip file, but neither PyTorch's (no data.pkl) nor a Stable-Baselines3 \
             model.zip (no policy.pth); it holds {}",
            zip.listing()
        ));
    }
    let inner = zip.read(&["policy.pth"])?;
    let in_policy = |e: Error| match e {
        Error::Input(m) => Error::Input(format!("policy.pth in the model.zip: {m}")),
        other => other,
    };
    let policy = Zip::open(inner).map_err(in_policy)?;
    let Some(dir) = pickle_dir(&policy)? else {
        return refuse("policy.pth in the model.zip is not a PyTorch zip (no data.pkl)".into());
    };
    let dict = state_dict(&policy, dir).map_err(in_policy)?;
    Ok((dict, Format::Sb3Zip))
}

/// The folder holding `data.pkl` (`archive/` since PyTorch 2.x, the file's stem before),
/// if there is exactly one.
fn pickle_dir<'a>(zip: &Zip<'a>) -> Result<Option<&'a str>> {
    let mut dirs = zip
        .names()
        .filter_map(|n| n.strip_suffix(b"data.pkl"))
        .filter(|d| d.is_empty() || d.ends_with(b"/"));
    match (dirs.next(), dirs.count()) {
        (None, _) => Ok(None),
        // Every storage's name starts with the folder's: a short one keeps each lookup short.
        (Some(one), 0) => match std::str::from_utf8(one) {
            Ok(dir) if dir.len() <= QUOTE_MAX => Ok(Some(dir)),
            _ => refuse(format!(
                "a PyTorch zip whose data.pkl is in a folder of {} bytes, expected a UTF-8 name \
                 of at most {QUOTE_MAX}",
                one.len()
            )),
        },
        (Some(_), more) => refuse(format!(
            "a PyTorch zip with {} data.pkl files, expected one",
            more + 1
        )),
    }
}

fn state_dict<'a>(zip: &Zip<'a>, dir: &str) -> Result<StateDict<'a>> {
    // A zip without the entry is read as little-endian.
    let big_endian = match zip.has(&[dir, "byteorder"]) {
        false => false,
        true => match zip.read(&[dir, "byteorder"])? {
            b"little" => false,
            b"big" => true,
            b => {
                return refuse(format!(
                    "a PyTorch zip of byte order {}, expected \"little\" or \"big\"",
                    quote(&String::from_utf8_lossy(b))
                ));
            }
        },
    };
    let refs = pickle::state_dict(zip.read(&[dir, "data.pkl"])?)?;
    let mut dict = StateDict::new();
    for (name, r) in refs {
        // PyTorch's keys are decimal numbers; a bounded key keeps each lookup short.
        if r.key.len() > QUOTE_MAX {
            return refuse(format!(
                "tensor {}: a storage key of {} bytes, expected at most {QUOTE_MAX}",
                quote(name),
                r.key.len()
            ));
        }
        let storage = zip.read(&[dir, "data/", r.key])?;
        let size = r.dtype.map_or_else(|(_, size)| size, Dtype::size);
        if Some(storage.len())
            != usize::try_from(r.numel)
                .ok()
                .and_then(|n| n.checked_mul(size))
        {
            return refuse(format!(
                "tensor {}: its storage {} holds {} bytes, expected {} elements of {size} bytes",
                quote(name),
                quote(r.key),
                storage.len(),
                r.numel
            ));
        }
        let tensor = Tensor {
            dtype: r.dtype.map_err(|(name, _)| name.to_string()),
            shape: r.shape,
            data: Data::View {
                storage,
                big_endian,
                offset: usize::try_from(r.offset).unwrap_or(usize::MAX),
                stride: r.stride,
            },
        };
        if dict.insert(Cow::Borrowed(name), tensor).is_some() {
            return refuse(format!("tensor {} appears twice", quote(name)));
        }
    }
    Ok(dict)
}
