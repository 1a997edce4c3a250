//! `spibench._spibench`: the extension module under the `spibench` Python package.
//!
//! A thin layer over the library: every computation is the library's own function (the
//! evaluate step's trace, the object kernel, `Transport::from_kernel` with the record stage,
//! `pipeline::operator::TracedOperator`, the TVAL3 solver, `dataset::generate`). Arrays cross as
//! contiguous float64 numpy arrays, already checked for shape and dtype by the Python layer
//! (`spibench/`), and checked again here for length and finiteness. Closed sets cross as
//! classes (`Arm`, `MirrorState`), results with several parts as classes with named fields
//! (`Csr`, `Product`, `Estimate`, `Coefficients`, `Solution`); strings only where the public
//! API takes them (scheme keys, the record model, variable paths). Errors become
//! `InputError` (a `ValueError`) for input a user can fix, `OSError` for files, `RuntimeError`
//! otherwise, each with the library's located message. Long calls release the GIL and run on
//! the library's threads (`threads=`, default the global pool); results do not depend on the
//! thread count.

use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

use spibench::acquisition::Scheme;
use spibench::error::{Error, Result};

mod acquisition;
mod bench;
mod contract;
mod dataset;
mod kernel;
mod trace;

create_exception!(
    _spibench,
    InputError,
    PyValueError,
    "Input a user can fix (a bench file, a variable path, an argument); the message names the \
     file, line and field or the argument, as the command line prints it."
);

pub(crate) fn to_py(e: Error) -> PyErr {
    let text = e.to_string();
    match e {
        Error::Input { .. } => InputError::new_err(text),
        Error::Io { .. } => PyOSError::new_err(text),
        Error::Numerical(_) => PyRuntimeError::new_err(text),
    }
}

/// Runs `f` without the GIL, on a pool of `threads` threads (the global pool when None).
pub(crate) fn run<T: Send>(
    py: Python<'_>,
    threads: Option<usize>,
    f: impl FnOnce() -> Result<T> + Send,
) -> PyResult<T> {
    py.detach(|| match threads {
        None => f(),
        Some(0) => Err(Error::field("threads", "at least one thread is needed")),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| Error::Numerical(format!("cannot start {n} threads: {e}")))?
            .install(f),
    })
    .map_err(to_py)
}

pub(crate) fn scheme_named(name: &str) -> Result<Scheme> {
    name.parse()
}

pub(crate) fn vec1<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    v.into_pyarray(py)
}

pub(crate) fn vec2<'py>(
    py: Python<'py>,
    v: Vec<f64>,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    v.into_pyarray(py).reshape([rows, cols])
}

/// The rows of a C-contiguous 2-D float64 array, named `what` in errors.
pub(crate) fn rows_of<'a>(
    a: &'a PyReadonlyArray2<'_, f64>,
    what: &str,
    cols: usize,
) -> Result<&'a [f64]> {
    let shape = a.as_array().shape().to_vec();
    if shape[1] != cols {
        return Err(Error::field(
            what,
            format!("has {} values per item, {cols} are needed", shape[1]),
        ));
    }
    a.as_slice()
        .map_err(|_| Error::field(what, "must be a C-contiguous array"))
}

/// The library's version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _spibench(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("InputError", m.py().get_type::<InputError>())?;
    m.add_class::<bench::Bench>()?;
    m.add_class::<trace::Trace>()?;
    m.add_class::<kernel::Kernel>()?;
    m.add_class::<acquisition::Acquisition>()?;
    m.add_class::<dataset::Dataset>()?;
    m.add_class::<kernel::PyArm>()?;
    m.add_class::<kernel::PyMirrorState>()?;
    m.add_class::<kernel::Csr>()?;
    m.add_class::<kernel::Estimate>()?;
    m.add_class::<kernel::Product>()?;
    m.add_class::<acquisition::Coefficients>()?;
    m.add_class::<acquisition::Solution>()?;
    m.add(
        "SCHEMES",
        pyo3::types::PyTuple::new(m.py(), contract::scheme_keys())?,
    )?;
    m.add_function(wrap_pyfunction!(contract::dataset_contract, m)?)?;
    m.add_function(wrap_pyfunction!(contract::dataset_array_name, m)?)?;
    m.add_function(wrap_pyfunction!(contract::dataset_array_names, m)?)?;
    m.add_function(wrap_pyfunction!(contract::dataset_shard_dir, m)?)?;
    m.add_function(wrap_pyfunction!(contract::read_dataset_manifest, m)?)?;
    m.add_function(wrap_pyfunction!(dataset::make_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(dataset::dataset_noise_seed, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
