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

/// Named float columns from Python as slices (each C-contiguous), for a core lookup.
pub fn column_slices<'a>(
    columns: &'a std::collections::HashMap<String, numpy::PyReadonlyArray1<'_, f64>>,
) -> PyResult<std::collections::HashMap<String, &'a [f64]>> {
    let mut out = std::collections::HashMap::with_capacity(columns.len());
    for (k, v) in columns {
        out.insert(k.clone(), v.as_slice()?);
    }
    Ok(out)
}

/// A C-contiguous numpy array as a slice, naming the argument otherwise.
pub fn slice<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    name: &str,
    a: &'a numpy::PyReadonlyArray<'_, T, D>,
) -> PyResult<&'a [T]> {
    a.as_slice()
        .map_err(|_| crate::error::to_py(AeroError::invalid(name, "must be a C-contiguous array")))
}

/// Indices from an int64 array, refusing a non-contiguous array or a negative index by name.
pub fn indices<D: numpy::ndarray::Dimension>(
    name: &str,
    a: &numpy::PyReadonlyArray<'_, i64, D>,
) -> PyResult<Vec<usize>> {
    slice(name, a)?
        .iter()
        .map(|&i| {
            usize::try_from(i).map_err(|_| {
                crate::error::to_py(AeroError::invalid(name, format!("negative index {i}")))
            })
        })
        .collect()
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

/// The record columns the qualified model reads, named in a dict of float64 columns (angles
/// in deg, rates in deg/s); a missing one is refused by name.
pub fn record_columns<'a>(
    cols: &'a std::collections::HashMap<String, &'a [f64]>,
) -> Result<aero_core::aircraft::records::RecordColumns<'a>, AeroError> {
    let column = |name: &str| {
        cols.get(name).copied().ok_or_else(|| {
            AeroError::invalid(
                format!("column '{name}'"),
                "is required by the qualified model but missing; run the ingestion first",
            )
        })
    };
    Ok(aero_core::aircraft::records::RecordColumns {
        alpha_deg: column("alpha_deg")?,
        beta_deg: column("beta_deg")?,
        phat: column("phat")?,
        qhat: column("qhat")?,
        rhat: column("rhat")?,
        alphadot_dps: column("alphadot_dps")?,
        betadot_dps: column("betadot_dps")?,
        da_deg: column("da_deg")?,
        de_deg: column("de_deg")?,
        dr_deg: column("dr_deg")?,
        dsl_deg: column("dsl_deg")?,
        dsr_deg: column("dsr_deg")?,
        flap_deg: column("flap_deg")?,
        ct_left: column("ct_left")?,
        ct_right: column("ct_right")?,
        tas_mps: column("tas_mps")?,
    })
}
