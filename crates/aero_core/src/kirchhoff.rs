//! The Kirchhoff flow-separation stall model of the longitudinal axis
//! (Fischenberg, "Identification of an unsteady aerodynamic stall model from
//! flight test data", AIAA 95-3438, 1995; Fischenberg & Jategaonkar, RTO-MP-11,
//! 1999; Goman & Khrabrov, J. Aircraft 31(5), 1994, for the first-order
//! separation dynamics).
//!
//! The trailing-edge separation point `x` (1 attached, 0 fully separated) lags
//! its static value through one time constant, and the static value sees the
//! angle of attack delayed by the boundary layer's convective lag:
//!
//! $$ \tau_1 \dot x + x = x_0(\alpha - \tau_2 \dot\alpha), \qquad
//!    x_0(\alpha) = \tfrac12\bigl(1 - \tanh(a_1(\alpha - \alpha^*))\bigr) $$
//!
//! Kirchhoff's flat-plate theory gives the lift of a partly separated plate,
//! and the pitching moment takes a term in the separated fraction (the centre of
//! pressure moving aft as the flow separates, Fischenberg's `C_m` with the
//! `x`-dependent centre of pressure linearised):
//!
//! $$ C_L = C_{L\alpha} (\alpha - \alpha_0) \Bigl(\frac{1 + \sqrt x}{2}\Bigr)^2, \qquad
//!    C_m = C_{m0} + C_{m\alpha}\,\alpha + C_{mx}\,(1 - x) $$
//!
//! These are the *static-curve* parts (the `CL_basic`, `Cm_basic` of a
//! qualified model); control, rate and thrust terms add to them. Units: angles in
//! **radians**, rates in rad/s, time constants in seconds; `a1` in 1/rad.
//!
//! The ODE is stepped exactly for an input that varies linearly between samples
//! (first-order hold): with `r = h/τ₁`, `e = exp(−r)`, `g = 1 − (1 − e)/r`,
//!
//! $$ x_{k+1} = e\,x_k + (1 - e - g)\,u_k + g\,u_{k+1}, \qquad u_k = x_0(\alpha_k - \tau_2\dot\alpha_k) $$
//!
//! a convex combination (`e, g, 1 − e − g ≥ 0`), so `x` stays in `[0, 1]` and a
//! constant input is a fixed point (the static solution of the ODE is `x₀`).
//! [`KirchhoffState`] runs it in a real-time simulator; [`simulate`] runs it over
//! a record (as output-error estimation integrates it from the measured α).

use crate::error::{AeroError, Result};

/// Number of parameters in [`KirchhoffParams::to_array`].
pub const N_PARAMS: usize = 9;

/// Parameter names in [`KirchhoffParams::to_array`] order (units: s, s, rad,
/// 1/rad, 1/rad, rad, -, 1/rad, -).
pub const PARAM_NAMES: [&str; N_PARAMS] = [
    "tau1",
    "tau2",
    "alpha_star",
    "a1",
    "CL_alpha",
    "alpha0",
    "Cm0",
    "Cm_alpha",
    "Cm_x",
];

/// Smallest separation point used where `1/√x` appears (sensitivities).
pub(crate) const X_FLOOR: f64 = 1e-12;

/// The parameters of the Kirchhoff stall model at one flap setting.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KirchhoffParams {
    /// Separation time constant τ₁, s (> 0).
    pub tau1: f64,
    /// Convective lag τ₂, s.
    pub tau2: f64,
    /// Breakpoint α*: x₀(α*) = 1/2, rad.
    pub alpha_star: f64,
    /// Steepness a₁ of the static separation curve, 1/rad (> 0).
    pub a1: f64,
    /// Attached-flow lift-curve slope, 1/rad.
    pub cl_alpha: f64,
    /// Zero-lift angle of attack, rad.
    pub alpha0: f64,
    /// Pitching moment at α = 0 with attached flow.
    pub cm0: f64,
    /// Attached-flow pitch stiffness, 1/rad.
    pub cm_alpha: f64,
    /// Pitching moment of full separation (nose-down break: negative).
    pub cm_x: f64,
}

