//! Cubic smoothing splines with MATLAB `csaps` semantics (thesis Section 3.4,
//! Eq. 3.13; de Boor, *A Practical Guide to Splines*, ch. XIV; Reinsch 1967).
//!
//! Given data sites $x_1 < \dots < x_n$, values $y_j$, weights $w_j > 0$ and a
//! smoothing parameter $p \in [0, 1]$, the smoothing spline $f$ minimises
//! $$ J(f) = p \sum_{j=1}^{n} w_j \,\big(y_j - f(x_j)\big)^2
//!         + (1 - p) \int_{x_1}^{x_n} \big(f''(t)\big)^2 \,dt \qquad \text{(thesis Eq. 3.13)}. $$
//! $p = 0$ gives the weighted least-squares straight line, $p = 1$ the natural
//! cubic interpolating spline. In the thesis, $x$ is the angle of attack (deg) of
//! the alpha-bin centres, $y$ a Δ-model parameter identified per bin, $p = 0.4$
//! and $w_j$ may be $1/\sigma_j^2$ from the per-bin standard errors.
//!
//! # Algorithm (Reinsch / de Boor, as `csaps`)
//! With $h_i = x_{i+1} - x_i$, $Q$ the $n \times (n-2)$ second-divided-difference
//! matrix (column $i$: $1/h_i$, $-(1/h_i + 1/h_{i+1})$, $1/h_{i+1}$), $R$ the
//! tridiagonal $(n-2)\times(n-2)$ matrix with diagonal $2(h_i + h_{i+1})$ and
//! off-diagonal $h_{i+1}$, and $W = \operatorname{diag}(w)$, solve the symmetric
//! positive definite pentadiagonal system
//! $$ \big(6(1-p)\, Q^\top W^{-1} Q + p R\big)\, u = Q^\top y $$
//! by a banded $LDL^\top$ factorisation in $O(n)$. The fitted values are
//! $\hat y = y - 6(1-p)\, W^{-1} Q u$ and the second derivatives at the sites
//! $f''(x_j) = 6 p\, u_j$ (zero at both ends: natural spline). Each piece is
//! returned in local power form
//! $f(x) = a_3 t^3 + a_2 t^2 + a_1 t + a_0$, $t = x - x_i$, exactly the
//! `(breaks, coefs)` of MATLAB's `ppform` and of the Python `csaps` package
//! (`csaps.CubicSmoothingSpline(x, y, weights, smooth=p)`, whose source this
//! follows operation for operation, so results agree to rounding).
//!
//! # Conventions
//! - `x` must be finite and *strictly* increasing (duplicates are refused);
//!   [`merge_sites`] sorts data and merges repeated sites by weighted averaging
//!   (summing their weights) as MATLAB `csaps` does, without changing the fit.
//! - `y` is scalar-valued; fit several series over the same sites by calling
//!   [`smoothing_spline`] once per series.
//! - Outside $[x_1, x_n]$ the end pieces are continued as polynomials
//!   ([`SplineExtrapolation::Polynomial`], what `csaps` and MATLAB `fnval` do)
//!   or the end values are held ([`SplineExtrapolation::Hold`]).
//! - Two points give the straight line through them for every $p$; the
//!   reported $p$ is then 1, as `csaps` reports.
//! - $p = 0$ is computed in closed form (weighted least-squares line), which is
//!   exact where the banded system loses digits on long series (see [`smoothing_spline`]).

use crate::error::{AeroError, Result};
use crate::table::{Axis, Table};

/// How the smoothing parameter $p$ of thesis Eq. 3.13 is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Smoothing {
    /// A given $p \in [0, 1]$ (the thesis uses 0.4).
    Fixed(f64),
    /// `csaps`'s default when no $p$ is given: $p = 1 / (1 + \operatorname{tr}(R) /
    /// (6 \operatorname{tr}(Q^\top W^{-1} Q)))$, which balances the two terms of the
    /// system matrix (MATLAB `csaps` with `p = []`).
    Auto,
    /// `csaps`'s `normalizedsmooth=True` (package version ≥ 1.1): a smoothing
    /// value $s \in [0, 1]$ (default 0.5) mapped to $p = s / (s + (1-s) k)$ with
    /// $k = 80\, \mathrm{span}^3 n^{-2} e_x^{-1/2} e_w^{-1/2}$, so results do not
    /// depend on the range of $x$ and less on the clumping of $x$ and $w$.
    Normalized(Option<f64>),
}

