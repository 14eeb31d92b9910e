//! The Goman-Khrabrov form of the separation model: the first-order separation
//! dynamics of [`crate::kirchhoff`] with the static separation curve `x₀(α)` a
//! **table** instead of Fischenberg's tanh (Goman & Khrabrov, "State-space
//! representation of aerodynamic characteristics of an aircraft at high angles
//! of attack", J. Aircraft 31(5), 1994, pp. 1109-1115: `x₀(α)` is whatever the
//! static lift curve says, found by inverting Kirchhoff's lift).
//!
//! $$ \tau_1 \dot x + x = x_0(\alpha - \tau_2 \dot\alpha), \qquad
//!    C_L = C_{L\alpha} (\alpha - \alpha_0) \Bigl(\frac{1 + \sqrt x}{2}\Bigr)^2, \qquad
//!    C_m = C_{m0} + C_{m\alpha}\,\alpha + C_{mx}\,(1 - x) $$
//!
//! `x₀` is a uniform cubic B-spline on equally spaced knots `α_0 < … < α_{K−1}`
//! (rad, spacing `h`) with coefficients `v_k ∈ [0, 1]`:
//! `x₀(z) = Σ_k v_k B((z − α_k)/h)`, `B` the cardinal cubic B-spline, a missing
//! neighbour beyond an end knot taking that end's coefficient, and `z` clamped
//! to `[α_0, α_{K−1}]` (constant beyond the ends). The weights are a partition
//! of unity, so `x₀` is a convex combination of the coefficients: it stays in
//! `[0, 1]` and is 1 where they are. It is twice continuously differentiable
//! inside the table (τ₂'s sensitivity, `−α̇ x₀'`, has no jumps; a piecewise
//! linear table, tried first, put τ₁ and τ₂ up to 25 % off on the virtual
//! aircraft's smooth truth at 1 deg spacing). A static lift curve that the tanh
//! cannot follow (a plateau, a second rise: a JSBSim lift table) is followed
//! coefficient by coefficient, and the state keeps its lag and hysteresis.
//!
//! Identified by output error ([`crate::output_error::fit_tabulated`]) on the
//! parameter vector `[τ₁, τ₂, C_Lα, α₀, C_m0, C_mα, C_mx, v_0, …, v_{K−1}]`
//! ([`GkParams::to_vec`]). The coefficients enter `x` linearly through the
//! cubic B-spline weights, so their output sensitivities are a forward recursion
//! of the same discrete step as `τ₂`'s.
//!
//! The lift line and the coefficients trade off (a steeper line with lower
//! coefficients gives the same static lift), so a fit holds one of them: the
//! Python front end holds the line (`C_Lα`, `α₀`) through
//! [`crate::output_error::fit_tabulated`]'s `fixed`.

use crate::error::{AeroError, Result};
use crate::kirchhoff::{
    check_lags, foh_weights, kirchhoff_lift, Inputs, Outputs, Separation, SeparationState, X_FLOOR,
};

/// Number of the scalar parameters ahead of the node values in [`GkParams::to_vec`].
pub const N_CORE: usize = 7;

/// Names of the scalar parameters in [`GkParams::to_vec`] order (units: s, s,
/// 1/rad, rad, -, 1/rad, -); the node values follow as `x0[k]`.
pub const CORE_NAMES: [&str; N_CORE] = [
    "tau1", "tau2", "CL_alpha", "alpha0", "Cm0", "Cm_alpha", "Cm_x",
];

/// The static separation curve `x₀(α)`: a uniform cubic B-spline on equally
/// spaced knots (rad) with coefficients in `[0, 1]`, constant beyond the end
/// knots (module docs).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct X0Table {
    knots: Vec<f64>,
    values: Vec<f64>,
}

