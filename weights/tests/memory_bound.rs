//! Every checkpoint reader's peak memory against its input's size, on files made to
//! amplify: pickles whose memo shares one large string, shape or storage among thousands
//! of uses, zips whose names share bytes, ONNX graphs of 250,000 nodes and protobufs of
//! millions of tiny fields. A counting allocator (`support/counting.rs`, this binary's
//! global allocator) measures the peak of live bytes during one `import`, above what was
//! live before it; each must stay within `FACTOR` times the file plus `SLACK`
//! (`support/import_bound.rs`). The bounds
//! count bytes, never time; the ONNX chains are cases a walk that rescans the graph per
//! node (the reader before) cannot finish.

#[path = "support/counting.rs"]
mod counting;
#[path = "support/import_bound.rs"]
mod import_bound;
mod support;

use counting::alone;
use import_bound::{SLACK, bounded, bounded_within, loaded};
use support::build::*;
use weights::checkpoint::MAX_HEADER_BYTES;

/// A state dict of the network under `net.` and `n` more items made by `item`.
fn torch(n: usize, item: impl Fn(&mut Pickle, usize)) -> (Vec<u8>, Vec<(String, Vec<u8>)>) {
    let mut p = Pickle::new();
    p.dict();
    let storages = network_items(&mut p, "net.");
    for i in 0..n {
        item(&mut p, i);
    }
    (p.end(), storages)
}

/// Pushes a value the first time (`i == 0`) and puts it in memo entry `k`; gets it after.
fn shared(p: &mut Pickle, i: usize, k: u32, push: impl FnOnce(&mut Pickle)) {
    if i == 0 {
        push(p);
        p.put(k);
    } else {
        p.get(k);
    }
}

#[test]
fn a_shared_string_as_thousands_of_names_is_not_copied() {
    let _alone = alone();
    // One 1 MiB string, memoised, the name of 30,000 items (one tensor, memoised too): the
    // reader before copied it per item, 30 GB.
    let big = "k".repeat(1 << 20);
    let (pkl, storages) = torch(30_000, |p, i| {
        shared(p, i, 1, |p| {
            p.str(&big);
        });
        shared(p, i, 2, |p| {
            p.tensor(|p| {
                p.storage("n0", 64).int(0).ints(&[64]).ints(&[1]);
            });
        });
    });
    let bytes = torch_zip(&pkl, &storages);
    let said = bounded("shared name", &bytes, Some("net."));
    assert!(said.contains("appears twice"), "{said}");
}

#[test]
fn a_shared_shape_and_a_shared_storage_are_viewed_not_copied() {
    let _alone = alone();
    // A shape of 10,000 dimensions shared by 2,000 tensors (the reader before made 320 MB
    // of shapes and strides), and a 16 MiB storage viewed whole by 2,000 more (32 GB of
    // copies before).
    let ones = vec![1; 10_000];
    let numel = 4 << 20;
    let (pkl, mut storages) = torch(4_000, |p, i| {
        p.str(&format!("x.{i}.weight"));
        p.tensor(|p| {
            shared(p, i, 1, |p| {
                p.storage("big", numel);
            });
            p.int(0);
            if i % 2 == 0 {
                shared(p, i, 2, |p| {
                    p.ints(&ones);
                });
                p.get(2);
            } else {
                shared(p, i / 2, 3, |p| {
                    p.ints(&[numel]);
                });
                shared(p, i / 2, 4, |p| {
                    p.ints(&[1]);
                });
            }
        });
    });
    storages.push(("archive/data/big".into(), vec![0; numel * 4]));
    let bytes = torch_zip(&pkl, &storages);
    assert_eq!(
        bounded("shared shape and storage", &bytes, Some("net.")),
        "ok"
    );
    let refused = bounded("the same without a prefix", &bytes, None);
    assert!(
        refused.contains("4000 tensors are not part of the network"),
        "{refused}"
    );
}

#[test]
fn loading_a_file_costs_its_size_once_more() {
    let _alone = alone();
    // `load` reads the file (its size, once) and imports it: the 17 MB file of the test
    // above, from disk.
    let numel = 4 << 20;
    let (pkl, mut storages) = torch(1, |p, _| {
        p.str("x.0.weight").tensor(|p| {
            p.storage("big", numel).int(0).ints(&[numel]).ints(&[1]);
        });
    });
    storages.push(("archive/data/big".into(), vec![0; numel * 4]));
    let bytes = torch_zip(&pkl, &storages);
    let path = std::env::temp_dir().join(format!("memory-bound-{}.pth", std::process::id()));
    std::fs::write(&path, &bytes).unwrap();
    let said = loaded("load", &path, bytes.len(), Some("net."));
    std::fs::remove_file(&path).unwrap();
    assert_eq!(said, "ok");
}

