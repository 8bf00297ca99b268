//! Safetensors bytes into the checkpoint importer, with and without a chosen prefix.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    for prefix in [None, Some("q_net.q_net."), Some("")] {
        if let Ok(got) = weights::checkpoint::import(data, prefix) {
            assert!(
                got.weights
                    .tensors()
                    .iter()
                    .flatten()
                    .all(|v| v.is_finite())
            );
        }
    }
});
