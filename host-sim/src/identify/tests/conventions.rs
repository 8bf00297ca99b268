//! The log format's signs, as `firmware::identify` states them, are the fit's: a log
//! written from the document's words by the tests' own cart-pole ([`independent`]) fits to
//! the truth, and one whose pole encoder is wired the other way is refused.

use super::independent::{self, Bench};
use super::*;

/// The desk rig as its builder measured it (`rigs/desk-measured.toml`): the motor a
/// datasheet's guess, the pole's centre of mass 1 cm short, the dead time unknown.
pub fn measured() -> Machine {
    twin::rigfile::load(&std::path::PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../rigs/desk-measured.toml"
    )))
    .unwrap()
}

/// `bench`'s cart (10 s, sequence `seed`) and swing (20 s) logs as the board running `board`
/// writes them.
pub fn bench_logs(bench: &Bench, board: &Rig, cart_s: f64, seed: u32) -> Vec<Log> {
    let cart = independent::cart_log(bench, board, cart_s, seed);
    let mut logs = log::parse(&cart, "cart").unwrap();
    logs.extend(log::parse(&independent::swing_log(bench, board, 20.0), "swing").unwrap());
    logs
}

/// The desk rig (`rigs/desk.toml`: 0.6 kg cart, 0.08 kg uniform pole with its centre of
/// mass at 0.22 m, 5 N stall and 3 N s/m, a period of dead time) on the tests' own bench,
/// with some friction at the pivot.
pub fn desk() -> Bench {
    Bench {
        pivot_n_m_s: 2e-4,
        ..Bench::uniform(0.6, 0.08, 0.22, [5.0, 3.0])
    }
}

#[test]
fn a_log_written_by_the_documents_words_fits_the_truth() {
    let board = measured();
    let bench = desk();
    for seed in [1, 2] {
        let logs = bench_logs(&bench, &board.rig, 10.0, seed);
        let fit = identify(&logs, &board).unwrap();
        let q = &fit.params;
        assert_eq!(fit.dead_time, 1, "seed {seed}");
        for (name, found, truth) in [
            ("stall force", q.force_mag, bench.stall_n),
            ("damping", q.motor_damping, bench.damping_n_s_per_m),
            ("pole length", q.length, bench.com_m),
        ] {
            assert!(
                relative(found, truth) < 1e-3,
                "seed {seed}: {name} {found}, truth {truth}"
            );
        }
        assert!(
            (q.pole_friction / bench.pivot_n_m_s - 1.0).abs() < 0.05,
            "{q:?}"
        );
        assert!(
            misfit::findings(&fit).is_empty(),
            "{:?}",
            report::warnings(&fit, &logs)
        );
    }
}

/// A board whose pole counts grow the other way (as the hanging pole's tip swings towards
/// +x): exit 2's refusal, naming the log and the fix.
#[test]
fn a_pole_wired_the_other_way_is_refused() {
    let board = measured();
    let bench = Bench {
        pole_as_documented: false,
        ..desk()
    };
    let logs = bench_logs(&bench, &board.rig, 10.0, 1);
    let e = identify(&logs, &board).unwrap_err().to_string();
    for want in [
        "cart: the pole's counts appear inverted",
        "as logged",
        "a hanging pole's tip towards -x",
        "swap the pole encoder's A and B",
    ] {
        assert!(e.contains(want), "{want:?} in {e}");
    }
    assert!(matches!(
        identify(&logs, &board),
        Err(weights::Error::Input(_))
    ));
}