impl KirchhoffParams {
    /// The parameters in [`PARAM_NAMES`] order.
    pub fn to_array(&self) -> [f64; N_PARAMS] {
        [
            self.tau1,
            self.tau2,
            self.alpha_star,
            self.a1,
            self.cl_alpha,
            self.alpha0,
            self.cm0,
            self.cm_alpha,
            self.cm_x,
        ]
    }

    /// From values in [`PARAM_NAMES`] order.
    pub fn from_array(v: &[f64; N_PARAMS]) -> Self {
        KirchhoffParams {
            tau1: v[0],
            tau2: v[1],
            alpha_star: v[2],
            a1: v[3],
            cl_alpha: v[4],
            alpha0: v[5],
            cm0: v[6],
            cm_alpha: v[7],
            cm_x: v[8],
        }
    }

    /// Refuse values the model cannot run with (non-finite, τ₁ ≤ 0, a₁ ≤ 0, τ₂ < 0).
    ///
    /// # Errors
    /// [`AeroError::OutOfRange`] naming the parameter.
    pub fn check(&self) -> Result<()> {
        check_lags(
            "Kirchhoff",
            &PARAM_NAMES,
            &self.to_array(),
            self.tau1,
            self.tau2,
        )?;
        if self.a1 <= 0.0 {
            return Err(AeroError::out_of_range(
                "Kirchhoff parameter a1",
                format!("is {} /rad; the steepness must be > 0", self.a1),
            ));
        }
        Ok(())
    }

    /// Static separation point x₀(α) (α in rad).
    ///
    /// ```
    /// use aero_core::kirchhoff::KirchhoffParams;
    /// let p = KirchhoffParams { tau1: 0.2, tau2: 0.05, alpha_star: 0.3, a1: 25.0,
    ///     cl_alpha: 5.2, alpha0: -0.05, cm0: 0.05, cm_alpha: -0.75, cm_x: -0.15 };
    /// assert!((p.x0(0.3) - 0.5).abs() < 1e-15);
    /// assert!(p.x0(0.0) > 0.999 && p.x0(0.6) < 0.001);
    /// ```
    #[inline]
    pub fn x0(&self, alpha: f64) -> f64 {
        0.5 * (1.0 - (self.a1 * (alpha - self.alpha_star)).tanh())
    }

    /// The separation point the flow tends to at `alpha`, `alpha_dot` (rad, rad/s): the
    /// input of the ODE, `x₀(α − τ₂ α̇)`.
    #[inline]
    pub fn x0_lagged(&self, alpha: f64, alpha_dot: f64) -> f64 {
        self.x0(alpha - self.tau2 * alpha_dot)
    }

    /// The ODE's right-hand side `ẋ = (x₀(α − τ₂ α̇) − x) / τ₁`, 1/s: what a host
    /// integrating the state itself (a DAVE-ML model's `x_sep_dot`) evaluates.
    #[inline]
    pub fn x_dot(&self, alpha: f64, alpha_dot: f64, x: f64) -> f64 {
        (self.x0_lagged(alpha, alpha_dot) - x) / self.tau1
    }

    /// Static lift coefficient C_L(α) with x = x₀(α) (the lift curve a quasi-steady pull-up follows).
    #[inline]
    pub fn cl_static(&self, alpha: f64) -> f64 {
        self.cl(alpha, self.x0(alpha))
    }

    /// Lift coefficient at α (rad) and separation point `x`.
    #[inline]
    pub fn cl(&self, alpha: f64, x: f64) -> f64 {
        kirchhoff_lift(self.cl_alpha, self.alpha0, alpha, x)
    }

    /// Pitching moment coefficient (static-curve part) at α (rad) and `x`.
    #[inline]
    pub fn cm(&self, alpha: f64, x: f64) -> f64 {
        self.cm0 + self.cm_alpha * alpha + self.cm_x * (1.0 - x)
    }

