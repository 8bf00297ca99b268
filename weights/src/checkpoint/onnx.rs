//! ONNX models of a 4-H-H-2 Q-network as `torch.onnx.export` writes them: from the one
//! graph input, three linear layers (`Gemm`, or `MatMul` then `Add`) with a `Relu` between
//! each, to the one graph output, the weights and biases as initializers. The graph is
//! recognised by that chain; any other operator is refused by name.
//!
//! The model is read in place. What is kept per node is its output's name and where the node
//! is (16 bytes: a node of a known operator with an output takes at least 12 in the file),
//! and per graph input its name (8 bytes, at least 5 in the file) and whether it is an
//! initializer: the index is at most twice the file. Initializers are not indexed: the six a
//! network uses are found in one more pass over the graph. The path is walked back from the
//! output through the index, one lookup per node of the path, and a path longer than a
//! network's is refused as soon as it is one.

use std::borrow::Cow;
use std::collections::BTreeMap;

use super::choose::unchained;
use super::protobuf::{Fields, Wire, count, each_varint, last, text, varints};
use super::state_dict::{Data, Dtype, Tensor, shape_text, to_f32};
use super::{Format, Import, checked_weights};
use crate::levels::{self, GivenLevels};
use crate::{Error, Result, check_shape, quote};

fn refuse<T>(why: String) -> Result<T> {
    Err(Error::Input(format!("ONNX: {why}")))
}

/// A part of the graph's bytes, by offset: half the size of a slice.
#[derive(Clone, Copy)]
struct Span {
    at: u32,
    len: u32,
}

/// A node, read from its bytes when the walk reaches it.
struct Node<'a> {
    op: &'a str,
    name: &'a str,
    /// Its inputs (the operators read at most three) and how many it has.
    inputs: [&'a str; 3],
    output: &'a str,
    bytes: &'a [u8],
}

impl<'a> Node<'a> {
    fn shown(&self) -> String {
        format!("node {} ({})", quote(self.name), quote(self.op))
    }

    /// Refuses an attribute its operator does not take (`known`: a Relu's `alpha` is a leaky
    /// one's slope) or one given twice (which of the two would the author mean?).
    fn check_attributes(&self, known: &[&str]) -> Result<()> {
        let mut seen: Vec<&str> = Vec::new();
        for f in Fields::new(self.bytes) {
            let (5, w) = f? else { continue };
            let name = string(message(w, "an attribute")?, 1)?;
            if !known.contains(&name) {
                return refuse(format!(
                    "{} has an attribute {} that {} does not take (expected {})",
                    self.shown(),
                    quote(name),
                    quote(self.op),
                    if known.is_empty() {
                        "none".into()
                    } else {
                        known.join(", ")
                    }
                ));
            }
            if seen.contains(&name) {
                return refuse(format!(
                    "{} gives its attribute {} twice",
                    self.shown(),
                    quote(name)
                ));
            }
            seen.push(name);
        }
        Ok(())
    }

    /// The value of the node's attribute `name` (an int's field 3, a float's field 2).
    fn attribute(&self, name: &str) -> Result<Option<Wire<'a>>> {
        let mut found = None;
        for f in Fields::new(self.bytes) {
            let (5, w) = f? else { continue };
            let a = message(w, "an attribute")?;
            if string(a, 1)? == name {
                found = Some(last(a, 3)?.or(last(a, 2)?).unwrap_or(Wire::Varint(0)));
            }
        }
        Ok(found)
    }
}

/// The graph: its bytes and the index of its nodes and inputs.
struct Graph<'a> {
    bytes: &'a [u8],
    /// Every node as (its output's name, the node), sorted by name.
    producers: Vec<(Span, Span)>,
    /// How many of the graph's inputs are not initializers, and the first of them.
    input: (usize, &'a str),
    /// How many outputs the graph has, and the first.
    output: (usize, &'a str),
}

fn message<'a>(w: Wire<'a>, what: &str) -> Result<&'a [u8]> {
    match w {
        Wire::Bytes(b) => Ok(b),
        _ => refuse(format!("{what} is not a message")),
    }
}

/// The string field `n` of a message, `""` if it has none.
fn string(bytes: &[u8], n: u64) -> Result<&str> {
    last(bytes, n)?.as_ref().map_or(Ok(""), text)
}