impl X0Table {
    /// A table of `knots` (rad, strictly increasing and equally spaced to 1e-9 of
    /// the spacing, at least two) and coefficients `values` (in `[0, 1]`).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the first bad knot or value.
    pub fn new(knots: Vec<f64>, values: Vec<f64>) -> Result<Self> {
        let place = "separation table x0(alpha)";
        if knots.len() < 2 || values.len() != knots.len() {
            return Err(AeroError::invalid(
                place,
                format!(
                    "has {} knots and {} values; give at least two knots and one value per knot",
                    knots.len(),
                    values.len()
                ),
            ));
        }
        if let Some(k) = knots.iter().position(|v| !v.is_finite()) {
            return Err(AeroError::invalid(
                format!("{place}: knot {k}"),
                "is not finite",
            ));
        }
        if let Some(k) = knots.windows(2).position(|w| w[1] <= w[0]) {
            return Err(AeroError::invalid(
                format!("{place}: knot {}", k + 1),
                format!(
                    "({:.4} deg) is not above the one before; knots must increase strictly",
                    knots[k + 1].to_degrees()
                ),
            ));
        }
        let h = knots[1] - knots[0];
        if let Some(k) =
            (2..knots.len()).find(|&k| ((knots[k] - knots[0]) - h * k as f64).abs() > 1e-9 * h)
        {
            return Err(AeroError::invalid(
                format!("{place}: knot {k}"),
                format!(
                    "({:.4} deg) is off the uniform spacing of {:.4} deg; the spline's knots \
                     must be equally spaced",
                    knots[k].to_degrees(),
                    h.to_degrees()
                ),
            ));
        }
        let t = X0Table { knots, values };
        t.check_values()?;
        Ok(t)
    }

    fn check_values(&self) -> Result<()> {
        if let Some(k) = self
            .values
            .iter()
            .position(|v| !(v.is_finite() && (0.0..=1.0).contains(v)))
        {
            return Err(AeroError::out_of_range(
                format!(
                    "separation table x0(alpha): value at knot {k} ({:.2} deg)",
                    self.knots[k].to_degrees()
                ),
                format!("is {}; a separation point lies in [0, 1]", self.values[k]),
            ));
        }
        Ok(())
    }

    /// Knots, rad.
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// Node values.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The spline's weights at `z` (rad): the four coefficients' indices, their
    /// weights, and the weights' derivatives in `z` (1/rad; zero beyond the ends,
    /// where `z` is clamped). Indices beyond an end are that end's.
    #[inline]
    fn basis(&self, z: f64) -> ([usize; 4], [f64; 4], [f64; 4]) {
        let n = self.knots.len();
        let h = (self.knots[n - 1] - self.knots[0]) / (n - 1) as f64;
        let s = (z - self.knots[0]) / h;
        let inside = s > 0.0 && s < (n - 1) as f64;
        let sc = s.clamp(0.0, (n - 1) as f64);
        let i = (sc.floor() as usize).min(n - 2);
        let u = sc - i as f64;
        let (u2, u3) = (u * u, u * u * u);
        let v = 1.0 - u;
        let w = [
            v * v * v / 6.0,
            (3.0 * u3 - 6.0 * u2 + 4.0) / 6.0,
            (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) / 6.0,
            u3 / 6.0,
        ];
        let dw = if inside {
            [
                -0.5 * v * v / h,
                (1.5 * u2 - 2.0 * u) / h,
                (-1.5 * u2 + u + 0.5) / h,
                0.5 * u2 / h,
            ]
        } else {
            [0.0; 4]
        };
        let idx = [i.saturating_sub(1), i, i + 1, (i + 2).min(n - 1)];
        (idx, w, dw)
    }

    /// The weight of each coefficient in `x₀(z)` (length K; four at most are
    /// non-zero): `∂x₀(z)/∂v_k`.
    pub fn weights(&self, z: f64) -> Vec<f64> {
        let (idx, w, _) = self.basis(z);
        let mut out = vec![0.0; self.knots.len()];
        for j in 0..4 {
            out[idx[j]] += w[j];
        }
        out
    }

    /// `x₀(z)`, z in rad.
    ///
    /// ```
    /// use aero_core::goman_khrabrov::X0Table;
    /// // all coefficients 1: attached everywhere (the weights sum to 1)
    /// let t = X0Table::new(vec![0.1, 0.2, 0.3], vec![1.0; 3]).unwrap();
    /// assert!((t.eval(0.17) - 1.0).abs() < 1e-15);
    /// // a convex combination of the coefficients, constant beyond the ends
    /// let t = X0Table::new(vec![0.1, 0.2, 0.3, 0.4], vec![1.0, 0.8, 0.3, 0.1]).unwrap();
    /// assert!((0.1..=1.0).contains(&t.eval(0.25)));
    /// assert_eq!(t.eval(0.5), t.eval(0.4));
    /// ```
    #[inline]
    pub fn eval(&self, z: f64) -> f64 {
        let (idx, w, _) = self.basis(z);
        (0..4).map(|j| w[j] * self.values[idx[j]]).sum()
    }
}