    /// The maximum of the static lift curve: `(α at C_L,max [rad], C_L,max)`, by
    /// golden-section search on `[α₀ + 0.01, α* + 10/a₁]` after a 0.05 deg scan
    /// (the static curve is unimodal there for `a₁ > 0`).
    pub fn cl_max(&self) -> (f64, f64) {
        let lo = self.alpha0 + 0.01;
        let hi = self.alpha_star + 10.0 / self.a1.max(1e-3);
        if hi <= lo {
            return (lo, self.cl_static(lo));
        }
        let step = 0.05f64.to_radians();
        let n = ((hi - lo) / step).ceil().min(1e6) as usize;
        let mut best = (lo, self.cl_static(lo));
        for k in 1..=n {
            let a = lo + step * k as f64;
            let c = self.cl_static(a);
            if c > best.1 {
                best = (a, c);
            }
        }
        let (mut a, mut b) = (best.0 - step, best.0 + step);
        let gr = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..100 {
            let c = b - gr * (b - a);
            let d = a + gr * (b - a);
            if self.cl_static(c) > self.cl_static(d) {
                b = d;
            } else {
                a = c;
            }
        }
        let am = 0.5 * (a + b);
        (am, self.cl_static(am))
    }
}

/// The checks both separation forms share: every named value finite, `τ₁ > 0`,
/// `τ₂ ≥ 0`; errors name the form (`model`) and the parameter.
pub(crate) fn check_lags(
    model: &str,
    names: &[&str],
    values: &[f64],
    tau1: f64,
    tau2: f64,
) -> Result<()> {
    for (name, v) in names.iter().zip(values) {
        if !v.is_finite() {
            return Err(AeroError::out_of_range(
                format!("{model} parameter {name}"),
                format!("is {v}; give a finite value"),
            ));
        }
    }
    if tau1 <= 0.0 {
        return Err(AeroError::out_of_range(
            format!("{model} parameter tau1"),
            format!("is {tau1} s; the separation time constant must be > 0"),
        ));
    }
    if tau2 < 0.0 {
        return Err(AeroError::out_of_range(
            format!("{model} parameter tau2"),
            format!("is {tau2} s; the convective lag must be >= 0"),
        ));
    }
    Ok(())
}

/// Kirchhoff's lift of a partly separated plate, `C_Lα (α − α₀) ((1 + √x)/2)²`
/// (α, α₀ in rad, C_Lα in 1/rad, `x` the separation point): the lift of both the
/// tanh ([`KirchhoffParams`]) and the tabulated ([`crate::goman_khrabrov`]) forms.
#[inline]
pub fn kirchhoff_lift(cl_alpha: f64, alpha0: f64, alpha: f64, x: f64) -> f64 {
    let f = 0.5 * (1.0 + x.max(0.0).sqrt());
    cl_alpha * (alpha - alpha0) * f * f
}

/// Number of parameters of [`KirchhoffDrag`].
pub const N_DRAG: usize = 3;

/// Drag parameter names in [`KirchhoffDrag::to_array`] order (all dimensionless).
pub const DRAG_NAMES: [&str; N_DRAG] = ["CD0", "CD_k", "CD_x"];

/// The drag of the Kirchhoff stall (its static-curve part, as [`KirchhoffParams::cl`] is
/// lift's): a parabolic polar in the Kirchhoff lift plus the pressure drag of the separated
/// flow,
///
/// $$ C_D = C_{D0} + k\,C_L(\alpha, x)^2 + C_{Dx}\,(1 - x) $$
///
/// with `C_L(α, x)` the Kirchhoff lift at the separation point `x`. In attached flow
/// (`x = 1`) it is the qualified aircraft's polar `C_D0 + k C_L²`; as the flow separates the
/// induced part falls with the lift and the wake's drag grows to `C_Dx` at full separation,
/// with the lag and hysteresis of `x` (a term linear in the separated fraction `1 − x`, as
/// `C_m`'s pitch break; this form is aerodelta's choice, not taken from a paper). Linear in its three
/// parameters once `x` is known, so it is fitted by equation error along the separation state
/// the output-error fit of the lift and pitching moment integrates.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KirchhoffDrag {
    /// Drag at zero lift with attached flow.
    pub cd0: f64,
    /// Induced-drag factor `k` of the polar (`1/(π e A)`).
    pub k: f64,
    /// Drag of the fully separated flow over the polar's (positive: drag rises as the flow
    /// separates).
    pub cd_x: f64,
}

impl KirchhoffDrag {
    /// The parameters in [`DRAG_NAMES`] order.
    pub fn to_array(&self) -> [f64; N_DRAG] {
        [self.cd0, self.k, self.cd_x]
    }

    /// From values in [`DRAG_NAMES`] order.
    pub fn from_array(v: &[f64; N_DRAG]) -> Self {
        KirchhoffDrag {
            cd0: v[0],
            k: v[1],
            cd_x: v[2],
        }
    }

