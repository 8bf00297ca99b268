//! A policy file loaded for Python: `weights::checkpoint::load` finds the network, and the
//! simulator's network (`host_sim::eval::Net`, the firmware's forward pass bit for bit)
//! computes its Q-values, as `host-sim eval --policy` runs it.

use std::path::PathBuf;
use std::sync::Arc;

use firmware::network::argmax;
use host_sim::eval::Net;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use twin::Machine;
use weights::Weights;
use weights::checkpoint::{self, Import};

use crate::{file_error, interruptible, reserve, value_error};

/// A Q-network and the machine it runs on.
#[pyclass(module = "cartpole_ddqn._native", frozen)]
pub struct Policy {
    /// The file's network; `None` for the policy compiled into the firmware.
    pub import: Option<Import>,
    /// The rig given, or the one the file records, or Gymnasium's.
    pub machine: Machine,
    /// Shared with the evaluation threads, which may outlive an interrupted call.
    pub net: Arc<Net>,
    /// The largest reading the network takes ([`weights::Weights::reading_bound`]).
    bound: f32,
}

/// The network at `path` (a policy file or a run directory), `prefix` choosing among several
/// in one file, on the machine of the rig file `rig` (without one, the rig the file records,
/// or Gymnasium's), its outputs driving the duty `levels` if its file records none
/// (`weights::levels`).
#[pyfunction]
#[pyo3(signature = (path, prefix=None, rig=None, levels=None))]
pub fn load(
    py: Python<'_>,
    path: PathBuf,
    prefix: Option<&str>,
    rig: Option<PathBuf>,
    levels: Option<Vec<f64>>,
) -> PyResult<Policy> {
    let given = crate::given_machine(rig.as_deref())?;
    let levels = crate::given_levels(levels)?;
    let import = checkpoint::load_with(&path, prefix, levels.as_ref()).map_err(file_error)?;
    let source = format!("policy {}", weights::shown(&path));
    let recorded = twin::rigfile::recorded(&import.metadata, &source).map_err(value_error)?;
    let (machine, other) = twin::rigfile::choose(given, recorded);
    crate::warn_other_rig(py, other)?;
    let net = Net::from_weights(&import.weights, None)
        .map_err(|e| value_error(format!("{source}: {e:#}")))?;
    Ok(Policy {
        bound: import.weights.reading_bound(),
        import: Some(import),
        machine,
        net: Arc::new(net),
    })
}

/// The policy compiled into the firmware, on Gymnasium's machine or `rig`'s.
#[pyfunction]
#[pyo3(signature = (rig=None))]
pub fn shipped(py: Python<'_>, rig: Option<PathBuf>) -> PyResult<Policy> {
    let given = crate::given_machine(rig.as_deref())?;
    let (machine, other) = twin::rigfile::choose(given, Some(Machine::GYMNASIUM));
    crate::warn_other_rig(py, other)?;
    let weights = Weights::from_mlp(&::shipped::policy::POLICY, &::shipped::policy::LEVELS)
        .map_err(value_error)?;
    Ok(Policy {
        import: None,
        machine,
        net: Arc::new(Net::shipped()),
        bound: weights.reading_bound(),
    })
}

impl Policy {
    /// The machine the policy was trained for: the rig its file records (none for a file
    /// that records none), Gymnasium's for the shipped policy.
    pub fn trained_for(&self) -> PyResult<Option<Machine>> {
        match &self.import {
            None => Ok(Some(Machine::GYMNASIUM)),
            Some(i) => twin::rigfile::recorded(&i.metadata, "policy").map_err(value_error),
        }
    }
}

#[pymethods]
impl Policy {
    /// Q-values `[n, A]` of readings `[n, 4]`, one column per duty level; `MemoryError` if
    /// they do not fit in memory.
    fn q_values<'py>(
        &self,
        py: Python<'py>,
        obs: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let rows = readings(&obs)?;
        let (n, a) = (rows.len(), self.net.levels().len());
        let mut q = Vec::new();
        reserve(&mut q, n.saturating_mul(a), "the Q-values")?;
        self.each(py, &rows, |v| q.extend_from_slice(v))?;
        PyArray1::from_vec(py, q).reshape([n, a])
    }

    /// The output the controller takes on each reading `[n, 4]` (with two levels, 1 right
    /// and 0 left; a tie is decided as the firmware decides it).
    fn act<'py>(
        &self,
        py: Python<'py>,
        obs: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let rows = readings(&obs)?;
        let mut a = Vec::new();
        reserve(&mut a, rows.len(), "the actions")?;
        self.each(py, &rows, |v| a.push(argmax(v) as i64))?;
        Ok(PyArray1::from_vec(py, a))
    }

    /// The largest reading (each channel within plus or minus it) whose forward pass stays
    /// within f32's range.
    #[getter]
    fn reading_bound(&self) -> f32 {
        self.bound
    }

    /// The duty level each output drives, as a fraction of the full push.
    #[getter]
    fn levels(&self) -> Vec<f32> {
        self.net.levels().iter().map(|d| d.fraction()).collect()
    }

    /// Where the network was found: its layers, prefix and width.
    #[getter]
    fn describe(&self) -> String {
        self.import.as_ref().map_or(
            "the policy compiled into the firmware".into(),
            Import::describe,
        )
    }
}

impl Policy {
    /// `out` of the network's outputs (one per level) on each of `rows` in order, the GIL
    /// released a range of rows at a time and Ctrl-C honoured between ranges.
    fn each(
        &self,
        py: Python<'_>,
        rows: &[[f32; 4]],
        mut out: impl FnMut(&[f32]) + Send,
    ) -> PyResult<()> {
        interruptible(py, rows.len() as u64, ROWS_PER_CHECK, |r| {
            let rows = &rows[r.start as usize..r.end as usize];
            rows.iter().for_each(|o| out(self.net.forward(o).values()));
        })
    }
}

/// Readings a forward pass runs between two looks at Python's signals: milliseconds. The
/// Python package converts and checks readings a range of this many at a time too.
pub(crate) const ROWS_PER_CHECK: u64 = 16384;

/// The rows of `obs`, which must be `[n, 4]`, copied (the GIL is released as the network
/// runs on them); `MemoryError` if they do not fit.
fn readings(obs: &PyReadonlyArray2<'_, f32>) -> PyResult<Vec<[f32; 4]>> {
    let v = obs.as_array();
    if v.ncols() != 4 {
        return Err(value_error(format!(
            "expected readings of 4 values [x, x_dot, theta, theta_dot]; found {}",
            v.ncols()
        )));
    }
    let mut rows = Vec::new();
    reserve(&mut rows, v.nrows(), "the readings")?;
    rows.extend(v.rows().into_iter().map(|r| [r[0], r[1], r[2], r[3]]));
    Ok(rows)
}