#[test]
fn memo_gets_of_large_containers_share_them() {
    let _alone = alone();
    // A list, a dict and a tuple of 10,000 items each, then 30,000 GETs of them in a tuple.
    let mut p = Pickle::new();
    p.dict().str("c").op(b"(](");
    for i in 0..10_000 {
        p.int(i);
    }
    p.op(b"e").put(1).op(b"}(");
    for i in 0..5_000 {
        p.int(i).int(i);
    }
    p.op(b"u").put(2).op(b"(");
    for i in 0..10_000 {
        p.int(i);
    }
    p.op(b"t").put(3);
    for i in 0..30_000 {
        p.get(1 + i % 3);
    }
    p.op(b"t");
    let bytes = torch_zip(&p.end(), &[]);
    let said = bounded("memo containers", &bytes, None);
    assert!(said.contains("found a tuple under key \"c\""), "{said}");
}

#[test]
fn an_expanded_view_of_a_small_storage_is_bounded_by_the_network() {
    let _alone = alone();
    // One element repeated as a [65536, 65536] tensor (16 GiB in f32): ignored under a
    // prefix, refused by its width as a network's layer, never materialised.
    let huge = 1 << 16;
    let one = || vec![("archive/data/one".to_string(), vec![0; 4])];
    let (pkl, mut storages) = torch(1, |p, _| {
        p.str("x.0.weight").tensor(|p| {
            p.storage("one", 1).int(0).ints(&[huge, huge]).ints(&[0, 0]);
        });
    });
    storages.extend(one());
    let bytes = torch_zip(&pkl, &storages);
    assert_eq!(bounded("expanded, ignored", &bytes, Some("net.")), "ok");
    let mut p = Pickle::new();
    p.dict();
    for (name, dims) in [("0", [huge, 4]), ("2", [huge, huge]), ("4", [2, huge])] {
        p.str(&format!("{name}.weight")).tensor(|p| {
            p.storage("one", 1).int(0).ints(&dims).ints(&[0, 0]);
        });
        p.str(&format!("{name}.bias")).tensor(|p| {
            p.storage("one", 1).int(0).ints(&[dims[0]]).ints(&[0]);
        });
    }
    let bytes = torch_zip(&p.end(), &one());
    let said = bounded("expanded network", &bytes, None);
    assert!(
        said.contains("hidden width 65536 with 2 outputs is not one the tools are built for"),
        "{said}"
    );
}

#[test]
fn the_pickle_machine_at_its_opcode_limit_stays_within_its_constant() {
    let _alone = alone();
    // 65,534 opcodes, each pushing a value or memoising one: the most the machine can hold.
    let mut p = Pickle::new();
    p.op(b"}(");
    for _ in 0..32_764 {
        p.op(b"N\x94");
    }
    let bytes = torch_zip(&p.end(), &[]);
    let said = bounded("opcode limit", &bytes, None);
    assert!(said.contains("names to be strings"), "{said}");
}

