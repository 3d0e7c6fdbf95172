//! evigrid for Python: the extension module `evigrid._evigrid` under the `evigrid` package.
//!
//! This crate is wiring, as the command line is: every number comes from the library crates
//! (`belief` for mass functions, `session` for drives, sessions and runs), and this crate only
//! turns Python values into theirs and back.
//! What a user touches is the plain Python package in `python/evigrid` (docstrings, type hints,
//! stubs), which calls the functions here; `pip install ./crates/python` builds both with maturin
//! into one abi3 wheel for CPython ≥ 3.9.
//!
//! **Key design decision**: errors cross the boundary as the package's own exception classes,
//! defined in Python (`evigrid._errors`) so that each can derive both from `evigrid.Error` and
//! from the built-in it refines (`InputError` is a `ValueError`), which an exception created in
//! Rust cannot. Nothing in this crate panics on what a caller passes: every problem is one of
//! those exceptions, its message naming the input and what was wrong.
//!
//! The crate is tested from Python (`crates/python/tests`, pytest), through the installed
//! package, as a user calls it.

mod arrays;
mod drive;
mod error;
mod mass;
mod options;
mod run;
mod session;

use pyo3::prelude::*;

/// The extension module: `evigrid._evigrid`.
#[pymodule]
mod _evigrid {
    use pyo3::prelude::*;

    /// The belief-function calculator (`evigrid.mass` wraps it).
    #[pymodule_export]
    use super::mass::mass;

    /// Drives and their frames.
    #[pymodule_export]
    use super::drive::{Drive, Frame, Frames, open_drive};

    /// The session, step by step.
    #[pymodule_export]
    use super::session::{Session, StepResult};

    /// A whole drive with every output.
    #[pymodule_export]
    use super::run::run;

    /// The package version, the crate's: `evigrid.__version__`.
    #[pymodule_init]
    fn init(module: &Bound<'_, PyModule>) -> PyResult<()> {
        module.add("__version__", env!("CARGO_PKG_VERSION"))
    }
}
