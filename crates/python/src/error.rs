//! The package's exceptions, as Rust raises them.
//!
//! The classes are defined in Python (`python/evigrid/_errors.py`), where an exception can have
//! two bases (`InputError(Error, ValueError)`); `import_exception!` looks them up on first use.

use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use session::SessionError;

pyo3::import_exception!(evigrid._errors, InputError);
pyo3::import_exception!(evigrid._errors, FileError);

/// An [`InputError`]: what the caller passed is wrong. `message` names the input and the problem.
pub fn input_error(message: impl Into<String>) -> PyErr {
    InputError::new_err(message.into())
}

/// A [`FileError`]: a file could not be read or written. `message` names it.
pub fn file_error(message: impl Into<String>) -> PyErr {
    FileError::new_err(message.into())
}

/// A session's error as the exception of its kind: the input's fault an [`InputError`], an
/// interruption `KeyboardInterrupt`, a failed output a [`FileError`]. The summary of a session
/// that stopped early is attached as the exception's `summary` (a dict, marked incomplete).
pub fn session_error(py: Python<'_>, error: SessionError) -> PyErr {
    let summary = match &error {
        SessionError::Stopped { summary, .. } => summary_dict(py, summary).ok(),
        _ => None,
    };
    let message = match &error {
        SessionError::Source(drive::SourceError::NeedsProjection { what }) => format!(
            "{what}: WGS84 poses need map= or origin= (or a KITTI raw drive, placed at its \
             first fix)"
        ),
        other => other.to_string(),
    };
    let raised = if error.is_interrupted() {
        PyKeyboardInterrupt::new_err(message)
    } else if error.is_bad_input() {
        input_error(message)
    } else {
        file_error(message)
    };
    if let Some(summary) = summary {
        // The exception stays what it is if the attribute cannot be set.
        let _ = raised.value(py).setattr("summary", summary);
    }
    raised
}

/// A serde value as the Python value `json.loads` makes of it: dicts, lists, numbers, strings.
pub fn to_python<'py>(
    py: Python<'py>,
    value: &impl serde::Serialize,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| PyErr::new::<pyo3::exceptions::PyRuntimeError, _>(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A session's summary as the dict `summary.json` holds.
pub fn summary_dict<'py>(
    py: Python<'py>,
    summary: &session::Summary,
) -> PyResult<Bound<'py, PyAny>> {
    to_python(py, summary)
}