#[test]
fn a_zip_of_a_million_names_indexes_in_less_than_its_size() {
    let _alone = alone();
    // 1,000,000 empty entries: 35 bytes of local header and 51 of central record each.
    let names: Vec<String> = (0..1_000_000).map(|i| format!("{i:05x}")).collect();
    let entries: Vec<(&str, &[u8])> = names.iter().map(|n| (n.as_str(), &[][..])).collect();
    let mut bytes = zip(&entries);
    // The end record counts 16 bits: the real count goes in a zip64 record.
    let end = bytes.len() - 22;
    let (size, at) = (
        bytes.len() - 22 - central_start(&bytes),
        central_start(&bytes),
    );
    let mut z64 = b"PK\x06\x06".to_vec();
    z64.extend(44u64.to_le_bytes());
    z64.extend([45, 0, 45, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    for v in [1_000_000u64, 1_000_000, size as u64, at as u64] {
        z64.extend(v.to_le_bytes());
    }
    let mut locator = b"PK\x06\x07\0\0\0\0".to_vec();
    locator.extend((end as u64).to_le_bytes());
    locator.extend(1u32.to_le_bytes());
    let mut tail = bytes.split_off(end);
    tail[10..12].copy_from_slice(&[0xff, 0xff]);
    tail[12..20].copy_from_slice(&[0xff; 8]);
    bytes.extend(z64.iter().chain(&locator).chain(&tail));
    let said = bounded("a million zip entries", &bytes, None);
    assert!(said.contains("neither PyTorch's (no data.pkl)"), "{said}");
    assert!(said.contains("and 999995 more"), "{said}");
}

/// Where the central directory of a zip made by `zip` starts (its end record says).
fn central_start(bytes: &[u8]) -> usize {
    let end = bytes.len() - 22;
    u32::from_le_bytes(bytes[end + 16..end + 20].try_into().unwrap()) as usize
}

#[test]
fn zip_entries_sharing_their_bytes_are_refused() {
    let _alone = alone();
    // 100,000 names for one 1 MiB data.pkl: a reader that copies entries copied 100 GB.
    let pkl = vec![b'N'; 1 << 20];
    let one = zip(&[("archive/data.pkl", &pkl)]);
    let record = one[central_start(&one)..one.len() - 22].to_vec();
    let mut central = Vec::new();
    for i in 0..100_000u32 {
        let mut r = record.clone();
        let name = format!("archive/data/{i:03}").into_bytes();
        r[28..30].copy_from_slice(&(name.len() as u16).to_le_bytes());
        r.truncate(46);
        r.extend(name);
        central.extend(r);
    }
    let local = one[..central_start(&one)].to_vec();
    let bytes = end_of_zip(local, &central, 0);
    // The end record's 16-bit count: set the count that the records hold, mod 2^16 aside.
    let said = bounded("overlapping entries", &fix_count(bytes, 100_000), None);
    assert!(said.contains("overlap"), "{said}");
}

/// `bytes` with its end record's entry count set to `n` (at most 65,535 are expressible;
/// larger counts are written as the largest, and the reader counts the records it finds
/// for no more than that).
fn fix_count(mut bytes: Vec<u8>, n: usize) -> Vec<u8> {
    let end = bytes.len() - 22;
    let n = (n.min(0xfffe) as u16).to_le_bytes();
    bytes[end + 8..end + 10].copy_from_slice(&n);
    bytes[end + 10..end + 12].copy_from_slice(&n);
    bytes
}

#[test]
fn a_model_zip_around_a_hostile_policy_is_bounded_alike() {
    let _alone = alone();
    let big = "k".repeat(1 << 20);
    let (pkl, storages) = torch(30_000, |p, i| {
        shared(p, i, 1, |p| {
            p.str(&big);
        });
        shared(p, i, 2, |p| {
            p.tensor(|p| {
                p.storage("n0", 64).int(0).ints(&[64]).ints(&[1]);
            });
        });
    });
    let policy = torch_zip(&pkl, &storages);
    let bytes = zip(&[("data", b"{}"), ("policy.pth", &policy)]);
    let said = bounded("SB3 around a shared name", &bytes, Some("net."));
    assert!(
        said.contains("policy.pth in the model.zip") && said.contains("appears twice"),
        "{said}"
    );
}

#[test]
fn an_onnx_chain_of_250000_nodes_is_read_in_bounded_memory() {
    let _alone = alone();
    // The network, then 250,000 Relus from its output to the graph's: the walk back meets
    // a Relu where the last layer should be.
    let mut g = onnx_network_fields();
    let mut cur = "q".to_string();
    for i in 0..250_000 {
        let out = if i == 249_999 {
            "out".to_string()
        } else {
            format!("c{i}")
        };
        bytes_field(
            1,
            &onnx_node("Relu", &format!("n{i}"), &[&cur], &out, &[]),
            &mut g,
        );
        cur = out;
    }
    let bytes = rename_output(g, "out");
    let said = bounded("ONNX chain", &bytes, None);
    assert!(
        said.contains("node \"n249999\" (\"Relu\") is not part of a 4-H-H-2 Q-network"),
        "{said}"
    );
}

/// The model of the graph fields `g` with input `x` and output `out` (rather than `q`).
fn rename_output(mut g: Vec<u8>, out: &str) -> Vec<u8> {
    bytes_field(11, &onnx_value("x"), &mut g);
    bytes_field(12, &onnx_value(out), &mut g);
    let mut m = Vec::new();
    int_field(1, 8, &mut m);
    bytes_field(7, &g, &mut m);
    m
}

#[test]
fn an_onnx_network_among_250000_nodes_off_its_path_names_a_few() {
    let _alone = alone();
    let mut g = onnx_network_fields();
    for i in 0..250_000 {
        let node = onnx_node(
            "Relu",
            &format!("off{i}"),
            &[&format!("z{i}")],
            &format!("y{i}"),
            &[],
        );
        bytes_field(1, &node, &mut g);
    }
    let bytes = onnx_model(g);
    let said = bounded("ONNX off-path nodes", &bytes, None);
    assert!(
        said.contains("(\"Relu\") and 249997 more off the path"),
        "{said}"
    );
    assert_eq!(
        bounded("ONNX network", &onnx_model(onnx_network_fields()), None),
        "ok"
    );
}

#[test]
fn onnx_messages_of_millions_of_tiny_fields_cost_no_memory_per_field() {
    let _alone = alone();
    // 2,000,000 two-byte varints in the model, 1,000,000 graph inputs, 1,000,000 inputs to
    // one node, 1,000,000 initializers, 1,000,000 dimensions of a weight.
    let mut m = Vec::new();
    int_field(1, 8, &mut m);
    for _ in 0..2_000_000 {
        int_field(3, 0, &mut m);
    }
    bytes_field(7, &onnx_model_graph(onnx_network_fields()), &mut m);
    assert_eq!(bounded("ONNX varints", &m, None), "ok");
    let mut g = onnx_network_fields();
    for i in 0..1_000_000 {
        bytes_field(11, &onnx_value(&format!("{i}")), &mut g);
    }
    let said = bounded("ONNX graph inputs", &onnx_model(g), None);
    assert!(said.contains("found 1000001 and 1"), "{said}");
    let mut g = onnx_network_fields();
    let names: Vec<String> = (0..1_000_000).map(|i| i.to_string()).collect();
    let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
    bytes_field(1, &onnx_node("Relu", "wide", &inputs, "w", &[]), &mut g);
    let said = bounded("ONNX node inputs", &onnx_model(g), None);
    assert!(
        said.contains("has 1000000 inputs and 1 outputs, expected 1 and one"),
        "{said}"
    );
    let mut g = onnx_network_fields();
    for i in 0..1_000_000 {
        bytes_field(5, &onnx_init(&format!("{i}"), &[], &[]), &mut g);
    }
    assert_eq!(bounded("ONNX initializers", &onnx_model(g), None), "ok");
    let mut g = Vec::new();
    bytes_field(5, &onnx_init("w0", &vec![1; 1_000_000], &[]), &mut g);
    g.extend(onnx_network_fields());
    let said = bounded("ONNX dimensions", &onnx_model(g), None);
    assert!(said.contains("appears twice"), "{said}");
}

#[test]
fn onnx_graphs_of_millions_of_empty_nodes_or_inputs_reserve_nothing_for_them() {
    let _alone = alone();
    // 3,000,000 empty nodes (two bytes each), or empty graph inputs: an index reserved per
    // field, 16 or 8 bytes each, was 8 or 4 times the file before a node was read.
    for (field, what, want) in [
        (1, "ONNX empty nodes", "node \"\" (\"\") is not part of"),
        (11, "ONNX empty inputs", "found 3000001 and 1"),
    ] {
        let mut g = onnx_network_fields();
        for _ in 0..3_000_000 {
            bytes_field(field, &[], &mut g);
        }
        let said = bounded(what, &onnx_model(g), None);
        assert!(said.contains(want), "{said}");
    }
}

/// The graph message of `onnx_model` (with its input and output), without the model.
fn onnx_model_graph(mut g: Vec<u8>) -> Vec<u8> {
    bytes_field(11, &onnx_value("x"), &mut g);
    bytes_field(12, &onnx_value("q"), &mut g);
    g
}

#[test]
fn a_safetensors_header_at_its_limit_stays_within_the_constant() {
    let _alone = alone();
    // 1 MiB of header: 12,000 empty tensors with a dozen dimensions each, or one tensor of
    // 520,000 dimensions. The safetensors crate parses the header (serde's buffering of a
    // flattened map: about 20 bytes per header byte), which the header's cap bounds.
    let slack = SLACK + 20 * MAX_HEADER_BYTES as usize;
    let mut many = String::from("{");
    for i in 0..12_000 {
        many += &format!(
            "\"t{i}\":{{\"dtype\":\"F32\",\"shape\":[0,1,1,1,1,1,1,1,1,1,1,1],\"data_offsets\":[0,0]}},"
        );
    }
    many.pop();
    many += "}";
    let deep = format!(
        "{{\"t\":{{\"dtype\":\"F32\",\"shape\":[{}1],\"data_offsets\":[0,4]}}}}",
        "1,".repeat(520_000)
    );
    for (what, header, data) in [("many tensors", many, 0), ("many dimensions", deep, 4)] {
        assert!(header.len() as u64 <= MAX_HEADER_BYTES);
        let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
        bytes.extend(header.as_bytes());
        bytes.extend(vec![0; data]);
        let said = bounded_within(what, &bytes, None, slack);
        assert!(said.contains("no 4-H-H-A network found"), "{said}");
    }
}
