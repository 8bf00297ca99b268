//! The path from the graph's output back to its input, node by node through the index of
//! producers: at most the eight nodes of a network's path are visited, whatever the graph's
//! size, and then the nodes are counted once.

use super::{Graph, Linear, Node, SHAPE, refuse};
use crate::checkpoint::protobuf::Wire;
use crate::{Result, few, quote};

/// The three linear layers on the one path from the graph's input to its output.
pub(super) fn walk<'a>(g: &Graph<'a>) -> Result<[Linear<'a>; 3]> {
    let ((1, input), (1, output)) = (g.input, g.output) else {
        return refuse(format!(
            "expected one graph input (the observation) and one output (the Q-values), \
             found {} and {}",
            g.input.0, g.output.0
        ));
    };
    let mut path = Path::default();
    let mut cur = output;
    let mut layers: [Option<Linear>; 3] = Default::default();
    for k in (0..3).rev() {
        let (layer, data) = linear(g, &mut path, cur)?;
        layers[k] = Some(layer);
        cur = data;
        if k > 0 {
            let relu = path.step(g, cur)?;
            if relu.op != "Relu" {
                return refuse(format!(
                    "{} is not part of a 4-H-H-2 Q-network (expected {SHAPE})",
                    relu.shown()
                ));
            }
            cur = relu.inputs[0];
        }
    }
    if let Some(n) = g.producer(cur) {
        return refuse(format!(
            "{} comes before the first layer, which should read the graph input {}",
            n.shown(),
            quote(input)
        ));
    }
    if cur != input {
        return refuse(format!(
            "the first layer reads {}, not the graph input {}",
            quote(cur),
            quote(input)
        ));
    }
    if g.producers.len() != path.at.len() {
        let off = g
            .producers
            .iter()
            .filter(|p| !path.at.contains(&p.1.at))
            .map(|p| g.node(p.1).shown());
        return refuse(format!(
            "{} off the path from the input to the output",
            few(off, 3)
        ));
    }
    Ok(layers.map(|l| l.expect("three layers")))
}

/// The nodes met on the way back from the output (at most a network's eight): their
/// operators, and where they are in the graph.
#[derive(Default)]
struct Path<'a> {
    ops: Vec<&'a str>,
    at: Vec<u32>,
}

impl<'a> Path<'a> {
    /// The node that computes `value`, which the path needs.
    fn step(&mut self, g: &Graph<'a>, value: &str) -> Result<Node<'a>> {
        let Some(n) = g.producer(value) else {
            let mut ops = self.ops.clone();
            ops.reverse();
            return refuse(format!(
                "the path from input to output is {} (from {}), expected {SHAPE}",
                if ops.is_empty() {
                    "empty".into()
                } else {
                    ops.join(", ")
                },
                quote(value)
            ));
        };
        // Another operator is refused by its name, where the walk reaches it.
        let known: Option<&[&str]> = match n.op {
            "Gemm" => Some(&["alpha", "beta", "transA", "transB"]),
            "Relu" | "MatMul" | "Add" => Some(&[]),
            _ => None,
        };
        if let Some(known) = known {
            n.check_attributes(known)?;
        }
        self.ops.push(n.op);
        self.at.push(g.at(&n));
        Ok(n)
    }
}

/// The linear layer whose output is `out`: a `Gemm`, or an `Add` of a bias to a `MatMul`
/// by a weight; and the value it reads.
fn linear<'a>(g: &Graph<'a>, path: &mut Path<'a>, out: &'a str) -> Result<(Linear<'a>, &'a str)> {
    let n = path.step(g, out)?;
    match n.op {
        "Gemm" => gemm(&n),
        "Add" => {
            // The operand a node computes is the MatMul's; the other is the bias.
            let [a, b, _] = n.inputs;
            let (data, bias) = if g.producer(a).is_some() {
                (a, b)
            } else {
                (b, a)
            };
            let m = path.step(g, data)?;
            let [x, weight, _] = m.inputs;
            if m.op != "MatMul" {
                return refuse(format!(
                    "{} comes before an Add; expected a MatMul",
                    m.shown()
                ));
            }
            let layer = Linear {
                weight,
                bias,
                transposed: true,
            };
            Ok((layer, x))
        }
        _ => refuse(format!(
            "{} is not part of a 4-H-H-2 Q-network (expected {SHAPE})",
            n.shown()
        )),
    }
}

/// `Gemm(A, B, C)`: `alpha = beta = 1`, `transA = 0`; A the layer's input, B and C its
/// weight and bias.
fn gemm<'a>(n: &Node<'a>) -> Result<(Linear<'a>, &'a str)> {
    let attr = |name: &str| n.attribute(name);
    let float_is_one = |name| match attr(name)? {
        None => Ok(true),
        Some(Wire::Fixed32(bits)) => Ok(f32::from_bits(bits) == 1.0),
        Some(_) => Ok(false),
    };
    if !float_is_one("alpha")?
        || !float_is_one("beta")?
        || attr("transA")?.is_some_and(|a| a != Wire::Varint(0))
    {
        return refuse(format!(
            "{} scales or transposes its input (alpha, beta or transA); expected a plain linear \
             layer",
            n.shown()
        ));
    }
    let transposed = match attr("transB")? {
        None | Some(Wire::Varint(0)) => true,
        Some(Wire::Varint(1)) => false,
        _ => return refuse(format!("{} has a transB other than 0 or 1", n.shown())),
    };
    let [a, b, c] = n.inputs;
    let layer = Linear {
        weight: b,
        bias: c,
        transposed,
    };
    Ok((layer, a))
}
