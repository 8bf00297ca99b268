//! The shipped policy (the `shipped` crate): where it came from, that it is what it claims to be,
//! and that it balances.

use std::path::PathBuf;

use policy_export::config::Config;
use policy_export::run::write_run;
use policy_export::train;
use shipped::policy::POLICY;
use weights::Weights;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The one documented recipe of the shipped policy (docs/GUIDE.md, "The shipped policy";
/// docs/results/manifest.toml's first steps), with the fastest kernel this CPU runs: every
/// kernel trains the same bits.
const SHIPPED_SEED: u64 = 5;
fn shipped_config() -> Config {
    Config::deploy()
}

fn bits(tensors: &[Vec<f32>; 6]) -> Vec<u32> {
    tensors.iter().flatten().map(|v| v.to_bits()).collect()
}

#[test]
fn compiled_constants_equal_the_committed_safetensors_bit_for_bit() {
    let w = weights::checkpoint::load(&repo().join("shipped/policy.safetensors"), None).unwrap();
    let compiled = Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap();
    assert_eq!(bits(w.weights.tensors()), bits(compiled.tensors()));
}

#[test]
fn the_shipped_policy_regenerates_bit_identically() {
    let cfg = shipped_config();
    let result = train::train(&cfg, SHIPPED_SEED, &mut |_| {}).unwrap();
    assert_eq!(
        bits(result.policy.tensors()),
        bits(
            Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG)
                .unwrap()
                .tensors()
        ),
        "retraining the recipe no longer gives the shipped weights: \
         regenerate shipped/src/policy.rs as docs/GUIDE.md says, or find what changed"
    );
    // The files a user's `train` writes, through the same writer: the metadata too, so a
    // config that gains keys shows here rather than as a "differs" in the main job.
    let dir = std::env::temp_dir().join(format!("shipped-policy-{}", std::process::id()));
    write_run(&dir, &cfg, SHIPPED_SEED, &result).unwrap();
    for (written, committed) in [
        ("policy.rs", "shipped/src/policy.rs"),
        ("policy.safetensors", "shipped/policy.safetensors"),
    ] {
        assert!(
            std::fs::read(dir.join(written)).unwrap()
                == std::fs::read(repo().join(committed)).unwrap(),
            "{committed} is not what the recipe's run writes: regenerate it as docs/GUIDE.md says"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
