//! ONNX models of a 4-H-H-2 Q-network as `torch.onnx.export` writes them: from the one
//! graph input, three linear layers (`Gemm`, or `MatMul` then `Add`) with a `Relu` between
//! each, to the one graph output, the weights and biases as initializers. The graph is
//! recognised by that chain; any other operator is refused by name.

use std::borrow::Cow;
use std::collections::BTreeMap;

use super::protobuf::{Wire, fields, text, varints};
use super::state_dict::{Dtype, Tensor, to_f32};
use super::{Format, Import, checked_weights, unchained};
use crate::{Error, Result, quote};

fn refuse<T>(why: String) -> Result<T> {
    Err(Error::Input(format!("ONNX: {why}")))
}

struct Node<'a> {
    op: &'a str,
    name: &'a str,
    inputs: Vec<&'a str>,
    outputs: Vec<&'a str>,
    attrs: Vec<(&'a str, Wire<'a>)>,
}

impl Node<'_> {
    fn shown(&self) -> String {
        format!("node {} ({})", quote(self.name), quote(self.op))
    }
}

struct Graph<'a> {
    nodes: Vec<Node<'a>>,
    inits: BTreeMap<&'a str, Tensor<'a>>,
    inputs: Vec<&'a str>,
    outputs: Vec<&'a str>,
}

/// The repeated field `n` of a message's fields.
fn all<'a>(fs: &[(u64, Wire<'a>)], n: u64) -> Vec<Wire<'a>> {
    fs.iter().filter(|f| f.0 == n).map(|f| f.1).collect()
}

/// The last value of field `n` (protobuf's rule for a repeated singular field).
fn one<'a>(fs: &[(u64, Wire<'a>)], n: u64) -> Option<Wire<'a>> {
    fs.iter().rev().find(|f| f.0 == n).map(|f| f.1)
}

fn message<'a>(w: Wire<'a>, what: &str) -> Result<&'a [u8]> {
    match w {
        Wire::Bytes(b) => Ok(b),
        _ => refuse(format!("{what} is not a message")),
    }
}

fn strings<'a>(fs: &[(u64, Wire<'a>)], n: u64) -> Result<Vec<&'a str>> {
    all(fs, n).iter().map(text).collect()
}

/// The network in the ONNX model `bytes`.
pub fn import(bytes: &[u8]) -> Result<Import> {
    let model = fields(bytes)?;
    let graphs = all(&model, 7);
    let [graph] = graphs[..] else {
        return refuse(format!(
            "expected a model with one graph, found {}",
            graphs.len()
        ));
    };
    let g = read_graph(message(graph, "the graph")?)?;
    let layers = walk(&g)?;
    let mut tensors: [Vec<f32>; 6] = Default::default();
    let mut names = [""; 6];
    let mut dims = [("", 0, 0); 3];
    let mut converted_from = None;
    for (k, l) in layers.iter().enumerate() {
        let (w, from) = to_f32(l.weight, &g.inits[l.weight])?;
        let (b, _) = to_f32(l.bias, &g.inits[l.bias])?;
        converted_from = converted_from.or(from);
        let [r, c] = g.inits[l.weight].shape[..] else {
            return refuse(format!("weight {} is not a matrix", quote(l.weight)));
        };
        let (out, inp) = if l.transposed { (c, r) } else { (r, c) };
        if b.len() != out {
            return refuse(format!(
                "bias {} has {} values for a layer of {out} outputs",
                quote(l.bias),
                b.len()
            ));
        }
        tensors[2 * k] = if l.transposed { transpose(&w, r, c) } else { w };
        tensors[2 * k + 1] = b;
        names[2 * k] = l.weight;
        names[2 * k + 1] = l.bias;
        dims[k] = (l.weight, out, inp);
    }
    if let Some(why) = unchained(dims) {
        return refuse(why);
    }
    // The names go into the exported source's provenance; PyTorch's are short.
    if let Some(long) = names.iter().find(|n| n.len() > crate::QUOTE_MAX) {
        return refuse(format!(
            "initializer names must be at most {} bytes, found one of {}: {}",
            crate::QUOTE_MAX,
            long.len(),
            quote(long)
        ));
    }
    Ok(Import {
        weights: checked_weights(tensors, &names)?,
        prefix: String::new(),
        layers: [names[0], names[2], names[4]].map(str::to_string),
        ignored: 0,
        converted_from,
        metadata: BTreeMap::new(),
        format: Format::Onnx,
    })
}

fn read_graph(b: &[u8]) -> Result<Graph<'_>> {
    let fs = fields(b)?;
    if one(&fs, 15).is_some() {
        return refuse("sparse initializers are not read; export dense weights".into());
    }
    let value_names = |n| -> Result<Vec<&str>> {
        all(&fs, n)
            .into_iter()
            .map(|w| {
                let v = fields(message(w, "a graph input or output")?)?;
                one(&v, 1).as_ref().map_or(Ok(""), text)
            })
            .collect()
    };
    let mut inits = BTreeMap::new();
    for w in all(&fs, 5) {
        let (name, t) = initializer(message(w, "an initializer")?)?;
        if inits.insert(name, t).is_some() {
            return refuse(format!("initializer {} appears twice", quote(name)));
        }
    }
    let nodes = all(&fs, 1)
        .into_iter()
        .map(|w| node(message(w, "a node")?))
        .collect::<Result<_>>()?;
    Ok(Graph {
        nodes,
        inputs: value_names(11)?,
        outputs: value_names(12)?,
        inits,
    })
}

