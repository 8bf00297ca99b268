//! `--world` beside the board's rig: the world a board runs in must run at its period, and
//! (where the board has a machine without it) be another than the board's own.

use std::path::Path;

use twin::{Machine, Scenario};

/// Refuses a world (`--world`, at `path`) whose control period is not its board's
/// ([`twin::machine::same_period`]), naming both: the board's machine as `named` says.
pub fn same_period(
    world: &Machine,
    path: &Path,
    board: &Machine,
    named: &str,
) -> anyhow::Result<()> {
    twin::machine::same_period(&world.rig, &board.rig).map_err(|e| refused(path, named, e))
}

/// [`same_period`], and refuses a world in which the board's episodes run as on its own
/// machine: the board models its physics, tuning and margin whatever the world, so a world
/// of the board's physics, encoders, dead time and integration changes nothing.
pub fn check(world: &Machine, path: &Path, board: &Machine, named: &str) -> anyhow::Result<()> {
    same_period(world, path, board, named)?;
    let runs = Scenario::nominal_on(world).known_as(&board.rig);
    if runs.map_err(|e| refused(path, named, e))? == Scenario::nominal_on(board) {
        return Err(refused(
            path,
            named,
            "expected another machine than the board's, or --world left out; found the same \
             physics, encoders, dead time and integration, which build the board's own world \
             (the board models the rest)"
                .into(),
        ));
    }
    Ok(())
}

/// How a message names the board's machine: `--rig` where one was given, else the machine
/// --policy gives, else `default`, the command's own.
pub fn board_name(rig: Option<&Path>, policy: bool, default: &str) -> String {
    match (rig, policy) {
        (Some(r), _) => format!("--rig {}", weights::shown(r)),
        (None, true) => "the machine --policy gives (the rig it records, or Gymnasium's)".into(),
        (None, false) => default.into(),
    }
}

/// `--world` at `path` refused beside the board `named`, for `why`.
fn refused(path: &Path, named: &str, why: String) -> anyhow::Error {
    weights::Error::Input(format!(
        "--world {} and {named}: {why}",
        weights::shown(path)
    ))
    .into()
}