/// The parameters of the tabulated (Goman-Khrabrov) form at one flap setting.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GkParams {
    /// Separation time constant, s.
    pub tau1: f64,
    /// Convective lag of the static input, s.
    pub tau2: f64,
    /// Attached-flow lift slope, 1/rad.
    pub cl_alpha: f64,
    /// Zero-lift alpha, rad.
    pub alpha0: f64,
    /// Pitching moment at α = 0, attached.
    pub cm0: f64,
    /// Pitching-moment slope, 1/rad.
    pub cm_alpha: f64,
    /// Pitching moment of full separation.
    pub cm_x: f64,
    /// The static separation curve.
    pub x0: X0Table,
}

impl GkParams {
    /// The tanh form's lags, lift line and pitching-moment terms over the separation
    /// table `x0` (a tanh fit's scalars, its curve replaced by a table).
    pub fn with_table(p: &crate::kirchhoff::KirchhoffParams, x0: X0Table) -> GkParams {
        GkParams {
            tau1: p.tau1,
            tau2: p.tau2,
            cl_alpha: p.cl_alpha,
            alpha0: p.alpha0,
            cm0: p.cm0,
            cm_alpha: p.cm_alpha,
            cm_x: p.cm_x,
            x0,
        }
    }

    /// The parameters from the scalars `c` in [`CORE_NAMES`] order and the table of `knots`
    /// (rad) and `values`, checked ([`X0Table::new`], [`GkParams::check`]): what a model
    /// file, the bindings and a replay build a stored table from.
    ///
    /// # Errors
    /// As [`X0Table::new`] and [`GkParams::check`].
    pub fn from_core(c: &[f64; N_CORE], knots: Vec<f64>, values: Vec<f64>) -> Result<GkParams> {
        let p = GkParams {
            tau1: c[0],
            tau2: c[1],
            cl_alpha: c[2],
            alpha0: c[3],
            cm0: c[4],
            cm_alpha: c[5],
            cm_x: c[6],
            x0: X0Table::new(knots, values)?,
        };
        p.check()?;
        Ok(p)
    }

    /// `[τ₁, τ₂, C_Lα, α₀, C_m0, C_mα, C_mx, v_0, …]`.
    pub fn to_vec(&self) -> Vec<f64> {
        let mut v = vec![
            self.tau1,
            self.tau2,
            self.cl_alpha,
            self.alpha0,
            self.cm0,
            self.cm_alpha,
            self.cm_x,
        ];
        v.extend_from_slice(&self.x0.values);
        v
    }

    /// From a [`GkParams::to_vec`] vector over the table's knots (unchecked).
    pub fn with_vec(&self, v: &[f64]) -> GkParams {
        GkParams {
            tau1: v[0],
            tau2: v[1],
            cl_alpha: v[2],
            alpha0: v[3],
            cm0: v[4],
            cm_alpha: v[5],
            cm_x: v[6],
            x0: X0Table {
                knots: self.x0.knots.clone(),
                values: v[N_CORE..].to_vec(),
            },
        }
    }

    /// Parameter names in [`GkParams::to_vec`] order.
    pub fn names(&self) -> Vec<String> {
        CORE_NAMES
            .iter()
            .map(|s| (*s).to_string())
            .chain((0..self.x0.knots.len()).map(|k| format!("x0[{k}]")))
            .collect()
    }

    /// Finite values, `τ₁ > 0`, `τ₂ ≥ 0`, nodes in `[0, 1]`.
    ///
    /// # Errors
    /// [`AeroError::OutOfRange`] naming the parameter.
    pub fn check(&self) -> Result<()> {
        check_lags(
            "Goman-Khrabrov",
            &CORE_NAMES,
            &self.to_vec(),
            self.tau1,
            self.tau2,
        )?;
        self.x0.check_values()
    }

    /// `x₀(α − τ₂ α̇)`, the ODE's input.
    #[inline]
    pub fn x0_lagged(&self, alpha: f64, alpha_dot: f64) -> f64 {
        self.x0.eval(alpha - self.tau2 * alpha_dot)
    }

    /// Lift coefficient (static-curve part) at α (rad) and `x`.
    #[inline]
    pub fn cl(&self, alpha: f64, x: f64) -> f64 {
        kirchhoff_lift(self.cl_alpha, self.alpha0, alpha, x)
    }

    /// Pitching moment coefficient (static-curve part) at α (rad) and `x`.
    #[inline]
    pub fn cm(&self, alpha: f64, x: f64) -> f64 {
        self.cm0 + self.cm_alpha * alpha + self.cm_x * (1.0 - x)
    }