/// What a spline returns outside its breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SplineExtrapolation {
    /// Continue the end cubic pieces (`csaps`, MATLAB `fnval`, scipy `PPoly`).
    #[default]
    Polynomial,
    /// Hold the end value; derivatives are zero outside (simulator tables).
    Hold,
}

impl std::str::FromStr for SplineExtrapolation {
    type Err = AeroError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "polynomial" => Ok(SplineExtrapolation::Polynomial),
            "hold" => Ok(SplineExtrapolation::Hold),
            other => Err(AeroError::invalid(
                "spline extrapolation",
                format!("unknown policy '{other}'; valid values are 'polynomial' and 'hold'"),
            )),
        }
    }
}

/// A cubic spline in piecewise-polynomial form: `breaks` $x_0 < \dots < x_{m}$
/// and, per piece $i$, coefficients `[a3, a2, a1, a0]` of
/// $a_3 t^3 + a_2 t^2 + a_1 t + a_0$ with $t = x - x_i$ (highest power first,
/// as MATLAB `ppform` and scipy `PPoly` store them).
///
/// ```
/// use aero_core::spline::{smoothing_spline, Smoothing, SplineExtrapolation};
/// // p = 1 interpolates; the natural spline through three collinear points is that line.
/// let s = smoothing_spline(&[0.0, 1.0, 3.0], &[1.0, 3.0, 7.0], None, Smoothing::Fixed(1.0)).unwrap();
/// assert!((s.eval(2.0, 0, SplineExtrapolation::Polynomial) - 5.0).abs() < 1e-12);
/// assert!((s.eval(5.0, 1, SplineExtrapolation::Polynomial) - 2.0).abs() < 1e-12);
/// assert_eq!(s.eval(5.0, 0, SplineExtrapolation::Hold), 7.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothingSpline {
    breaks: Vec<f64>,
    coefs: Vec<[f64; 4]>,
    p: f64,
}