    /// Refuse non-finite values.
    ///
    /// # Errors
    /// [`AeroError::OutOfRange`] naming the parameter.
    pub fn check(&self) -> Result<()> {
        for (name, v) in DRAG_NAMES.iter().zip(self.to_array()) {
            if !v.is_finite() {
                return Err(AeroError::out_of_range(
                    format!("Kirchhoff drag parameter {name}"),
                    format!("is {v}; give a finite value"),
                ));
            }
        }
        Ok(())
    }

    /// Drag coefficient (static-curve part) at the Kirchhoff lift `cl` and separation point
    /// `x`.
    ///
    /// ```
    /// use aero_core::kirchhoff::KirchhoffDrag;
    /// let d = KirchhoffDrag { cd0: 0.03, k: 0.04, cd_x: 0.3 };
    /// assert!((d.cd(1.0, 1.0) - 0.07).abs() < 1e-15);   // attached: the polar
    /// assert!((d.cd(0.5, 0.0) - 0.34).abs() < 1e-15);   // separated: wake drag
    /// ```
    #[inline]
    pub fn cd(&self, cl: f64, x: f64) -> f64 {
        self.cd0 + self.k * cl * cl + self.cd_x * (1.0 - x)
    }

    /// The regressors of [`KirchhoffDrag::cd`], `[1, C_L², 1 − x]`: drag is linear in its
    /// parameters along a known separation state.
    #[inline]
    pub fn regressors(cl: f64, x: f64) -> [f64; N_DRAG] {
        [1.0, cl * cl, 1.0 - x]
    }
}

/// Weights of the exact first-order-hold step over `h` seconds: `(e, c0, g)`
/// with `x₁ = e x₀ + c0 u₀ + g u₁`, and their derivatives in τ₁.
#[inline]
pub(crate) fn foh_weights(h: f64, tau1: f64) -> ([f64; 3], [f64; 3]) {
    let r = h / tau1;
    if r > 700.0 {
        // τ₁ → 0: the state follows its input
        return ([0.0, 0.0, 1.0], [0.0; 3]);
    }
    let e = (-r).exp();
    // 1 − (1 − e)/r, by its series for small r (cancellation)
    let (g, dg_dr) = if r < 1e-4 {
        (r / 2.0 - r * r / 6.0, 0.5 - r / 3.0)
    } else {
        let q = (1.0 - e) / r;
        (1.0 - q, q / r - e / r)
    };
    let c0 = 1.0 - e - g;
    // d/dτ = −(r/τ) d/dr
    let dr_dt = -r / tau1;
    let de = -e * dr_dt;
    let dg = dg_dr * dr_dt;
    ([e, c0, g], [de, -de - dg, dg])
}

/// One step of the separation ODE from `(x, u0)` to the input `u1` over `h` s.
///
/// ```
/// use aero_core::kirchhoff::step;
/// // a constant input is a fixed point; a step input relaxes as 1 − exp(−t/τ₁)
/// assert!((step(0.3, 0.3, 0.3, 0.01, 0.2) - 0.3).abs() < 1e-15);
/// let x = step(1.0, 0.0, 0.0, 0.2, 0.2);
/// assert!((x - (-1.0f64).exp()).abs() < 1e-15);
/// ```
#[inline]
pub fn step(x: f64, u0: f64, u1: f64, h: f64, tau1: f64) -> f64 {
    let ([e, c0, g], _) = foh_weights(h, tau1);
    e * x + c0 * u0 + g * u1
}

/// A static separation curve a running state can be stepped with: the tanh form
/// ([`KirchhoffParams`]) or the tabulated form ([`crate::goman_khrabrov::GkParams`]).
pub trait Separation {
    /// `x₀(α − τ₂ α̇)`, the ODE's input (rad, rad/s).
    fn x0_lagged(&self, alpha: f64, alpha_dot: f64) -> f64;
    /// The separation time constant τ₁, s.
    fn tau1(&self) -> f64;
    /// Refuse values the model cannot run with.
    ///
    /// # Errors
    /// [`AeroError::OutOfRange`] naming the parameter.
    fn check_params(&self) -> Result<()>;
}

