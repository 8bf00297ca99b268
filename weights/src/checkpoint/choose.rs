//! Which of a state dict's tensors are the network: chosen by their names and shapes
//! alone, before any is converted (the rules are [the module's](super)), so that a tensor
//! outside the network is never read, whatever its size.

use std::cmp::Ordering;
use std::collections::BTreeMap;

use firmware::network::OBS_DIM;

use super::show_prefix;
use super::state_dict::shape_text;
use crate::{Error, Result, check_shape, few, quote};

/// The network among a state dict's tensors, by name.
#[derive(Clone, Debug, PartialEq)]
pub struct Chosen<'a> {
    /// The prefix its tensors share (`""` for none).
    pub prefix: &'a str,
    /// Its three layers' names under the prefix, input side first.
    pub layers: [&'a str; 3],
    /// Its six tensors' names, in the canonical order (each layer's weight, then bias).
    pub tensors: [&'a str; 6],
    /// Its outputs, one per duty level.
    pub outputs: usize,
    /// Tensors outside it, ignored because the prefix was chosen.
    pub ignored: usize,
}

/// The 4-H-H-A network among the tensors `names`, each of the shape `shape` gives, under
/// `prefix` if one is chosen: refused if there is none or several, if its shape is not one
/// the tools are built for, or if tensors outside it were not ignored by choosing a prefix.
pub fn choose<'a, 's>(
    names: &[&'a str],
    shape: impl Fn(&str) -> &'s [usize],
    prefix: Option<&str>,
) -> Result<Chosen<'a>> {
    // Messages quote names; PyTorch's are short (`q_net_target.q_net.4.weight` is 27 bytes).
    if let Some(long) = names.iter().find(|n| n.len() > crate::QUOTE_MAX) {
        return Err(Error::Input(format!(
            "tensor names must be at most {} bytes, found one of {} bytes: {}",
            crate::QUOTE_MAX,
            long.len(),
            quote(long)
        )));
    }
    let groups = by_prefix(names);
    let checked: Vec<(&str, std::result::Result<[&str; 3], String>)> = groups
        .iter()
        .map(|(p, layers)| (*p, chain(&shape, layers)))
        .collect();
    let (pre, layers) = select(&checked, prefix)?;
    let group = &groups[pre];
    let own: Vec<&'a str> = layers
        .iter()
        .flat_map(|k| [group[k].weight, group[k].bias])
        .flatten()
        .collect();
    let outside: Vec<&str> = names.iter().copied().filter(|n| !own.contains(n)).collect();
    // The chain's first layer is [H, 4]: a width no network has is refused before any
    // tensor is converted, so no view is materialised beyond the largest network's.
    let (width, outputs) = (shape(own[0])[0], shape(own[4])[0]);
    check_shape(width, outputs).map_err(|e| match e {
        Error::Input(m) => Error::Input(format!("{}: {m}", show_prefix(pre))),
        other => other,
    })?;
    if prefix.is_none() && !outside.is_empty() {
        return Err(Error::Input(format!(
            "{} tensors are not part of the network under {} (e.g. {}); pass --prefix {} to \
             import that network and ignore them",
            outside.len(),
            show_prefix(pre),
            quote(outside[0]),
            shell_word(pre)
        )));
    }
    let tensors = <[&str; 6]>::try_from(own).expect("a chained network has six tensors");
    Ok(Chosen {
        prefix: pre,
        layers,
        tensors,
        outputs,
        ignored: outside.len(),
    })
}

/// One linear layer's two tensors, by name.
#[derive(Default)]
struct Layer<'a> {
    weight: Option<&'a str>,
    bias: Option<&'a str>,
    /// Tensors of the layer that are neither (a BatchNorm's `running_mean`, say).
    other: Vec<&'a str>,
}

/// `names` by prefix, then by layer: `network.0.weight` is layer `0`'s weight under
/// `network.`.
fn by_prefix<'a>(names: &[&'a str]) -> BTreeMap<&'a str, BTreeMap<&'a str, Layer<'a>>> {
    let mut groups: BTreeMap<&str, BTreeMap<&str, Layer>> = BTreeMap::new();
    for &name in names {
        let (stem, param) = name.rsplit_once('.').unwrap_or((name, ""));
        let (pre, layer) = match stem.rfind('.') {
            Some(i) => stem.split_at(i + 1),
            None => ("", stem),
        };
        let l = groups.entry(pre).or_default().entry(layer).or_default();
        match param {
            "weight" => l.weight = Some(name),
            "bias" => l.bias = Some(name),
            _ => l.other.push(name),
        }
    }
    groups
}

