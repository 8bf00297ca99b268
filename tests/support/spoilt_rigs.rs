//! `rigs/desk.toml` spoilt four ways, for the tests of every tool that takes `--rig` (each
//! includes this file): made from the rig file as it stands, so they follow its format.

use std::path::{Path, PathBuf};

/// The spoilt files, written into `dir`: each file and the field its refusal must name.
pub fn bad_rigs(dir: &Path) -> Vec<(PathBuf, &'static str)> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let desk = std::fs::read_to_string(repo.join("rigs/desk.toml")).unwrap();
    let spoilt = [
        ("missing", "period_s = 0.02\n", "", "period_s"),
        ("nan", "period_s = 0.02", "period_s = nan", "period_s"),
        (
            "negative-mass",
            "cart_mass_kg = 0.6",
            "cart_mass_kg = -0.6",
            "cart_mass_kg",
        ),
        ("zero-period", "period_s = 0.02", "period_s = 0", "period_s"),
    ];
    spoilt
        .iter()
        .map(|&(name, from, to, field)| {
            assert!(desk.contains(from), "rigs/desk.toml no longer has {from:?}");
            let path = dir.join(format!("{name}.toml"));
            std::fs::write(&path, desk.replacen(from, to, 1)).unwrap();
            (path, field)
        })
        .collect()
}
