//! The dataset folder's contract (`spibench::dataset::contract`) for Python: its tables, its
//! names, and a folder's manifest read and checked by the library's rules.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;

use spibench::acquisition::{Scheme, Sequence};
use spibench::dataset::contract::{self, CellArray, SampleArray};
use spibench::dataset::{self, manifest_text};
use spibench::error::{Error, Result};

use crate::{scheme_named, to_py};

/// The contract's tables: the manifest's format and file, the input copies by their
/// `provenance` field, the patterns file, the per-sample arrays, the per-(scheme, ratio) array
/// kinds, the sequences of the oscilloscope records and the schemes' keys.
#[pyfunction]
pub(crate) fn dataset_contract(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("format", contract::FORMAT)?;
    d.set_item("manifest", contract::MANIFEST)?;
    let copies = PyDict::new(py);
    for (field, file) in contract::COPIES {
        copies.set_item(field, file)?;
    }
    d.set_item("copies", copies)?;
    d.set_item("patterns", contract::PATTERNS)?;
    let sample: Vec<&str> = SampleArray::ALL.iter().map(|a| a.name()).collect();
    d.set_item("sample_arrays", sample)?;
    let cells: Vec<&str> = CellArray::ALL.iter().map(|c| c.prefix()).collect();
    d.set_item("cell_arrays", cells)?;
    let sequences: Vec<&str> = Sequence::all().iter().map(|q| q.key()).collect();
    d.set_item("sequences", sequences)?;
    d.set_item("schemes", scheme_keys())?;
    Ok(d)
}

/// Every scheme's key, as the command line, the manifests and the Python package name them.
pub(crate) fn scheme_keys() -> Vec<&'static str> {
    Scheme::all().iter().map(|s| s.key()).collect()
}

/// The array of kind `kind` (`meas`, `recon`, `score`) of scheme `scheme` at sampling ratio
/// `ratio`.
#[pyfunction]
pub(crate) fn dataset_array_name(kind: &str, scheme: &str, ratio: f64) -> PyResult<String> {
    let make = || -> Result<String> {
        let cell = CellArray::parse(kind).ok_or_else(|| {
            let kinds: Vec<&str> = CellArray::ALL.iter().map(|c| c.prefix()).collect();
            Error::field("kind", format!("{kind:?} is none of {}", kinds.join(", ")))
        })?;
        let scheme = scheme_named(scheme)?;
        if !(ratio.is_finite() && ratio > 0.0 && ratio <= 1.0) {
            return Err(Error::field(
                "ratio",
                format!("a sampling ratio lies in (0, 1], got {ratio}"),
            ));
        }
        Ok(cell.name(scheme.key(), ratio))
    };
    make().map_err(to_py)
}

/// Every array name a dataset of these schemes (keys) and ratios may hold, sorted.
#[pyfunction]
pub(crate) fn dataset_array_names(schemes: Vec<String>, ratios: Vec<f64>) -> Vec<String> {
    contract::array_names(&schemes, &ratios)
        .into_iter()
        .collect()
}

/// The folder of shard `index`.
#[pyfunction]
pub(crate) fn dataset_shard_dir(index: u64) -> String {
    contract::shard_dir(index)
}

/// The manifest of the dataset folder `path` as JSON text, read and checked by the library
/// (every name and path in it, before any other file of the folder is opened).
#[pyfunction]
pub(crate) fn read_dataset_manifest(py: Python<'_>, path: PathBuf) -> PyResult<String> {
    py.detach(|| dataset::read_manifest(&path).and_then(|m| manifest_text(&m)))
        .map_err(to_py)
}
