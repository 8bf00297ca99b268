//! The checkpoint readers' memory bound, enforced while they are fuzzed: the global
//! allocator counts live bytes and aborts (a crash libFuzzer keeps) when one input's
//! reading holds more than [`PER_BYTE`] bytes per input byte plus [`SLACK`] above what was
//! live before it. The readers' own tests (`weights/tests/memory_bound.rs`) hold a tighter
//! bound; this one is what `docs/HOSTILE_INPUT.md` promises.
//!
//! `GlobalAlloc` is an unsafe trait: every call is forwarded to the system allocator
//! unchanged, and only counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering::SeqCst};

/// Bytes the readers may hold per input byte.
pub const PER_BYTE: usize = 4;
/// And beyond that: the pickle machine at its opcode limit, a safetensors header's parse,
/// the network's tensors converted.
pub const SLACK: usize = 8 << 20;

pub struct Bounded;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static MOST: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let now = LIVE.fetch_add(by, SeqCst) + by;
    PEAK.fetch_max(now, SeqCst);
    if now > LIMIT.load(SeqCst) {
        LIMIT.store(usize::MAX, SeqCst);
        let _ = std::io::stderr().write_all(b"bound: a reader exceeded its memory bound\n");
        std::process::abort();
    }
}

// SAFETY: each call goes to `System` with the caller's own arguments, which satisfy
// `System`'s contract as they satisfy this one's; the counters never change a result.
unsafe impl GlobalAlloc for Bounded {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as above.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as above.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System` with `layout`: every allocation here does.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), SeqCst);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new: usize) -> *mut u8 {
        // SAFETY: as for `dealloc`; `new` is the caller's valid size.
        let p = unsafe { System.realloc(ptr, layout, new) };
        if !p.is_null() {
            LIVE.fetch_sub(layout.size(), SeqCst);
            grew(new);
        }
        p
    }
}

/// Runs `read` with the bound for an input of `len` bytes in force, and prints the largest
/// peak seen so far each time it grows by a quarter.
pub fn within<T>(len: usize, read: impl FnOnce() -> T) -> T {
    let base = LIVE.load(SeqCst);
    PEAK.store(base, SeqCst);
    LIMIT.store(base + PER_BYTE * len + SLACK, SeqCst);
    let out = read();
    LIMIT.store(usize::MAX, SeqCst);
    let peak = PEAK.load(SeqCst) - base;
    if peak > MOST.load(SeqCst) + MOST.load(SeqCst) / 4 {
        MOST.store(peak, SeqCst);
        eprintln!("bound: peak {peak} bytes above the input, for an input of {len} bytes");
    }
    out
}
