//! Bytes into the ONNX reader: a model it accepts is a finite 4-H-H-2 network.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(got) = weights::checkpoint::onnx::import(data) {
        assert!(
            got.weights
                .tensors()
                .iter()
                .flatten()
                .all(|v| v.is_finite())
        );
    }
});