impl Separation for KirchhoffParams {
    #[inline]
    fn x0_lagged(&self, alpha: f64, alpha_dot: f64) -> f64 {
        KirchhoffParams::x0_lagged(self, alpha, alpha_dot)
    }
    #[inline]
    fn tau1(&self) -> f64 {
        self.tau1
    }
    fn check_params(&self) -> Result<()> {
        self.check()
    }
}

/// The separation state of a running simulation (one per aircraft), for either
/// form ([`KirchhoffState`], [`crate::goman_khrabrov::GkState`]).
///
/// Call [`SeparationState::update`] once per step with the time and the flow
/// angles; before the first call the state is the static solution
/// x₀(α − τ₂α̇) of the input it is asked about ([`SeparationState::x_at`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SeparationState<P> {
    /// The model parameters.
    pub params: P,
    /// `(t, x, u)` at the last update.
    last: Option<(f64, f64, f64)>,
}

/// The tanh form's running state.
pub type KirchhoffState = SeparationState<KirchhoffParams>;

impl<P: Separation> SeparationState<P> {
    /// A state that has not been stepped yet.
    ///
    /// # Errors
    /// If the parameters fail their check ([`KirchhoffParams::check`],
    /// [`crate::goman_khrabrov::GkParams::check`]).
    pub fn new(params: P) -> Result<Self> {
        params.check_params()?;
        Ok(SeparationState { params, last: None })
    }

    /// The separation point to use at `alpha`, `alpha_dot` (rad, rad/s): the
    /// integrated state after the first update, the static solution before.
    #[inline]
    pub fn x_at(&self, alpha: f64, alpha_dot: f64) -> f64 {
        match self.last {
            Some((_, x, _)) => x,
            None => self.params.x0_lagged(alpha, alpha_dot),
        }
    }

    /// Advance to time `t` (s) where the flow angles are `alpha`, `alpha_dot`
    /// (the input held linear since the last update: the exact step of [`step`]).
    /// The first call sets the static solution; a call at the time of the last one
    /// changes nothing; a call at an earlier time restarts at the static solution
    /// there.
    pub fn update(&mut self, t: f64, alpha: f64, alpha_dot: f64) {
        let u = self.params.x0_lagged(alpha, alpha_dot);
        let x = match self.last {
            Some((t0, _, _)) if t == t0 => return,
            Some((t0, x, u0)) if t > t0 => step(x, u0, u, t - t0, self.params.tau1()),
            _ => u,
        };
        self.last = Some((t, x, u));
    }

    /// Forget the history (the next update starts at the static solution).
    pub fn reset(&mut self) {
        self.last = None;
    }
}

/// One record's inputs: time (s, strictly increasing), α (rad), α̇ (rad/s).
#[derive(Debug, Clone, Copy)]
pub struct Inputs<'a> {
    /// Time, s.
    pub t: &'a [f64],
    /// Angle of attack, rad.
    pub alpha: &'a [f64],
    /// Its rate, rad/s.
    pub alpha_dot: &'a [f64],
}

impl Inputs<'_> {
    /// Equal lengths, finite values, strictly increasing time.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming `place`, the channel and the first bad row.
    pub fn check(&self, place: &str) -> Result<()> {
        let n = self.t.len();
        for (name, v) in [("alpha", self.alpha), ("alpha_dot", self.alpha_dot)] {
            if v.len() != n {
                return Err(AeroError::invalid(
                    format!("{place}: {name}"),
                    format!("has {} rows, t has {n}", v.len()),
                ));
            }
        }
        for (name, v) in [
            ("t", self.t),
            ("alpha", self.alpha),
            ("alpha_dot", self.alpha_dot),
        ] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(AeroError::invalid(
                    format!("{place}: {name} row {i}"),
                    "is not finite; drop or fill the row before fitting",
                ));
            }
        }
        if let Some(i) = self.t.windows(2).position(|w| w[1] <= w[0]) {
            return Err(AeroError::invalid(
                format!("{place}: t row {}", i + 1),
                "is not after the previous sample; time must increase strictly",
            ));
        }
        Ok(())
    }
}

