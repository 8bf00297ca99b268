//! Bytes into the checkpoint importer (every format), with and without a chosen prefix,
//! within the readers' memory bound (`bound.rs`).
#![no_main]

use libfuzzer_sys::fuzz_target;

mod bound;

#[global_allocator]
static ALLOCATOR: bound::Bounded = bound::Bounded;

fuzz_target!(|data: &[u8]| {
    for prefix in [None, Some("q_net.q_net."), Some("")] {
        if let Ok(got) = bound::within(data.len(), || weights::checkpoint::import(data, prefix)) {
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
