//! A loaded DAVE-ML model and its evaluation: inputs, then every computed
//! variable in a topological order fixed at load, each limited to its
//! `minValue`/`maxValue`.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use super::check::Shot;
use super::mathml::Expr;
use crate::error::{AeroError, Result};
use crate::table::{Table, MAX_DIMS};
use crate::text::shown;

/// One `variableDef`.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// `varID`, unique in the file.
    pub id: String,
    /// `name` (check cases refer to variables by it).
    pub name: String,
    /// `units` as written (e.g. `deg`, `ft_s`, `nd`).
    pub units: String,
    /// `description`, trimmed.
    pub description: String,
    /// Flagged `<isInput/>`.
    pub is_input: bool,
    /// Flagged `<isOutput/>`.
    pub is_output: bool,
    /// Flagged `<isStdAIAA/>`.
    pub is_std_aiaa: bool,
    /// `initialValue`: the value of a constant, or the default of an input.
    pub initial_value: Option<f64>,
    /// `minValue`: the value is limited from below after it is computed or set.
    pub min_value: Option<f64>,
    /// `maxValue`: the value is limited from above after it is computed or set.
    pub max_value: Option<f64>,
    /// Line of the `variableDef` in its file.
    pub line: usize,
}

impl Variable {
    #[inline]
    fn limit(&self, mut x: f64) -> f64 {
        if let Some(lo) = self.min_value {
            if x < lo {
                x = lo;
            }
        }
        if let Some(hi) = self.max_value {
            if x > hi {
                x = hi;
            }
        }
        x
    }
}

/// How a variable gets its value.
#[derive(Debug, Clone)]
pub(crate) enum Def {
    /// Set by the caller, or its `initialValue`.
    Free,
    /// A MathML `calculation`.
    Calc(Expr),
    /// The output of a `function`: a table looked up with `args`; `locs[k]`
    /// is the shared [`Locator`] of axis `k`.
    Table {
        table: Table,
        args: Vec<usize>,
        locs: Vec<usize>,
    },
}

/// An input variable located on one axis: shared by every table that looks
/// the same variable up in the same breakpoints with the same limits and policy.
#[derive(Debug, Clone)]
pub(crate) struct Locator {
    pub var: usize,
    pub axis: crate::table::Axis,
}

/// Per-evaluation memo of locator results: `stamp[l] == gen` when `loc[l]` is current.
#[derive(Debug, Clone)]
pub(crate) struct LocCache {
    gen: u64,
    stamp: Vec<u64>,
    loc: Vec<Option<(usize, f64)>>,
}

impl LocCache {
    pub(crate) fn new(n: usize) -> Self {
        LocCache {
            gen: 0,
            stamp: vec![0; n],
            loc: vec![None; n],
        }
    }
}

/// A DAVE-ML model ready to evaluate.
///
/// ```
/// use aero_core::daveml::DaveModel;
/// let m = DaveModel::from_str(r#"<DAVEfunc>
///   <variableDef name="alpha" varID="alpha" units="deg"><isInput/></variableDef>
///   <variableDef name="CL" varID="CL" units="nd"><isOutput/></variableDef>
///   <function name="CL"><independentVarPts varID="alpha">0, 10</independentVarPts>
///     <dependentVarPts varID="CL">0.1, 1.1</dependentVarPts></function>
/// </DAVEfunc>"#, "doc.dml").unwrap();
/// let v = m.evaluate(&[("alpha", 5.0)]).unwrap();
/// assert!((v[m.index_of("CL").unwrap()] - 0.6).abs() < 1e-15);
/// ```
#[derive(Debug, Clone)]
pub struct DaveModel {
    pub(crate) name: String,
    pub(crate) vars: Vec<Variable>,
    pub(crate) defs: Vec<Def>,
    /// Computed variables in evaluation order.
    pub(crate) order: Vec<usize>,
    /// Free variables without a value of their own: callers must set them.
    pub(crate) required: Vec<usize>,
    /// Start values: initial values (limited), NaN elsewhere.
    pub(crate) base: Vec<f64>,
    /// Distinct (variable, axis) lookups shared between tables.
    pub(crate) locators: Vec<Locator>,
    pub(crate) by_id: HashMap<String, usize>,
    pub(crate) shots: Vec<Shot>,
    /// The `uncertainty` elements of variables and tables.
    pub(crate) uncertainties: Vec<super::uncertainty::Uncertainty>,
}