fn node(b: &[u8]) -> Result<Node<'_>> {
    let fs = fields(b)?;
    let attrs = all(&fs, 5)
        .into_iter()
        .map(|w| {
            let a = fields(message(w, "an attribute")?)?;
            let name = one(&a, 1).as_ref().map_or(Ok(""), text)?;
            // An int attribute's value is field 3, a float's field 2.
            let value = one(&a, 3).or(one(&a, 2)).unwrap_or(Wire::Varint(0));
            Ok((name, value))
        })
        .collect::<Result<_>>()?;
    let domain = one(&fs, 7).as_ref().map_or(Ok(""), text)?;
    let node = Node {
        op: one(&fs, 4).as_ref().map_or(Ok(""), text)?,
        name: one(&fs, 3).as_ref().map_or(Ok(""), text)?,
        inputs: strings(&fs, 1)?,
        outputs: strings(&fs, 2)?,
        attrs,
    };
    if !domain.is_empty() && domain != "ai.onnx" {
        return refuse(format!(
            "{} is of operator domain {}",
            node.shown(),
            quote(domain)
        ));
    }
    Ok(node)
}

/// An initializer's name and its tensor, with its data in raw little-endian bytes.
fn initializer(b: &[u8]) -> Result<(&str, Tensor<'_>)> {
    let fs = fields(b)?;
    let name = one(&fs, 8).as_ref().map_or(Ok(""), text)?;
    if one(&fs, 14) == Some(Wire::Varint(1)) {
        return refuse(format!(
            "initializer {} is stored in an external file; export with the weights inside",
            quote(name)
        ));
    }
    let shape: Option<Vec<usize>> = varints(&all(&fs, 1))?
        .into_iter()
        .map(|d| usize::try_from(d).ok().filter(|&d| d <= 1 << 20))
        .collect();
    let Some(shape) = shape else {
        return refuse(format!(
            "initializer {} has a dimension out of range",
            quote(name)
        ));
    };
    let dtype = match one(&fs, 2) {
        Some(Wire::Varint(1)) => Ok(Dtype::F32),
        Some(Wire::Varint(11)) => Ok(Dtype::F64),
        Some(Wire::Varint(10)) => Ok(Dtype::F16),
        Some(Wire::Varint(16)) => Ok(Dtype::BF16),
        Some(Wire::Varint(t)) => Err(format!("ONNX data type {t}")),
        _ => Err("no data type".to_string()),
    };
    let data: Cow<[u8]> = match (one(&fs, 9), &dtype) {
        (Some(Wire::Bytes(raw)), _) => Cow::Borrowed(raw),
        (None, Ok(Dtype::F32)) => Cow::Owned(fixed(&all(&fs, 4), 4)),
        (None, Ok(Dtype::F64)) => Cow::Owned(fixed(&all(&fs, 10), 8)),
        _ => Cow::Borrowed(&[]),
    };
    let len = shape
        .iter()
        .try_fold(dtype.as_ref().map_or(0, |d| d.size()), |a, &d| {
            a.checked_mul(d)
        });
    if dtype.is_ok() && Some(data.len()) != len {
        return refuse(format!(
            "initializer {} of shape {shape:?} holds {} bytes, expected {}",
            quote(name),
            data.len(),
            len.map_or("more than fit in memory".into(), |l| l.to_string())
        ));
    }
    Ok((name, Tensor { dtype, shape, data }))
}

/// The little-endian bytes of a repeated float or double field, packed or not.
fn fixed(values: &[Wire], size: usize) -> Vec<u8> {
    let mut out = Vec::new();
    for v in values {
        match *v {
            Wire::Bytes(b) => out.extend_from_slice(b),
            Wire::Fixed32(x) if size == 4 => out.extend_from_slice(&x.to_le_bytes()),
            Wire::Fixed64(x) if size == 8 => out.extend_from_slice(&x.to_le_bytes()),
            // A value of the wrong width: the length check refuses the tensor.
            _ => out.push(0),
        }
    }
    out
}

fn transpose(v: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    (0..cols)
        .flat_map(|c| (0..rows).map(move |r| v[r * cols + c]))
        .collect()
}

/// A linear layer found in the graph: its initializers, and whether the weight is stored
/// `[in, out]` (MatMul's, and Gemm's with `transB = 0`) rather than PyTorch's `[out, in]`.
struct Linear<'a> {
    weight: &'a str,
    bias: &'a str,
    transposed: bool,
}

#[path = "onnx_walk.rs"]
mod walk;
use walk::walk;