/// Fit the cubic smoothing spline of thesis Eq. 3.13 (MATLAB / Python `csaps`).
///
/// `x`: data sites, strictly increasing (e.g. alpha-bin centres, deg); `y`:
/// values at the sites; `weights`: $w_j > 0$ (default all 1), e.g. $1/\sigma_j^2$.
///
/// # Errors
/// - [`AeroError::TooLittleData`] with fewer than 2 points;
/// - [`AeroError::InvalidInput`] naming the index for lengths that differ,
///   non-finite `x`, `y` or `weights`, or `x` not strictly increasing;
/// - [`AeroError::OutOfRange`] naming the index for a weight $\le 0$, and for
///   $p$ (or the normalised $s$) outside $[0, 1]$;
/// - [`AeroError::InvalidInput`] if the banded system is numerically singular
///   (sites so clustered that $h_i$ underflows the conditioning).
pub fn smoothing_spline(
    x: &[f64],
    y: &[f64],
    weights: Option<&[f64]>,
    smoothing: Smoothing,
) -> Result<SmoothingSpline> {
    const PLACE: &str = "smoothing spline";
    let n = x.len();
    if y.len() != n {
        return Err(AeroError::invalid(
            PLACE,
            format!("x has {n} points but y has {}; give one y per x", y.len()),
        ));
    }
    if n < 2 {
        return Err(AeroError::too_little(
            PLACE,
            format!("{n} data point(s); a spline needs at least 2"),
        ));
    }
    for (i, (&xi, &yi)) in x.iter().zip(y).enumerate() {
        if !xi.is_finite() {
            return Err(AeroError::invalid(
                format!("{PLACE}, x[{i}]"),
                format!("is {xi}; data sites must be finite"),
            ));
        }
        if !yi.is_finite() {
            return Err(AeroError::invalid(
                format!("{PLACE}, y[{i}]"),
                format!("is {yi}; values must be finite (drop the point or fill it)"),
            ));
        }
        if i > 0 && xi <= x[i - 1] {
            return Err(AeroError::invalid(
                format!("{PLACE}, x[{i}]"),
                format!(
                    "{xi} does not exceed x[{}] = {}; sites must be strictly increasing \
                     (sort them and merge duplicates by weighted averaging)",
                    i - 1,
                    x[i - 1]
                ),
            ));
        }
    }
    let ones;
    let w: &[f64] = match weights {
        Some(w) => {
            if w.len() != n {
                return Err(AeroError::invalid(
                    PLACE,
                    format!("x has {n} points but weights has {}", w.len()),
                ));
            }
            for (i, &wi) in w.iter().enumerate() {
                if !wi.is_finite() {
                    return Err(AeroError::invalid(
                        format!("{PLACE}, weights[{i}]"),
                        format!("is {wi}; weights must be finite"),
                    ));
                }
                if wi <= 0.0 {
                    return Err(AeroError::out_of_range(
                        format!("{PLACE}, weights[{i}]"),
                        format!("is {wi}; weights must be > 0 (drop the point instead)"),
                    ));
                }
            }
            w
        }
        None => {
            ones = vec![1.0; n];
            &ones
        }
    };
    let check_unit = |what: &str, v: f64| -> Result<f64> {
        if (0.0..=1.0).contains(&v) {
            Ok(v)
        } else {
            Err(AeroError::out_of_range(
                format!("{PLACE}, {what}"),
                format!("is {v}; it must lie in [0, 1] (0: least-squares line, 1: interpolant)"),
            ))
        }
    };
    match smoothing {
        Smoothing::Fixed(p) => {
            check_unit("smoothing parameter p", p)?;
        }
        Smoothing::Normalized(Some(s)) => {
            check_unit("normalised smoothing s", s)?;
        }
        Smoothing::Auto | Smoothing::Normalized(None) => {}
    }

    let h: Vec<f64> = x.windows(2).map(|v| v[1] - v[0]).collect();
    let slope: Vec<f64> = y
        .windows(2)
        .zip(&h)
        .map(|(v, hi)| (v[1] - v[0]) / hi)
        .collect();

    if n == 2 {
        return Ok(SmoothingSpline {
            breaks: x.to_vec(),
            coefs: vec![[0.0, 0.0, slope[0], y[0]]],
            p: 1.0,
        });
    }

    // Bands of R (diag r0, super-diagonal r1) and M = Q^T W^-1 Q (m0, m1, m2).
    let m = n - 2;
    let r0: Vec<f64> = (0..m).map(|i| 2.0 * (h[i] + h[i + 1])).collect();
    let r1: Vec<f64> = (0..m - 1).map(|i| h[i + 1]).collect();
    let inv_h: Vec<f64> = h.iter().map(|v| 1.0 / v).collect();
    // Column i of Q: rows i, i+1, i+2 hold q0[i], q1[i], q2[i].
    let q0 = |i: usize| inv_h[i];
    let q1 = |i: usize| -(inv_h[i + 1] + inv_h[i]);
    let q2 = |i: usize| inv_h[i + 1];
    let m0: Vec<f64> = (0..m)
        .map(|i| q0(i) * q0(i) / w[i] + q1(i) * q1(i) / w[i + 1] + q2(i) * q2(i) / w[i + 2])
        .collect();
    let m1: Vec<f64> = (0..m.saturating_sub(1))
        .map(|i| q1(i) * q0(i + 1) / w[i + 1] + q2(i) * q1(i + 1) / w[i + 2])
        .collect();
    let m2: Vec<f64> = (0..m.saturating_sub(2))
        .map(|i| q2(i) * q0(i + 2) / w[i + 2])
        .collect();

    let p = match smoothing {
        Smoothing::Fixed(p) => p,
        Smoothing::Auto => {
            let tr_r: f64 = r0.iter().sum();
            let tr_m: f64 = m0.iter().sum();
            1.0 / (1.0 + tr_r / (6.0 * tr_m))
        }
        Smoothing::Normalized(s) => {
            let s = s.unwrap_or(0.5);
            let span = x[n - 1] - x[0];
            let eff_x = 1.0 + span * span / h.iter().map(|v| v * v).sum::<f64>();
            let sw: f64 = w.iter().sum();
            let eff_w = sw * sw / w.iter().map(|v| v * v).sum::<f64>();
            let k = 80.0 * span.powi(3) * (n as f64).powi(-2) / eff_x.sqrt() / eff_w.sqrt();
            s / (s + (1.0 - s) * k)
        }
    };
    if p == 0.0 {
        return Ok(wls_line(x, y, w));
    }
    let pp = 6.0 * (1.0 - p);

    let a0: Vec<f64> = (0..m).map(|i| pp * m0[i] + p * r0[i]).collect();
    let a1: Vec<f64> = (0..m.saturating_sub(1))
        .map(|i| pp * m1[i] + p * r1[i])
        .collect();
    let a2: Vec<f64> = m2.iter().map(|v| pp * v).collect();
    let mut u: Vec<f64> = (0..m).map(|i| slope[i + 1] - slope[i]).collect();
    solve_pentadiagonal_spd(&a0, &a1, &a2, &mut u)?;

    // d1 = diff(pad(u)) / h ; d2 = diff(pad(d1)) = Q u ; yhat = y - pp / w * d2.
    let upad = |j: usize| if j == 0 || j == n - 1 { 0.0 } else { u[j - 1] };
    let d1: Vec<f64> = (0..n - 1).map(|j| (upad(j + 1) - upad(j)) / h[j]).collect();
    let yhat: Vec<f64> = (0..n)
        .map(|j| {
            let lo = if j == 0 { 0.0 } else { d1[j - 1] };
            let hi = if j == n - 1 { 0.0 } else { d1[j] };
            y[j] - pp / w[j] * (hi - lo)
        })
        .collect();
    let coefs: Vec<[f64; 4]> = (0..n - 1)
        .map(|j| {
            let pu0 = p * upad(j);
            let pu1 = p * upad(j + 1);
            [
                (pu1 - pu0) / h[j],
                3.0 * pu0,
                (yhat[j + 1] - yhat[j]) / h[j] - h[j] * (2.0 * pu0 + pu1),
                yhat[j],
            ]
        })
        .collect();
    Ok(SmoothingSpline {
        breaks: x.to_vec(),
        coefs,
        p,
    })
}

