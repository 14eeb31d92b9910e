//! The diagnosis's cross-validated penalised least squares on the hat basis
//! (`aero_core::hatcv`). Conversion and error mapping only.
use aero_core::hatcv::{self, Blocks, Columns, GlobalBlock, HatGrid, Layout, LowRank, Rows};
use aero_core::AeroError;
use numpy::{
    IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArrayDyn,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::util::{detached, indices, slice};

/// A design's block statistics as Python passes them: `(diag, off, cross, glob, xty, yty,
/// block_rows | None, lowrank | None, lowrank_of | None)`.
type BlockArgs<'py> = (
    PyReadonlyArrayDyn<'py, f64>,
    PyReadonlyArrayDyn<'py, f64>,
    PyReadonlyArrayDyn<'py, f64>,
    PyReadonlyArrayDyn<'py, f64>,
    PyReadonlyArrayDyn<'py, f64>,
    PyReadonlyArray1<'py, f64>,
    Option<PyReadonlyArray1<'py, i64>>,
    Option<PyReadonlyArrayDyn<'py, f64>>,
    Option<PyReadonlyArray1<'py, i64>>,
);

/// Two float arrays returned together.
type Pair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// `hat_profile_out`'s `(xty, yty, factors, owner)`.
type ProfiledArrays<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<i64>>,
);

/// Owned index vectors of a block argument tuple (block rows, lowrank owners).
struct BlockIndex {
    rows: Option<Vec<usize>>,
    owner: Option<Vec<usize>>,
}

fn block_index(b: &BlockArgs<'_>) -> PyResult<BlockIndex> {
    let rows = match &b.6 {
        Some(r) => Some(indices("block_rows", r)?),
        None => None,
    };
    let owner = match &b.8 {
        Some(o) => Some(indices("lowrank_of", o)?),
        None => None,
    };
    Ok(BlockIndex { rows, owner })
}

fn blocks<'a>(
    b: &'a BlockArgs<'_>,
    idx: &'a BlockIndex,
    layout: (usize, usize, usize),
) -> PyResult<Blocks<'a>> {
    let lowrank = match (&b.7, &idx.owner) {
        (Some(f), Some(owner)) => Some(LowRank {
            factors: slice("lowrank", f)?,
            owner,
        }),
        (None, None) => None,
        _ => {
            return Err(crate::error::to_py(AeroError::invalid(
                "lowrank",
                "lowrank and lowrank_of come together",
            )))
        }
    };
    Ok(Blocks {
        layout: self::layout(layout),
        diag: slice("diag", &b.0)?,
        off: slice("off", &b.1)?,
        cross: slice("cross", &b.2)?,
        glob: slice("glob", &b.3)?,
        xty: slice("xty", &b.4)?,
        yty: slice("yty", &b.5)?,
        block_row: idx.rows.as_deref(),
        lowrank,
    })
}

fn layout(l: (usize, usize, usize)) -> Layout {
    Layout {
        knots: l.0,
        aero: l.1,
        global: l.2,
    }
}

fn columns(
    a_cols: &PyReadonlyArray1<'_, i64>,
    g_cols: &PyReadonlyArray1<'_, i64>,
) -> PyResult<Columns> {
    Ok(Columns {
        aero: indices("aero columns", a_cols)?,
        global: indices("global columns", g_cols)?,
    })
}

/// `(sse, thetas)`: held-out squared error per maneuver of the model on `(a_cols, g_cols)`
/// and each fold's per-flap parameters (flat, folds × flaps × n_local), from the design's
/// blocks and the folds' penalised training statistics (`aero_core::hatcv::held_out`).
#[pyfunction]
#[pyo3(signature = (blocks, layout, train_grams, train_xty, folds, flap, n_flaps, a_cols, g_cols))]
#[allow(clippy::too_many_arguments)]
fn hat_held_out<'py>(
    py: Python<'py>,
    blocks: BlockArgs<'py>,
    layout: (usize, usize, usize),
    train_grams: PyReadonlyArrayDyn<'py, f64>,
    train_xty: PyReadonlyArrayDyn<'py, f64>,
    folds: PyReadonlyArray1<'py, i64>,
    flap: PyReadonlyArray1<'py, i64>,
    n_flaps: usize,
    a_cols: PyReadonlyArray1<'py, i64>,
    g_cols: PyReadonlyArray1<'py, i64>,
) -> PyResult<Pair<'py>> {
    let idx = block_index(&blocks)?;
    let b = self::blocks(&blocks, &idx, layout)?;
    let cols = columns(&a_cols, &g_cols)?;
    let folds = indices("folds", &folds)?;
    let flap = indices("flap", &flap)?;
    let tg = slice("train_grams", &train_grams)?;
    let tx = slice("train_xty", &train_xty)?;
    let (sse, thetas) = detached(py, || {
        hatcv::held_out(&b, tg, tx, &folds, &flap, n_flaps, &cols)
    })?;
    Ok((sse.into_pyarray(py), thetas.into_pyarray(py)))
}