/// The network in the ONNX model `bytes`; `given` the duty levels of its outputs (a model
/// records none).
pub fn import(bytes: &[u8], given: Option<&GivenLevels>) -> Result<Import> {
    let graphs = count(bytes, 7)?;
    let (1, Some(graph)) = (graphs, last(bytes, 7)?) else {
        return refuse(format!("expected a model with one graph, found {graphs}"));
    };
    let g = Graph::read(message(graph, "the graph")?)?;
    let layers = walk(&g)?;
    let names = layers.each_ref().map(|l| [l.weight, l.bias]).concat();
    let inits = g.initializers(&names)?;
    let mut dims = [("", 0, 0); 3];
    for (k, l) in layers.iter().enumerate() {
        let w = &inits[2 * k];
        let [r, c] = w.dims[..] else {
            return refuse(format!(
                "weight {} has shape {}, expected a matrix",
                quote(l.weight),
                shape_text(&w.dims)
            ));
        };
        let (out, inp) = if l.transposed { (c, r) } else { (r, c) };
        let bias = inits[2 * k + 1].dims.iter().product::<usize>();
        if bias != out || inits[2 * k + 1].dims.len() > 2 {
            return refuse(format!(
                "bias {} has shape {} for a layer of {out} outputs",
                quote(l.bias),
                shape_text(&inits[2 * k + 1].dims)
            ));
        }
        dims[k] = (l.weight, out, inp);
    }
    if let Some(why) = unchained(dims) {
        return refuse(why);
    }
    // Nothing is converted before the width is known to be one the tools are built for.
    check_shape(dims[0].1, dims[2].1)?;
    // The names go into the exported source's provenance; PyTorch's are short.
    if let Some(long) = names.iter().find(|n| n.len() > crate::QUOTE_MAX) {
        return refuse(format!(
            "initializer names must be at most {} bytes, found one of {}: {}",
            crate::QUOTE_MAX,
            long.len(),
            quote(long)
        ));
    }
    let mut tensors: [Vec<f32>; 6] = Default::default();
    let mut converted_from = None;
    for (k, init) in inits.iter().enumerate() {
        let (v, from) = to_f32(init.name, &init.tensor()?)?;
        converted_from = converted_from.or(from);
        let l = &layers[k / 2];
        tensors[k] = match (k % 2, l.transposed) {
            (0, true) => transpose(&v, init.dims[0], init.dims[1]),
            _ => v,
        };
    }
    let names: [&str; 6] = names.try_into().expect("six names");
    let levels = levels::of_file(&BTreeMap::new(), dims[2].1, given)?;
    Ok(Import {
        weights: checked_weights(tensors, levels, &names)?,
        prefix: String::new(),
        layers: [names[0], names[2], names[4]].map(str::to_string),
        ignored: 0,
        converted_from,
        metadata: BTreeMap::new(),
        format: Format::Onnx,
    })
}

impl<'a> Graph<'a> {
    fn read(bytes: &'a [u8]) -> Result<Graph<'a>> {
        // Offsets into it are kept in 32 bits (a policy file is at most 64 MiB).
        if u32::try_from(bytes.len()).is_err() {
            return refuse(format!("a graph of {} bytes", bytes.len()));
        }
        if last(bytes, 15)?.is_some() {
            return refuse("sparse initializers are not read; export dense weights".into());
        }
        let span = |s: &[u8]| Span {
            at: (s.as_ptr() as usize - bytes.as_ptr() as usize) as u32,
            len: s.len() as u32,
        };
        // Reserved only for fields that can be what they are counted as: an empty field is
        // two bytes, and its entry in the index eight or sixteen.
        let mut producers = Vec::with_capacity(count_at_least(bytes, 1, MIN_NODE_BYTES)?);
        let mut inputs = Vec::with_capacity(count_at_least(bytes, 11, MIN_INPUT_BYTES)?);
        let mut unnamed = 0;
        let mut output = (0, "");
        for f in Fields::new(bytes) {
            match f? {
                (1, w) => {
                    let n = node(message(w, "a node")?)?;
                    producers.push((span(n.output.as_bytes()), span(n.bytes)));
                }
                (11, w) => match string(message(w, "a graph input")?, 1)? {
                    "" => unnamed += 1,
                    name => inputs.push(span(name.as_bytes())),
                },
                (12, w) => {
                    let name = string(message(w, "a graph output")?, 1)?;
                    output = (output.0 + 1, if output.0 == 0 { name } else { output.1 });
                }
                _ => {}
            }
        }
        let text = |s: &Span| {
            std::str::from_utf8(&bytes[s.at as usize..(s.at + s.len) as usize]).unwrap_or("")
        };
        producers.sort_unstable_by(|a, b| text(&a.0).cmp(text(&b.0)));
        if let Some(w) = producers
            .windows(2)
            .find(|w| text(&w[0].0) == text(&w[1].0))
        {
            return refuse(format!(
                "value {} is the output of two nodes",
                quote(text(&w[0].0))
            ));
        }
        // An initializer listed among the inputs (older exporters list every one) is not
        // the observation.
        inputs.sort_unstable_by(|a, b| text(a).cmp(text(b)));
        let mut initializer = vec![false; inputs.len()];
        for f in Fields::new(bytes) {
            if let (5, w) = f? {
                let name = string(message(w, "an initializer")?, 8)?;
                if let Ok(k) = inputs.binary_search_by(|i| text(i).cmp(name)) {
                    initializer[k] = true;
                }
            }
        }
        let mut observed = inputs.iter().zip(&initializer).filter(|i| !*i.1);
        let first = observed.next().map_or("", |i| text(i.0));
        let input = (
            unnamed + usize::from(!first.is_empty()) + observed.count(),
            first,
        );
        Ok(Graph {
            bytes,
            producers,
            input,
            output,
        })
    }

    fn text(&self, s: Span) -> &'a str {
        let b = &self.bytes[s.at as usize..(s.at + s.len) as usize];
        std::str::from_utf8(b).unwrap_or("")
    }

