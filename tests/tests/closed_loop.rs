//! Train -> save -> load -> balance, across the crates, through the firmware's
//! `Controller` and the digital twin.

use host_sim::eval::{ControllerKind, Net, evaluate};
use policy_export::config::Config;
use policy_export::train;
use twin::Scenario;
use weights::checkpoint::{load, to_safetensors};
use weights::files::write_atomic;

#[test]
fn a_small_trained_policy_round_trips_and_balances_better_than_random() {
    // A short robust-preset run: 120 episodes, seconds of training, far from the full budget.
    let cfg = Config {
        episodes: 120,
        ..Config::robust()
    };
    let run = train::train(&cfg, 3, &mut |_| {}).unwrap();
    let dir = std::env::temp_dir().join(format!("e2e-closed-loop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("policy.safetensors");
    write_atomic(
        &file,
        &to_safetensors(&run.policy, &Default::default()).unwrap(),
    )
    .unwrap();

    let loaded = load(&file, None).unwrap().weights;
    assert_eq!(loaded, run.policy);
    let net = Net::from_weights(&loaded, None).unwrap();
    let nominal = Scenario::nominal();
    let policy = evaluate(ControllerKind::Policy, &net, &nominal, 500, 9, 100);
    let random = evaluate(ControllerKind::Random, &net, &nominal, 500, 9, 100);
    assert!(
        policy.mean_steps - policy.mean_steps_ci95 > random.mean_steps + random.mean_steps_ci95,
        "trained {:.1} ± {:.1} steps vs random {:.1} ± {:.1}",
        policy.mean_steps,
        policy.mean_steps_ci95,
        random.mean_steps,
        random.mean_steps_ci95
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_shipped_policy_passes_the_500_step_horizon_on_100_seeded_starts() {
    let net = Net::shipped();
    let row = evaluate(
        ControllerKind::Policy,
        &net,
        &Scenario::nominal(),
        500,
        2024,
        100,
    );
    assert_eq!(row.episodes, 100);
    assert_eq!(row.success_rate, 1.0, "{row:?}");
    assert_eq!(row.min_steps, 500);
    assert_eq!(row.faults, 0);
}
