//! The checkpoint importer's memory bound: the peak of one import within `FACTOR` times its
//! input plus a constant, measured by the counting allocator (`counting.rs`).

use crate::counting::peak_of;
use weights::checkpoint::import;

/// Peak memory per input byte allowed.
const FACTOR: usize = 2;
/// And beyond it: the pickle machine's stack and memo at its 65,536 opcodes, the six
/// tensors converted, a width-256 network for the Q-value check.
pub const SLACK: usize = 8 << 20;

/// Imports `bytes` with `prefix`, checks the peak memory of the import and returns its
/// message (or `ok`). The caller holds [`crate::counting::alone`].
pub fn bounded(what: &str, bytes: &[u8], prefix: Option<&str>) -> String {
    bounded_within(what, bytes, prefix, SLACK)
}

/// [`bounded`] for `weights::checkpoint::load` of the file at `path` (of `len` bytes),
/// which holds the file's bytes besides what the import holds.
pub fn loaded(what: &str, path: &std::path::Path, len: usize, prefix: Option<&str>) -> String {
    let (said, peak) = peak_of(|| match weights::checkpoint::load(path, prefix) {
        Ok(_) => "ok".to_string(),
        Err(e) => e.to_string(),
    });
    eprintln!("{what}: {len} bytes, peak {peak} bytes: {said}");
    assert!(
        peak <= (FACTOR + 1) * len + SLACK,
        "{what}: peak {peak} bytes for a file of {len}"
    );
    said
}

/// [`bounded`] with another constant than [`SLACK`].
pub fn bounded_within(what: &str, bytes: &[u8], prefix: Option<&str>, slack: usize) -> String {
    let (got, peak) = peak_of(|| import(bytes, prefix));
    let said = match got {
        Ok(_) => "ok".to_string(),
        Err(e) => e.to_string(),
    };
    eprintln!("{what}: {} bytes, peak {peak} bytes: {said}", bytes.len());
    assert!(
        peak <= FACTOR * bytes.len() + slack,
        "{what}: peak {peak} bytes for a file of {}",
        bytes.len()
    );
    assert!(
        said.len() < 2_000,
        "{what}: a message of {} bytes",
        said.len()
    );
    said
}