/// The separation point along a record, started at the static solution.
///
/// # Errors
/// For invalid parameters or inputs.
pub fn simulate(p: &KirchhoffParams, inp: &Inputs<'_>) -> Result<Vec<f64>> {
    p.check()?;
    inp.check("Kirchhoff simulation")?;
    let n = inp.t.len();
    let mut x = Vec::with_capacity(n);
    if n == 0 {
        return Ok(x);
    }
    let u = |k: usize| p.x0_lagged(inp.alpha[k], inp.alpha_dot[k]);
    let mut uk = u(0);
    let mut xk = uk;
    x.push(xk);
    for k in 0..n - 1 {
        let u1 = u(k + 1);
        xk = step(xk, uk, u1, inp.t[k + 1] - inp.t[k], p.tau1);
        x.push(xk);
        uk = u1;
    }
    Ok(x)
}

/// The model outputs along a record and their sensitivities.
#[derive(Debug, Clone)]
pub struct Outputs {
    /// Separation point.
    pub x: Vec<f64>,
    /// C_L (static-curve part).
    pub cl: Vec<f64>,
    /// C_m (static-curve part).
    pub cm: Vec<f64>,
    /// ∂C_L/∂θ, row-major `N × 9` ([`PARAM_NAMES`] order); empty unless asked.
    pub dcl: Vec<f64>,
    /// ∂C_m/∂θ, row-major `N × 9`; empty unless asked.
    pub dcm: Vec<f64>,
}

