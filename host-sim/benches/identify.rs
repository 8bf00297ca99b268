//! How long identification takes on one core: one cart and one swing experiment (about 30 s
//! of logs, `synthetic::experiments`) of a desk rig fitted from the rig file its builder
//! wrote, the motor, friction, length and dead time wrong.
//!
//! `cargo bench -p host-sim --bench identify` prints one row per rig: the fit's time (the
//! best of three runs, since a busy machine only ever slows a run down), the dead time found
//! against the true one, and how far each goal's unknown landed from the truth. The goal is
//! under 10 s a fit.

use std::path::PathBuf;
use std::time::Instant;

use host_sim::identify::{self, Log, log, synthetic};
use twin::Machine;
use twin::machine::Integration;

/// Fits a run takes, the best of which is reported.
const REPETITIONS: usize = 3;

/// The desk rig at period `tau` with dead time `dead`, friction on, its world five times
/// finer than a rig file's default; and the rig file that starts the fit.
fn rig(tau: f64, dead: u32, force: f64) -> (Machine, Machine) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../rigs/desk.toml");
    let mut truth = twin::rigfile::load(&path).expect("rigs/desk.toml");
    let p = &mut truth.rig.params;
    p.tau = tau;
    p.force_mag = force;
    p.cart_friction = 0.02;
    p.pole_friction = 3e-4;
    truth.rig.dead_time = dead;
    let mut measured = truth;
    truth.integration = Integration::rk4(tau, 0.0002);
    measured.integration = Integration::rk4(tau, twin::rigfile::DEFAULT_SUBSTEP_S);
    let q = &mut measured.rig.params;
    q.force_mag *= 1.5;
    q.motor_damping *= 0.6;
    q.length *= 0.93;
    q.cart_friction = 0.0;
    q.pole_friction = 0.0;
    measured.rig.dead_time = 1;
    (truth, measured)
}

fn percent(found: f64, truth: f64) -> f64 {
    100.0 * (found / truth - 1.0)
}

fn main() {
    println!(
        "{:>6} {:>5} {:>6} {:>7} {:>9} {:>9} {:>9} {:>9}",
        "tau_s", "dead", "F_N", "logs_s", "fit_s", "F_err%", "b_err%", "l_err%"
    );
    for (tau, dead, force) in [
        (0.02, 1, 5.0),
        (0.02, 3, 10.0),
        (0.01, 0, 5.0),
        (0.01, 2, 8.0),
    ] {
        let (truth, measured) = rig(tau, dead, force);
        let logs: Vec<Log> = synthetic::experiments(&truth, &measured.rig, 1, Default::default())
            .iter()
            .flat_map(|text| log::parse(text, "synthetic").expect("a board's log"))
            .collect();
        let seconds: f64 = logs.iter().map(|l| l.duty.len() as f64 * tau).sum();
        let mut best = f64::INFINITY;
        let mut fit = None;
        for _ in 0..REPETITIONS {
            let t = Instant::now();
            fit = Some(identify::identify(&logs, &measured).expect("logs the fit takes"));
            best = best.min(t.elapsed().as_secs_f64());
        }
        let Some(fit) = fit else { return };
        let (q, p) = (&fit.params, &truth.rig.params);
        println!(
            "{tau:>6} {:>5} {force:>6} {seconds:>7.1} {best:>9.2} {:>9.3} {:>9.3} {:>9.3}{}",
            format!("{}/{dead}", fit.dead_time),
            percent(q.force_mag, p.force_mag),
            percent(q.motor_damping, p.motor_damping),
            percent(q.length, p.length),
            if fit.dead_time == dead {
                ""
            } else {
                "  (dead time wrong)"
            }
        );
    }
}
