//! Output-error estimation of the Kirchhoff stall model ([`crate::kirchhoff`])
//! from measured lift and pitching-moment time histories, over many maneuvers
//! (Fischenberg's approach, AIAA 95-3438: the separation state is integrated
//! from the *measured* α and α̇; the model output is the coefficient).
//!
//! # Estimator
//! Maximum likelihood with the measurement-noise covariance `R` estimated
//! (Maine & Iliff, NASA RP-1168, 1986; Jategaonkar, "Flight Vehicle System
//! Identification", 2nd ed., Ch. 4; Morelli & Klein, "Aircraft System
//! Identification", Ch. 6). With `R` diagonal, eliminating it leaves the cost
//!
//! $$ J(\theta) = \sum_o \ln\Bigl(\frac1N \sum_{i} v_{o}(i)^2\Bigr), \qquad v = z - y(\theta), $$
//!
//! minimised by relaxation: each iteration takes `R = diag(mean v²)` at the
//! current θ and a Levenberg-Marquardt step on the weighted least-squares
//! problem, `(M + λ D) Δθ = Σ_i S_iᵀ R⁻¹ v_i`, `M = Σ_i S_iᵀ R⁻¹ S_i`,
//! `D = diag(M)` (Marquardt's scaling), with the output sensitivities
//! `S = ∂y/∂θ` from the forward sensitivity recursion of the discretised
//! separation ODE ([`crate::kirchhoff::outputs`]). A step is kept when it
//! lowers `J`; λ shrinks tenfold after a kept step and grows tenfold after a
//! refused one. The iterations are bounded ([`OeOptions::max_iter`]).
//!
//! # Start
//! Equation error ([`equation_error_start`]): a line through the attached-flow
//! lift (α below the alpha of the largest binned C_L minus 5°; minus 3° or 1.5°
//! when that leaves too little attached flow or break to start from) gives C_Lα, α₀;
//! inverting Kirchhoff's lift gives the separation point of each sample,
//! `x = (2√(C_L / C_Lα(α − α₀)) − 1)²`; `atanh(1 − 2x) = a₁(α − τ α̇ − α*)`
//! is linear in `(α, α̇, 1)` (the quasi-steady solution of the ODE with
//! τ = τ₁ + τ₂ to first order), giving a₁, α*, τ; C_m on `(1, α, 1 − x)` gives
//! C_m0, C_mα, C_mx. τ is split between τ₁ and τ₂ by the smallest output-error
//! cost over the ratios 0.1, 0.2, ..., 0.9.
//!
//! # Uncertainty
//! Cramér-Rao bounds `Cov = M⁻¹` at the estimate, and the bounds corrected for
//! coloured residuals (Morelli & Klein, "Determining the accuracy of maximum
//! likelihood parameter estimates with colored residuals", NASA CR-194893,
//! 1994; SIDPAC `m_colores`):
//!
//! $$ \mathrm{Cov} = M^{-1} \Bigl[\sum_i \sum_j S_i^\top R^{-1} R_{vv}(i-j) R^{-1} S_j\Bigr] M^{-1} $$
//!
//! summed over maneuvers (no correlation across maneuvers), with `R_vv` kept
//! diagonal (the auto-correlation of each output's residuals, the option
//! `m_colores` carries as a comment; the cross-correlation of the C_L and C_m
//! residuals is left out) and the *biased* sample autocorrelation of the
//! crate's `r_colores` ([`crate::lsq::colored`], evaluated by FFT).

use nalgebra::{DMatrix, DVector};

use crate::error::{AeroError, Result};
use crate::goman_khrabrov::{self as gk, GkParams, N_CORE};
use crate::kirchhoff::{outputs, Inputs, KirchhoffParams, Outputs, N_PARAMS, PARAM_NAMES};
use crate::lsq::colored::toeplitz_gram;
use crate::lsq::{ols, OlsOptions};

/// One maneuver: the model inputs and the measured outputs.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    /// Time (s), α (rad), α̇ (rad/s).
    pub inputs: Inputs<'a>,
    /// Measured C_L minus the known terms (the static-curve part the model explains).
    pub cl: &'a [f64],
    /// Measured C_m minus the known terms; `None` fits C_L alone.
    pub cm: Option<&'a [f64]>,
}

/// Settings of [`fit`].
#[derive(Debug, Clone)]
pub struct OeOptions {
    /// Iteration bound (Levenberg-Marquardt steps taken or refused). Default 60.
    pub max_iter: usize,
    /// Convergence: the cost `J` changes by less than this over a kept step (or
    /// every parameter moves by less than 1e-10 of its value). Default 1e-9.
    pub tol: f64,
    /// Start values; `None`: [`equation_error_start`].
    pub start: Option<KirchhoffParams>,
    /// Parameters held at their start value ([`PARAM_NAMES`] order). When C_m is
    /// not fitted its three parameters are held whatever this says.
    pub fixed: [bool; N_PARAMS],
    /// Truncate the residual autocorrelation of the coloured-residual bounds
    /// beyond this lag (samples); `None`: all lags.
    pub max_lag: Option<usize>,
}

impl Default for OeOptions {
    fn default() -> Self {
        OeOptions {
            max_iter: 60,
            tol: 1e-9,
            start: None,
            fixed: [false; N_PARAMS],
            max_lag: None,
        }
    }
}

/// The result of [`fit`].
#[derive(Debug, Clone)]
pub struct OeFit {
    /// Estimates.
    pub params: KirchhoffParams,
    /// The start (equation error unless given).
    pub start: KirchhoffParams,
    /// Which parameters were estimated ([`PARAM_NAMES`] order).
    pub free: [bool; N_PARAMS],
    /// Cramér-Rao bounds (standard errors), NaN for held parameters.
    pub std_err: [f64; N_PARAMS],
    /// The bounds corrected for coloured residuals, NaN for held parameters.
    pub std_err_colored: [f64; N_PARAMS],
    /// Row-major `9 × 9` Cramér-Rao covariance (zeros for held parameters).
    pub cov: Vec<f64>,
    /// Row-major `9 × 9` coloured-residual covariance.
    pub cov_colored: Vec<f64>,
    /// Iterations taken.
    pub iterations: usize,
    /// True when the cost change met the tolerance.
    pub converged: bool,
    /// Final cost `J`.
    pub cost: f64,
    /// Residual variance per output (C_L, C_m; C_m NaN when not fitted).
    pub residual_var: [f64; 2],
    /// Samples used.
    pub n_samples: usize,
    /// Maneuvers used.
    pub n_maneuvers: usize,
}