/// Outputs along a record with, if `sensitivities`, their exact derivatives in
/// the parameters: the forward sensitivity recursion of the discrete step
/// (the derivative of the discretised model, not of the continuous one, so it
/// matches finite differences of [`simulate`] to rounding).
///
/// # Errors
/// For invalid parameters or inputs.
pub fn outputs(p: &KirchhoffParams, inp: &Inputs<'_>, sensitivities: bool) -> Result<Outputs> {
    p.check()?;
    inp.check("Kirchhoff outputs")?;
    let n = inp.t.len();
    let mut o = Outputs {
        x: Vec::with_capacity(n),
        cl: Vec::with_capacity(n),
        cm: Vec::with_capacity(n),
        dcl: Vec::with_capacity(if sensitivities { n * N_PARAMS } else { 0 }),
        dcm: Vec::with_capacity(if sensitivities { n * N_PARAMS } else { 0 }),
    };
    if n == 0 {
        return Ok(o);
    }
    // input u and its derivatives in (τ₂, α*, a₁): indices 1, 2, 3
    let u_of = |k: usize| -> (f64, [f64; 3]) {
        let z = inp.alpha[k] - p.tau2 * inp.alpha_dot[k];
        let th = (p.a1 * (z - p.alpha_star)).tanh();
        let u = 0.5 * (1.0 - th);
        let s2 = 1.0 - th * th;
        let du_dz = -0.5 * p.a1 * s2;
        (
            u,
            [
                -du_dz * inp.alpha_dot[k],
                0.5 * p.a1 * s2,
                -0.5 * (z - p.alpha_star) * s2,
            ],
        )
    };
    let (mut u0, mut du0) = u_of(0);
    let mut x = u0;
    // state sensitivities in τ₁, τ₂, α*, a₁ (the other parameters do not enter x)
    let mut sx = [0.0, du0[0], du0[1], du0[2]];
    let emit = |k: usize, x: f64, sx: &[f64; 4], o: &mut Outputs| {
        let a = inp.alpha[k];
        o.x.push(x);
        o.cl.push(p.cl(a, x));
        o.cm.push(p.cm(a, x));
        if sensitivities {
            let sq = x.max(0.0).sqrt();
            let f = 0.5 * (1.0 + sq);
            let da = a - p.alpha0;
            let dcl_dx = p.cl_alpha * da * f / (2.0 * sq.max(X_FLOOR.sqrt()));
            for s in sx {
                o.dcl.push(dcl_dx * s);
            }
            o.dcl
                .extend_from_slice(&[f * f * da, -p.cl_alpha * f * f, 0.0, 0.0, 0.0]);
            for s in sx {
                o.dcm.push(-p.cm_x * s);
            }
            o.dcm.extend_from_slice(&[0.0, 0.0, 1.0, a, 1.0 - x]);
        }
    };
    emit(0, x, &sx, &mut o);
    for k in 0..n - 1 {
        let (u1, du1) = u_of(k + 1);
        let h = inp.t[k + 1] - inp.t[k];
        let ([e, c0, g], [de, dc0, dg]) = foh_weights(h, p.tau1);
        let xn = e * x + c0 * u0 + g * u1;
        if sensitivities {
            let s_tau1 = e * sx[0] + de * x + dc0 * u0 + dg * u1;
            let mut s = [s_tau1, 0.0, 0.0, 0.0];
            for j in 0..3 {
                s[j + 1] = e * sx[j + 1] + c0 * du0[j] + g * du1[j];
            }
            sx = s;
        }
        x = xn;
        u0 = u1;
        du0 = du1;
        emit(k + 1, x, &sx, &mut o);
    }
    Ok(o)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The parameters both this module's and `output_error`'s tests fly.
    pub(crate) fn truth() -> KirchhoffParams {
        KirchhoffParams {
            tau1: 0.25,
            tau2: 0.08,
            alpha_star: 18.0f64.to_radians(),
            a1: 25.0,
            cl_alpha: 5.2,
            alpha0: -3.0f64.to_radians(),
            cm0: 0.05,
            cm_alpha: -0.75,
            cm_x: -0.15,
        }
    }

    fn sweep(n: usize, hz: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        sweep_about(12.0, n, hz)
    }

    /// `(t, alpha, alpha_dot)` of a two-tone sweep about `mean_deg` (9 and 1.5 deg
    /// at 0.4 and 2.3 rad/s), `n` samples at `hz`; rad and rad/s.
    pub(crate) fn sweep_about(mean_deg: f64, n: usize, hz: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..n).map(|k| k as f64 / hz).collect();
        let a: Vec<f64> = t
            .iter()
            .map(|&t| (mean_deg + 9.0 * (0.4 * t).sin() + 1.5 * (2.3 * t).sin()).to_radians())
            .collect();
        let ad: Vec<f64> = t
            .iter()
            .map(|&t| (9.0 * 0.4 * (0.4 * t).cos() + 1.5 * 2.3 * (2.3 * t).cos()).to_radians())
            .collect();
        (t, a, ad)
    }

    #[test]
    fn static_solution_of_the_ode_is_x0() {
        let p = truth();
        // held alpha: the state stays at x0 exactly; from another start it converges to x0
        for a_deg in [5.0, 16.0, 18.0, 19.5, 25.0] {
            let a = f64::to_radians(a_deg);
            let n = 400;
            let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.02).collect();
            let al = vec![a; n];
            let ad = vec![0.0; n];
            let x = simulate(
                &p,
                &Inputs {
                    t: &t,
                    alpha: &al,
                    alpha_dot: &ad,
                },
            )
            .unwrap();
            for v in &x {
                assert!((v - p.x0(a)).abs() < 1e-14, "{a_deg}: {v} vs {}", p.x0(a));
            }
            let mut s = KirchhoffState::new(p).unwrap();
            s.update(0.0, 0.0, 0.0); // attached
            for k in 1..n {
                s.update(k as f64 * 0.02, a, 0.0);
            }
            // 8 s = 32 τ₁ later the transient has decayed
            assert!((s.x_at(a, 0.0) - p.x0(a)).abs() < 1e-12);
        }
    }

    #[test]
    fn step_matches_the_continuous_solution_for_a_ramp() {
        // u(t) = u0 + b t: x(t) = u(t) − b τ + (x0 − u0 + b τ) e^{−t/τ}
        let (tau, x0, u0, b, h) = (0.3, 0.9, 0.6, -0.4, 0.05);
        let x = step(x0, u0, u0 + b * h, h, tau);
        let exact = u0 + b * h - b * tau + (x0 - u0 + b * tau) * (-h / tau).exp();
        assert!((x - exact).abs() < 1e-15);
        // tiny and huge h/τ use the series and the limit
        assert!((step(0.5, 0.2, 0.2, 1e-9, 1.0) - 0.5).abs() < 1e-9);
        assert!((step(0.5, 0.2, 0.7, 10.0, 1e-3) - 0.7).abs() < 1e-15);
    }

    #[test]
    fn state_update_equals_the_batch_simulation() {
        let p = truth();
        let (t, a, ad) = sweep(500, 50.0);
        let x = simulate(
            &p,
            &Inputs {
                t: &t,
                alpha: &a,
                alpha_dot: &ad,
            },
        )
        .unwrap();
        let mut s = KirchhoffState::new(p).unwrap();
        assert!((s.x_at(a[0], ad[0]) - x[0]).abs() < 1e-15);
        for k in 0..t.len() {
            s.update(t[k], a[k], ad[k]);
            assert_eq!(s.x_at(0.0, 0.0), x[k]);
            s.update(t[k], a[k] + 0.1, 0.0); // again at the same time: no change
            assert_eq!(s.x_at(0.0, 0.0), x[k]);
        }
    }

    #[test]
    fn hysteresis_lift_lower_on_the_way_down() {
        let p = truth();
        let (t, a, ad) = sweep(1500, 50.0);
        let o = outputs(
            &p,
            &Inputs {
                t: &t,
                alpha: &a,
                alpha_dot: &ad,
            },
            false,
        )
        .unwrap();
        // at the same alpha above the break, lift is higher while alpha rises
        let target = 19.0f64.to_radians();
        let (mut up, mut down) = (Vec::new(), Vec::new());
        for k in 1..t.len() {
            if (a[k - 1] - target) * (a[k] - target) <= 0.0 {
                if ad[k] > 0.0 {
                    up.push(o.cl[k])
                } else {
                    down.push(o.cl[k])
                }
            }
        }
        assert!(!up.is_empty() && !down.is_empty());
        assert!(
            up.iter().cloned().fold(f64::INFINITY, f64::min)
                > down.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        );
    }

    #[test]
    fn sensitivities_equal_finite_differences() {
        let p = truth();
        let (t, a, ad) = sweep(800, 50.0);
        let inp = Inputs {
            t: &t,
            alpha: &a,
            alpha_dot: &ad,
        };
        let o = outputs(&p, &inp, true).unwrap();
        let th = p.to_array();
        for j in 0..N_PARAMS {
            let d = 1e-6 * th[j].abs().max(1e-3);
            let (mut hi, mut lo) = (th, th);
            hi[j] += d;
            lo[j] -= d;
            let oh = outputs(&KirchhoffParams::from_array(&hi), &inp, false).unwrap();
            let ol = outputs(&KirchhoffParams::from_array(&lo), &inp, false).unwrap();
            let (mut scale_l, mut scale_m) = (1e-12f64, 1e-12f64);
            for k in 0..t.len() {
                scale_l = scale_l.max(o.dcl[k * N_PARAMS + j].abs());
                scale_m = scale_m.max(o.dcm[k * N_PARAMS + j].abs());
            }
            for k in 0..t.len() {
                let fd_l = (oh.cl[k] - ol.cl[k]) / (2.0 * d);
                let fd_m = (oh.cm[k] - ol.cm[k]) / (2.0 * d);
                assert!(
                    (fd_l - o.dcl[k * N_PARAMS + j]).abs() <= 1e-6 * scale_l,
                    "dCL/d{} row {k}: fd {fd_l} analytic {}",
                    PARAM_NAMES[j],
                    o.dcl[k * N_PARAMS + j]
                );
                assert!(
                    (fd_m - o.dcm[k * N_PARAMS + j]).abs() <= 1e-6 * scale_m,
                    "dCm/d{} row {k}",
                    PARAM_NAMES[j]
                );
            }
        }
    }

    #[test]
    fn cl_max_is_the_maximum_of_the_static_curve() {
        let p = truth();
        let (am, cm) = p.cl_max();
        for k in 0..4000 {
            let a = (-2.0 + 0.01 * k as f64).to_radians();
            assert!(p.cl_static(a) <= cm + 1e-12);
        }
        assert!(am < p.alpha_star);
    }

    #[test]
    fn bad_parameters_and_inputs_are_refused() {
        let mut p = truth();
        p.tau1 = 0.0;
        assert!(p.check().unwrap_err().to_string().contains("tau1"));
        let t = [0.0, 0.1, 0.1];
        let a = [0.1; 3];
        let e = simulate(
            &truth(),
            &Inputs {
                t: &t,
                alpha: &a,
                alpha_dot: &a,
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("t row 2"), "{e}");
        let e = simulate(
            &truth(),
            &Inputs {
                t: &t[..2],
                alpha: &a,
                alpha_dot: &a[..2],
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("alpha"), "{e}");
    }
}
