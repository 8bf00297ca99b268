//! Bytes into the restricted reader of a state dict's pickle (`data.pkl` in PyTorch's zip):
//! it must refuse or read, never run anything, panic, overflow its stack, or hold more than
//! its memory bound (`bound.rs`).
#![no_main]

use libfuzzer_sys::fuzz_target;

mod bound;

#[global_allocator]
static ALLOCATOR: bound::Bounded = bound::Bounded;

fuzz_target!(|data: &[u8]| {
    if let Ok(tensors) = bound::within(data.len(), || weights::checkpoint::pickle::state_dict(data))
    {
        assert!(tensors.iter().all(|(_, t)| t.shape.len() == t.stride.len()));
    }
});
