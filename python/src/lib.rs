//! `cartpole_ddqn`'s native module: the twin's worlds as Gymnasium environments
//! ([`env`], one world or many stepped in one call), policy files ([`policy`]), the
//! exporter ([`export`]) and the evaluation ([`evaluate`]), each through the code the
//! command-line tools run. The Python package around it (`python/cartpole_ddqn/`) registers the
//! environments and turns arguments and results into Python's.

use std::fmt::Display;
use std::path::Path;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use twin::Machine;
use weights::levels::GivenLevels;

mod env;
mod evaluate;
mod export;
mod lane;
mod policy;

/// A refused argument, as the `ValueError` Python callers expect, with the message that
/// says what was expected and what was found.
pub(crate) fn value_error(e: impl Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The duty levels a caller gave as `levels=`, checked as the firmware checks them.
pub(crate) fn given_levels(levels: Option<Vec<f32>>) -> PyResult<Option<GivenLevels>> {
    levels
        .map(|l| GivenLevels::new(l, "levels"))
        .transpose()
        .map_err(value_error)
}

/// The record a results file keeps of the run that wrote it (`host_common::provenance`), as
/// JSON: a run of `tool` (a script's path from the repository's root) with `argv`, now, here.
/// The Python scripts' results carry the same record as the tools'.
#[pyfunction]
fn provenance_json(tool: &str, argv: Vec<String>) -> PyResult<String> {
    let p = host_common::provenance::Provenance::new(tool, argv);
    serde_json::to_string(&p).map_err(value_error)
}

/// The machine of the rig file at `rig`, if one is given.
pub(crate) fn given_machine(rig: Option<&Path>) -> PyResult<Option<Machine>> {
    rig.map(twin::rigfile::load)
        .transpose()
        .map_err(value_error)
}

/// The machine of the rig file at `rig`, or Gymnasium's.
pub(crate) fn machine(rig: Option<&Path>) -> PyResult<Machine> {
    Ok(given_machine(rig)?.unwrap_or(Machine::GYMNASIUM))
}

#[pymodule]
mod _native {
    #[pymodule_export]
    use super::env::{Twin, VecTwin};
    #[pymodule_export]
    use super::evaluate::evaluate_json;
    #[pymodule_export]
    use super::export::export;
    #[pymodule_export]
    use super::policy::{Policy, load, shipped};
    #[pymodule_export]
    use super::provenance_json;
}