impl DaveModel {
    /// Read and compile a DAVE-ML file.
    ///
    /// # Errors
    /// [`AeroError::Io`] when the file cannot be read; [`AeroError::Parse`]
    /// naming file, line and element for malformed XML, unknown references,
    /// wrong table sizes, non-increasing breakpoints, dependency cycles or check
    /// cases whose units differ from the variable's.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| AeroError::io(path, e))?;
        Self::from_bytes(&bytes, &path.display().to_string())
    }

    /// Compile DAVE-ML bytes (the contents of a file); `name` names the file
    /// in messages.
    ///
    /// # Errors
    /// As [`DaveModel::from_str`]; bytes that are not UTF-8 are a parse error
    /// naming the line and byte offset of the first bad byte.
    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<Self> {
        let text = std::str::from_utf8(bytes).map_err(|e| {
            let at = e.valid_up_to();
            let line = 1 + bytes[..at].iter().filter(|&&c| c == b'\n').count();
            AeroError::parse(
                name,
                line,
                format!(
                    "not UTF-8 text: byte 0x{:02X} at offset {at} is not valid UTF-8; \
                     save the file as UTF-8",
                    bytes[at]
                ),
            )
        })?;
        Self::from_str(text, name)
    }

    /// Compile DAVE-ML text; `name` names the file in messages.
    ///
    /// # Errors
    /// As [`DaveModel::from_file`], without the I/O error.
    #[allow(clippy::should_implement_trait)]
    pub fn from_str(text: &str, name: &str) -> Result<Self> {
        super::parse::parse(text, name)
    }

    /// The model's name: the `fileHeader` `name` attribute, else the file name
    /// (without its folder).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Every variable in file order; [`DaveModel::evaluate`] returns values in this order.
    pub fn variables(&self) -> &[Variable] {
        &self.vars
    }

    /// Index of the variable with `varID` `id`.
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.by_id.get(id).copied()
    }

    /// The model's inputs: free variables flagged `isInput`, or with no value of
    /// their own (no calculation, no function, no `initialValue`).
    pub fn inputs(&self) -> Vec<&Variable> {
        self.vars
            .iter()
            .zip(&self.defs)
            .filter(|(v, d)| matches!(d, Def::Free) && (v.is_input || v.initial_value.is_none()))
            .map(|(v, _)| v)
            .collect()
    }

    /// The variables flagged `isOutput`.
    pub fn outputs(&self) -> Vec<&Variable> {
        self.vars.iter().filter(|v| v.is_output).collect()
    }

    /// The `uncertainty` elements of the file's variables and tables, in file
    /// order (variables first), each checked against its nominal value.
    pub fn uncertainties(&self) -> &[super::uncertainty::Uncertainty] {
        &self.uncertainties
    }

    /// The static check cases of the file.
    pub fn shots(&self) -> &[Shot] {
        &self.shots
    }

    /// Whether variable `i` can be set by the caller (it is not computed).
    pub fn is_free(&self, i: usize) -> bool {
        matches!(self.defs.get(i), Some(Def::Free))
    }

    /// Map `varID`s to indices of free variables, and check every required input is given.
    pub(crate) fn input_indices<'a>(
        &self,
        ids: impl Iterator<Item = &'a str>,
    ) -> Result<Vec<usize>> {
        let mut idx = Vec::new();
        for id in ids {
            let place = || format!("model '{}', input '{}'", shown(&self.name), shown(id));
            let Some(i) = self.index_of(id) else {
                return Err(AeroError::invalid(
                    place(),
                    format!(
                        "is not a varID of the model; its inputs are {}",
                        self.input_list()
                    ),
                ));
            };
            if !self.is_free(i) {
                return Err(AeroError::invalid(
                    place(),
                    "is computed by the model and cannot be set; pass only its inputs",
                ));
            }
            idx.push(i);
        }
        // Every required input is given when as many distinct ones are
        // among them as there are (linear: a file may have many of both).
        let given: HashSet<usize> = idx
            .iter()
            .copied()
            .filter(|&i| self.vars[i].initial_value.is_none())
            .collect();
        if given.len() != self.required.len() {
            if let Some(&r) = self.required.iter().find(|r| !given.contains(r)) {
                return Err(AeroError::invalid(
                    format!("model '{}'", shown(&self.name)),
                    format!(
                        "input '{}' ({}) is missing and has no initialValue; give it a value",
                        shown(&self.vars[r].id),
                        shown(&self.vars[r].name)
                    ),
                ));
            }
        }
        Ok(idx)
    }

    fn input_list(&self) -> String {
        let ids: Vec<&str> = self.inputs().iter().map(|v| v.id.as_str()).collect();
        shown(&ids.join(", "))
    }

    /// Evaluate every variable for inputs given as `(varID, value)`; inputs not
    /// given take their `initialValue`. Returns one value per variable, in the
    /// order of [`DaveModel::variables`].
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] for an unknown or computed varID, or a missing
    /// input that has no `initialValue` (the message names it).
    pub fn evaluate(&self, inputs: &[(&str, f64)]) -> Result<Vec<f64>> {
        let idx = self.input_indices(inputs.iter().map(|(k, _)| *k))?;
        let mut values = self.base.clone();
        let set: Vec<(usize, f64)> = idx.into_iter().zip(inputs.iter().map(|p| p.1)).collect();
        let mut cache = LocCache::new(self.locators.len());
        self.compute_cached(&set, &mut values, &mut cache);
        Ok(values)
    }

    /// The real-time path: set free variables `set` (indices from
    /// [`DaveModel::index_of`]) and compute all others into `values` (length
    /// [`DaveModel::variables`]`.len()`), without allocating. The caller is
    /// responsible for giving every required input; a missing one is NaN.
    pub fn compute(&self, set: &[(usize, f64)], values: &mut [f64]) {
        values.copy_from_slice(&self.base);
        for &(i, x) in set {
            values[i] = self.vars[i].limit(x);
        }
        let mut args = [0.0f64; MAX_DIMS];
        for &i in &self.order {
            let y = match &self.defs[i] {
                Def::Free => continue,
                Def::Calc(e) => e.eval(values),
                Def::Table { table, args: a, .. } => match a.as_slice() {
                    [x] => lookup_1d(table, values[*x]),
                    [x, y] => lookup_2d(table, values[*x], values[*y]),
                    _ => {
                        for (k, &j) in a.iter().enumerate() {
                            args[k] = values[j];
                        }
                        table.eval(&args[..a.len()])
                    }
                },
            };
            values[i] = self.vars[i].limit(y);
        }
    }

    /// [`DaveModel::compute`] locating each shared (variable, axis) pair once
    /// per point; bit-identical results.
    pub(crate) fn compute_cached(
        &self,
        set: &[(usize, f64)],
        values: &mut [f64],
        cache: &mut LocCache,
    ) {
        values.copy_from_slice(&self.base);
        for &(i, x) in set {
            values[i] = self.vars[i].limit(x);
        }
        cache.gen += 1;
        let gen = cache.gen;
        let mut locate = |l: usize, values: &[f64]| -> Option<(usize, f64)> {
            if cache.stamp[l] != gen {
                let lc = &self.locators[l];
                cache.loc[l] = lc.axis.locate(values[lc.var]);
                cache.stamp[l] = gen;
            }
            cache.loc[l]
        };
        let mut args = [0.0f64; MAX_DIMS];
        for &i in &self.order {
            let y = match &self.defs[i] {
                Def::Free => continue,
                Def::Calc(e) => e.eval(values),
                Def::Table {
                    table,
                    args: a,
                    locs,
                } => match locs.as_slice() {
                    [l] => lerp_1d(table, locate(*l, values)),
                    [l0, l1] => lerp_2d(table, locate(*l0, values), locate(*l1, values)),
                    _ => {
                        for (k, &j) in a.iter().enumerate() {
                            args[k] = values[j];
                        }
                        table.eval(&args[..a.len()])
                    }
                },
            };
            values[i] = self.vars[i].limit(y);
        }
    }

    /// Evaluate at many points: `inputs` gives one column per input varID (all
    /// the same length), `outputs` the varIDs wanted. Returns one column per
    /// output. Runs in parallel over chunks of points with the `parallel`
    /// feature; results are identical to [`DaveModel::evaluate`] point by point.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] for unknown varIDs, missing inputs, or
    /// columns of different lengths.
    pub fn evaluate_columns(
        &self,
        inputs: &[(&str, &[f64])],
        outputs: &[&str],
    ) -> Result<Vec<Vec<f64>>> {
        let idx = self.input_indices(inputs.iter().map(|(k, _)| *k))?;
        let npts = inputs.first().map_or(1, |c| c.1.len());
        for (k, c) in inputs {
            if c.len() != npts {
                return Err(AeroError::invalid(
                    format!("model '{}', input '{k}'", self.name),
                    format!(
                        "has {} points but input '{}' has {npts}",
                        c.len(),
                        inputs[0].0
                    ),
                ));
            }
        }
        let mut out_idx = Vec::with_capacity(outputs.len());
        for o in outputs {
            out_idx.push(self.index_of(o).ok_or_else(|| {
                AeroError::invalid(
                    format!("model '{}', output '{o}'", self.name),
                    "is not a varID of the model",
                )
            })?);
        }
        let nout = out_idx.len();
        let mut rows = vec![0.0f64; npts * nout];
        let work = |start: usize, chunk: &mut [f64]| {
            let mut values = vec![0.0f64; self.vars.len()];
            let mut cache = LocCache::new(self.locators.len());
            let mut set: Vec<(usize, f64)> = idx.iter().map(|&i| (i, 0.0)).collect();
            for (j, row) in chunk.chunks_mut(nout.max(1)).enumerate() {
                for (s, (_, col)) in set.iter_mut().zip(inputs) {
                    s.1 = col[start + j];
                }
                self.compute_cached(&set, &mut values, &mut cache);
                for (r, &o) in row.iter_mut().zip(&out_idx) {
                    *r = values[o];
                }
            }
        };
        if nout > 0 {
            run_chunks(&mut rows, nout, work);
        }
        let mut cols = vec![Vec::with_capacity(npts); nout];
        for row in rows.chunks(nout.max(1)) {
            for (c, &v) in cols.iter_mut().zip(row) {
                c.push(v);
            }
        }
        Ok(cols)
    }
}

