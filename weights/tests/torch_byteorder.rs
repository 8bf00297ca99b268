//! A `torch.save` zip written on a big-endian machine: its `byteorder` entry says `big`,
//! and every element of a storage has its most significant byte first. Made here as the
//! fixtures' files are laid out (`tests/support/build.rs`); the expected values are the
//! network's own, which the little-endian file of the same pickle gives.

mod support;

use support::build::{Pickle, network, network_items, torch_zip_of_order};
use weights::checkpoint::import;

/// The width-16 network saved with the byte order entry `order`, each storage element's
/// bytes reversed (most significant first) with `swap`.
fn saved(order: &[u8], swap: bool) -> Vec<u8> {
    let mut p = Pickle::new();
    p.dict();
    let mut storages = network_items(&mut p, "");
    if swap {
        for (_, bytes) in &mut storages {
            bytes.chunks_exact_mut(4).for_each(<[u8]>::reverse);
        }
    }
    torch_zip_of_order(&p.end(), &storages, order)
}

#[test]
fn a_big_endian_zip_imports_the_values_of_the_little_endian_one() {
    let want: Vec<Vec<f32>> = network().into_iter().map(|t| t.0).collect();
    for file in [saved(b"little", false), saved(b"big", true)] {
        assert_eq!(
            import(&file, None).unwrap().weights.tensors().to_vec(),
            want
        );
    }
    // The big-endian bytes said to be little-endian are other values: the entry is read.
    let misread = import(&saved(b"little", true), None);
    assert!(misread.is_err() || misread.unwrap().weights.tensors().to_vec() != want);
}

#[test]
fn a_byte_order_other_than_little_or_big_is_refused_by_name() {
    let e = import(&saved(b"middle", false), None).unwrap_err();
    assert!(e.is_input(), "{e}");
    assert!(
        e.to_string()
            .contains("byte order \"middle\", expected \"little\" or \"big\""),
        "{e}"
    );
}