/// Sort the sites and merge repeated ones, so data in any order can be passed to
/// [`smoothing_spline`] (what MATLAB `csaps` does before fitting; the Python
/// `csaps` package refuses such data).
///
/// Sites are sorted increasingly (stable); the values at equal sites are
/// replaced by their weighted mean $\bar y = \sum w_k y_k / \sum w_k$ with
/// weight $\sum w_k$. Because
/// $\sum_k w_k (y_k - f)^2 = (\sum_k w_k)(\bar y - f)^2 + \text{const}$,
/// the merged data give the same minimiser of thesis Eq. 3.13 as the original.
/// Returns `(x, y, w)`; `w` is all ones when no weights are given and no site repeats.
///
/// # Errors
/// [`AeroError::InvalidInput`] naming the index (in the input order) for lengths
/// that differ or non-finite data; [`AeroError::OutOfRange`] for a weight $\le 0$.
pub fn merge_sites(
    x: &[f64],
    y: &[f64],
    weights: Option<&[f64]>,
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    const PLACE: &str = "smoothing spline";
    let n = x.len();
    if y.len() != n || weights.is_some_and(|w| w.len() != n) {
        return Err(AeroError::invalid(
            PLACE,
            format!(
                "x has {n} points, y {} and weights {}; give one of each per site",
                y.len(),
                weights.map_or(n, <[f64]>::len)
            ),
        ));
    }
    for i in 0..n {
        for (name, v) in [("x", x[i]), ("y", y[i])] {
            if !v.is_finite() {
                return Err(AeroError::invalid(
                    format!("{PLACE}, {name}[{i}]"),
                    format!("is {v}; data must be finite (drop the point or fill it)"),
                ));
            }
        }
        if let Some(w) = weights {
            if !w[i].is_finite() {
                return Err(AeroError::invalid(
                    format!("{PLACE}, weights[{i}]"),
                    format!("is {}; weights must be finite", w[i]),
                ));
            }
            if w[i] <= 0.0 {
                return Err(AeroError::out_of_range(
                    format!("{PLACE}, weights[{i}]"),
                    format!("is {}; weights must be > 0 (drop the point instead)", w[i]),
                ));
            }
        }
    }
    let wt = |i: usize| weights.map_or(1.0, |w| w[i]);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
    let (mut xs, mut ys, mut ws): (Vec<f64>, Vec<f64>, Vec<f64>) = (vec![], vec![], vec![]);
    let mut k = 0;
    while k < n {
        let xi = x[order[k]];
        let (mut sw, mut swy) = (0.0, 0.0);
        while k < n && x[order[k]] == xi {
            let i = order[k];
            sw += wt(i);
            swy += wt(i) * y[i];
            k += 1;
        }
        xs.push(xi);
        ys.push(swy / sw);
        ws.push(sw);
    }
    Ok((xs, ys, ws))
}

