//! Checkpoint files made byte by byte, as the formats define them: zips of stored entries
//! (PKWARE's APPNOTE, sections 4.3 and 4.4), pickles (CPython's `pickletools` opcodes) and
//! protobuf messages (the encoding guide), so that tests can make files no tool would.

#![allow(dead_code)]

use firmware::link::crc::crc32;
use firmware::network::shapes;

/// A zip of stored entries, in order, with local headers, a central directory and its end.
pub fn zip(entries: &[(&str, &[u8])]) -> Vec<u8> {
    let (mut out, mut central) = (Vec::new(), Vec::new());
    for (name, data) in entries {
        let at = out.len() as u32;
        let fixed = |sig: &[u8], central: bool| {
            let mut h = sig.to_vec();
            if central {
                h.extend(20u16.to_le_bytes());
            }
            for v in [20u16, 0, 0, 0, 0] {
                h.extend(v.to_le_bytes());
            }
            for v in [crc32(data), data.len() as u32, data.len() as u32] {
                h.extend(v.to_le_bytes());
            }
            h.extend((name.len() as u16).to_le_bytes());
            h.extend(0u16.to_le_bytes());
            h
        };
        out.extend(fixed(b"PK\x03\x04", false));
        out.extend(name.as_bytes());
        out.extend_from_slice(data);
        central.extend(fixed(b"PK\x01\x02", true));
        central.extend([0u8; 6]);
        central.extend(0u32.to_le_bytes());
        central.extend(at.to_le_bytes());
        central.extend(name.as_bytes());
    }
    end_of_zip(out, &central, entries.len())
}

/// `out` followed by the central directory `central` of `n` entries and the end record.
pub fn end_of_zip(mut out: Vec<u8>, central: &[u8], n: usize) -> Vec<u8> {
    let at = out.len() as u32;
    out.extend_from_slice(central);
    out.extend(b"PK\x05\x06");
    out.extend([0u8; 4]);
    out.extend((n as u16).to_le_bytes());
    out.extend((n as u16).to_le_bytes());
    out.extend((central.len() as u32).to_le_bytes());
    out.extend(at.to_le_bytes());
    out.extend(0u16.to_le_bytes());
    out
}

/// A pickle, opcode by opcode (protocol 2 and `LONG_BINPUT`/`LONG_BINGET` for the memo).
#[derive(Default)]
pub struct Pickle(pub Vec<u8>);

impl Pickle {
    pub fn new() -> Pickle {
        Pickle(b"\x80\x02".to_vec())
    }
    pub fn op(&mut self, bytes: &[u8]) -> &mut Self {
        self.0.extend_from_slice(bytes);
        self
    }
    pub fn str(&mut self, s: &str) -> &mut Self {
        self.0.push(b'X');
        self.0.extend((s.len() as u32).to_le_bytes());
        self.op(s.as_bytes())
    }
    pub fn int(&mut self, i: i32) -> &mut Self {
        self.0.push(b'J');
        self.op(&i.to_le_bytes())
    }
    pub fn put(&mut self, k: u32) -> &mut Self {
        self.0.push(b'r');
        self.op(&k.to_le_bytes())
    }
    pub fn get(&mut self, k: u32) -> &mut Self {
        self.0.push(b'j');
        self.op(&k.to_le_bytes())
    }
    pub fn ints(&mut self, v: &[usize]) -> &mut Self {
        self.op(b"(");
        for &x in v {
            self.int(x as i32);
        }
        self.op(b"t")
    }
    /// `OrderedDict()` and a MARK for its items.
    pub fn dict(&mut self) -> &mut Self {
        self.op(b"ccollections\nOrderedDict\n)R(")
    }
    /// A float storage's persistent id, turned into the storage.
    pub fn storage(&mut self, key: &str, numel: usize) -> &mut Self {
        self.op(b"(").str("storage").op(b"ctorch\nFloatStorage\n");
        self.str(key).str("cpu").int(numel as i32).op(b"tQ")
    }
    /// `_rebuild_tensor_v2(storage, offset, shape, stride, False, {})` with the storage,
    /// shape and stride already pushed by `args`.
    pub fn tensor(&mut self, args: impl FnOnce(&mut Pickle)) -> &mut Self {
        self.op(b"ctorch._utils\n_rebuild_tensor_v2\n(");
        args(self);
        self.op(b"\x89}tR")
    }
    /// SETITEMS for the dict's MARK, and STOP.
    pub fn end(&mut self) -> Vec<u8> {
        self.op(b"u.");
        std::mem::take(&mut self.0)
    }
}