    /// The node whose output is `value`, if one is.
    fn producer(&self, value: &str) -> Option<Node<'a>> {
        let k = self
            .producers
            .binary_search_by(|p| self.text(p.0).cmp(value))
            .ok()?;
        Some(self.node(self.producers[k].1))
    }

    /// The node at `s`, read once already when the index was made.
    fn node(&self, s: Span) -> Node<'a> {
        node(&self.bytes[s.at as usize..(s.at + s.len) as usize]).expect("read before")
    }

    /// Where the node is in the graph's bytes.
    fn at(&self, n: &Node) -> u32 {
        (n.bytes.as_ptr() as usize - self.bytes.as_ptr() as usize) as u32
    }

    /// The initializers named `names`, in that order, from one pass over the graph.
    fn initializers(&self, names: &[&'a str]) -> Result<Vec<Init<'a>>> {
        let mut found: Vec<Option<Init>> = names.iter().map(|_| None).collect();
        for f in Fields::new(self.bytes) {
            let (5, w) = f? else { continue };
            let b = message(w, "an initializer")?;
            let name = string(b, 8)?;
            for (k, _) in names.iter().enumerate().filter(|(_, n)| **n == name) {
                if found[k].is_some() {
                    return refuse(format!("initializer {} appears twice", quote(name)));
                }
                found[k] = Some(Init::read(name, b)?);
            }
        }
        found
            .into_iter()
            .zip(names)
            .map(|(f, n)| {
                f.map_or_else(|| refuse(format!("{} is not an initializer", quote(n))), Ok)
            })
            .collect()
    }
}

/// The fewest bytes of a node's message that can hold a known operator with its inputs and
/// output (`Relu`: its operator field, 6 bytes, and an input and an output, 2 each).
const MIN_NODE_BYTES: usize = 10;

/// The fewest bytes of a graph input's message that can hold a name (a field of one byte).
const MIN_INPUT_BYTES: usize = 3;

/// How many fields `n` of `bytes` are messages of at least `min` bytes: the entries an index
/// of them can need, where [`count`] would count empty fields too.
fn count_at_least(bytes: &[u8], n: u64, min: usize) -> Result<usize> {
    let mut k = 0;
    for f in Fields::new(bytes) {
        k += usize::from(matches!(f?, (m, Wire::Bytes(b)) if m == n && b.len() >= min));
    }
    Ok(k)
}

/// The operators of a network's graph and how many inputs each takes.
const OPERATORS: [(&str, usize); 4] = [("Gemm", 3), ("MatMul", 2), ("Add", 2), ("Relu", 1)];

/// What a 4-H-H-2 Q-network's graph is made of, in order.
const SHAPE: &str = "Gemm (or MatMul and Add), Relu, Gemm, Relu, Gemm";

/// The node in `b`, refused unless it is one of [`OPERATORS`] with its number of inputs
/// and one output.
fn node(b: &[u8]) -> Result<Node<'_>> {
    let mut inputs = [""; 3];
    let (mut n_in, mut n_out, mut output) = (0, 0, "");
    for f in Fields::new(b) {
        match f? {
            (1, w) => {
                if let Some(slot) = inputs.get_mut(n_in) {
                    *slot = text(&w)?;
                }
                n_in += 1;
            }
            (2, w) => {
                output = text(&w)?;
                n_out += 1;
            }
            _ => {}
        }
    }
    let domain = string(b, 7)?;
    let node = Node {
        op: string(b, 4)?,
        name: string(b, 3)?,
        inputs,
        output,
        bytes: b,
    };
    if !domain.is_empty() && domain != "ai.onnx" {
        return refuse(format!(
            "{} is of operator domain {}",
            node.shown(),
            quote(domain)
        ));
    }
    let Some(&(_, arity)) = OPERATORS.iter().find(|o| o.0 == node.op) else {
        return refuse(format!(
            "{} is not part of a 4-H-H-2 Q-network (expected {SHAPE})",
            node.shown()
        ));
    };
    if n_out != 1 || n_in != arity {
        return refuse(format!(
            "{} has {n_in} inputs and {n_out} outputs, expected {arity} and one",
            node.shown()
        ));
    }
    Ok(node)
}

