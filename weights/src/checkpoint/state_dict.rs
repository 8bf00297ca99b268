//! A state dict as every checkpoint format reads into it: tensor names to dtype, shape and
//! little-endian bytes, whatever file they came from.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::rc::Rc;

use firmware::network::{SUPPORTED_SHAPES, shapes};

use crate::{Error, Result, quote};

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
    /// Its shape, shared by every tensor the file gave the same one.
    pub shape: Rc<[usize]>,
    /// Its elements.
    pub data: Data<'a>,
}

/// Where a tensor's elements are: nothing is copied until the network's six are converted.
#[derive(Clone, Debug)]
pub enum Data<'a> {
    /// Row-major, little-endian, exactly the shape's elements.
    Dense(Cow<'a, [u8]>),
    /// A view of a storage (PyTorch's): the element at `index` is element
    /// `offset + sum(index[k] * stride[k])` of `storage`. A stride of 0 repeats a dimension
    /// (`expand`); a transposed view has its strides swapped.
    View {
        /// The storage's elements, in the byte order `big_endian` says.
        storage: &'a [u8],
        /// Whether each element's bytes are most significant first (a file written on a
        /// big-endian machine): read, they are reversed into little-endian.
        big_endian: bool,
        /// The view's first element.
        offset: usize,
        /// Elements to step per index, per dimension.
        stride: Rc<[usize]>,
    },
}

/// Tensor names to tensors, sorted by name; names are borrowed from the file where it
/// holds them as they are.
pub type StateDict<'a> = BTreeMap<Cow<'a, str>, Tensor<'a>>;

/// The most elements a tensor of the network has (the widest hidden layer's `[H, H]`): no
/// tensor is converted beyond it, whatever its view repeats.
pub fn largest_tensor() -> usize {
    SUPPORTED_SHAPES
        .iter()
        .flat_map(|&(h, a)| shapes(h, a))
        .map(|s| s.len())
        .max()
        .unwrap_or(0)
}

/// A shape for a message: its first dimensions, and how many there are when they are many.
pub fn shape_text(shape: &[usize]) -> String {
    const SHOWN: usize = 4;
    let dims: Vec<String> = shape.iter().take(SHOWN).map(usize::to_string).collect();
    match shape.len() {
        n if n > SHOWN => format!("[{}, ... ({n} dimensions)]", dims.join(", ")),
        _ => format!("[{}]", dims.join(", ")),
    }
}

/// The tensor's values as f32, and the dtype they were converted from, if not F32.
pub fn to_f32(name: &str, t: &Tensor) -> Result<(Vec<f32>, Option<String>)> {
    let refuse = |why: String| Error::Input(format!("tensor {}: {why}", quote(name)));
    let dtype = match &t.dtype {
        Ok(d) => *d,
        Err(other) => {
            return Err(refuse(format!(
                "expected dtype F32 (or F64, F16, BF16), found {}",
                quote(other)
            )));
        }
    };
    let bytes = elements(t, dtype).map_err(refuse)?;
    let d = &bytes[..];
    let v: Vec<f32> = match dtype {
        Dtype::F32 => d
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        Dtype::F64 => narrowed(d).map_err(refuse)?,
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

/// F64 elements rounded to f32, refusing one that is finite but past f32's range, which
/// would round to an infinity and be called one.
fn narrowed(d: &[u8]) -> std::result::Result<Vec<f32>, String> {
    let wide = d
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("chunks of 8")));
    let mut v = Vec::with_capacity(d.len() / 8);
    for (i, x) in wide.enumerate() {
        if crate::past_f32(x) {
            return Err(format!(
                "element {i} is {x:e}, past float32's range (+-{:e}); expected a value float32 \
                 holds",
                f32::MAX
            ));
        }
        v.push(x as f32);
    }
    Ok(v)
}

/// The tensor's elements in row-major order, little-endian: a dense tensor's bytes as they
/// are, a view's read through its offset and strides, every index checked against the
/// storage. At most
/// [`largest_tensor`] elements, so a view that repeats a small storage cannot make a large
/// tensor.
fn elements<'t>(t: &'t Tensor, dtype: Dtype) -> std::result::Result<Cow<'t, [u8]>, String> {
    let size = dtype.size();
    let count = t
        .shape
        .iter()
        .try_fold(1usize, |n, &d| n.checked_mul(d))
        .filter(|&n| n <= largest_tensor());
    let Some(count) = count else {
        return Err(format!(
            "shape {} has more than the {} elements of the network's largest tensor",
            shape_text(&t.shape),
            largest_tensor()
        ));
    };
    let (storage, (offset, big_endian), stride) = match &t.data {
        Data::Dense(bytes) if bytes.len() == count * size => return Ok(Cow::Borrowed(bytes)),
        Data::Dense(bytes) => {
            return Err(format!(
                "{} bytes for shape {}, expected {}",
                bytes.len(),
                shape_text(&t.shape),
                count * size
            ));
        }
        Data::View {
            storage,
            big_endian,
            offset,
            stride,
        } => (*storage, (*offset, *big_endian), stride),
    };
    let numel = storage.len() / size;
    // The farthest element the view reaches, checked once: every index lies below it.
    let last = t
        .shape
        .iter()
        .zip(stride.iter())
        .try_fold(offset, |a, (&d, &s)| {
            a.checked_add(d.saturating_sub(1).checked_mul(s)?)
        });
    if t.shape.len() != stride.len() || (count > 0 && last.is_none_or(|l| l >= numel)) {
        return Err(format!(
            "offset {offset} and strides {} reach past its storage of {numel} elements",
            shape_text(stride)
        ));
    }
    let mut data = Vec::with_capacity(count * size);
    let mut index = vec![0usize; t.shape.len()];
    for _ in 0..count {
        let at = index
            .iter()
            .zip(stride.iter())
            .fold(offset, |a, (&i, &s)| a + i * s);
        let element = &storage[at * size..(at + 1) * size];
        if big_endian {
            data.extend(element.iter().rev());
        } else {
            data.extend_from_slice(element);
        }
        // The next row-major index: the last dimension fastest.
        for (i, &d) in index.iter_mut().zip(t.shape.iter()).rev() {
            *i += 1;
            if *i < d {
                break;
            }
            *i = 0;
        }
    }
    Ok(Cow::Owned(data))
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