/// A separation-state model the engine fits: a parameter vector, the bounds
/// the iterations respect, and the outputs with their sensitivities (rows of
/// [`OeModel::n_params`]). The tanh form ([`fit`]) and the tabulated
/// Goman-Khrabrov form ([`fit_tabulated`]) share everything else: cost,
/// Levenberg-Marquardt loop, Cramér-Rao and coloured-residual bounds.
trait OeModel {
    fn n_params(&self) -> usize;
    fn names(&self) -> Vec<String>;
    /// Parameters only C_m sees (held when C_m is not fitted).
    fn cm_only(&self) -> [usize; 3];
    fn project(&self, th: &mut [f64]);
    /// The interval [`OeModel::project`] keeps parameter `j` in.
    fn bounds(&self, j: usize) -> (f64, f64);
    fn outputs(&self, th: &[f64], inp: &Inputs<'_>, sens: bool) -> Result<Outputs>;
}

/// Fischenberg's tanh form, [`KirchhoffParams`].
struct TanhForm;

impl OeModel for TanhForm {
    fn n_params(&self) -> usize {
        N_PARAMS
    }
    fn names(&self) -> Vec<String> {
        PARAM_NAMES.iter().map(|s| (*s).to_string()).collect()
    }
    fn cm_only(&self) -> [usize; 3] {
        [6, 7, 8]
    }
    /// τ₁ ≥ 1 ms, τ₂ ≥ 0, a₁ ≥ 0.1 /rad.
    fn project(&self, th: &mut [f64]) {
        th[0] = th[0].max(1e-3);
        th[1] = th[1].max(0.0);
        th[3] = th[3].max(0.1);
    }
    fn bounds(&self, j: usize) -> (f64, f64) {
        match j {
            0 => (1e-3, f64::INFINITY),
            1 => (0.0, f64::INFINITY),
            3 => (0.1, f64::INFINITY),
            _ => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
    fn outputs(&self, th: &[f64], inp: &Inputs<'_>, sens: bool) -> Result<Outputs> {
        outputs(&tanh_params(th), inp, sens)
    }
}

fn tanh_params(th: &[f64]) -> KirchhoffParams {
    let mut a = [0.0; N_PARAMS];
    a.copy_from_slice(&th[..N_PARAMS]);
    KirchhoffParams::from_array(&a)
}

/// The tabulated form over the knots of `template`.
struct TableForm<'a> {
    template: &'a GkParams,
}

impl OeModel for TableForm<'_> {
    fn n_params(&self) -> usize {
        N_CORE + self.template.x0.knots().len()
    }
    fn names(&self) -> Vec<String> {
        self.template.names()
    }
    fn cm_only(&self) -> [usize; 3] {
        [4, 5, 6]
    }
    /// τ₁ ≥ 1 ms, τ₂ ≥ 0, node values in [0, 1].
    fn project(&self, th: &mut [f64]) {
        th[0] = th[0].max(1e-3);
        th[1] = th[1].max(0.0);
        for v in &mut th[N_CORE..] {
            *v = v.clamp(0.0, 1.0);
        }
    }
    fn bounds(&self, j: usize) -> (f64, f64) {
        match j {
            0 => (1e-3, f64::INFINITY),
            1 => (0.0, f64::INFINITY),
            _ if j >= N_CORE => (0.0, 1.0),
            _ => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
    fn outputs(&self, th: &[f64], inp: &Inputs<'_>, sens: bool) -> Result<Outputs> {
        gk::outputs(&self.template.with_vec(th), inp, sens)
    }
}

fn check(series: &[Series<'_>]) -> Result<bool> {
    if series.is_empty() {
        return Err(AeroError::too_little(
            "output-error fit",
            "no maneuvers given; pass at least one record that reaches the stall",
        ));
    }
    let with_cm = series[0].cm.is_some();
    for (m, s) in series.iter().enumerate() {
        let place = format!("output-error fit, maneuver {m}");
        s.inputs.check(&place)?;
        let n = s.inputs.t.len();
        if s.cm.is_some() != with_cm {
            return Err(AeroError::invalid(
                place,
                "gives C_m while another maneuver does not; give C_m for all maneuvers or none",
            ));
        }
        for (name, y) in [("CL", Some(s.cl)), ("Cm", s.cm)] {
            let Some(y) = y else { continue };
            if y.len() != n {
                return Err(AeroError::invalid(
                    format!("{place}: {name}"),
                    format!("has {} rows, t has {n}", y.len()),
                ));
            }
            if let Some(i) = y.iter().position(|v| !v.is_finite()) {
                return Err(AeroError::invalid(
                    format!("{place}: {name} row {i}"),
                    "is not finite; drop or fill the row before fitting",
                ));
            }
        }
    }
    Ok(with_cm)
}

/// Residual sums of squares per output and the sample count at θ.
fn sums<M: OeModel>(model: &M, th: &[f64], series: &[Series<'_>]) -> Result<([f64; 2], usize)> {
    let mut ss = [0.0; 2];
    let mut n = 0;
    for s in series {
        let o = model.outputs(th, &s.inputs, false)?;
        for (k, y) in s.cl.iter().enumerate() {
            ss[0] += (y - o.cl[k]).powi(2);
        }
        if let Some(cm) = s.cm {
            for (k, y) in cm.iter().enumerate() {
                ss[1] += (y - o.cm[k]).powi(2);
            }
        }
        n += s.cl.len();
    }
    Ok((ss, n))
}

fn cost_of(ss: [f64; 2], n: usize, with_cm: bool) -> f64 {
    let nf = n.max(1) as f64;
    let floor = 1e-300;
    let mut j = (ss[0] / nf).max(floor).ln();
    if with_cm {
        j += (ss[1] / nf).max(floor).ln();
    }
    j
}

/// Information matrix and gradient over the free parameters with weights `w`.
fn normal_equations<M: OeModel>(
    model: &M,
    th: &[f64],
    series: &[Series<'_>],
    free: &[usize],
    w: [f64; 2],
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let np = free.len();
    let stride = model.n_params();
    let mut m = DMatrix::<f64>::zeros(np, np);
    let mut g = DVector::<f64>::zeros(np);
    let mut row = vec![0.0; np];
    for s in series {
        let o = model.outputs(th, &s.inputs, true)?;
        let mut add = |sens: &[f64], v: f64, wo: f64| {
            for (r, &j) in row.iter_mut().zip(free) {
                *r = sens[j];
            }
            for a in 0..np {
                let ra = row[a] * wo;
                g[a] += ra * v;
                for b in a..np {
                    m[(a, b)] += ra * row[b];
                }
            }
        };
        for k in 0..s.cl.len() {
            add(
                &o.dcl[k * stride..(k + 1) * stride],
                s.cl[k] - o.cl[k],
                w[0],
            );
            if let Some(cm) = s.cm {
                add(&o.dcm[k * stride..(k + 1) * stride], cm[k] - o.cm[k], w[1]);
            }
        }
    }
    for a in 0..np {
        for b in 0..a {
            m[(a, b)] = m[(b, a)];
        }
    }
    Ok((m, g))
}

/// Inverse of a symmetric positive definite matrix after diagonal scaling.
fn spd_inverse(m: &DMatrix<f64>, names: &[String]) -> Result<DMatrix<f64>> {
    let n = m.nrows();
    let d: Vec<f64> = (0..n).map(|i| 1.0 / m[(i, i)].max(1e-300).sqrt()).collect();
    let scaled = DMatrix::from_fn(n, n, |i, j| m[(i, j)] * d[i] * d[j]);
    let chol = scaled.cholesky().ok_or_else(|| {
        AeroError::too_little(
            "output-error fit",
            format!(
                "the information matrix of ({}) is singular: the records do not excite every \
                 parameter; fly deeper or more dynamic stalls, or hold some parameters fixed",
                names.join(", ")
            ),
        )
    })?;
    let inv = chol.inverse();
    Ok(DMatrix::from_fn(n, n, |i, j| inv[(i, j)] * d[i] * d[j]))
}

/// Equation-error start values (module docs, "Start"); `with_cm` fits the C_m
/// parameters too (else they are 0).
///
/// # Errors
/// [`AeroError::TooLittleData`] when the records hold too few attached-flow
/// samples or too few samples in the stall break to fit the static curve.
pub fn equation_error_start(series: &[Series<'_>]) -> Result<KirchhoffParams> {
    let with_cm = check(series)?;
    let place = "output-error start (equation error)";
    let (mut a, mut ad, mut cl, mut cm) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for s in series {
        a.extend_from_slice(s.inputs.alpha);
        ad.extend_from_slice(s.inputs.alpha_dot);
        cl.extend_from_slice(s.cl);
        if let Some(c) = s.cm {
            cm.extend_from_slice(c);
        }
    }
    // the alpha of the largest binned mean C_L (0.5 deg bins of at least 20 points)
    let bin = 0.5f64.to_radians();
    let mut bins: std::collections::BTreeMap<i64, (f64, usize)> = std::collections::BTreeMap::new();
    for (&ai, &ci) in a.iter().zip(&cl) {
        let e = bins.entry((ai / bin).floor() as i64).or_insert((0.0, 0));
        e.0 += ci;
        e.1 += 1;
    }
    let peak = bins
        .iter()
        .filter(|(_, (_, n))| *n >= 20)
        .map(|(b, (s, n))| ((*b as f64 + 0.5) * bin, s / *n as f64))
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .ok_or_else(|| AeroError::too_little(place, "no 0.5 deg alpha bin holds 20 samples"))?;
    // the attached-flow margin under the peak: 5 deg, or narrower when the records hold too
    // little attached flow or break under it (records that start a few degrees under the
    // stall: JSBSim's DHC-6 at flap 0 peaks at 11-12 deg from 6.5 deg); the first margin that
    // gives a start wins, so records that give one at 5 deg keep it
    let mut first_err = None;
    for margin in START_MARGINS_DEG {
        match start_at_margin(series, with_cm, &a, &ad, &cl, &cm, peak.0, margin) {
            Ok(p) => return Ok(p),
            Err(e) if e.kind() == crate::ErrorKind::TooLittleData => {
                first_err.get_or_insert(e);
            }
            Err(e) => return Err(e),
        }
    }
    Err(first_err.unwrap_or_else(|| AeroError::too_little(place, "no start margin")))
}

/// Margins under the alpha of the largest binned C_L below which [`equation_error_start`]
/// takes the flow as attached, deg, tried in this order.
const START_MARGINS_DEG: [f64; 3] = [5.0, 3.0, 1.5];

/// [`equation_error_start`] with the attached flow below `peak - margin_deg`.
#[allow(clippy::too_many_arguments)]
fn start_at_margin(
    series: &[Series<'_>],
    with_cm: bool,
    a: &[f64],
    ad: &[f64],
    cl: &[f64],
    cm: &[f64],
    peak: f64,
    margin_deg: f64,
) -> Result<KirchhoffParams> {
    let place = "output-error start (equation error)";
    let a_lin = peak - margin_deg.to_radians();
    let lin: Vec<usize> = (0..a.len()).filter(|&i| a[i] <= a_lin).collect();
    if lin.len() < 20 {
        return Err(AeroError::too_little(
            place,
            format!(
                "{} samples below alpha {:.1} deg ({margin_deg} deg under the largest C_L); the \
                 attached-flow lift slope needs records that start below the stall",
                lin.len(),
                a_lin.to_degrees()
            ),
        ));
    }
    let opts = OlsOptions {
        colored: false,
        ..OlsOptions::default()
    };
    let x: Vec<f64> = lin.iter().flat_map(|&i| [1.0, a[i]]).collect();
    let z: Vec<f64> = lin.iter().map(|&i| cl[i]).collect();
    let f = ols(&x, lin.len(), 2, &z, &opts).map_err(|e| e.context(place))?;
    let (cl_alpha, alpha0) = (f.params[1], -f.params[0] / f.params[1]);
    if !(cl_alpha > 0.0 && alpha0.is_finite()) {
        return Err(AeroError::too_little(
            place,
            format!(
                "the attached-flow lift slope is {cl_alpha:.3} /rad; lift must rise with alpha"
            ),
        ));
    }
    // separation point of each sample from Kirchhoff's lift
    let x_sep: Vec<f64> = (0..a.len())
        .map(|i| {
            let base = cl_alpha * (a[i] - alpha0);
            if a[i] <= a_lin || base <= 0.0 {
                return 1.0;
            }
            let r = (cl[i] / base).clamp(0.25 + 1e-6, 1.0);
            (2.0 * r.sqrt() - 1.0).powi(2)
        })
        .collect();
    let brk: Vec<usize> = (0..a.len())
        .filter(|&i| a[i] > a_lin && x_sep[i] > 0.03 && x_sep[i] < 0.97)
        .collect();
    if brk.len() < 20 {
        return Err(AeroError::too_little(
            place,
            format!(
                "{} samples in the lift break (separation 3-97 %); the records must fly into the stall",
                brk.len()
            ),
        ));
    }
    let x: Vec<f64> = brk.iter().flat_map(|&i| [a[i], ad[i], 1.0]).collect();
    let z: Vec<f64> = brk
        .iter()
        .map(|&i| (1.0 - 2.0 * x_sep[i]).atanh())
        .collect();
    let f = ols(&x, brk.len(), 3, &z, &opts).map_err(|e| e.context(place))?;
    let a1 = f.params[0];
    if a1.is_nan() || a1 <= 0.0 {
        return Err(AeroError::too_little(
            place,
            format!("the static separation curve does not fall with alpha (a1 = {a1:.3} /rad)"),
        ));
    }
    let tau = (-f.params[1] / a1).clamp(0.01, 2.0);
    let alpha_star = -f.params[2] / a1;
    let (mut cm0, mut cm_alpha, mut cm_x) = (0.0, 0.0, 0.0);
    if with_cm {
        let x: Vec<f64> = (0..a.len())
            .flat_map(|i| [1.0, a[i], 1.0 - x_sep[i]])
            .collect();
        let f = ols(&x, a.len(), 3, cm, &opts).map_err(|e| e.context(place))?;
        (cm0, cm_alpha, cm_x) = (f.params[0], f.params[1], f.params[2]);
    }
    let mut best: Option<(f64, KirchhoffParams)> = None;
    for k in 1..10 {
        let share = 0.1 * k as f64;
        let p = KirchhoffParams {
            tau1: (1.0 - share) * tau,
            tau2: share * tau,
            alpha_star,
            a1,
            cl_alpha,
            alpha0,
            cm0,
            cm_alpha,
            cm_x,
        };
        let (ss, n) = sums(&TanhForm, &p.to_array(), series)?;
        let j = cost_of(ss, n, with_cm);
        if best.as_ref().is_none_or(|(bj, _)| j < *bj) {
            best = Some((j, p));
        }
    }
    best.map(|(_, p)| p)
        .ok_or_else(|| AeroError::too_little(place, "no start candidate"))
}

/// What [`run`] returns: estimates and bounds over the model's whole vector.
struct EngineFit {
    th: Vec<f64>,
    free: Vec<bool>,
    se: Vec<f64>,
    se_c: Vec<f64>,
    cov: Vec<f64>,
    cov_c: Vec<f64>,
    iterations: usize,
    converged: bool,
    cost: f64,
    residual_var: [f64; 2],
    n_samples: usize,
}

/// Iteration bound, tolerance and coloured-residual lag of [`run`].
struct Settings {
    max_iter: usize,
    tol: f64,
    max_lag: Option<usize>,
    /// Hold, for a step, each parameter at a bound whose gradient points out of its
    /// interval (projected-gradient active set), and leave the parameters at a bound at
    /// the end out of the bounds (NaN: a Cramér-Rao bound at a constraint is not a
    /// confidence interval). Off for the tanh form, whose iterations are unchanged.
    active_set: bool,
}

/// The engine (module docs): Levenberg-Marquardt on the relaxed maximum-likelihood
/// cost from `start` with the parameters in `fixed` held, then the Cramér-Rao and
/// coloured-residual bounds at the estimate.
fn run<M: OeModel>(
    model: &M,
    series: &[Series<'_>],
    with_cm: bool,
    start: &[f64],
    fixed: &[bool],
    set: &Settings,
) -> Result<EngineFit> {
    let dim = model.n_params();
    let mut free: Vec<bool> = fixed.iter().map(|f| !f).collect();
    if !with_cm {
        for j in model.cm_only() {
            free[j] = false;
        }
    }
    let idx: Vec<usize> = (0..dim).filter(|&j| free[j]).collect();
    let all_names = model.names();
    let names: Vec<String> = idx.iter().map(|&j| all_names[j].clone()).collect();
    let mut th = start.to_vec();
    model.project(&mut th);
    let (mut ss, n) = sums(model, &th, series)?;
    let mut j = cost_of(ss, n, with_cm);
    let mut lambda = 1e-3;
    let (mut iterations, mut converged) = (0, false);
    while iterations < set.max_iter {
        iterations += 1;
        let nf = n as f64;
        let w = [
            nf / ss[0].max(1e-300),
            if with_cm { nf / ss[1].max(1e-300) } else { 0.0 },
        ];
        let (m, g) = normal_equations(model, &th, series, &idx, w)?;
        let np = idx.len();
        let d: Vec<f64> = (0..np).map(|i| m[(i, i)].max(1e-300)).collect();
        // the parameters this step moves (all, unless held at a bound by the active set)
        let moving: Vec<usize> = if set.active_set {
            (0..np)
                .filter(|&k| !pinned(model.bounds(idx[k]), th[idx[k]], g[k]))
                .collect()
        } else {
            (0..np).collect()
        };
        let nm = moving.len();
        let gm = DVector::from_fn(nm, |r, _| g[moving[r]]);
        let mut accepted = false;
        while iterations <= set.max_iter {
            let a = DMatrix::from_fn(nm, nm, |r, c| {
                let (i, j) = (moving[r], moving[c]);
                m[(i, j)] + if i == j { lambda * d[i] } else { 0.0 }
            });
            let step = match a.cholesky() {
                Some(ch) => {
                    let sm = ch.solve(&gm);
                    let mut full = DVector::<f64>::zeros(np);
                    for (r, &k) in moving.iter().enumerate() {
                        full[k] = sm[r];
                    }
                    full
                }
                None => {
                    lambda *= 10.0;
                    iterations += 1;
                    continue;
                }
            };
            let mut trial = th.clone();
            for (k, &jx) in idx.iter().enumerate() {
                trial[jx] += step[k];
            }
            model.project(&mut trial);
            let (ss_t, _) = sums(model, &trial, series)?;
            let j_t = cost_of(ss_t, n, with_cm);
            if j_t.is_finite() && j_t <= j {
                let dj = j - j_t;
                th = trial;
                ss = ss_t;
                j = j_t;
                lambda = (lambda / 10.0).max(1e-12);
                accepted = true;
                // a cost change within the tolerance, or a step at rounding level
                // (a noise-free fit drives ln(mean v²) down without bound)
                let tiny = idx
                    .iter()
                    .enumerate()
                    .all(|(k, &jx)| step[k].abs() <= 1e-10 * (th[jx].abs() + 1e-10));
                if dj < set.tol || tiny {
                    converged = true;
                }
                break;
            }
            lambda *= 10.0;
            if lambda > 1e12 {
                // no descent direction left: a stationary point
                converged = true;
                break;
            }
            iterations += 1;
        }
        if converged || !accepted {
            break;
        }
    }
    if !converged {
        return Err(AeroError::NoConvergence {
            place: "output-error fit".into(),
            iterations,
            residual: j,
            message: "raise max_iter, or give start values closer to the solution".into(),
        });
    }
    let nf = n as f64;
    let r = [ss[0] / nf, if with_cm { ss[1] / nf } else { f64::NAN }];
    let w = [
        1.0 / r[0].max(1e-300),
        if with_cm { 1.0 / r[1].max(1e-300) } else { 0.0 },
    ];
    let (idx, names) = if set.active_set {
        // parameters ending on a bound are reported held there: not free, no bounds
        let (_, g) = normal_equations(model, &th, series, &idx, w)?;
        let keep: Vec<usize> = (0..idx.len())
            .filter(|&k| !at_bound(model.bounds(idx[k]), th[idx[k]], g[k]))
            .collect();
        for k in 0..idx.len() {
            if !keep.contains(&k) {
                free[idx[k]] = false;
            }
        }
        (
            keep.iter().map(|&k| idx[k]).collect::<Vec<_>>(),
            keep.iter().map(|&k| names[k].clone()).collect::<Vec<_>>(),
        )
    } else {
        (idx, names)
    };
    let (m, _) = normal_equations(model, &th, series, &idx, w)?;
    let minv = spd_inverse(&m, &names)?;
    // coloured-residual middle matrix, per maneuver and output
    let np = idx.len();
    let mut mid = DMatrix::<f64>::zeros(np, np);
    for s in series {
        let o = model.outputs(&th, &s.inputs, true)?;
        // (measured, model, sensitivities, weight) per output
        type Output<'a> = (&'a [f64], &'a [f64], &'a [f64], f64);
        let outs: [Output<'_>; 2] = [
            (s.cl, &o.cl, &o.dcl, w[0]),
            (s.cm.unwrap_or(&[]), &o.cm, &o.dcm, w[1]),
        ];
        for (z, y, sens, wo) in outs {
            if z.is_empty() {
                continue;
            }
            let v: Vec<f64> = z.iter().zip(y).map(|(a, b)| a - b).collect();
            let g = toeplitz_gram(
                np,
                |b, out| {
                    for (k, o) in out.iter_mut().enumerate() {
                        *o = sens[k * dim + idx[b]] * wo;
                    }
                },
                &v,
                set.max_lag,
            )?;
            for a in 0..np {
                for b in 0..np {
                    mid[(a, b)] += g[(a, b)];
                }
            }
        }
    }
    let cc = &minv * mid * &minv;
    let mut cov = vec![0.0; dim * dim];
    let mut cov_c = vec![0.0; dim * dim];
    let mut se = vec![f64::NAN; dim];
    let mut se_c = vec![f64::NAN; dim];
    for (a, &ja) in idx.iter().enumerate() {
        for (b, &jb) in idx.iter().enumerate() {
            cov[ja * dim + jb] = minv[(a, b)];
            cov_c[ja * dim + jb] = cc[(a, b)];
        }
        se[ja] = minv[(a, a)].max(0.0).sqrt();
        se_c[ja] = cc[(a, a)].max(0.0).sqrt();
    }
    Ok(EngineFit {
        th,
        free,
        se,
        se_c,
        cov,
        cov_c,
        iterations,
        converged,
        cost: j,
        residual_var: r,
        n_samples: n,
    })
}

/// True when `v` sits on a bound of `(lo, hi)` and the descent direction `g`
/// (`Σ Sᵀ R⁻¹ v`: raising θ lowers the cost when positive) points out of it.
fn pinned((lo, hi): (f64, f64), v: f64, g: f64) -> bool {
    (v <= lo && g < 0.0) || (v >= hi && g > 0.0)
}

/// True when `v` sits on a bound of `(lo, hi)` with the descent direction out of
/// it or along it (a parameter the data would move past its bound).
fn at_bound((lo, hi): (f64, f64), v: f64, g: f64) -> bool {
    (v <= lo && g <= 0.0) || (v >= hi && g >= 0.0)
}

/// Fit the Kirchhoff model to `series` by output error (module docs).
///
/// # Errors
/// Invalid inputs (lengths, non-finite values, time not increasing), too little
/// data for the start, a singular information matrix, or no convergence within
/// [`OeOptions::max_iter`] ([`AeroError::NoConvergence`] with the last cost).
pub fn fit(series: &[Series<'_>], opts: &OeOptions) -> Result<OeFit> {
    let with_cm = check(series)?;
    let start = match opts.start {
        Some(p) => {
            p.check()?;
            p
        }
        None => equation_error_start(series)?,
    };
    let set = Settings {
        max_iter: opts.max_iter,
        tol: opts.tol,
        max_lag: opts.max_lag,
        active_set: false,
    };
    let e = run(
        &TanhForm,
        series,
        with_cm,
        &start.to_array(),
        &opts.fixed,
        &set,
    )?;
    let arr = |v: &[f64]| {
        let mut a = [0.0; N_PARAMS];
        a.copy_from_slice(v);
        a
    };
    let mut free = [false; N_PARAMS];
    free.copy_from_slice(&e.free);
    Ok(OeFit {
        params: tanh_params(&e.th),
        start,
        free,
        std_err: arr(&e.se),
        std_err_colored: arr(&e.se_c),
        cov: e.cov,
        cov_colored: e.cov_c,
        iterations: e.iterations,
        converged: e.converged,
        cost: e.cost,
        residual_var: e.residual_var,
        n_samples: e.n_samples,
        n_maneuvers: series.len(),
    })
}

/// Settings of [`fit_tabulated`].
#[derive(Debug, Clone)]
pub struct GkOptions {
    /// Iteration bound. Default 60.
    pub max_iter: usize,
    /// Convergence tolerance on the cost, as [`OeOptions::tol`]. Default 1e-9.
    pub tol: f64,
    /// Parameters held at their start ([`GkParams::names`] order); empty: none.
    pub fixed: Vec<bool>,
    /// As [`OeOptions::max_lag`].
    pub max_lag: Option<usize>,
}

impl Default for GkOptions {
    fn default() -> Self {
        GkOptions {
            max_iter: 60,
            tol: 1e-9,
            fixed: Vec::new(),
            max_lag: None,
        }
    }
}

/// The result of [`fit_tabulated`]: as [`OeFit`] over [`GkParams::names`].
#[derive(Debug, Clone)]
pub struct GkFit {
    /// Estimates (the start's knots).
    pub params: GkParams,
    /// The start.
    pub start: GkParams,
    /// Which parameters were estimated (false: held, or ending on a bound).
    pub free: Vec<bool>,
    /// Cramér-Rao bounds, NaN for held parameters.
    pub std_err: Vec<f64>,
    /// The bounds corrected for coloured residuals, NaN for held parameters.
    pub std_err_colored: Vec<f64>,
    /// Row-major Cramér-Rao covariance (zeros for held parameters).
    pub cov: Vec<f64>,
    /// Row-major coloured-residual covariance.
    pub cov_colored: Vec<f64>,
    /// Iterations taken.
    pub iterations: usize,
    /// True when the cost change met the tolerance.
    pub converged: bool,
    /// Final cost `J`.
    pub cost: f64,
    /// Residual variance per output (C_L, C_m; C_m NaN when not fitted).
    pub residual_var: [f64; 2],
    /// Samples used.
    pub n_samples: usize,
    /// Maneuvers used.
    pub n_maneuvers: usize,
}

/// Fit the tabulated (Goman-Khrabrov) form ([`crate::goman_khrabrov`]) by output
/// error from `start` over its knots, with the engine of [`fit`] (same cost,
/// iterations and bounds), with the active set: a coefficient on its bound 0 or 1
/// whose gradient points outward is held for the step, and one ending there is
/// reported not free, without bounds. The start is typically the tanh fit's curve
/// re-expressed on the knots, with the lift line `C_Lα`, `α₀` held (`opts.fixed`):
/// with both free, the line and the coefficients trade off.
///
/// # Errors
/// As [`fit`]; a start that fails [`GkParams::check`]; `fixed` of the wrong length.
pub fn fit_tabulated(series: &[Series<'_>], start: &GkParams, opts: &GkOptions) -> Result<GkFit> {
    let with_cm = check(series)?;
    start.check()?;
    let model = TableForm { template: start };
    let dim = model.n_params();
    let fixed = if opts.fixed.is_empty() {
        vec![false; dim]
    } else {
        opts.fixed.clone()
    };
    if fixed.len() != dim {
        return Err(AeroError::invalid(
            "output-error fit (tabulated): fixed",
            format!(
                "has {} flags for {dim} parameters ({} scalar and one per knot)",
                fixed.len(),
                N_CORE
            ),
        ));
    }
    let set = Settings {
        max_iter: opts.max_iter,
        tol: opts.tol,
        max_lag: opts.max_lag,
        active_set: true,
    };
    let e = run(&model, series, with_cm, &start.to_vec(), &fixed, &set)?;
    Ok(GkFit {
        params: start.with_vec(&e.th),
        start: start.clone(),
        free: e.free,
        std_err: e.se,
        std_err_colored: e.se_c,
        cov: e.cov,
        cov_colored: e.cov_c,
        iterations: e.iterations,
        converged: e.converged,
        cost: e.cost,
        residual_var: e.residual_var,
        n_samples: e.n_samples,
        n_maneuvers: series.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::goman_khrabrov::{GkParams, N_CORE};
    use crate::kirchhoff::outputs;
    use crate::kirchhoff::tests::truth;
    use crate::sim::rng::Stream;

    /// Stall-like maneuvers: a slow pull through the break and a recovery, with doublets.
    fn maneuvers(k: usize, seed: u64) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let mut rng = Stream::new(seed, 1);
        (0..k)
            .map(|_| {
                let hz = 50.0;
                let n = 1200;
                let top = rng.range(20.0, 24.0);
                let f1 = rng.range(1.0, 2.5);
                let amp = rng.range(0.5, 2.0);
                let t: Vec<f64> = (0..n).map(|i| i as f64 / hz).collect();
                let dur = n as f64 / hz;
                let shape = |t: f64| {
                    let s = (std::f64::consts::PI * t / dur).sin();
                    6.0 + (top - 6.0) * s * s + amp * (f1 * t).sin()
                };
                let a: Vec<f64> = t.iter().map(|&t| shape(t).to_radians()).collect();
                let h = 1e-5;
                let ad: Vec<f64> = t
                    .iter()
                    .map(|&t| ((shape(t + h) - shape(t - h)) / (2.0 * h)).to_radians())
                    .collect();
                (t, a, ad)
            })
            .collect()
    }

    fn data(
        p: &KirchhoffParams,
        ms: &[(Vec<f64>, Vec<f64>, Vec<f64>)],
        noise: f64,
        seed: u64,
    ) -> Vec<(Vec<f64>, Vec<f64>)> {
        let mut rng = Stream::new(seed, 2);
        ms.iter()
            .map(|(t, a, ad)| {
                let o = outputs(
                    p,
                    &Inputs {
                        t,
                        alpha: a,
                        alpha_dot: ad,
                    },
                    false,
                )
                .unwrap();
                let cl = o.cl.iter().map(|v| v + noise * rng.normal()).collect();
                let cm =
                    o.cm.iter()
                        .map(|v| v + 0.3 * noise * rng.normal())
                        .collect();
                (cl, cm)
            })
            .collect()
    }

    fn series<'a>(
        ms: &'a [(Vec<f64>, Vec<f64>, Vec<f64>)],
        ys: &'a [(Vec<f64>, Vec<f64>)],
    ) -> Vec<Series<'a>> {
        ms.iter()
            .zip(ys)
            .map(|((t, a, ad), (cl, cm))| Series {
                inputs: Inputs {
                    t,
                    alpha: a,
                    alpha_dot: ad,
                },
                cl,
                cm: Some(cm),
            })
            .collect()
    }

    #[test]
    fn recovers_known_parameters_from_noise_free_histories() {
        let p = truth();
        let ms = maneuvers(6, 7);
        let ys = data(&p, &ms, 0.0, 1);
        let s = series(&ms, &ys);
        let f = fit(&s, &OeOptions::default()).unwrap();
        assert!(f.converged);
        let (est, tru) = (f.params.to_array(), p.to_array());
        for j in 0..N_PARAMS {
            let rel = (est[j] - tru[j]).abs() / tru[j].abs();
            assert!(rel < 1e-5, "{}: {} vs {}", PARAM_NAMES[j], est[j], tru[j]);
        }
        // the start came from equation error and was not already the answer
        let st = f.start.to_array();
        assert!((st[0] - tru[0]).abs() / tru[0] > 1e-3);
    }

    #[test]
    fn noisy_histories_give_estimates_within_their_bounds() {
        let p = truth();
        let ms = maneuvers(8, 11);
        let ys = data(&p, &ms, 0.02, 3);
        let s = series(&ms, &ys);
        let f = fit(&s, &OeOptions::default()).unwrap();
        let (est, tru) = (f.params.to_array(), p.to_array());
        for j in 0..N_PARAMS {
            // white noise: the conventional and the corrected bounds agree, and cover the truth
            assert!(f.std_err[j] > 0.0);
            let ratio = f.std_err_colored[j] / f.std_err[j];
            assert!(
                (0.7..1.4).contains(&ratio),
                "{}: ratio {ratio}",
                PARAM_NAMES[j]
            );
            assert!(
                (est[j] - tru[j]).abs() < 4.0 * f.std_err[j],
                "{}: {} vs {} (se {})",
                PARAM_NAMES[j],
                est[j],
                tru[j],
                f.std_err[j]
            );
        }
        assert!((f.residual_var[0].sqrt() - 0.02).abs() < 0.002);
    }

    #[test]
    fn held_parameters_stay_and_cm_can_be_left_out() {
        let p = truth();
        let ms = maneuvers(4, 5);
        let ys = data(&p, &ms, 0.0, 1);
        let s: Vec<Series<'_>> = series(&ms, &ys)
            .into_iter()
            .map(|mut x| {
                x.cm = None;
                x
            })
            .collect();
        let mut start = p;
        start.tau2 = 0.05;
        let mut fixed = [false; N_PARAMS];
        fixed[4] = true;
        let f = fit(
            &s,
            &OeOptions {
                start: Some(start),
                fixed,
                ..OeOptions::default()
            },
        )
        .unwrap();
        assert_eq!(f.params.cl_alpha, p.cl_alpha);
        assert_eq!(f.params.cm_x, p.cm_x); // not fitted: held at the start
        assert!(f.std_err[4].is_nan() && f.std_err[8].is_nan());
        assert!((f.params.tau2 - p.tau2).abs() < 1e-6);
    }

    /// A table truth: the tanh curve of [`truth`] every 1.5 deg, with a plateau
    /// the tanh cannot follow (the nodes at 19.5-21 deg held at 0.55).
    fn table_truth() -> GkParams {
        let p = truth();
        let knots: Vec<f64> = (0..8)
            .map(|k| (12.0 + 1.5 * k as f64).to_radians())
            .collect();
        let values = knots
            .iter()
            .map(|&a| {
                let d = a.to_degrees();
                if (19.4..21.1).contains(&d) {
                    0.55
                } else {
                    p.x0(a)
                }
            })
            .collect();
        GkParams::with_table(
            &p,
            crate::goman_khrabrov::X0Table::new(knots, values).unwrap(),
        )
    }

    fn gk_data(g: &GkParams, ms: &[(Vec<f64>, Vec<f64>, Vec<f64>)]) -> Vec<(Vec<f64>, Vec<f64>)> {
        ms.iter()
            .map(|(t, a, ad)| {
                let o = crate::goman_khrabrov::outputs(
                    g,
                    &Inputs {
                        t,
                        alpha: a,
                        alpha_dot: ad,
                    },
                    false,
                )
                .unwrap();
                (o.cl, o.cm)
            })
            .collect()
    }

    #[test]
    fn tabulated_form_recovers_a_table_the_tanh_cannot_follow() {
        let g = table_truth();
        let ms = maneuvers(6, 7);
        let ys = gk_data(&g, &ms);
        let s = series(&ms, &ys);
        // the tanh fit misses the plateau; the table started from it finds it
        let tanh = fit(&s, &OeOptions::default()).unwrap();
        let mut st = g.clone();
        let tp = tanh.params;
        let vals: Vec<f64> = g.x0.knots().iter().map(|&a| tp.x0(a)).collect();
        st = st.with_vec(
            &[
                vec![
                    tp.tau1,
                    tp.tau2,
                    tp.cl_alpha,
                    tp.alpha0,
                    tp.cm0,
                    tp.cm_alpha,
                    tp.cm_x,
                ],
                vals,
            ]
            .concat(),
        );
        // the first node is attached flow: held (it trades with CL_alpha)
        let mut fixed = vec![false; st.to_vec().len()];
        fixed[N_CORE] = true;
        let mut st_vals = st.to_vec();
        st_vals[N_CORE] = g.x0.values()[0];
        let st = st.with_vec(&st_vals);
        let f = fit_tabulated(
            &s,
            &st,
            &GkOptions {
                fixed,
                max_iter: 200,
                ..GkOptions::default()
            },
        )
        .unwrap();
        assert!(f.converged);
        let (est, tru) = (f.params.to_vec(), g.to_vec());
        let names = g.names();
        for j in 0..est.len() {
            assert!(
                (est[j] - tru[j]).abs() <= 1e-5 * tru[j].abs().max(1e-2),
                "{}: {} vs {}",
                names[j],
                est[j],
                tru[j]
            );
        }
        assert!(f.std_err[N_CORE].is_nan() && f.std_err[N_CORE + 1] > 0.0);
        // the tanh form's residual is not noise: it could not follow the plateau
        assert!(
            tanh.residual_var[0].sqrt() > 1e-3,
            "{:?}",
            tanh.residual_var
        );
        // wrong length of fixed: refused
        let bad = GkOptions {
            fixed: vec![false; 3],
            ..GkOptions::default()
        };
        assert!(fit_tabulated(&s, &st, &bad)
            .unwrap_err()
            .to_string()
            .contains("fixed"));
    }

    #[test]
    fn tabulated_bounds_cover_the_truth_on_noisy_histories() {
        let g = table_truth();
        let ms = maneuvers(8, 11);
        let mut rng = Stream::new(3, 2);
        let ys: Vec<(Vec<f64>, Vec<f64>)> = gk_data(&g, &ms)
            .into_iter()
            .map(|(cl, cm)| {
                (
                    cl.iter().map(|v| v + 0.02 * rng.normal()).collect(),
                    cm.iter().map(|v| v + 0.006 * rng.normal()).collect(),
                )
            })
            .collect();
        let s = series(&ms, &ys);
        let mut fixed = vec![false; N_CORE + g.x0.knots().len()];
        fixed[N_CORE] = true;
        let f = fit_tabulated(
            &s,
            &g,
            &GkOptions {
                fixed,
                max_iter: 200,
                ..GkOptions::default()
            },
        )
        .unwrap();
        let (est, tru) = (f.params.to_vec(), g.to_vec());
        let names = g.names();
        let mut outside = 0;
        for j in 0..est.len() {
            if !f.free[j] {
                continue;
            }
            let ratio = f.std_err_colored[j] / f.std_err[j];
            assert!((0.7..1.4).contains(&ratio), "{}: ratio {ratio}", names[j]);
            // nodes at 0 or 1 sit on their bound: skip those
            let on_bound = j >= N_CORE && (tru[j] < 0.01 || tru[j] > 0.99);
            if !on_bound && (est[j] - tru[j]).abs() > 3.0 * f.std_err[j] {
                outside += 1;
            }
        }
        assert!(outside <= 1, "{outside} parameters outside 3 bounds");
        assert!((f.residual_var[0].sqrt() - 0.02).abs() < 0.002);
    }

    #[test]
    fn tabulated_coefficients_at_their_bounds_are_held_there() {
        // the first nodes are attached flow (x0 = 1, the bound): with noise the data push
        // some of them past 1; the active set holds those at 1 (no bound reported) and the
        // fit converges in the default iterations
        let mut g = table_truth();
        let mut v = g.to_vec();
        for x in &mut v[N_CORE..N_CORE + 3] {
            *x = 1.0;
        }
        g = g.with_vec(&v);
        let ms = maneuvers(8, 13);
        let mut rng = Stream::new(5, 2);
        let ys: Vec<(Vec<f64>, Vec<f64>)> = gk_data(&g, &ms)
            .into_iter()
            .map(|(cl, cm)| {
                (
                    cl.iter().map(|v| v + 0.02 * rng.normal()).collect(),
                    cm.iter().map(|v| v + 0.006 * rng.normal()).collect(),
                )
            })
            .collect();
        let s = series(&ms, &ys);
        let mut fixed = vec![false; v.len()];
        fixed[2] = true; // the lift line held, as the Python front end holds it
        fixed[3] = true;
        let f = fit_tabulated(
            &s,
            &g,
            &GkOptions {
                fixed,
                ..GkOptions::default()
            },
        )
        .unwrap();
        assert!(f.converged && f.iterations < 60, "{}", f.iterations);
        let est = f.params.to_vec();
        for (k, (&e, &se)) in est[N_CORE..N_CORE + 3]
            .iter()
            .zip(&f.std_err[N_CORE..N_CORE + 3])
            .enumerate()
        {
            if e >= 1.0 {
                assert!(se.is_nan(), "x0[{k}] at 1 with a bound");
            } else {
                assert!((1.0 - e) < 3.0 * se, "x0[{k}]");
            }
        }
        assert!((f.params.tau1 / g.tau1 - 1.0).abs() < 0.05);
        // this seed's data push at least one of them past 1
        assert!(est[N_CORE..N_CORE + 3].contains(&1.0));
    }

    #[test]
    fn bad_inputs_are_refused_with_the_place() {
        let ms = maneuvers(1, 5);
        let ys = data(&truth(), &ms, 0.0, 1);
        let mut cl = ys[0].0.clone();
        cl[17] = f64::NAN;
        let s = [Series {
            inputs: Inputs {
                t: &ms[0].0,
                alpha: &ms[0].1,
                alpha_dot: &ms[0].2,
            },
            cl: &cl,
            cm: None,
        }];
        let e = fit(&s, &OeOptions::default()).unwrap_err();
        assert!(e.to_string().contains("maneuver 0: CL row 17"), "{e}");
        assert!(fit(&[], &OeOptions::default()).is_err());
        // pre-stall only: too little data for the start, said so
        let t: Vec<f64> = (0..500).map(|i| i as f64 * 0.02).collect();
        let a: Vec<f64> = t.iter().map(|t| (4.0 + t).to_radians()).collect();
        let ad = vec![1.0f64.to_radians(); 500];
        let cl: Vec<f64> = a.iter().map(|a| 5.2 * a).collect();
        let s = [Series {
            inputs: Inputs {
                t: &t,
                alpha: &a,
                alpha_dot: &ad,
            },
            cl: &cl,
            cm: None,
        }];
        let e = fit(&s, &OeOptions::default()).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::TooLittleData, "{e}");
    }
}
