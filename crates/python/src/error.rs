//! The package's exceptions, as Rust raises them.
//!
//! The classes are defined in Python (`python/evigrid/_errors.py`), where an exception can have
//! two bases (`InputError(Error, ValueError)`); `import_exception!` looks them up on first use.

use pyo3::PyErr;

pyo3::import_exception!(evigrid._errors, InputError);

/// An [`InputError`]: what the caller passed is wrong. `message` names the input and the problem.
pub fn input_error(message: impl Into<String>) -> PyErr {
    InputError::new_err(message.into())
}
