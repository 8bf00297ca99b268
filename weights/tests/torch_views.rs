//! Tensors that `torch.save` writes as views of a storage rather than as their own
//! elements: `expand()` (a stride of 0 repeats a dimension: `torch.ones(4).expand(16, 4)`
//! is a storage of 4 elements viewed with size (16, 4) and stride (0, 1)) and a view that
//! starts inside its storage. PyTorch is not installed where these tests run, so the files
//! are made here, opcode by opcode, as the fixtures' `torch.save` files are laid out (the
//! same globals, persistent ids and `_rebuild_tensor_v2` arguments; `tests/support/build.rs`);
//! the expected values are computed from the view's definition, element
//! `offset + sum(index * stride)` of the storage.

mod support;

use support::build::{Pickle, network, torch_zip};
use weights::checkpoint::{Format, import};

/// The width-16 network with `fc1.weight` and `fc1.bias` replaced by views of the storages
/// `w` and `b` (with their offsets, shapes and strides).
fn with_views(
    w: (&[f32], usize, [usize; 2], [usize; 2]),
    b: (&[f32], usize, usize, usize),
) -> Vec<u8> {
    let bytes = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let mut p = Pickle::new();
    p.dict();
    p.str("fc1.weight").tensor(|p| {
        p.storage("w", w.0.len())
            .int(w.1 as i32)
            .ints(&w.2)
            .ints(&w.3);
    });
    p.str("fc1.bias").tensor(|p| {
        p.storage("b", b.0.len())
            .int(b.1 as i32)
            .ints(&[b.2])
            .ints(&[b.3]);
    });
    let mut storages = vec![
        ("archive/data/w".to_string(), bytes(w.0)),
        ("archive/data/b".to_string(), bytes(b.0)),
    ];
    for (k, (v, data, dims)) in network().into_iter().enumerate().skip(2) {
        let name = format!("fc{}.{}", k / 2 + 1, ["weight", "bias"][k % 2]);
        let key = format!("n{k}");
        let stride: Vec<usize> = if dims.len() == 2 {
            vec![dims[1], 1]
        } else {
            vec![1]
        };
        p.str(&name).tensor(|p| {
            p.storage(&key, v.len()).int(0).ints(&dims).ints(&stride);
        });
        storages.push((format!("archive/data/{key}"), data));
    }
    torch_zip(&p.end(), &storages)
}

#[test]
fn an_expanded_tensor_reads_as_its_repeated_values() {
    // fc1.weight: one row of 4 repeated 16 times; fc1.bias: one value repeated 16 times.
    let row = [0.5, -1.25, 2.0, 0.125];
    let file = with_views((&row, 0, [16, 4], [0, 1]), (&[0.75], 0, 16, 0));
    let got = import(&file, None).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(got.format, Format::TorchZip);
    let t = got.weights.tensors();
    let want_w: Vec<f32> = (0..16).flat_map(|_| row).collect();
    assert_eq!(t[0], want_w);
    assert_eq!(t[1], vec![0.75; 16]);
    // The other layers as stored.
    let net = network();
    assert_eq!((&t[2], &t[5]), (&net[2].0, &net[5].0));
}

#[test]
fn a_column_expanded_and_an_offset_view_read_through_their_strides() {
    // fc1.weight[i][j] = storage[3 + i] (each row one value, `x[:, None].expand(16, 4)` of
    // a view starting at element 3); fc1.bias[i] = storage[1 + 2 i] (every other element).
    let col: Vec<f32> = (0..19).map(|i| i as f32 * 0.5).collect();
    let bias: Vec<f32> = (0..33).map(|i| -(i as f32)).collect();
    let file = with_views((&col, 3, [16, 4], [1, 0]), (&bias, 1, 16, 2));
    let got = import(&file, None).unwrap_or_else(|e| panic!("{e}"));
    let t = got.weights.tensors();
    let want_w: Vec<f32> = (0..16).flat_map(|i| [col[3 + i]; 4]).collect();
    let want_b: Vec<f32> = (0..16).map(|i| bias[1 + 2 * i]).collect();
    assert_eq!((&t[0], &t[1]), (&want_w, &want_b));
}

#[test]
fn a_view_reaching_past_its_storage_is_refused() {
    // The last row of an expanded column starts at element 3 + 15 = 18 of 18 elements.
    let col = [1.0f32; 18];
    let e = import(
        &with_views((&col, 3, [16, 4], [1, 0]), (&[0.0], 0, 16, 0)),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("tensor \"fc1.weight\": offset 3 and strides [1, 0] reach past its storage of 18 elements"),
        "{e}"
    );
}
