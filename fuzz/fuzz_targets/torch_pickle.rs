//! Bytes into the restricted reader of a state dict's pickle (`data.pkl` in PyTorch's zip):
//! it must refuse or read, never run anything, panic, or overflow its stack.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(tensors) = weights::checkpoint::pickle::state_dict(data) {
        assert!(tensors.iter().all(|(_, t)| t.shape.len() == t.stride.len()));
    }
});