/// The $p = 0$ limit of Eq. 3.13, the weighted least-squares straight line, in
/// closed form with centred sums: the banded system for $p = 0$ has a condition
/// number growing like $n^4$, which costs `csaps` digits on long series.
fn wls_line(x: &[f64], y: &[f64], w: &[f64]) -> SmoothingSpline {
    let sw: f64 = w.iter().sum();
    let xm = x.iter().zip(w).map(|(a, b)| a * b).sum::<f64>() / sw;
    let ym = y.iter().zip(w).map(|(a, b)| a * b).sum::<f64>() / sw;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for ((xi, yi), wi) in x.iter().zip(y).zip(w) {
        sxy += wi * (xi - xm) * (yi - ym);
        sxx += wi * (xi - xm) * (xi - xm);
    }
    let slope = sxy / sxx;
    let coefs = x[..x.len() - 1]
        .iter()
        .map(|xi| [0.0, 0.0, slope, ym + slope * (xi - xm)])
        .collect();
    SmoothingSpline {
        breaks: x.to_vec(),
        coefs,
        p: 0.0,
    }
}

/// Solve $A u = b$ in place for a symmetric positive definite pentadiagonal $A$
/// given by its diagonal `d`, first super-diagonal `e` and second `f`, by a
/// banded $LDL^\top$ factorisation ($O(n)$, no pivoting needed for SPD).
fn solve_pentadiagonal_spd(d: &[f64], e: &[f64], f: &[f64], b: &mut [f64]) -> Result<()> {
    let m = d.len();
    // L has unit diagonal, sub-diagonals l1 (i+1, i) and l2 (i+2, i).
    let mut dd = vec![0.0; m];
    let mut l1 = vec![0.0; m];
    let mut l2 = vec![0.0; m];
    for i in 0..m {
        let mut di = d[i];
        if i >= 1 {
            di -= l1[i - 1] * l1[i - 1] * dd[i - 1];
        }
        if i >= 2 {
            di -= l2[i - 2] * l2[i - 2] * dd[i - 2];
        }
        let scale = d[i].abs();
        if !(di.is_finite() && di > scale * 1e-15) {
            return Err(AeroError::invalid(
                "smoothing spline",
                format!(
                    "the banded system is numerically singular at interior site {} (pivot {di:e}); \
                     the sites are too clustered or the weights too disparate",
                    i + 1
                ),
            ));
        }
        dd[i] = di;
        if i + 1 < m {
            let mut v = e[i];
            if i >= 1 {
                v -= l2[i - 1] * dd[i - 1] * l1[i - 1];
            }
            l1[i] = v / di;
        }
        if i + 2 < m {
            l2[i] = f[i] / di;
        }
    }
    // Forward: L z = b.
    for i in 0..m {
        let mut v = b[i];
        if i >= 1 {
            v -= l1[i - 1] * b[i - 1];
        }
        if i >= 2 {
            v -= l2[i - 2] * b[i - 2];
        }
        b[i] = v;
    }
    // Diagonal, then backward: L^T u = D^-1 z.
    for i in 0..m {
        b[i] /= dd[i];
    }
    for i in (0..m).rev() {
        let mut v = b[i];
        if i + 1 < m {
            v -= l1[i] * b[i + 1];
        }
        if i + 2 < m {
            v -= l2[i] * b[i + 2];
        }
        b[i] = v;
    }
    Ok(())
}

