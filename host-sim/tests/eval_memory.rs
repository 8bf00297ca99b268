//! What a row of `eval` keeps per episode, counted by an allocator of this test binary's
//! own rather than read from the process's size: `docs/HOSTILE_INPUT.md`'s bound on
//! `eval --episodes` (a row keeps [`EPISODE_BYTES`] an episode, 720 MB at the limit) is
//! this test's. A parallel collect held every episode twice at its end, and the row's
//! statistics sorted a copy of the lengths and a list per figure: about 137 bytes an
//! episode, where the documents said 48.

#[path = "../../weights/tests/support/counting.rs"]
mod counting;

use counting::{alone, peak_of};
use host_sim::eval::{self, ControllerKind, EPISODE_BYTES, MAX_EPISODES, Net};
use twin::{EpisodeStats, Scenario};

#[test]
fn a_row_keeps_its_episodes_statistics_and_little_more() {
    let _alone = alone();
    assert_eq!(size_of::<EpisodeStats>(), EPISODE_BYTES);
    // The documents' figure: 72 bytes an episode, 720 MB at the limit.
    assert_eq!(
        (EPISODE_BYTES, EPISODE_BYTES as u64 * MAX_EPISODES),
        (72, 720_000_000)
    );
    let (net, nominal) = (Net::shipped(), Scenario::parse("nominal").unwrap());
    // Each thread holds a chunk of episodes' state at the peak, so the threads are fixed at
    // two: with one a processor, a many-core machine would pass the allowance below.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let n = 200_000;
    let (row, peak) = pool.install(|| {
        // Warm the thread pool, so that its start is not counted.
        eval::evaluate(ControllerKind::Lqr, &net, &nominal, 1, 0, 1000);
        peak_of(|| eval::evaluate(ControllerKind::Lqr, &net, &nominal, 1, 0, n))
    });
    assert_eq!(row.episodes, n as usize);
    // A chunk of episodes per thread, the row's own fields and the pool's bookkeeping: 1 MiB
    // is 5 bytes an episode, so a row keeping much more than its 72 fails.
    let besides = 1 << 20;
    assert!(
        peak <= n as usize * EPISODE_BYTES + besides,
        "{peak} bytes at the peak for {n} episodes: {} an episode",
        peak as f64 / n as f64
    );
}