/// A width-16 network's six tensors with recognisable values (tensor `t`, element `i` is
/// `t + i / 1000`): the values, as little-endian bytes, and the shapes.
pub fn network() -> Vec<(Vec<f32>, Vec<u8>, Vec<usize>)> {
    network_of(16, 2)
}

/// [`network`] of hidden width `width` with `outputs` outputs.
pub fn network_of(width: usize, outputs: usize) -> Vec<(Vec<f32>, Vec<u8>, Vec<usize>)> {
    shapes(width, outputs)
        .iter()
        .enumerate()
        .map(|(t, s)| {
            let v: Vec<f32> = (0..s.len())
                .map(|i| (t + 1) as f32 + i as f32 / 1000.0)
                .collect();
            let b = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            (v, b, s.dims().to_vec())
        })
        .collect()
}

/// The pickle items of the network under `prefix` (`{prefix}0.weight` ...), storages `n0`
/// to `n5`, and the storages' entries for the zip.
pub fn network_items(p: &mut Pickle, prefix: &str) -> Vec<(String, Vec<u8>)> {
    items_of(p, prefix, "n", network())
}

/// [`network_items`] of the tensors `net` ([`network_of`]), storages `{keys}0` to
/// `{keys}5` (two networks in one file need two sets of keys).
pub fn items_of(
    p: &mut Pickle,
    prefix: &str,
    keys: &str,
    net: Vec<(Vec<f32>, Vec<u8>, Vec<usize>)>,
) -> Vec<(String, Vec<u8>)> {
    let mut storages = Vec::new();
    for (k, (v, bytes, dims)) in net.into_iter().enumerate() {
        let name = format!("{prefix}{}.{}", 2 * (k / 2), ["weight", "bias"][k % 2]);
        let key = format!("{keys}{k}");
        let stride: Vec<usize> = if dims.len() == 2 {
            vec![dims[1], 1]
        } else {
            vec![1]
        };
        p.str(&name).tensor(|p| {
            p.storage(&key, v.len()).int(0).ints(&dims).ints(&stride);
        });
        storages.push((format!("archive/data/{key}"), bytes));
    }
    storages
}

/// A `torch.save` zip of the pickle `pkl` and the storages.
pub fn torch_zip(pkl: &[u8], storages: &[(String, Vec<u8>)]) -> Vec<u8> {
    torch_zip_of_order(pkl, storages, b"little")
}

/// [`torch_zip`] whose `byteorder` entry is `order`.
pub fn torch_zip_of_order(pkl: &[u8], storages: &[(String, Vec<u8>)], order: &[u8]) -> Vec<u8> {
    let mut entries: Vec<(&str, &[u8])> =
        vec![("archive/data.pkl", pkl), ("archive/byteorder", order)];
    entries.extend(storages.iter().map(|(n, b)| (n.as_str(), b.as_slice())));
    zip(&entries)
}

