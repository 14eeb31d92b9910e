//! `aerodelta._core`: PyO3 bindings over `aero_core`.
//!
//! Conversion and error mapping only: every formula lives in `aero_core`.
//! Heavy calls release the GIL through [`util::detached`].

use pyo3::prelude::*;

mod chain;
mod daveml;
mod delta_model;
mod error;
mod goman_khrabrov;
mod hatcv;
mod identify;
mod kirchhoff;
mod lsq;
mod partition;
mod preprocess;
mod rolloff;
mod signflip;
mod sim;
mod spline;
mod table;
mod util;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    error::register(m)?;
    table::register(m)?;
    identify::register(m)?;
    chain::register(m)?;
    goman_khrabrov::register(m)?;
    kirchhoff::register(m)?;
    delta_model::register(m)?;
    spline::register(m)?;
    partition::register(m)?;
    daveml::register(m)?;
    sim::register(m)?;
    preprocess::register(m)?;
    lsq::register(m)?;
    rolloff::register(m)?;
    signflip::register(m)?;
    hatcv::register(m)?;
    Ok(())
}