impl SmoothingSpline {
    /// The breaks (the data sites), strictly increasing.
    pub fn breaks(&self) -> &[f64] {
        &self.breaks
    }

    /// Per piece, `[a3, a2, a1, a0]` in powers of $t = x - x_i$, highest first.
    pub fn coefs(&self) -> &[[f64; 4]] {
        &self.coefs
    }

    /// The smoothing parameter $p$ actually used (useful with [`Smoothing::Auto`]).
    pub fn p(&self) -> f64 {
        self.p
    }

    /// Value (`nu = 0`) or derivative of order `nu` at `x` (per unit of $x$;
    /// orders above 3 are 0). Pieces are half-open $[x_i, x_{i+1})$, the last
    /// closed, as scipy `PPoly`. A NaN input gives NaN.
    pub fn eval(&self, x: f64, nu: u32, extrapolation: SplineExtrapolation) -> f64 {
        if x.is_nan() {
            return f64::NAN;
        }
        let first = self.breaks[0];
        let last = self.breaks[self.breaks.len() - 1];
        let x = match extrapolation {
            SplineExtrapolation::Polynomial => x,
            SplineExtrapolation::Hold => {
                if x < first || x > last {
                    if nu > 0 {
                        return 0.0;
                    }
                    x.clamp(first, last)
                } else {
                    x
                }
            }
        };
        let interior = &self.breaks[1..self.breaks.len() - 1];
        let i = interior.partition_point(|&b| b <= x);
        let t = x - self.breaks[i];
        let [a3, a2, a1, a0] = self.coefs[i];
        match nu {
            0 => ((a3 * t + a2) * t + a1) * t + a0,
            1 => (3.0 * a3 * t + 2.0 * a2) * t + a1,
            2 => 6.0 * a3 * t + 2.0 * a2,
            3 => 6.0 * a3,
            _ => 0.0,
        }
    }

    /// [`SmoothingSpline::eval`] at every point of `x`, into `out`.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when `x` and `out` differ in length.
    pub fn eval_many(
        &self,
        x: &[f64],
        nu: u32,
        extrapolation: SplineExtrapolation,
        out: &mut [f64],
    ) -> Result<()> {
        if x.len() != out.len() {
            return Err(AeroError::invalid(
                "spline evaluation",
                format!("{} points but an output of {}", x.len(), out.len()),
            ));
        }
        for (o, &xi) in out.iter_mut().zip(x) {
            *o = self.eval(xi, nu, extrapolation);
        }
        Ok(())
    }

