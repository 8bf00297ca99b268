//! Which machine a policy runs on: the rig given with it, or the one its file records, and
//! a warning where the two differ.

use super::parse;
use crate::machine::Machine;
use weights::Result;

/// The key under which a policy file's metadata records the rig it was trained for, as a
/// rig file's text.
pub const METADATA_KEY: &str = "rig";

/// The machine a policy file's metadata records (`None` for a file without one: a PyTorch
/// checkpoint); `source` names the policy in a refusal (`policy runs/x`).
pub fn recorded(
    metadata: &std::collections::BTreeMap<String, String>,
    source: &str,
) -> Result<Option<Machine>> {
    metadata
        .get(METADATA_KEY)
        .map(|text| parse(text, &format!("{source}: its recorded rig")))
        .transpose()
}

/// The machine to run a policy with: `given` (a rig file given with it) or, without one, the
/// rig the policy file records or Gymnasium's; with [`OtherRig`] when the two differ, since
/// the policy was trained for another machine.
pub fn choose(given: Option<Machine>, recorded: Option<Machine>) -> (Machine, Option<OtherRig>) {
    match (given, recorded) {
        (Some(g), Some(r)) if g != r => (g, Some(OtherRig)),
        (Some(g), _) => (g, None),
        (None, Some(r)) => (r, None),
        (None, None) => (Machine::GYMNASIUM, None),
    }
}

/// [`choose`] for a command line, its warning on standard error naming `--rig`.
pub fn choose_warned(given: Option<Machine>, recorded: Option<Machine>) -> Machine {
    let (machine, other) = choose(given, recorded);
    warn(other);
    machine
}

/// A command line's warning of [`OtherRig`], on standard error, naming `--rig`.
pub fn warn(other: Option<OtherRig>) {
    if let Some(o) = other {
        host_common::errln!("warning: {}", o.warning("--rig"));
    }
}

/// A policy run on another machine than the one it was trained for.
#[derive(Debug, PartialEq)]
pub struct OtherRig;

impl OtherRig {
    /// The warning, naming the rig given as `given` (`--rig`, `rig=`).
    pub fn warning(&self, given: &str) -> String {
        format!(
            "the policy was trained for another rig than {given} gives; its predictor, \
             observer and limits will model the machine {given} describes"
        )
    }
}
