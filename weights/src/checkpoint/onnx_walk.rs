//! The path from the graph's input to its output, node by node.

use super::{Graph, Linear, Node, refuse};
use crate::checkpoint::protobuf::Wire;
use crate::{Result, quote};

/// What a 4-H-H-2 Q-network's graph is made of, in order.
const SHAPE: &str = "Gemm (or MatMul and Add), Relu, Gemm, Relu, Gemm";

/// The three linear layers on the one path from the graph's input to its output.
pub(super) fn walk<'a>(g: &Graph<'a>) -> Result<Vec<Linear<'a>>> {
    let inputs: Vec<&str> = g
        .inputs
        .iter()
        .copied()
        .filter(|i| !g.inits.contains_key(i))
        .collect();
    let ([input], [output]) = (&inputs[..], &g.outputs[..]) else {
        return refuse(format!(
            "expected one graph input (the observation) and one output (the Q-values), \
             found {} and {}",
            inputs.len(),
            g.outputs.len()
        ));
    };
    let mut used = vec![false; g.nodes.len()];
    let mut cur: &str = input;
    let mut seen: Vec<&str> = Vec::new();
    let mut layers = Vec::new();
    while cur != *output {
        let k = consumer(g, &used, cur)?;
        used[k] = true;
        let n = &g.nodes[k];
        let [out] = n.outputs[..] else {
            return refuse(format!(
                "{} has {} outputs, expected one",
                n.shown(),
                n.outputs.len()
            ));
        };
        seen.push(n.op);
        match n.op {
            "Gemm" => layers.push(gemm(g, n, cur)?),
            "MatMul" => {
                let (layer, next) = matmul(g, &mut used, n, cur, out)?;
                layers.push(layer);
                cur = next;
                continue;
            }
            "Relu" if n.inputs[..] == [cur] => {}
            _ => {
                return refuse(format!(
                    "{} is not part of a 4-H-H-2 Q-network (expected {SHAPE})",
                    n.shown()
                ));
            }
        }
        cur = out;
    }
    let gemm_like: Vec<&str> = seen
        .iter()
        .map(|op| if *op == "MatMul" { "Gemm" } else { op })
        .collect();
    if gemm_like != ["Gemm", "Relu", "Gemm", "Relu", "Gemm"] {
        return refuse(format!(
            "the path from input to output is {}, expected {SHAPE}",
            seen.join(", ")
        ));
    }
    if let Some(k) = used.iter().position(|u| !u) {
        return refuse(format!(
            "{} is off the path from the input to the output",
            g.nodes[k].shown()
        ));
    }
    Ok(layers)
}

/// `MatMul(data, W)` then the `Add` of a bias to its output `out`: the layer, and the
/// value after it.
fn matmul<'a>(
    g: &Graph<'a>,
    used: &mut [bool],
    n: &Node<'a>,
    data: &str,
    out: &'a str,
) -> Result<(Linear<'a>, &'a str)> {
    let weight = operand(g, n, data, 2)?;
    let add = consumer(g, used, out)?;
    used[add] = true;
    let a = &g.nodes[add];
    if a.op != "Add" {
        return refuse(format!("{} follows a MatMul; expected an Add", a.shown()));
    }
    let bias = operand(g, a, out, 2)?;
    let [next] = a.outputs[..] else {
        return refuse(format!(
            "{} has {} outputs, expected one",
            a.shown(),
            a.outputs.len()
        ));
    };
    let layer = Linear {
        weight,
        bias,
        transposed: true,
    };
    Ok((layer, next))
}

/// The one node not yet visited that reads `value`.
fn consumer(g: &Graph, used: &[bool], value: &str) -> Result<usize> {
    let readers: Vec<usize> = (0..g.nodes.len())
        .filter(|&k| g.nodes[k].inputs.contains(&value))
        .collect();
    match readers[..] {
        [k] if !used[k] => Ok(k),
        [] => refuse(format!(
            "nothing reads {} on the way to the output",
            quote(value)
        )),
        _ => refuse(format!(
            "{} is read by {} nodes; a 4-H-H-2 Q-network's graph is one chain",
            quote(value),
            readers.len()
        )),
    }
}

/// The initializer among a two-input node's operands, the other being `data`.
fn operand<'a>(g: &Graph<'a>, n: &Node<'a>, data: &str, count: usize) -> Result<&'a str> {
    if n.inputs.len() != count || !n.inputs.contains(&data) {
        return refuse(format!(
            "{} does not take the layer's input and one initializer",
            n.shown()
        ));
    }
    match n.inputs.iter().find(|i| **i != data) {
        Some(i) if g.inits.contains_key(i) => Ok(i),
        other => refuse(format!(
            "{}'s operand {} is not an initializer",
            n.shown(),
            quote(other.copied().unwrap_or(""))
        )),
    }
}

/// `Gemm(A, B, C)` with A the layer's input: `alpha = beta = 1`, `transA = 0`.
fn gemm<'a>(g: &Graph<'a>, n: &Node<'a>, data: &str) -> Result<Linear<'a>> {
    let attr = |name: &str| n.attrs.iter().rev().find(|a| a.0 == name).map(|a| a.1);
    let float_is_one = |name| match attr(name) {
        None => true,
        Some(Wire::Fixed32(bits)) => f32::from_bits(bits) == 1.0,
        Some(_) => false,
    };
    if !float_is_one("alpha")
        || !float_is_one("beta")
        || attr("transA").is_some_and(|a| a != Wire::Varint(0))
    {
        return refuse(format!(
            "{} scales or transposes its input (alpha, beta or transA); expected a plain linear \
             layer",
            n.shown()
        ));
    }
    let transposed = match attr("transB") {
        None | Some(Wire::Varint(0)) => true,
        Some(Wire::Varint(1)) => false,
        _ => return refuse(format!("{} has a transB other than 0 or 1", n.shown())),
    };
    let [a, b, c] = n.inputs[..] else {
        return refuse(format!(
            "{} has {} inputs, expected 3",
            n.shown(),
            n.inputs.len()
        ));
    };
    if a != data || !g.inits.contains_key(b) || !g.inits.contains_key(c) {
        return refuse(format!(
            "{} does not take the layer's input, a weight and a bias initializer",
            n.shown()
        ));
    }
    Ok(Linear {
        weight: b,
        bias: c,
        transposed,
    })
}
