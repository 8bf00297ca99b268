//! A global allocator that counts: the peak of live bytes during one import, for the
//! memory bounds of `memory_bound.rs`.
//!
//! The allocator is the one `unsafe` of the crate's tests: `GlobalAlloc` is an unsafe trait.
//! It forwards every call to the system allocator unchanged and only counts.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::SeqCst};
use std::sync::{Mutex, MutexGuard};

use weights::checkpoint::import;

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let now = LIVE.fetch_add(by, SeqCst) + by;
    PEAK.fetch_max(now, SeqCst);
}

// SAFETY: every call is passed to `System` with its own arguments, as `GlobalAlloc`
// requires of a forwarding allocator; the counters are atomics and never affect the result.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc` is `System.alloc`'s.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation is).
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), SeqCst);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new: usize) -> *mut u8 {
        // SAFETY: as for `dealloc`, and `new` is the caller's valid size.
        let p = unsafe { System.realloc(ptr, layout, new) };
        if !p.is_null() {
            LIVE.fetch_sub(layout.size(), SeqCst);
            grew(new);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Peak memory per input byte allowed.
const FACTOR: usize = 2;
/// And beyond it: the pickle machine's stack and memo at its 65,536 opcodes, the six
/// tensors converted, a width-256 network for the Q-value check.
pub const SLACK: usize = 8 << 20;

/// Tests run one at a time here, so that one's allocations (making its files, say) are not
/// counted in another's measurement.
static ONE: Mutex<()> = Mutex::new(());

/// Holds the other tests of the binary back while it lives: every test takes it first.
pub fn alone() -> MutexGuard<'static, ()> {
    ONE.lock().unwrap_or_else(|p| p.into_inner())
}

/// Imports `bytes` with `prefix`, checks the peak memory of the import and returns its
/// message (or `ok`). The caller holds [`alone`].
pub fn bounded(what: &str, bytes: &[u8], prefix: Option<&str>) -> String {
    bounded_within(what, bytes, prefix, SLACK)
}

/// [`bounded`] for `weights::checkpoint::load` of the file at `path` (of `len` bytes),
/// which holds the file's bytes besides what the import holds.
pub fn loaded(what: &str, path: &std::path::Path, len: usize, prefix: Option<&str>) -> String {
    let base = LIVE.load(SeqCst);
    PEAK.store(base, SeqCst);
    let said = match weights::checkpoint::load(path, prefix) {
        Ok(_) => "ok".to_string(),
        Err(e) => e.to_string(),
    };
    let peak = PEAK.load(SeqCst) - base;
    eprintln!("{what}: {len} bytes, peak {peak} bytes: {said}");
    assert!(
        peak <= (FACTOR + 1) * len + SLACK,
        "{what}: peak {peak} bytes for a file of {len}"
    );
    said
}

/// [`bounded`] with another constant than [`SLACK`].
pub fn bounded_within(what: &str, bytes: &[u8], prefix: Option<&str>, slack: usize) -> String {
    let base = LIVE.load(SeqCst);
    PEAK.store(base, SeqCst);
    let got = import(bytes, prefix);
    let peak = PEAK.load(SeqCst) - base;
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