/// An initializer's name, dimensions (at most three kept) and message.
struct Init<'a> {
    name: &'a str,
    dims: Vec<usize>,
    bytes: &'a [u8],
}

impl<'a> Init<'a> {
    fn read(name: &'a str, b: &'a [u8]) -> Result<Init<'a>> {
        if last(b, 14)? == Some(Wire::Varint(1)) {
            return refuse(format!(
                "initializer {} is stored in an external file; export with the weights inside",
                quote(name)
            ));
        }
        let (dims, _) = varints(b, 1, 3)?;
        let dims: Option<Vec<usize>> = dims.into_iter().map(|d| usize::try_from(d).ok()).collect();
        let Some(dims) = dims else {
            return refuse(format!(
                "initializer {} has a dimension out of range",
                quote(name)
            ));
        };
        Ok(Init {
            name,
            dims,
            bytes: b,
        })
    }

    /// Its tensor: raw little-endian data borrowed, float or double values gathered, and
    /// float16 or bfloat16 values gathered from `int32_data`, where ONNX keeps each one's
    /// 16 bits when they are not raw.
    fn tensor(&self) -> Result<Tensor<'a>> {
        let b = self.bytes;
        let dtype = match last(b, 2)? {
            Some(Wire::Varint(1)) => Ok(Dtype::F32),
            Some(Wire::Varint(11)) => Ok(Dtype::F64),
            Some(Wire::Varint(10)) => Ok(Dtype::F16),
            Some(Wire::Varint(16)) => Ok(Dtype::BF16),
            Some(Wire::Varint(t)) => Err(format!("ONNX data type {t}")),
            _ => Err("no data type".to_string()),
        };
        let data: Cow<[u8]> = match (last(b, 9)?, &dtype) {
            (Some(Wire::Bytes(raw)), _) => Cow::Borrowed(raw),
            (None, Ok(Dtype::F32)) => Cow::Owned(fixed(b, 4, 4)?),
            (None, Ok(Dtype::F64)) => Cow::Owned(fixed(b, 10, 8)?),
            (None, Ok(Dtype::F16 | Dtype::BF16)) => Cow::Owned(self.halves()?),
            _ => Cow::Borrowed(&[]),
        };
        Ok(Tensor {
            dtype,
            shape: self.dims.as_slice().into(),
            data: Data::Dense(data),
        })
    }

    /// The little-endian bytes of the 16-bit values in `int32_data` (field 5), refused
    /// where one does not fit 16 bits.
    fn halves(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        each_varint(self.bytes, 5, |x| match u16::try_from(x) {
            Ok(h) => {
                out.extend_from_slice(&h.to_le_bytes());
                Ok(())
            }
            Err(_) => refuse(format!(
                "initializer {}: int32_data holds {x} for a 16-bit float, expected at most 65535",
                quote(self.name)
            )),
        })?;
        Ok(out)
    }
}

/// The little-endian bytes of the repeated float or double field `n`, packed or not.
fn fixed(b: &[u8], n: u64, size: usize) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for f in Fields::new(b) {
        match f? {
            (k, _) if k != n => {}
            (_, Wire::Bytes(b)) => out.extend_from_slice(b),
            (_, Wire::Fixed32(x)) if size == 4 => out.extend_from_slice(&x.to_le_bytes()),
            (_, Wire::Fixed64(x)) if size == 8 => out.extend_from_slice(&x.to_le_bytes()),
            // A value of the wrong width: the length check refuses the tensor.
            _ => out.push(0),
        }
    }
    Ok(out)
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
