//! `Trace`: a traced bench's metrics, per-unit maps and flux ledger.

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use spibench::optics::Arm;
use spibench::pipeline::Traced;
use spibench::pipeline::evaluate::{self, Evaluation};

use crate::kernel::PyArm;
use crate::vec1;

/// A traced bench (see `spibench.Trace`).
#[pyclass(frozen, module = "spibench._spibench")]
pub(crate) struct Trace {
    pub(crate) traced: Traced,
    pub(crate) evaluation: Evaluation,
}

#[pymethods]
impl Trace {
    /// The recorded numbers of `sweep` against `reference` (itself when None).
    #[pyo3(signature = (reference=None))]
    fn values(&self, reference: Option<&Trace>) -> Vec<(String, f64)> {
        let r = reference.map_or(&self.evaluation, |r| &r.evaluation);
        evaluate::values(&self.evaluation, r)
    }

    /// Lamp rays traced.
    #[getter]
    fn rays(&self) -> u64 {
        self.traced.rays
    }

    /// Seed of the trace.
    #[getter]
    fn seed(&self) -> u64 {
        self.traced.seed
    }

    /// (down, across) DMD units.
    #[getter]
    fn units(&self) -> (usize, usize) {
        let t = &self.traced.transport;
        (t.units_down, t.units_across)
    }

    /// The power incident on each unit x_j (W), units row-major (down, across).
    fn x_w<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.traced.transport.x_w.clone())
    }

    /// The per-unit gains g_j of `arm` (A).
    fn g_a<'py>(&self, py: Python<'py>, arm: PyArm) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.traced.transport.g_a[Arm::from(arm)].clone())
    }

    /// k_j = g_j / x_j of `arm` (A/W).
    fn k_a_per_w<'py>(&self, py: Python<'py>, arm: PyArm) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.traced.transport.k_map[Arm::from(arm)].clone())
    }

    /// The standard errors of k_j of `arm` (A/W).
    fn k_stderr_a_per_w<'py>(&self, py: Python<'py>, arm: PyArm) -> Bound<'py, PyArray1<f64>> {
        vec1(
            py,
            self.traced.transport.k_map_stderr[Arm::from(arm)].clone(),
        )
    }

    /// T[d][s][j] (A), the four blocks in `BatchTally::t_block` order (d·2 + s).
    fn t_a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.traced.transport.t_a.clone())
    }

    /// The flux ledger: per world (+, −) absorbed per element, escaped, path cap, detected.
    fn ledger<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let l = &self.traced.transport.ledger;
        let d = PyDict::new(py);
        d.set_item("emitted_w", l.emitted_w)?;
        d.set_item("emitted_nominal_w", l.emitted_nominal_w)?;
        d.set_item("outside_cone_w", l.outside_cone_w)?;
        for (name, w) in ["plus", "minus"].iter().zip(&l.worlds) {
            let wd = PyDict::new(py);
            wd.set_item("absorbed_w", w.absorbed_w.clone())?;
            wd.set_item("escaped_w", w.escaped_w)?;
            wd.set_item("path_cap_w", w.path_cap_w)?;
            wd.set_item("detected_w", w.detected_w.to_vec())?;
            wd.set_item("sampled_w", w.sampled_w)?;
            wd.set_item("residual_w", w.residual_w)?;
            d.set_item(format!("world_{name}"), wd)?;
        }
        Ok(d)
    }
}