    /// Static lift coefficient, `x = x₀(α)`.
    #[inline]
    pub fn cl_static(&self, alpha: f64) -> f64 {
        self.cl(alpha, self.x0.eval(alpha))
    }

    /// The maximum of the static lift curve over `[α₀ + 0.01, last knot]`:
    /// `(α at C_L,max [rad], C_L,max)`: scanned at 0.01 deg and refined by golden
    /// section around the best point. With a maximum at the last knot the curve rises past the table
    /// (the lift line with the last node): the maximum is not in the data.
    pub fn cl_max(&self) -> (f64, f64) {
        // from just past the zero-lift alpha, or half a radian under the table when that
        // is higher (below the table the lift is the line times a constant: no maximum)
        let lo = (self.alpha0 + 0.01).max(self.x0.knots[0] - 0.5);
        let hi = *self.x0.knots.last().unwrap_or(&lo);
        if hi <= lo {
            return (lo, self.cl_static(lo));
        }
        let step = 0.01f64.to_radians();
        let n = ((hi - lo) / step).ceil().min(1e6) as usize;
        let mut best = (lo, self.cl_static(lo));
        for k in 1..=n {
            let a = (lo + step * k as f64).min(hi);
            let c = self.cl_static(a);
            if c > best.1 {
                best = (a, c);
            }
        }
        let (mut a, mut b) = ((best.0 - step).max(lo), (best.0 + step).min(hi));
        let gr = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..60 {
            let c = b - gr * (b - a);
            let d = a + gr * (b - a);
            if self.cl_static(c) > self.cl_static(d) {
                b = d;
            } else {
                a = c;
            }
        }
        let am = 0.5 * (a + b);
        let cm = self.cl_static(am);
        if cm >= best.1 {
            (am, cm)
        } else {
            best
        }
    }
}

/// The outputs of the tabulated form along a record with, if `sensitivities`,
/// their exact derivatives in [`GkParams::to_vec`]'s parameters (rows of
/// `N_CORE + K`): the forward sensitivity recursion of the discrete step, as
/// [`crate::kirchhoff::outputs`] for the tanh form.
///
/// # Errors
/// For invalid parameters or inputs.
pub fn outputs(p: &GkParams, inp: &Inputs<'_>, sensitivities: bool) -> Result<Outputs> {
    p.check()?;
    inp.check("Goman-Khrabrov outputs")?;
    let n = inp.t.len();
    let nk = p.x0.knots.len();
    let np = N_CORE + nk;
    let mut o = Outputs {
        x: Vec::with_capacity(n),
        cl: Vec::with_capacity(n),
        cm: Vec::with_capacity(n),
        dcl: Vec::with_capacity(if sensitivities { n * np } else { 0 }),
        dcm: Vec::with_capacity(if sensitivities { n * np } else { 0 }),
    };
    if n == 0 {
        return Ok(o);
    }
    // the input u, its derivative in τ₂, and its spline weights
    type Basis = ([usize; 4], [f64; 4]);
    let u_of = |k: usize| -> (f64, f64, Basis) {
        let z = inp.alpha[k] - p.tau2 * inp.alpha_dot[k];
        let (idx, w, dw) = p.x0.basis(z);
        let (mut u, mut du) = (0.0, 0.0);
        for j in 0..4 {
            u += w[j] * p.x0.values[idx[j]];
            du += dw[j] * p.x0.values[idx[j]];
        }
        (u, -du * inp.alpha_dot[k], (idx, w))
    };
    // state sensitivities: [τ₁, τ₂, v_0..v_{K-1}]
    let ns = 2 + nk;
    let mut sx = vec![0.0; ns];
    let mut sn = vec![0.0; ns];
    let (mut u0, mut du0_t2, mut b0) = u_of(0);
    let mut x = u0;
    if sensitivities {
        sx[1] = du0_t2;
        for j in 0..4 {
            sx[2 + b0.0[j]] += b0.1[j];
        }
    }
    let emit = |k: usize, x: f64, sx: &[f64], o: &mut Outputs| {
        let a = inp.alpha[k];
        o.x.push(x);
        o.cl.push(p.cl(a, x));
        o.cm.push(p.cm(a, x));
        if sensitivities {
            let sq = x.max(0.0).sqrt();
            let f = 0.5 * (1.0 + sq);
            let da = a - p.alpha0;
            let dcl_dx = p.cl_alpha * da * f / (2.0 * sq.max(X_FLOOR.sqrt()));
            o.dcl.extend_from_slice(&[
                dcl_dx * sx[0],
                dcl_dx * sx[1],
                f * f * da,
                -p.cl_alpha * f * f,
                0.0,
                0.0,
                0.0,
            ]);
            o.dcl.extend(sx[2..].iter().map(|s| dcl_dx * s));
            o.dcm
                .extend_from_slice(&[-p.cm_x * sx[0], -p.cm_x * sx[1], 0.0, 0.0, 1.0, a, 1.0 - x]);
            o.dcm.extend(sx[2..].iter().map(|s| -p.cm_x * s));
        }
    };
    emit(0, x, &sx, &mut o);
    for k in 0..n - 1 {
        let (u1, du1_t2, b1) = u_of(k + 1);
        let h = inp.t[k + 1] - inp.t[k];
        let ([e, c0, g], [de, dc0, dg]) = foh_weights(h, p.tau1);
        let xn = e * x + c0 * u0 + g * u1;
        if sensitivities {
            sn[0] = e * sx[0] + de * x + dc0 * u0 + dg * u1;
            sn[1] = e * sx[1] + c0 * du0_t2 + g * du1_t2;
            for (s, &v) in sn[2..].iter_mut().zip(&sx[2..]) {
                *s = e * v;
            }
            for j in 0..4 {
                sn[2 + b0.0[j]] += c0 * b0.1[j];
                sn[2 + b1.0[j]] += g * b1.1[j];
            }
            std::mem::swap(&mut sx, &mut sn);
        }
        x = xn;
        (u0, du0_t2, b0) = (u1, du1_t2, b1);
        emit(k + 1, x, &sx, &mut o);
    }
    Ok(o)
}

