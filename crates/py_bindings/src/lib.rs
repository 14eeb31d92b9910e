//! `aerodelta._core`: PyO3 bindings over `aero_core`.
//!
//! Conversion and error mapping only: every formula lives in `aero_core`.
//! Heavy calls release the GIL through [`util::detached`].

use pyo3::prelude::*;

mod error;
mod lsq;
mod table;
mod util;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    error::register(m)?;
    table::register(m)?;
    lsq::register(m)?;
    Ok(())
}