/// [`Table::eval`] for a 1-D table, bit for bit, without its 2^8-corner scratch array.
#[inline]
pub(crate) fn lookup_1d(t: &Table, x: f64) -> f64 {
    lerp_1d(t, t.axes()[0].locate(x))
}

/// A 1-D table at a located point `(i, f)` (`None`: NaN input).
#[inline]
fn lerp_1d(t: &Table, at: Option<(usize, f64)>) -> f64 {
    let v = t.values();
    let Some((i, f)) = at else {
        return f64::NAN;
    };
    if v.len() == 1 {
        return (1.0 - f) * v[0] + f * v[0];
    }
    (1.0 - f) * v[i] + f * v[i + 1]
}

/// [`Table::eval`] for a 2-D table, bit for bit (same reduction order: last axis first).
#[inline]
pub(crate) fn lookup_2d(t: &Table, x: f64, y: f64) -> f64 {
    let axes = t.axes();
    lerp_2d(t, axes[0].locate(x), axes[1].locate(y))
}

/// A 2-D table at located points on both axes.
#[inline]
fn lerp_2d(t: &Table, a: Option<(usize, f64)>, b: Option<(usize, f64)>) -> f64 {
    let axes = t.axes();
    let v = t.values();
    let (Some((i, f0)), Some((j, f1))) = (a, b) else {
        return f64::NAN;
    };
    let n1 = axes[1].breakpoints().len();
    let s0 = if axes[0].breakpoints().len() > 1 {
        n1
    } else {
        0
    };
    let s1 = usize::from(n1 > 1);
    let b = i * n1 + j;
    let (g0, g1) = (1.0 - f0, 1.0 - f1);
    let lo = g1 * v[b] + f1 * v[b + s1];
    let hi = g1 * v[b + s0] + f1 * v[b + s0 + s1];
    g0 * lo + f0 * hi
}

/// Points per parallel task.
const CHUNK: usize = 4096;

#[cfg(feature = "parallel")]
fn run_chunks(rows: &mut [f64], width: usize, work: impl Fn(usize, &mut [f64]) + Sync) {
    use rayon::prelude::*;
    if rows.len() <= CHUNK * width {
        work(0, rows);
        return;
    }
    rows.par_chunks_mut(CHUNK * width)
        .enumerate()
        .for_each(|(c, chunk)| work(c * CHUNK, chunk));
}

#[cfg(not(feature = "parallel"))]
fn run_chunks(rows: &mut [f64], width: usize, work: impl Fn(usize, &mut [f64])) {
    for (c, chunk) in rows.chunks_mut(CHUNK * width).enumerate() {
        work(c * CHUNK, chunk);
    }
}