/// Penalised least squares on `(a_cols, g_cols)` per flap (`aero_core::hatcv::solve_flaps`):
/// `grams` (flaps × p × p), `xtys` (flaps × p); the parameters flat, flaps × p.
#[pyfunction]
fn hat_solve<'py>(
    py: Python<'py>,
    grams: PyReadonlyArrayDyn<'py, f64>,
    xtys: PyReadonlyArrayDyn<'py, f64>,
    layout: (usize, usize, usize),
    a_cols: PyReadonlyArray1<'py, i64>,
    g_cols: PyReadonlyArray1<'py, i64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let cols = columns(&a_cols, &g_cols)?;
    let g = slice("grams", &grams)?;
    let x = slice("xtys", &xtys)?;
    let layout = self::layout(layout);
    let out = detached(py, || hatcv::solve_flaps(g, x, &layout, &cols))?;
    Ok(out.into_pyarray(py))
}

/// `θ'G_mθ − 2θ'b_m` per maneuver of `ms` (`aero_core::hatcv::quadratic_forms_checked`).
#[pyfunction]
fn hat_quadratic_forms<'py>(
    py: Python<'py>,
    blocks: BlockArgs<'py>,
    layout: (usize, usize, usize),
    ms: PyReadonlyArray1<'py, i64>,
    theta: PyReadonlyArray1<'py, f64>,
    a_cols: PyReadonlyArray1<'py, i64>,
    g_cols: PyReadonlyArray1<'py, i64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let idx = block_index(&blocks)?;
    let b = self::blocks(&blocks, &idx, layout)?;
    let cols = columns(&a_cols, &g_cols)?;
    let ms = indices("maneuvers", &ms)?;
    let theta = slice("theta", &theta)?;
    let out = detached(py, || hatcv::quadratic_forms_checked(&b, &ms, theta, &cols))?;
    Ok(out.into_pyarray(py))
}

/// The global columns as Python passes them: a dense `n × c` block, or one sparse column
/// `(rows, values)`.
enum GlobalArg<'py> {
    Dense(PyReadonlyArray2<'py, f64>),
    Sparse(Vec<usize>, PyReadonlyArray1<'py, f64>),
}

type Built<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

/// `(diag, off, cross, glob, xty, yty)`, flat, C order: the rows reduced to per-maneuver
/// block statistics on the grid `(k0, step, n)` (`aero_core::hatcv::build_blocks`).
/// `globals`: dense `n × c` arrays or `(rows, values)` sparse columns, in column order.
#[pyfunction]
#[pyo3(signature = (y, maneuver, alpha_deg, aero, globals, grid, n_maneuvers))]
#[allow(clippy::too_many_arguments)]
fn hat_build<'py>(
    py: Python<'py>,
    y: PyReadonlyArray1<'py, f64>,
    maneuver: PyReadonlyArray1<'py, i64>,
    alpha_deg: PyReadonlyArray1<'py, f64>,
    aero: PyReadonlyArray2<'py, f64>,
    globals: Vec<Bound<'py, PyAny>>,
    grid: (f64, f64, usize),
    n_maneuvers: usize,
) -> PyResult<Built<'py>> {
    let mut args = Vec::with_capacity(globals.len());
    for (b, g) in globals.iter().enumerate() {
        if let Ok(a) = g.extract::<PyReadonlyArray2<'py, f64>>() {
            args.push(GlobalArg::Dense(a));
        } else if let Ok((r, v)) =
            g.extract::<(PyReadonlyArray1<'py, i64>, PyReadonlyArray1<'py, f64>)>()
        {
            let rows = indices(&format!("global block {b} rows"), &r)?;
            args.push(GlobalArg::Sparse(rows, v));
        } else {
            return Err(crate::error::to_py(AeroError::invalid(
                format!("global block {b}"),
                "must be a 2-d float64 array or a (rows, values) pair of 1-d arrays",
            )));
        }
    }
    let mut blocks = Vec::with_capacity(args.len());
    for a in &args {
        blocks.push(match a {
            GlobalArg::Dense(d) => GlobalBlock::Dense {
                data: slice("global block", d)?,
                cols: d.shape()[1],
            },
            GlobalArg::Sparse(r, v) => GlobalBlock::Sparse {
                rows: r,
                values: slice("sparse values", v)?,
            },
        });
    }
    let man = indices("maneuver", &maneuver)?;
    let rows = Rows {
        y: slice("y", &y)?,
        maneuver: &man,
        alpha_deg: slice("alpha_deg", &alpha_deg)?,
        aero: slice("aero", &aero)?,
        n_aero: aero.shape()[1],
    };
    let grid = HatGrid {
        k0: grid.0,
        step: grid.1,
        n: grid.2,
    };
    let out = detached(py, || {
        hatcv::build_blocks(&rows, &blocks, &grid, n_maneuvers)
    })?;
    Ok((
        out.diag.into_pyarray(py),
        out.off.into_pyarray(py),
        out.cross.into_pyarray(py),
        out.glob.into_pyarray(py),
        out.xty.into_pyarray(py),
        out.yty.into_pyarray(py),
    ))
}

