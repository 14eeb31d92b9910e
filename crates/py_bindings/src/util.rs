//! The one place where heavy core calls leave the GIL and their errors are mapped.
use aero_core::AeroError;
use pyo3::prelude::*;

/// Run `f` with the GIL released and map its error to the exception of its kind.
pub fn detached<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    F: FnOnce() -> Result<T, AeroError> + Send,
    T: Send,
{
    py.detach(f).map_err(crate::error::to_py)
}

/// Parse a string option into a core enum, naming the argument on error.
pub fn parse_opt<T>(arg: &str, value: &str) -> PyResult<T>
where
    T: std::str::FromStr<Err = AeroError>,
{
    value
        .parse::<T>()
        .map_err(|e| crate::error::to_py(e.context(format!("argument '{arg}'"))))
}
