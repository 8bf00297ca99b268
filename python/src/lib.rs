//! `cartpole_ddqn`'s native module: the twin's worlds as Gymnasium environments
//! ([`env`], one world or many stepped in one call), policy files ([`policy`]), the
//! exporter ([`export`]) and the evaluation ([`evaluate`]), each through the code the
//! command-line tools run. The Python package around it (`python/cartpole_ddqn/`) registers the
//! environments and turns arguments and results into Python's.

use std::fmt::Display;
use std::ops::Range;
use std::path::Path;

use pyo3::exceptions::{PyMemoryError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use twin::Machine;
use weights::levels::GivenLevels;

mod env;
mod evaluate;
mod export;
mod lane;
mod policy;
mod swing;

/// A refused argument, as the `ValueError` Python callers expect, with the message that
/// says what was expected and what was found.
pub(crate) fn value_error(e: impl Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A call an environment's episode does not allow (a step before `reset()`, after
/// `close()` or past the episode's end), as the `RuntimeError` Gymnasium's CartPole raises:
/// every environment of the package raises the same.
pub(crate) fn not_running(what: &str) -> PyErr {
    PyRuntimeError::new_err(what.to_string())
}

/// A file refused or not written, as the tools tell them apart: bad input as `ValueError`
/// (their exit status 2), a failure of the system's (a full disk) as `OSError` (their 1), so
/// a caller catching `OSError` for a full disk sees it.
pub(crate) fn file_error(e: weights::Error) -> PyErr {
    if e.is_input() {
        value_error(e)
    } else {
        PyOSError::new_err(e.to_string())
    }
}

/// An allocation that failed, as the `MemoryError` Python callers expect, saying what it
/// was for.
pub(crate) fn memory_error(what: &str, bytes: usize) -> PyErr {
    PyMemoryError::new_err(format!("could not allocate {bytes} bytes for {what}"))
}

/// `v` with room for `more` items, or a `MemoryError` naming `what`.
pub(crate) fn reserve<T>(v: &mut Vec<T>, more: usize, what: &str) -> PyResult<()> {
    v.try_reserve_exact(more)
        .map_err(|_| memory_error(what, more.saturating_mul(size_of::<T>())))
}

/// Most worlds one vector environment holds. Each keeps its own scenario, world and
/// controller; Gymnasium's vectorised training runs a few hundred to a few thousand.
pub(crate) const MAX_ENVS: usize = 1 << 16;

/// Worlds a vector environment starts or steps between two looks at Python's signals: a
/// few milliseconds of work, so Ctrl-C stops it at once.
pub(crate) const WORLDS_PER_CHECK: u64 = 4096;

/// Runs `work` on `0..n` in consecutive ranges of at most `chunk` (at least 1), with the
/// GIL released, looking at Python's signals after each: Ctrl-C (`KeyboardInterrupt`)
/// stops it after the range in progress.
pub(crate) fn interruptible(
    py: Python<'_>,
    n: u64,
    chunk: u64,
    mut work: impl FnMut(Range<u64>) + Send,
) -> PyResult<()> {
    let mut start = 0;
    while start < n {
        let end = start.saturating_add(chunk.max(1)).min(n);
        py.detach(|| work(start..end));
        py.check_signals()?;
        start = end;
    }
    Ok(())
}

/// The duty levels a caller gave as `levels=`, checked as the firmware checks them.
pub(crate) fn given_levels(levels: Option<Vec<f64>>) -> PyResult<Option<GivenLevels>> {
    levels
        .map(|l| GivenLevels::new(&l, "levels"))
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

/// A Python `UserWarning` (which a caller can catch or filter) when the policy runs on
/// another machine than it was trained for.
pub(crate) fn warn_other_rig(
    py: Python<'_>,
    other: Option<twin::rigfile::OtherRig>,
) -> PyResult<()> {
    match other {
        Some(o) => warn(py, &o.warning("rig=")),
        None => Ok(()),
    }
}

/// `text` as a Python `UserWarning`, where the tools print a warning on standard error.
pub(crate) fn warn(py: Python<'_>, text: &str) -> PyResult<()> {
    let text = std::ffi::CString::new(text).map_err(value_error)?;
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    // Named at the caller of the package's wrapper, which calls this module.
    PyErr::warn(py, &category, &text, 2)
}

/// The machine of the rig file at `rig`, or Gymnasium's.
pub(crate) fn machine(rig: Option<&Path>) -> PyResult<Machine> {
    Ok(given_machine(rig)?.unwrap_or(Machine::GYMNASIUM))
}

#[pymodule]
mod _native {
    use super::*;

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        m.add("MAX_ENVS", MAX_ENVS)?;
        m.add("MAX_EPISODES", host_sim::eval::MAX_EPISODES)?;
        m.add("MAX_HORIZON", host_sim::eval::MAX_HORIZON)?;
        m.add("MAX_ROWS", host_sim::eval::MAX_ROWS)?;
        m.add("ROWS_PER_CHECK", policy::ROWS_PER_CHECK)?;
        Ok(())
    }

    #[pymodule_export]
    use super::env::{Twin, VecTwin};
    #[pymodule_export]
    use super::evaluate::{check_count, evaluate_json};
    #[pymodule_export]
    use super::export::export;
    #[pymodule_export]
    use super::policy::{Policy, load, shipped};
    #[pymodule_export]
    use super::provenance_json;
    #[pymodule_export]
    use super::swing::SwingUp;
}