/// The separation point along a record, started at the static solution.
///
/// # Errors
/// For invalid parameters or inputs.
pub fn simulate(p: &GkParams, inp: &Inputs<'_>) -> Result<Vec<f64>> {
    Ok(outputs(p, inp, false)?.x)
}

impl Separation for GkParams {
    #[inline]
    fn x0_lagged(&self, alpha: f64, alpha_dot: f64) -> f64 {
        GkParams::x0_lagged(self, alpha, alpha_dot)
    }
    #[inline]
    fn tau1(&self) -> f64 {
        self.tau1
    }
    fn check_params(&self) -> Result<()> {
        self.check()
    }
}

/// The tabulated form's running state (one per aircraft), as
/// [`crate::kirchhoff::KirchhoffState`] is the tanh form's: the same
/// [`SeparationState`], stepped exactly as [`outputs`] steps a record.
pub type GkState = SeparationState<GkParams>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kirchhoff::tests::{sweep_about, truth};
    use crate::kirchhoff::KirchhoffParams;

    /// The tanh curve of `p` tabulated every `step_deg` over `[lo, hi]` deg.
    pub(crate) fn tabulated(p: &KirchhoffParams, lo: f64, hi: f64, step_deg: f64) -> GkParams {
        let n = ((hi - lo) / step_deg).round() as usize + 1;
        let knots: Vec<f64> = (0..n)
            .map(|k| (lo + step_deg * k as f64).to_radians())
            .collect();
        let values = knots.iter().map(|&a| p.x0(a)).collect();
        GkParams::with_table(p, X0Table::new(knots, values).unwrap())
    }

    fn sweep(n: usize, hz: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        sweep_about(14.0, n, hz)
    }

    #[test]
    fn a_fine_table_of_the_tanh_flies_as_the_tanh() {
        let p = truth();
        let g = tabulated(&p, 5.0, 30.0, 0.05);
        let (t, a, ad) = sweep(1500, 50.0);
        let inp = Inputs {
            t: &t,
            alpha: &a,
            alpha_dot: &ad,
        };
        let ok = crate::kirchhoff::outputs(&p, &inp, false).unwrap();
        let og = outputs(&g, &inp, false).unwrap();
        let worst = ok
            .cl
            .iter()
            .zip(&og.cl)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // the spline with the curve's values as coefficients: error ~ h^2/6 max|x0''| ~ 1e-5
        assert!(worst < 1e-4, "{worst}");
        // a held alpha is a fixed point: the static solution is x0
        let al = vec![0.33; 50];
        let z = vec![0.0; 50];
        let tt: Vec<f64> = (0..50).map(|k| k as f64 * 0.02).collect();
        let x = simulate(
            &g,
            &Inputs {
                t: &tt,
                alpha: &al,
                alpha_dot: &z,
            },
        )
        .unwrap();
        assert!(x.iter().all(|&v| (v - g.x0.eval(0.33)).abs() < 1e-15));
    }

    #[test]
    fn the_runtime_state_is_the_batch_simulation() {
        let g = tabulated(&truth(), 10.0, 26.0, 1.0);
        let (t, a, ad) = sweep(900, 50.0);
        let batch = simulate(
            &g,
            &Inputs {
                t: &t,
                alpha: &a,
                alpha_dot: &ad,
            },
        )
        .unwrap();
        let mut st = GkState::new(g.clone()).unwrap();
        assert_eq!(st.x_at(a[0], ad[0]), g.x0_lagged(a[0], ad[0]));
        for k in 0..t.len() {
            st.update(t[k], a[k], ad[k]);
            assert!((st.x_at(a[k], ad[k]) - batch[k]).abs() < 1e-15, "row {k}");
            st.update(t[k], a[k] + 0.1, ad[k]); // the same time again: no change
            assert!((st.x_at(a[k], ad[k]) - batch[k]).abs() < 1e-15);
        }
        st.reset();
        assert_eq!(st.x_at(0.3, 0.0), g.x0.eval(0.3));
        let mut bad = g;
        bad.tau2 = -1.0;
        assert!(GkState::new(bad).is_err());
    }

    #[test]
    fn sensitivities_equal_central_differences() {
        let p = truth();
        let mut g = tabulated(&p, 10.0, 26.0, 2.0);
        // nodes away from 0 and 1 so a difference step stays inside [0, 1]
        for v in g.x0.values.iter_mut() {
            *v = v.clamp(0.05, 0.95);
        }
        let (t, a, ad) = sweep(800, 50.0);
        let inp = Inputs {
            t: &t,
            alpha: &a,
            alpha_dot: &ad,
        };
        let o = outputs(&g, &inp, true).unwrap();
        let th = g.to_vec();
        let np = th.len();
        for j in 0..np {
            let h = 1e-6 * th[j].abs().max(1e-3);
            let mut up = th.clone();
            let mut dn = th.clone();
            up[j] += h;
            dn[j] -= h;
            let ou = outputs(&g.with_vec(&up), &inp, false).unwrap();
            let od = outputs(&g.with_vec(&dn), &inp, false).unwrap();
            let mut worst = 0.0f64;
            let mut scale = 0.0f64;
            for k in 0..t.len() {
                for (num, an) in [
                    ((ou.cl[k] - od.cl[k]) / (2.0 * h), o.dcl[k * np + j]),
                    ((ou.cm[k] - od.cm[k]) / (2.0 * h), o.dcm[k * np + j]),
                ] {
                    worst = worst.max((num - an).abs());
                    scale = scale.max(an.abs());
                }
            }
            // a kink of the table crossed inside the difference step is the only
            // difference from the analytic derivative
            assert!(
                worst <= 1e-5 * scale.max(1e-3),
                "{}: {worst} of {scale}",
                g.names()[j]
            );
        }
    }

    #[test]
    fn bad_tables_are_refused_by_knot() {
        let e = X0Table::new(vec![0.1, 0.1], vec![1.0, 0.5]).unwrap_err();
        assert!(e.to_string().contains("knot 1"), "{e}");
        let e = X0Table::new(vec![0.1, 0.2], vec![1.0, 1.5]).unwrap_err();
        assert!(e.to_string().contains("knot 1"), "{e}");
        assert!(X0Table::new(vec![0.1], vec![1.0]).is_err());
        let e = X0Table::new(vec![0.1, 0.2, 0.35], vec![1.0; 3]).unwrap_err();
        assert!(e.to_string().contains("uniform spacing"), "{e}");
        let mut g = tabulated(&truth(), 10.0, 20.0, 5.0);
        g.tau1 = 0.0;
        assert!(g.check().unwrap_err().to_string().contains("tau1"));
    }

    #[test]
    fn cl_max_of_the_table_is_that_of_the_tanh() {
        let p = truth();
        let g = tabulated(&p, 5.0, 30.0, 0.05);
        let (ak, ck) = p.cl_max();
        let (ag, cg) = g.cl_max();
        assert!((ck - cg).abs() < 2e-4, "{ck} {cg}");
        assert!((ak - ag).abs() < 0.1f64.to_radians(), "{ak} {ag}");
    }
}
