//! The loader against hostile bytes: random files and mutations of valid checkpoints never
//! panic, and whatever they give is either a checked network or a short message. A fixed
//! case budget keeps this in the normal test run; `fuzz/` runs the same loader for longer.

use proptest::prelude::*;
use proptest::test_runner::Config;
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
