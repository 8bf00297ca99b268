//! ONNX graphs and zips made byte by byte (`tests/support/build.rs`), for what no exporter
//! writes: graphs that branch, loop back or carry another operator, and zips whose entries
//! are compressed, corrupt, doubled or out of place. Each is refused with a message naming
//! what is wrong, short and on one line whatever the names in the file.

mod support;

use support::build::*;
use weights::checkpoint::import;

fn refusal(bytes: &[u8]) -> String {
    let e = import(bytes, None).unwrap_err();
    assert!(e.is_input(), "{e}");
    let m = e.to_string();
    assert!(m.len() < 2_000 && !m.chars().any(char::is_control), "{m}");
    m
}

#[test]
fn a_hand_made_onnx_network_imports_its_values() {
    let got = import(&onnx_model(onnx_network_fields()), None).unwrap();
    let want: Vec<Vec<f32>> = network().into_iter().map(|t| t.0).collect();
    assert_eq!(got.weights.tensors().to_vec(), want);
    assert_eq!(got.layers, ["w0", "w1", "w2"].map(String::from));
}

/// The network's graph with `edit` applied to its fields, then `extra` nodes appended.
fn graph(edit: impl Fn(Vec<u8>) -> Vec<u8>, extra: &[Vec<u8>]) -> Vec<u8> {
    let mut g = edit(onnx_network_fields());
    for n in extra {
        bytes_field(1, n, &mut g);
    }
    onnx_model(g)
}

/// `g` with every occurrence of `from` replaced by `to` (of the same length).
fn replace(mut g: Vec<u8>, from: &[u8], to: &[u8]) -> Vec<u8> {
    assert_eq!(from.len(), to.len());
    let mut at = 0;
    while let Some(k) = g[at..].windows(from.len()).position(|w| w == from) {
        g[at + k..at + k + from.len()].copy_from_slice(to);
        at += k + from.len();
    }
    g
}

#[test]
fn graphs_that_are_not_the_chain_are_refused_naming_the_node() {
    let net = network();
    let init = |name: &str, t: usize| onnx_init(name, &net[t].2, &net[t].1);
    for (what, bytes, says) in [
        (
            "another operator",
            graph(|g| replace(g, b"Relu", b"Tanh"), &[]),
            "node \"relu0\" (\"Tanh\") is not part of a 4-H-H-2 Q-network",
        ),
        (
            "a node before the first layer",
            graph(
                |g| replace(g, b"\x0a\x01x", b"\x0a\x01p"),
                &[onnx_node("Relu", "pre", &["x"], "p", &[])],
            ),
            "node \"pre\" (\"Relu\") comes before the first layer",
        ),
        (
            "a branch off the path",
            graph(|g| g, &[onnx_node("Relu", "side", &["h0"], "s", &[])]),
            "node \"side\" (\"Relu\") off the path",
        ),
        (
            "two producers of one value",
            graph(|g| g, &[onnx_node("Relu", "again", &["x"], "h0", &[])]),
            "value \"h0\" is the output of two nodes",
        ),
        (
            "a transposed input",
            graph(|g| replace(g, b"transB", b"transA"), &[]),
            "node \"gemm2\" (\"Gemm\") scales or transposes its input",
        ),
        (
            "an attribute its operator does not take",
            graph(|g| replace(g, b"transB", b"transX"), &[]),
            "node \"gemm2\" (\"Gemm\") has an attribute \"transX\" that \"Gemm\" does not \
             take (expected alpha, beta, transA, transB)",
        ),
        (
            "an attribute given twice, the last the plain layer's",
            onnx_model(onnx_fields_with(init, &[("transB", 0), ("transB", 1)])),
            "node \"gemm2\" (\"Gemm\") gives its attribute \"transB\" twice",
        ),
        (
            "a weight that is not an initializer",
            graph(|g| replace(g, b"\x42\x02w1", b"\x42\x02v1"), &[]),
            "\"w1\" is not an initializer",
        ),
        (
            "a loop from the output back to the first layer",
            graph(|g| replace(g, b"\x0a\x01x", b"\x0a\x01q"), &[]),
            "node \"gemm2\" (\"Gemm\") comes before the first layer",
        ),
    ] {
        let m = refusal(&bytes);
        assert!(m.contains(says), "{what}: {m}");
    }
}

#[test]
fn hostile_node_names_are_escaped_and_cut() {
    let name = "\u{1b}[31m".repeat(2_000);
    let nodes: Vec<Vec<u8>> = (0..1_000)
        .map(|i| onnx_node("Relu", &format!("{name}{i}"), &["z"], &format!("y{i}"), &[]))
        .collect();
    let m = refusal(&graph(|g| g, &nodes));
    assert!(
        m.contains("\\u{1b}[31m") && m.contains("and 997 more off the path"),
        "{m}"
    );
}

fn valid_zip() -> Vec<u8> {
    let mut p = Pickle::new();
    p.dict();
    let storages = network_items(&mut p, "");
    torch_zip(&p.end(), &storages)
}

#[test]
fn a_hand_made_torch_zip_imports_and_damaged_ones_are_refused() {
    let good = valid_zip();
    let want: Vec<Vec<f32>> = network().into_iter().map(|t| t.0).collect();
    assert_eq!(
        import(&good, None).unwrap().weights.tensors().to_vec(),
        want
    );
    // A storage's byte changed: its CRC-32 no longer matches.
    let mut corrupt = good.clone();
    let at = good
        .windows(4)
        .position(|w| w == 1.001f32.to_le_bytes())
        .unwrap();
    corrupt[at] ^= 1;
    assert!(refusal(&corrupt).contains("zip entry \"archive/data/n0\" does not match its CRC-32"));
    // Method 8 (deflate) in the first entry's central record.
    let mut deflated = good.clone();
    let central = good.len() - 22 - central_size(&good);
    deflated[central + 10] = 8;
    let m = refusal(&deflated);
    assert!(
        m.contains("\"archive/data.pkl\" is compressed or encrypted (method 8)"),
        "{m}"
    );
    // The first record's local header offset past the directory.
    let mut outside = good.clone();
    outside[central + 42..central + 46].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(refusal(&outside).contains("central directory entry 0"));
    // Two entries of one name.
    let doubled = zip(&[("archive/data.pkl", b"."), ("archive/data.pkl", b".")]);
    assert!(refusal(&doubled).contains("entry \"archive/data.pkl\" appears twice"));
    // Cut anywhere: refused, never a panic.
    for cut in (0..good.len()).step_by(97) {
        assert!(import(&good[..cut], None).is_err(), "cut at {cut}");
    }
}

/// The size of the central directory of a zip made by `zip` (its end record says).
fn central_size(bytes: &[u8]) -> usize {
    let end = bytes.len() - 22;
    u32::from_le_bytes(bytes[end + 12..end + 16].try_into().unwrap()) as usize
}
