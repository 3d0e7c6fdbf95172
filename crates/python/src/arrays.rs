//! numpy arrays from Rust vectors: moved, not copied, and marked read-only.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// `values` as a read-only numpy array of `shape` (their count must be its product). The vector
/// becomes the array's buffer: nothing is copied.
pub fn readonly<'py, T: numpy::Element>(
    py: Python<'py>,
    values: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    let array = PyArray1::from_vec(py, values).reshape(shape.to_vec())?;
    let flags = PyDict::new(py);
    flags.set_item("write", false)?;
    array.call_method("setflags", (), Some(&flags))?;
    Ok(array.into_any())
}
