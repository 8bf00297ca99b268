//! A state dict as every checkpoint format reads into it: tensor names to dtype, shape and
//! little-endian bytes, whatever file they came from.

use std::borrow::Cow;
use std::collections::BTreeMap;

use crate::{Error, Result};

/// The float element types a network's tensors may be stored in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    /// IEEE binary32, taken as it is.
    F32,
    /// IEEE binary64, rounded to nearest f32.
    F64,
    /// IEEE binary16, widened exactly.
    F16,
    /// bfloat16, widened exactly.
    BF16,
}

impl Dtype {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            Dtype::F32 => 4,
            Dtype::F64 => 8,
            Dtype::F16 | Dtype::BF16 => 2,
        }
    }
}

/// One tensor of a state dict.
#[derive(Clone, Debug)]
pub struct Tensor<'a> {
    /// Its element type, or the name of one the importer does not read (an integer
    /// tensor is refused only if the network needs it).
    pub dtype: std::result::Result<Dtype, String>,
    /// Its shape.
    pub shape: Vec<usize>,
    /// Its elements, row-major, little-endian.
    pub data: Cow<'a, [u8]>,
}

/// Tensor names to tensors, sorted by name.
pub type StateDict<'a> = BTreeMap<String, Tensor<'a>>;

/// The tensor's values as f32, and the dtype they were converted from, if not F32.
pub fn to_f32(name: &str, t: &Tensor) -> Result<(Vec<f32>, Option<String>)> {
    let d = &t.data[..];
    let dtype = match &t.dtype {
        Ok(d) => *d,
        Err(other) => {
            return Err(Error::Input(format!(
                "tensor `{name}`: expected dtype F32 (or F64, F16, BF16), found {other}"
            )));
        }
    };
    let v: Vec<f32> = match dtype {
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
    };
    let from = (dtype != Dtype::F32).then(|| format!("{dtype:?}"));
    Ok((v, from))
}

/// IEEE binary16 to binary32, exactly (every f16 is an f32).
pub(crate) fn f16_to_f32(h: u16) -> f32 {
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
