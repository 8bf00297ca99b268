//! The fit's memory and work grow in proportion to the logs, counted rather than timed: an
//! allocator of this test binary's own counts the bytes live at the fit's peak and the
//! bytes allocated in all (every working buffer, the Jacobians' blocks and the normal
//! equations' among them), and the fit counts the periods it simulates. A dense Jacobian
//! (rows times parameters, both growing with the logs) would make each of these, per
//! logged period, grow with the logs' length; here they stay flat.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use host_sim::identify::{self, Log, log, synthetic};

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static TOTAL: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(live, Ordering::Relaxed);
    TOTAL.fetch_add(bytes, Ordering::Relaxed);
}

// SAFETY: every call is passed on to the system allocator unchanged; only counters move.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        grew(new_size);
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// What one fit took, per logged period: bytes live at its peak beyond those before it,
/// bytes allocated, periods simulated.
fn per_period(logs: &[Log], machine: &twin::Machine) -> [f64; 3] {
    let periods: usize = logs.iter().map(|l| l.duty.len()).sum();
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let total = TOTAL.load(Ordering::Relaxed);
    let fit = identify::identify(logs, machine).expect("logs the fit takes");
    let peak = PEAK.load(Ordering::Relaxed) - before;
    let allocated = TOTAL.load(Ordering::Relaxed) - total;
    let n = periods as f64;
    [
        peak as f64 / n,
        allocated as f64 / n,
        fit.evaluated as f64 / n,
    ]
}

/// The desk rig's cart experiment of 30, 60 and 120 s (beside the same 20 s swing): the
/// longest's peak memory, allocations and simulated periods per logged period within 1.5
/// times the shortest's.
#[test]
fn memory_and_work_grow_in_proportion_to_the_logs() {
    let rigs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../rigs");
    let truth = twin::rigfile::load(&rigs.join("desk.toml")).unwrap();
    let measured = twin::rigfile::load(&rigs.join("desk-measured.toml")).unwrap();
    let mut rows = Vec::new();
    for cart_s in [30.0, 60.0, 120.0] {
        let texts = synthetic::experiments_lasting(
            &truth,
            &measured.rig,
            (1, Default::default()),
            [cart_s, 20.0],
        );
        let logs: Vec<Log> = texts
            .iter()
            .flat_map(|t| log::parse(t, "synthetic").unwrap())
            .collect();
        let row = per_period(&logs, &measured);
        println!(
            "cart {cart_s:>5} s: {:8.0} bytes live at the peak, {:10.0} allocated, {:6.1} \
             periods simulated, per logged period",
            row[0], row[1], row[2]
        );
        rows.push(row);
    }
    for (i, what) in ["peak memory", "allocations", "work"]
        .into_iter()
        .enumerate()
    {
        let (first, last) = (rows[0][i], rows[rows.len() - 1][i]);
        assert!(
            last <= 1.5 * first,
            "{what} per logged period grew from {first:.1} to {last:.1}"
        );
    }
}