/// `(G, b)` flat: per fold and flap the sums of its maneuvers' Gram matrices and `X'y`
/// (`aero_core::hatcv::fold_sums`), folds × flaps × p × p and folds × flaps × p.
#[pyfunction]
#[pyo3(signature = (blocks, layout, folds, flap, n_folds, n_flaps))]
fn hat_fold_sums<'py>(
    py: Python<'py>,
    blocks: BlockArgs<'py>,
    layout: (usize, usize, usize),
    folds: PyReadonlyArray1<'py, i64>,
    flap: PyReadonlyArray1<'py, i64>,
    n_folds: usize,
    n_flaps: usize,
) -> PyResult<Pair<'py>> {
    let idx = block_index(&blocks)?;
    let b = self::blocks(&blocks, &idx, layout)?;
    let folds = indices("folds", &folds)?;
    let flap = indices("flap", &flap)?;
    let (g, x) = detached(py, || hatcv::fold_sums(&b, &folds, &flap, n_folds, n_flaps))?;
    Ok((g.into_pyarray(py), x.into_pyarray(py)))
}

/// `(G, b)` flat: the sums of the maneuvers `ms`' Gram matrices and `X'y`
/// (`aero_core::hatcv::gram_sum`), p × p and p.
#[pyfunction]
fn hat_gram_sum<'py>(
    py: Python<'py>,
    blocks: BlockArgs<'py>,
    layout: (usize, usize, usize),
    ms: PyReadonlyArray1<'py, i64>,
) -> PyResult<Pair<'py>> {
    let idx = block_index(&blocks)?;
    let b = self::blocks(&blocks, &idx, layout)?;
    let ms = indices("maneuvers", &ms)?;
    let (g, x) = detached(py, || hatcv::gram_sum_checked(&b, &ms))?;
    Ok((g.into_pyarray(py), x.into_pyarray(py)))
}

/// `(xty, yty, factors, owner)`: the last `n_nuisance` global columns profiled out per
/// maneuver (`aero_core::hatcv::profile_out`); `xty` flat M × p_keep, `factors` flat
/// p_keep × L, `owner` the maneuver of each factor column.
#[pyfunction]
fn hat_profile_out<'py>(
    py: Python<'py>,
    blocks: BlockArgs<'py>,
    layout: (usize, usize, usize),
    n_nuisance: usize,
) -> PyResult<ProfiledArrays<'py>> {
    let idx = block_index(&blocks)?;
    let b = self::blocks(&blocks, &idx, layout)?;
    let pr = detached(py, || hatcv::profile_out(&b, n_nuisance))?;
    let owner: Vec<i64> = pr
        .owner
        .iter()
        .map(|&o| i64::try_from(o).unwrap_or(i64::MAX))
        .collect();
    Ok((
        pr.xty.into_pyarray(py),
        pr.yty.into_pyarray(py),
        pr.factors.into_pyarray(py),
        owner.into_pyarray(py),
    ))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(hat_held_out, m)?)?;
    m.add_function(wrap_pyfunction!(hat_solve, m)?)?;
    m.add_function(wrap_pyfunction!(hat_build, m)?)?;
    m.add_function(wrap_pyfunction!(hat_fold_sums, m)?)?;
    m.add_function(wrap_pyfunction!(hat_gram_sum, m)?)?;
    m.add_function(wrap_pyfunction!(hat_profile_out, m)?)?;
    m.add_function(wrap_pyfunction!(hat_quadratic_forms, m)?)?;
    Ok(())
}
