//! `Trace`: a traced bench's metrics, per-unit maps and flux ledger.

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use spibench::error::Error;
use spibench::pipeline::Traced;
use spibench::pipeline::evaluate::{self, Evaluation};

use crate::{to_py, vec1};

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

    #[getter]
    fn rays(&self) -> u64 {
        self.traced.rays
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.traced.seed
    }

    #[getter]
    fn units(&self) -> (usize, usize) {
        let t = &self.traced.transport;
        (t.units_down, t.units_across)
    }

    /// The per-unit maps by name: x_w, g_plus_a, g_minus_a, k_plus_a_per_w, …, t_a (4 blocks).
    fn map<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let t = &self.traced.transport;
        let v = match name {
            "x_w" => t.x_w.clone(),
            "g_plus_a" => t.g_a[0].clone(),
            "g_minus_a" => t.g_a[1].clone(),
            "k_plus_a_per_w" => t.k_map[0].clone(),
            "k_minus_a_per_w" => t.k_map[1].clone(),
            "k_plus_stderr_a_per_w" => t.k_map_stderr[0].clone(),
            "k_minus_stderr_a_per_w" => t.k_map_stderr[1].clone(),
            "t_a" => t.t_a.clone(),
            _ => return Err(to_py(Error::field("name", format!("no map {name:?}")))),
        };
        Ok(vec1(py, v))
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