/// The group to import: the one `prefix` names, or the only one that is a network.
fn select<'a>(
    checked: &[(&'a str, std::result::Result<[&'a str; 3], String>)],
    prefix: Option<&str>,
) -> Result<(&'a str, [&'a str; 3])> {
    if let Some(p) = prefix {
        return match checked.iter().find(|(q, _)| *q == p) {
            None => Err(Error::Input(format!(
                "no tensors under prefix {} (prefixes found: {})",
                quote(p),
                few(checked.iter().map(|(p, _)| shell_word(p)), 8)
            ))),
            Some((_, Err(why))) => Err(Error::Input(format!("{}: {why}", show_prefix(p)))),
            Some((p, Ok(layers))) => Ok((*p, *layers)),
        };
    }
    let valid: Vec<(&str, [&str; 3])> = checked
        .iter()
        .filter_map(|(p, r)| r.as_ref().ok().map(|l| (*p, *l)))
        .collect();
    match valid[..] {
        [one] => Ok(one),
        [] => {
            let why: Vec<String> = checked
                .iter()
                .filter_map(|(p, r)| r.as_ref().err().map(|w| format!("{}: {w}", show_prefix(p))))
                .take(8)
                .collect();
            Err(Error::Input(format!(
                "no 4-H-H-A network found (three linear layers [H, {OBS_DIM}] -> [H, H] -> \
                 [A, H], A one output per duty level); {}",
                why.join("; ")
            )))
        }
        ref many => Err(Error::Input(format!(
            "{} networks found, under the prefixes {}; choose one with --prefix (e.g. \
             --prefix {})",
            many.len(),
            few(many.iter().map(|(p, _)| shell_word(p)), 8),
            shell_word(many[0].0)
        ))),
    }
}

/// `--prefix` as a user would type it in a shell.
fn shell_word(p: &str) -> String {
    if p.is_empty() {
        "\"\"".into()
    } else {
        quote(p).trim_matches('"').to_string()
    }
}

/// The group's three layers in order if they chain `[H, 4] -> [H, H] -> [2, H]`, or why not.
/// The order is the names' natural order (`fc1 < fc2 < fc10`, `0 < 2 < 4`); names that do not
/// sort that way (`input`, `hidden`, `output`) are ordered by the one chain their shapes form.
fn chain<'a, 's>(
    shape: &impl Fn(&str) -> &'s [usize],
    layers: &BTreeMap<&'a str, Layer<'a>>,
) -> std::result::Result<[&'a str; 3], String> {
    let mut order: Vec<&str> = layers.keys().copied().collect();
    order.sort_by(|a, b| natural(a, b));
    let [a, b, c] = order[..] else {
        return Err(format!(
            "{} layers ({}), expected 3 linear layers",
            order.len(),
            few(order.iter().map(|l| quote(l)), 6)
        ));
    };
    let mut dims = BTreeMap::new();
    for key in [a, b, c] {
        let l = &layers[key];
        if let Some(o) = l.other.first() {
            return Err(format!(
                "{} is not a linear layer's weight or bias",
                quote(o)
            ));
        }
        let (Some(w), Some(bias)) = (l.weight, l.bias) else {
            let missing = if l.weight.is_none() { "weight" } else { "bias" };
            return Err(format!("layer {} lacks its {missing}", quote(key)));
        };
        let (ws, bs) = (shape(w), shape(bias));
        let [out, inp] = ws[..] else {
            return Err(format!(
                "{} has shape {}, expected [out, in]",
                quote(w),
                shape_text(ws)
            ));
        };
        if bs[..] != [out] {
            return Err(format!(
                "{} has shape {}, expected [{out}] to match {}",
                quote(bias),
                shape_text(bs),
                quote(w)
            ));
        }
        dims.insert(key, (w, out, inp));
    }
    let why = |[a, b, c]: [&str; 3]| unchained([dims[a], dims[b], dims[c]]);
    let Some(first) = why([a, b, c]) else {
        return Ok([a, b, c]);
    };
    let others = [[a, c, b], [b, a, c], [b, c, a], [c, a, b], [c, b, a]];
    match others
        .iter()
        .filter(|p| why(**p).is_none())
        .collect::<Vec<_>>()[..]
    {
        [only] => Ok(*only),
        _ => Err(first),
    }
}

/// Why three linear layers `(weight name, out, in)`, in this order, are not a 4-H-H-2
/// network, if they are not.
pub(super) fn unchained(layers: [(&str, usize, usize); 3]) -> Option<String> {
    let [(w1, h1, i1), (w2, h2, i2), (w3, o3, i3)] = layers;
    let (w1, w2, w3) = (quote(w1), quote(w2), quote(w3));
    if i1 != OBS_DIM {
        Some(format!(
            "{w1} is [{h1}, {i1}]: the first layer takes the {OBS_DIM} observations"
        ))
    } else if i2 != h1 || i3 != h2 {
        Some(format!(
            "the layers do not chain: {w1} [{h1}, {i1}], {w2} [{h2}, {i2}], {w3} [{o3}, {i3}]"
        ))
    } else if h1 != h2 {
        Some(format!(
            "hidden widths {h1} and {h2} differ; the network has two hidden layers of one \
             width"
        ))
    } else if o3 < 2 {
        Some(format!(
            "{w3} is [{o3}, {i3}]: the output layer has one output per duty level, at least two"
        ))
    } else {
        None
    }
}

/// Orders layer names as a person would: `fc2` before `fc10`, `2` before `10`. Runs of digits
/// compare as numbers, other runs as text, digits after letters.
pub(super) fn natural(a: &str, b: &str) -> Ordering {
    fn runs(s: &str) -> impl Iterator<Item = (bool, usize, &str)> {
        let b = s.as_bytes();
        let mut start = 0;
        (1..=b.len()).filter_map(move |i| {
            if i < b.len() && b[i].is_ascii_digit() == b[i - 1].is_ascii_digit() {
                return None;
            }
            let run = &s[start..i];
            start = i;
            let digits = run.as_bytes()[0].is_ascii_digit();
            // A number's magnitude first (its length without leading zeros), then its text.
            let len = if digits {
                run.trim_start_matches('0').len()
            } else {
                0
            };
            Some((digits, len, run))
        })
    }
    runs(a).cmp(runs(b))
}
