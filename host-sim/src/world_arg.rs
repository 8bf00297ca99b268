//! `--world` beside the board's rig: the world a board runs in must run at its period.

use std::path::Path;

use twin::Machine;

/// Refuses a world (`--world`, at `path`) whose control period is not its board's
/// ([`twin::machine::same_period`]), naming both: the board's rig is `--rig` where one was
/// given, else the policy's own.
pub fn same_period(
    world: &Machine,
    path: &Path,
    board: &Machine,
    rig: Option<&Path>,
) -> anyhow::Result<()> {
    twin::machine::same_period(&world.rig, &board.rig).map_err(|e| {
        let board = rig.map_or("the rig the policy records".into(), |r| {
            format!("--rig {}", weights::shown(r))
        });
        weights::Error::Input(format!("--world {} and {board}: {e}", weights::shown(path))).into()
    })
}