    /// Resample onto a table grid as a 1-D [`Table`] with axis `name` (e.g.
    /// `alpha_deg`), values from [`SmoothingSpline::eval`] with `extrapolation`
    /// beyond the data; the table itself holds its end values beyond the grid
    /// (thesis Section 3.4: tables clipped past stall refer to the end value).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when `grid` is empty, not finite or not
    /// strictly increasing (from [`Axis::new`]).
    pub fn to_table(
        &self,
        name: &str,
        grid: &[f64],
        extrapolation: SplineExtrapolation,
    ) -> Result<Table> {
        let axis = Axis::new(name, grid.to_vec())?;
        let values = grid
            .iter()
            .map(|&g| self.eval(g, 0, extrapolation))
            .collect();
        Table::new(vec![axis], values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand_chacha::ChaCha8Rng;
    use rand_core::{Rng, SeedableRng};

    const P: SplineExtrapolation = SplineExtrapolation::Polynomial;

    fn random_data(seed: u64, n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut u = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let mut x = vec![0.0; n];
        let mut acc = 0.0;
        for xi in x.iter_mut() {
            acc += 0.05 + u();
            *xi = acc;
        }
        let y: Vec<f64> = x.iter().map(|v| v.sin() + 0.3 * (u() - 0.5)).collect();
        let w: Vec<f64> = (0..n).map(|_| 0.2 + 2.0 * u()).collect();
        (x, y, w)
    }

    /// Weighted least-squares line, closed form.
    fn wls_line(x: &[f64], y: &[f64], w: &[f64]) -> (f64, f64) {
        let sw: f64 = w.iter().sum();
        let xm = x.iter().zip(w).map(|(a, b)| a * b).sum::<f64>() / sw;
        let ym = y.iter().zip(w).map(|(a, b)| a * b).sum::<f64>() / sw;
        let sxy: f64 = (0..x.len()).map(|i| w[i] * (x[i] - xm) * (y[i] - ym)).sum();
        let sxx: f64 = (0..x.len()).map(|i| w[i] * (x[i] - xm).powi(2)).sum();
        let b = sxy / sxx;
        (ym - b * xm, b)
    }

    #[test]
    fn p_zero_is_the_weighted_least_squares_line() {
        for seed in 0..6 {
            let n = if seed == 5 { 5000 } else { 12 + seed as usize };
            let (x, y, w) = random_data(seed, n);
            let s = smoothing_spline(&x, &y, Some(&w), Smoothing::Fixed(0.0)).expect("fit");
            let (a, b) = wls_line(&x, &y, &w);
            for &t in &[x[0] - 1.0, x[3], 0.5 * (x[4] + x[5]), x[x.len() - 1] + 2.0] {
                assert!((s.eval(t, 0, P) - (a + b * t)).abs() < 1e-9);
                assert!((s.eval(t, 1, P) - b).abs() < 1e-9);
                assert!(s.eval(t, 2, P).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn spline_is_c2_and_natural() {
        let (x, y, w) = random_data(7, 30);
        let s = smoothing_spline(&x, &y, Some(&w), Smoothing::Fixed(0.4)).expect("fit");
        let c = s.coefs();
        for i in 0..c.len() - 1 {
            let h = x[i + 1] - x[i];
            let [a3, a2, a1, a0] = c[i];
            let next = c[i + 1];
            assert!((((a3 * h + a2) * h + a1) * h + a0 - next[3]).abs() < 1e-10);
            assert!(((3.0 * a3 * h + 2.0 * a2) * h + a1 - next[2]).abs() < 1e-10);
            assert!((6.0 * a3 * h + 2.0 * a2 - 2.0 * next[1]).abs() < 1e-9);
        }
        assert!(s.eval(x[0], 2, P).abs() < 1e-12);
        assert!(s.eval(x[29], 2, P).abs() < 1e-9);
    }

    /// The residuals of the smoothing spline satisfy the optimality condition
    /// p w_j (y_j - f(x_j)) = (1 - p) * jump of f''' at x_j (Reinsch).
    #[test]
    fn residuals_match_third_derivative_jumps() {
        let (x, y, w) = random_data(3, 20);
        let p = 0.4;
        let s = smoothing_spline(&x, &y, Some(&w), Smoothing::Fixed(p)).expect("fit");
        let c = s.coefs();
        for j in 0..x.len() {
            let right = if j < c.len() { 6.0 * c[j][0] } else { 0.0 };
            let left = if j > 0 { 6.0 * c[j - 1][0] } else { 0.0 };
            let lhs = p * w[j] * (y[j] - s.eval(x[j], 0, P));
            let rhs = (1.0 - p) * (right - left);
            assert!((lhs - rhs).abs() < 1e-9, "site {j}: {lhs} vs {rhs}");
        }
    }

    #[test]
    fn auto_and_normalized_p_lie_in_unit_interval() {
        let (x, y, w) = random_data(11, 15);
        let a = smoothing_spline(&x, &y, Some(&w), Smoothing::Auto).expect("fit");
        let b = smoothing_spline(&x, &y, None, Smoothing::Normalized(None)).expect("fit");
        assert!(a.p() > 0.0 && a.p() < 1.0);
        assert!(b.p() > 0.0 && b.p() < 1.0);
    }

    #[test]
    fn two_points_give_the_line() {
        let s =
            smoothing_spline(&[1.0, 3.0], &[2.0, 6.0], None, Smoothing::Fixed(0.3)).expect("fit");
        assert_eq!(s.p(), 1.0);
        assert!((s.eval(0.0, 0, P) - 0.0).abs() < 1e-15);
        assert_eq!(s.eval(0.0, 0, SplineExtrapolation::Hold), 2.0);
    }

    #[test]
    fn hold_extrapolation_holds_and_zeroes_derivatives() {
        let (x, y, _) = random_data(5, 10);
        let s = smoothing_spline(&x, &y, None, Smoothing::Fixed(0.7)).expect("fit");
        let h = SplineExtrapolation::Hold;
        assert_eq!(s.eval(x[0] - 3.0, 0, h), s.eval(x[0], 0, P));
        assert_eq!(s.eval(x[9] + 3.0, 0, h), s.eval(x[9], 0, P));
        assert_eq!(s.eval(x[9] + 3.0, 1, h), 0.0);
        assert!(s.eval(f64::NAN, 0, h).is_nan());
        let t = s
            .to_table("alpha_deg", &[x[0] - 1.0, x[4], x[9] + 1.0], h)
            .expect("table");
        assert_eq!(t.values()[1], s.eval(x[4], 0, P));
    }

    #[test]
    fn errors_name_the_index() {
        let e = smoothing_spline(&[1.0], &[1.0], None, Smoothing::Fixed(0.4)).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::TooLittleData);
        let e =
            smoothing_spline(&[0.0, 1.0, 1.0], &[0.0; 3], None, Smoothing::Fixed(0.4)).unwrap_err();
        assert!(e.to_string().contains("x[2]"), "{e}");
        let e = smoothing_spline(
            &[0.0, 1.0, 2.0],
            &[0.0, f64::NAN, 0.0],
            None,
            Smoothing::Auto,
        )
        .unwrap_err();
        assert!(e.to_string().contains("y[1]"), "{e}");
        let e = smoothing_spline(
            &[0.0, 1.0, 2.0],
            &[0.0; 3],
            Some(&[1.0, 1.0, 0.0]),
            Smoothing::Auto,
        )
        .unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::OutOfRange);
        assert!(e.to_string().contains("weights[2]"), "{e}");
        let e =
            smoothing_spline(&[0.0, 1.0, 2.0], &[0.0; 3], None, Smoothing::Fixed(1.5)).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::OutOfRange);
        let e = smoothing_spline(&[0.0, 1.0], &[0.0; 3], None, Smoothing::Fixed(0.5)).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::InvalidInput);
    }

    #[test]
    fn merge_sites_sorts_and_averages() {
        let (x, y, w) = merge_sites(
            &[2.0, 1.0, 2.0, 0.0],
            &[1.0, 5.0, 4.0, 3.0],
            Some(&[1.0, 1.0, 2.0, 1.0]),
        )
        .expect("merge");
        assert_eq!(x, vec![0.0, 1.0, 2.0]);
        assert_eq!(y, vec![3.0, 5.0, 3.0]);
        assert_eq!(w, vec![1.0, 1.0, 3.0]);
        let e = merge_sites(&[0.0, f64::NAN], &[0.0, 0.0], None).unwrap_err();
        assert!(e.to_string().contains("x[1]"), "{e}");
        let e = merge_sites(&[0.0, 1.0], &[0.0, 0.0], Some(&[1.0, -1.0])).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::OutOfRange);
    }

    proptest! {
        /// p = 1 interpolates the data (natural cubic interpolant).
        #[test]
        fn p_one_interpolates(seed in 0u64..1000, n in 2usize..40) {
            let (x, y, w) = random_data(seed, n);
            let s = smoothing_spline(&x, &y, Some(&w), Smoothing::Fixed(1.0)).expect("fit");
            for j in 0..n {
                prop_assert!((s.eval(x[j], 0, P) - y[j]).abs() < 1e-10);
            }
        }

        /// The smoothing spline never costs more (Eq. 3.13) than the interpolant
        /// or the least-squares line, for any p.
        #[test]
        fn residual_shrinks_as_p_grows(seed in 0u64..1000, n in 3usize..30) {
            let (x, y, w) = random_data(seed, n);
            let rss = |p: f64| {
                let s = smoothing_spline(&x, &y, Some(&w), Smoothing::Fixed(p)).expect("fit");
                (0..n).map(|j| w[j] * (y[j] - s.eval(x[j], 0, P)).powi(2)).sum::<f64>()
            };
            let (r0, r4, r9) = (rss(0.0), rss(0.4), rss(0.9));
            prop_assert!(r4 <= r0 * (1.0 + 1e-9) + 1e-12);
            prop_assert!(r9 <= r4 * (1.0 + 1e-9) + 1e-12);
        }
    }
}