/// Protobuf: a varint.
pub fn varint(mut v: u64, out: &mut Vec<u8>) {
    while v >= 0x80 {
        out.push(v as u8 | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Protobuf: field `n` as a varint.
pub fn int_field(n: u64, v: u64, out: &mut Vec<u8>) {
    varint(n << 3, out);
    varint(v, out);
}

/// Protobuf: field `n` as length-delimited bytes.
pub fn bytes_field(n: u64, b: &[u8], out: &mut Vec<u8>) {
    varint(n << 3 | 2, out);
    varint(b.len() as u64, out);
    out.extend_from_slice(b);
}

/// An ONNX node: `op` named `name`, reading `inputs`, writing `output`, with int
/// attributes.
pub fn onnx_node(
    op: &str,
    name: &str,
    inputs: &[&str],
    output: &str,
    ints: &[(&str, u64)],
) -> Vec<u8> {
    let mut n = Vec::new();
    for i in inputs {
        bytes_field(1, i.as_bytes(), &mut n);
    }
    bytes_field(2, output.as_bytes(), &mut n);
    bytes_field(3, name.as_bytes(), &mut n);
    bytes_field(4, op.as_bytes(), &mut n);
    for (a, v) in ints {
        let mut attr = Vec::new();
        bytes_field(1, a.as_bytes(), &mut attr);
        int_field(3, *v, &mut attr);
        bytes_field(5, &attr, &mut n);
    }
    n
}

/// An ONNX float initializer with raw data.
pub fn onnx_init(name: &str, dims: &[usize], data: &[u8]) -> Vec<u8> {
    let mut t = Vec::new();
    for &d in dims {
        int_field(1, d as u64, &mut t);
    }
    int_field(2, 1, &mut t);
    bytes_field(8, name.as_bytes(), &mut t);
    bytes_field(9, data, &mut t);
    t
}

/// A value's name as a graph input or output.
pub fn onnx_value(name: &str) -> Vec<u8> {
    let mut v = Vec::new();
    bytes_field(1, name.as_bytes(), &mut v);
    v
}

/// The graph fields of the width-16 network as `Gemm`s (`transB = 1`) with `Relu`s
/// between, from input `x` to output `q`.
pub fn onnx_network_fields() -> Vec<u8> {
    onnx_fields_of(&network())
}

/// [`onnx_network_fields`] of the tensors `net` ([`network_of`]).
pub fn onnx_fields_of(net: &[(Vec<f32>, Vec<u8>, Vec<usize>)]) -> Vec<u8> {
    onnx_fields_by(|name, t| onnx_init(name, &net[t].2, &net[t].1))
}

/// [`onnx_network_fields`] with each initializer written by `init(name, t)`, `t` the
/// tensor's index in PyTorch's order (`fc1.weight` is 0, `fc3.bias` 5).
pub fn onnx_fields_by(init: impl Fn(&str, usize) -> Vec<u8>) -> Vec<u8> {
    onnx_fields_with(init, &[("transB", 1)])
}

/// [`onnx_fields_by`] with each Gemm's int attributes `gemm`.
pub fn onnx_fields_with(init: impl Fn(&str, usize) -> Vec<u8>, gemm: &[(&str, u64)]) -> Vec<u8> {
    let mut g = Vec::new();
    let mut cur = "x".to_string();
    for k in 0..3 {
        let (w, b) = (format!("w{k}"), format!("b{k}"));
        let out = if k == 2 {
            "q".to_string()
        } else {
            format!("h{k}")
        };
        let gemm = onnx_node("Gemm", &format!("gemm{k}"), &[&cur, &w, &b], &out, gemm);
        bytes_field(1, &gemm, &mut g);
        bytes_field(5, &init(&w, 2 * k), &mut g);
        bytes_field(5, &init(&b, 2 * k + 1), &mut g);
        cur = out;
        if k < 2 {
            let r = format!("r{k}");
            bytes_field(
                1,
                &onnx_node("Relu", &format!("relu{k}"), &[&cur], &r, &[]),
                &mut g,
            );
            cur = r;
        }
    }
    g
}

/// An ONNX model (IR version 8) of the graph fields `graph`, the input `x` and output `q`
/// added.
pub fn onnx_model(mut graph: Vec<u8>) -> Vec<u8> {
    bytes_field(11, &onnx_value("x"), &mut graph);
    bytes_field(12, &onnx_value("q"), &mut graph);
    let mut m = Vec::new();
    int_field(1, 8, &mut m);
    bytes_field(7, &graph, &mut m);
    m
}
