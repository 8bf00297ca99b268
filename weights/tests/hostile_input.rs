//! The loader against hostile bytes: random files and mutations of valid checkpoints never
//! panic, and whatever they give is either a checked network or a short message. A fixed
//! case budget keeps this in the normal test run; `fuzz/` runs the same loader for longer.

mod support;

use proptest::prelude::*;
use proptest::test_runner::Config;
use support::build::{Pickle, network, network_items, torch_zip};
use weights::checkpoint::import;

fn valid_file() -> Vec<u8> {
    std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/sb3_policy.safetensors"
    ))
    .unwrap()
}

/// What every outcome must satisfy.
fn check(bytes: &[u8], prefix: Option<&str>) {
    match import(bytes, prefix) {
        Ok(got) => {
            assert!(firmware::network::SUPPORTED_WIDTHS.contains(&got.weights.width()));
            assert!(
                got.weights
                    .tensors()
                    .iter()
                    .flatten()
                    .all(|v| v.is_finite())
            );
        }
        Err(e) => {
            assert!(e.is_input(), "{e}");
            // Input is quoted at most 200 characters at a time; a message names a few.
            assert!(
                e.to_string().len() < 2_000,
                "{} bytes of message",
                e.to_string().len()
            );
        }
    }
}

fn config() -> Config {
    // No regression files in the source tree: a failure prints its case instead.
    Config {
        cases: 512,
        failure_persistence: None,
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn random_bytes_are_refused_cleanly(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        check(&bytes, None);
    }

    #[test]
    fn random_headers_are_refused_cleanly(header in "\\PC{0,300}", tail in proptest::collection::vec(any::<u8>(), 0..64)) {
        let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
        bytes.extend_from_slice(header.as_bytes());
        bytes.extend_from_slice(&tail);
        check(&bytes, None);
    }

    #[test]
    fn mutated_checkpoints_never_panic(
        edits in proptest::collection::vec((any::<proptest::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<proptest::sample::Index>(),
        truncate in any::<bool>(),
        prefix in prop_oneof![Just(None), Just(Some("q_net.q_net.")), Just(Some(""))],
    ) {
        let mut bytes = valid_file();
        // Most edits land in the JSON header, where the structure is.
        let header = 8 + u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        for (at, value) in edits {
            let i = if value % 4 == 0 { at.index(bytes.len()) } else { at.index(header) };
            bytes[i] = value;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len()));
        }
        check(&bytes, prefix);
    }
}

/// A PyTorch buffer of another element type beside the network (a batch norm's count):
/// refused by name, not as a global the reader does not know, and ignored under a prefix.
#[test]
fn an_integer_buffer_beside_the_network_is_ignored_under_its_prefix() {
    let mut p = Pickle::new();
    p.dict();
    let mut storages = network_items(&mut p, "net.");
    p.str("bn.num_batches_tracked").tensor(|p| {
        p.op(b"(").str("storage").op(b"ctorch\nLongStorage\n");
        p.str("count")
            .str("cpu")
            .int(1)
            .op(b"tQ")
            .int(0)
            .ints(&[])
            .ints(&[]);
    });
    storages.push(("archive/data/count".into(), 7i64.to_le_bytes().to_vec()));
    let bytes = torch_zip(&p.end(), &storages);
    let got = import(&bytes, Some("net.")).unwrap();
    assert_eq!((got.ignored, got.weights.width()), (1, 16));
    let e = import(&bytes, None).unwrap_err().to_string();
    assert!(e.contains("1 tensors are not part of the network"), "{e}");
}

/// `dict(module.named_parameters())`: each tensor wrapped as a parameter, read as the
/// tensor; an integer tensor where the network needs floats is refused by its type.
#[test]
fn a_dict_of_parameters_is_read_as_its_tensors() {
    for (class, size, want) in [
        ("FloatStorage", 4, None),
        ("LongStorage", 8, Some("found \"I64\"")),
    ] {
        let mut p = Pickle::new();
        p.dict();
        let mut storages = Vec::new();
        for (k, (_, bytes, dims)) in network().into_iter().enumerate() {
            let name = format!("{}.{}", 2 * (k / 2), ["weight", "bias"][k % 2]);
            let stride = if dims.len() == 2 {
                vec![dims[1], 1]
            } else {
                vec![1]
            };
            let (key, numel) = (format!("s{k}"), bytes.len() / size);
            let parameter = b"ctorch._utils\n_rebuild_parameter\n(";
            p.str(&name).op(parameter).tensor(|p| {
                let class = format!("ctorch\n{class}\n");
                p.op(b"(")
                    .str("storage")
                    .op(class.as_bytes())
                    .str(&key)
                    .str("cpu");
                p.int(numel as i32)
                    .op(b"tQ")
                    .int(0)
                    .ints(&dims)
                    .ints(&stride);
            });
            // requires_grad, no hooks.
            p.op(b"\x88}tR");
            storages.push((format!("archive/data/{key}"), bytes));
        }
        let bytes = torch_zip(&p.end(), &storages);
        match (import(&bytes, None), want) {
            (Ok(got), None) => assert_eq!(got.weights.width(), 16),
            (Err(e), Some(w)) => assert!(e.to_string().contains(w), "{e}"),
            (got, _) => panic!("{class}: {got:?}"),
        }
    }
}
