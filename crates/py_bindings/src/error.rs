//! One Python exception per `aero_core` error kind, all under `AerodeltaError`.
use aero_core::{AeroError, ErrorKind};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    _core,
    AerodeltaError,
    PyException,
    "Base class of every aerodelta error."
);
create_exception!(
    _core,
    InvalidInputError,
    AerodeltaError,
    "Malformed input: shape, ordering, NaN, unknown name."
);
create_exception!(
    _core,
    OutOfRangeError,
    AerodeltaError,
    "A value outside the range where it is defined."
);
create_exception!(
    _core,
    TooLittleDataError,
    AerodeltaError,
    "Too little data (points per parameter, rank) for what was asked."
);
create_exception!(
    _core,
    NoConvergenceError,
    AerodeltaError,
    "An iterative method stopped without meeting its tolerance."
);
create_exception!(
    _core,
    ParseError,
    AerodeltaError,
    "A file could not be parsed; the message names file and line."
);
create_exception!(
    _core,
    AeroIOError,
    AerodeltaError,
    "A file could not be read or written."
);

/// Map a core error to the exception of its kind, keeping the full message.
pub fn to_py(e: AeroError) -> PyErr {
    let msg = e.to_string();
    match e.kind() {
        ErrorKind::InvalidInput => InvalidInputError::new_err(msg),
        ErrorKind::OutOfRange => OutOfRangeError::new_err(msg),
        ErrorKind::TooLittleData => TooLittleDataError::new_err(msg),
        ErrorKind::NoConvergence => NoConvergenceError::new_err(msg),
        ErrorKind::Parse => ParseError::new_err(msg),
        ErrorKind::Io => AeroIOError::new_err(msg),
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("AerodeltaError", py.get_type::<AerodeltaError>())?;
    m.add("InvalidInputError", py.get_type::<InvalidInputError>())?;
    m.add("OutOfRangeError", py.get_type::<OutOfRangeError>())?;
    m.add("TooLittleDataError", py.get_type::<TooLittleDataError>())?;
    m.add("NoConvergenceError", py.get_type::<NoConvergenceError>())?;
    m.add("ParseError", py.get_type::<ParseError>())?;
    m.add("AeroIOError", py.get_type::<AeroIOError>())?;
    Ok(())
}
