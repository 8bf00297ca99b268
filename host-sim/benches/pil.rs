//! How fast the loop runs with the controller on a target: control periods a second of
//! `eval --pil` on one episode stream (one QEMU, this process's world and reference), per
//! target and format, and the same with the target built for the host, which computes each
//! period in about a microsecond, so its rate is the link's round trip alone.
//!
//! `cargo bench -p host-sim --bench pil` prints one row per target and format. It runs the
//! `pil` applications cargo built (`cargo build --release -p selftest-app --bin pil
//! [--target TARGET]`) and names the ones it did not find. The goal is 20,000 periods a
//! second in QEMU.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use firmware::link::Format;
use host_sim::eval::ControllerKind;
use host_sim::pil::link::Session;
use host_sim::pil::{Board, MACHINES, Place, handshake, run_row};
use twin::Scenario;

/// Episodes of 500 periods a row: 10,000 periods.
const EPISODES: u64 = 20;

/// Periods a second of `place` in `format` on the encoder scenario, best of two runs (a
/// busy machine only ever slows a run down); `None` when the link fails.
fn rate(place: &Place, format: Format) -> Option<f64> {
    let scenario = Scenario::parse("encoder").expect("a scenario");
    let mut best: Option<f64> = None;
    for _ in 0..2 {
        let mut remote = Session::new(place.start(Duration::from_secs(60)).ok()?);
        let mut here = Session::new(Board::Shipped.reference());
        let scenarios = std::slice::from_ref(&scenario);
        let info = handshake(&mut remote, &mut here, format, scenarios, Board::Shipped).ok()?;
        let t = Instant::now();
        let (_, check) = run_row(
            &mut remote,
            &mut here,
            (&info, ControllerKind::Policy),
            &scenario,
            500,
            0,
            EPISODES,
            || (),
        )
        .ok()?;
        let r = check.periods as f64 / t.elapsed().as_secs_f64();
        best = Some(best.map_or(r, |b| b.max(r)));
    }
    best
}

fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../target"),
        PathBuf::from,
    )
}

fn main() {
    let mut places = Vec::new();
    let host = target_dir().join("release/pil");
    match Place::parse(format!("exec:{}", host.display()), None, Board::Shipped) {
        Ok(p) => places.push(p),
        Err(e) => println!("skipped: {e}"),
    }
    for m in &MACHINES {
        match Place::parse(format!("qemu:{}", m.target), None, Board::Shipped) {
            Ok(p) => places.push(p),
            Err(e) => println!("skipped: {e}"),
        }
    }
    println!("{:<44} {:>8} {:>14}", "place", "format", "periods/s");
    for place in &places {
        for format in [Format::Int8, Format::F32] {
            let cell = rate(place, format).map_or("link failed".into(), |r| format!("{r:.0}"));
            println!(
                "{:<44} {:>8} {:>14}",
                place.name(),
                format!("{format:?}"),
                cell
            );
        }
    }
}
