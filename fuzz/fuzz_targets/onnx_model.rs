//! Bytes into the ONNX reader: a model it accepts is a finite 4-H-H-2 network, and no model
//! makes it hold more than its memory bound (`bound.rs`).
#![no_main]

use libfuzzer_sys::fuzz_target;

mod bound;

#[global_allocator]
static ALLOCATOR: bound::Bounded = bound::Bounded;

fuzz_target!(|data: &[u8]| {
    if let Ok(got) = bound::within(data.len(), || weights::checkpoint::onnx::import(data, None)) {
        assert!(
            got.weights
                .tensors()
                .iter()
                .flatten()
                .all(|v| v.is_finite())
        );
    }
});
