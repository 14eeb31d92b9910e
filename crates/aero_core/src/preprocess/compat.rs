//! Data compatibility check / flight path reconstruction (thesis Section 2.4, Eq. 2.23-2.26).
//!
//! The specific forces and rates at the CG are inputs; the kinematic equations (thesis Eq.
//! 3.1a-c, 3.1g-i with the aerodynamic and thrust forces replaced by the measured specific
//! force; body axes x fwd, y right, z down; $g$ = 9.80665 m/s²)
//! $$\dot u = rv - qw + a_x - g\sin\theta,\quad \dot v = pw - ru + a_y + g\cos\theta\sin\phi,
//! \quad \dot w = qu - pv + a_z + g\cos\theta\cos\phi$$
//! $$\dot\phi = p + \tan\theta(q\sin\phi + r\cos\phi),\quad \dot\theta = q\cos\phi - r\sin\phi,
//! \quad \dot\psi = (q\sin\phi + r\cos\phi)/\cos\theta$$
//! are integrated (RK4, inputs linear between samples) and compared with the measured outputs
//! $V = |(u,v,w)|$, $\alpha = \operatorname{atan2}(w,u)$, $\beta = \arcsin(v/V)$ (Eq. 2.23),
//! $\phi$, $\theta$, $\psi$. The velocities are air-relative; a constant wind does not change
//! their derivatives, so steady wind is allowed, gusts are not modelled.
//!
//! Error model (all biases are *measured minus true*, so corrected = measured - bias):
//! $a_{x,E} = a_x + b_{a_x}$ (Eq. 2.25), likewise $a_y, a_z, p, q, r$;
//! $\alpha_E = (1+k_\alpha)\alpha + b_\alpha$, $\beta_E = (1+k_\beta)\beta + b_\beta$ (the
//! vanes' scale factors: upwash and sidewash at the vane, Eq. 2.24's form for the angles),
//! $V_E = (1+\lambda_V)V$ (Eq. 2.24 with $b_V = 0$: a speed bias and a scale factor are
//! not separable over a stall's speed range). Unknowns: these 11 plus the 6 initial states.
//! A scale factor and its bias separate only where the angle varies (a stall's alpha sweep;
//! sideslip maneuvers for beta); the Cramér-Rao bounds say how well.
//!
//! **Gusts** (`gusts = true`). Output error assumes the air moves steadily: a gust moves the
//! vanes and the airspeed but not the accelerometers, and since the aircraft answers a slow
//! gust (a side gust weathercocks it) the reconstructed angle carries part of the gust with
//! the opposite sign, an error in the regressor that biases the scale factors toward zero
//! (on 0.5 m/s Dryden turbulence $k_\beta$ came out 1.2 % low). With gusts the reconstruction
//! is the one-step predictor of the innovations form (Maine & Iliff 1985, NASA RP-1138,
//! Section 5.3: the steady-state filter gain estimated directly with the parameters; Ljung
//! 1999, Chapter 7, prediction-error method): after each sample the air-relative velocity is
//! corrected toward the airspeed and vane readings, $\delta(V,\alpha,\beta) =
//! (K_V\nu_V/(1+\lambda_V), K_\alpha\nu_\alpha/(1+k_\alpha), K_\beta\nu_\beta/(1+k_\beta))$
//! mapped to $(u, v, w)$ through $\partial(u,v,w)/\partial(V,\alpha,\beta)$, where $\nu$ is the
//! output's innovation (measured minus predicted) and the gains $K \in (0, 1)$ are three more
//! unknowns (estimated as logits). The innovations, not the open-loop outputs, enter the
//! cost: a slow gust is followed by the predictor and leaves the scale factors to the parts
//! of the angles' motion it cannot follow. In calm air the gains go to zero and the estimate
//! is the output-error one. Every sensitivity is then a finite difference (the feedback makes
//! the output parameters act on the states).
//!
//! They are estimated by output error (thesis Section 2.3.2): Gauss-Newton (modified
//! Newton-Raphson, Eq. 2.21) with finite-difference output sensitivities, the output noise
//! covariance re-estimated each iteration from the residuals, Levenberg damping when a step
//! does not lower the cost; converged when the relative cost change falls under 1e-7 or every
//! step is under [`STEP_TOL`] of its standard error. Standard errors are the Cramér-Rao bounds
//! $\sqrt{\operatorname{diag}(\mathbf M^{-1})}$.

use nalgebra::{DMatrix, DVector};

use crate::error::{AeroError, Result};

/// Standard gravity, m/s².
pub const G0: f64 = 9.80665;

/// Names of the estimated parameters, in order.
pub const PARAM_NAMES: [&str; 20] = [
    "b_ax_mps2",
    "b_ay_mps2",
    "b_az_mps2",
    "b_p_rps",
    "b_q_rps",
    "b_r_rps",
    "b_alpha_rad",
    "b_beta_rad",
    "lambda_v",
    "k_alpha",
    "k_beta",
    "u0_mps",
    "v0_mps",
    "w0_mps",
    "phi0_rad",
    "theta0_rad",
    "psi0_rad",
    "gain_v",
    "gain_alpha",
    "gain_beta",
];

/// Indices of the innovation gains $K_V, K_\alpha, K_\beta$ in [`PARAM_NAMES`] (estimated
/// with `gusts` only; held as logits while estimating, reported as gains in (0, 1)).
pub const GAINS: [usize; 3] = [17, 18, 19];

/// Starting gain of the gust predictor (a small correction per sample).
const GAIN_START: f64 = 0.02;

fn sigmoid(g: f64) -> f64 {
    1.0 / (1.0 + (-g).exp())
}

/// Convergence: every parameter step below this fraction of its Cramér-Rao standard error
/// (or a relative cost change under 1e-7).
pub const STEP_TOL: f64 = 0.1;

/// Names of the compared outputs, in order.
pub const OUTPUT_NAMES: [&str; 6] = ["tas", "alpha", "beta", "phi", "theta", "psi"];

/// Where the air-data vanes sit and what the sideslip vane reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vanes {
    /// Alpha vane position from the CG, body axes, m.
    pub r_alpha: [f64; 3],
    /// Beta vane position from the CG, body axes, m.
    pub r_beta: [f64; 3],
    /// The beta vane reads the flank angle $\operatorname{atan2}(v, u)$ (a boom-mounted yaw
    /// vane) instead of the sideslip $\arcsin(v/V)$.
    pub flank: bool,
}

impl Vanes {
    /// Angles already at the CG (sideslip): the output equations of Eq. 2.23 as they stand.
    pub const AT_CG: Vanes = Vanes {
        r_alpha: [0.0; 3],
        r_beta: [0.0; 3],
        flank: false,
    };
}

/// Measured channels of one maneuver (SI, radians, at the CG).
#[derive(Debug, Clone, Copy)]
pub struct CompatInput<'a> {
    /// Time, s, strictly increasing.
    pub t: &'a [f64],
    /// Specific forces at the CG, m/s².
    pub accel: [&'a [f64]; 3],
    /// Body rates, rad/s.
    pub rates: [&'a [f64]; 3],
    /// True airspeed, m/s.
    pub tas: &'a [f64],
    /// Angle of attack as the vane reads it (at the CG for [`Vanes::AT_CG`]), rad.
    pub alpha: &'a [f64],
    /// Sideslip (or flank angle) as the vane reads it, rad.
    pub beta: &'a [f64],
    /// The vanes: the outputs are the angles they read, $\mathbf V + \boldsymbol\omega\times
    /// \mathbf r$ at each vane (SIDPAC `compat`'s vane position terms), so a scale factor or
    /// bias applies to the reading itself.
    pub vanes: Vanes,
    /// Euler angles phi, theta, psi, rad.
    pub euler: [&'a [f64]; 3],
}

/// Result of the compatibility check.
#[derive(Debug, Clone)]
pub struct CompatResult {
    /// Estimates in the order of [`PARAM_NAMES`] (a parameter not estimated holds 0; the
    /// gains [`GAINS`] are gains in (0, 1)).
    pub params: Vec<f64>,
    /// Cramér-Rao standard errors, same order (NaN for a parameter not estimated).
    pub std_err: Vec<f64>,
    /// Whether each parameter was estimated (the scale factors only on request).
    pub estimated: Vec<bool>,
    /// RMS of each output residual before estimation (all parameters zero, initial states
    /// from the first measured samples), order of [`OUTPUT_NAMES`] (m/s, rad).
    pub rms_before: Vec<f64>,
    /// RMS of each output residual at the estimate.
    pub rms_after: Vec<f64>,
    /// Gauss-Newton iterations used.
    pub iterations: usize,
    /// Whether the relative cost change fell below the tolerance.
    pub converged: bool,
}

type State = [f64; 6];

fn rhs(x: &State, a: [f64; 3], w: [f64; 3]) -> State {
    let [u, v, ww, phi, th, _] = *x;
    let [p, q, r] = w;
    let (sf, cf) = phi.sin_cos();
    let (st, ct) = th.sin_cos();
    [
        r * v - q * ww + a[0] - G0 * st,
        p * ww - r * u + a[1] + G0 * ct * sf,
        q * u - p * v + a[2] + G0 * ct * cf,
        p + st / ct * (q * sf + r * cf),
        q * cf - r * sf,
        (q * sf + r * cf) / ct,
    ]
}

/// Simulate the outputs for parameters `th`; returns 6 output vectors. With `gusts`, the
/// one-step predictions of the innovations form: after each sample the air-relative velocity
/// is corrected toward the measured airspeed and vane angles with the gains `th[GAINS]`
/// (logits; see the module notes).
fn simulate(inp: &CompatInput<'_>, th: &[f64], gusts: bool) -> [Vec<f64>; 6] {
    let n = inp.t.len();
    let inputs = |i: usize| -> ([f64; 3], [f64; 3]) {
        (
            [
                inp.accel[0][i] - th[0],
                inp.accel[1][i] - th[1],
                inp.accel[2][i] - th[2],
            ],
            [
                inp.rates[0][i] - th[3],
                inp.rates[1][i] - th[4],
                inp.rates[2][i] - th[5],
            ],
        )
    };
    let mut out: [Vec<f64>; 6] = Default::default();
    for o in out.iter_mut() {
        o.reserve_exact(n);
    }
    let mut x: State = [th[11], th[12], th[13], th[14], th[15], th[16]];
    let vn = inp.vanes;
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    for i in 0..n {
        let [u, v, w, phi, theta, psi] = x;
        let vt = (u * u + v * v + w * w).sqrt();
        let (_, om) = inputs(i);
        let ca = cross(om, vn.r_alpha);
        let cb = cross(om, vn.r_beta);
        let (ub, vb, wb) = (u + cb[0], v + cb[1], w + cb[2]);
        let beta_vane = if vn.flank {
            vb.atan2(ub)
        } else {
            (vb / (ub * ub + vb * vb + wb * wb).sqrt())
                .clamp(-1.0, 1.0)
                .asin()
        };
        let y = [
            (1.0 + th[8]) * vt,
            (1.0 + th[9]) * (w + ca[2]).atan2(u + ca[0]) + th[6],
            (1.0 + th[10]) * beta_vane + th[7],
        ];
        out[0].push(y[0]);
        out[1].push(y[1]);
        out[2].push(y[2]);
        out[3].push(phi);
        out[4].push(theta);
        out[5].push(psi);
        if i + 1 == n {
            break;
        }
        if gusts && vt > 0.0 {
            // innovations of airspeed and vane angles, as increments of V, alpha, beta
            let d = [
                sigmoid(th[17]) * (inp.tas[i] - y[0]) / (1.0 + th[8]),
                sigmoid(th[18]) * (inp.alpha[i] - y[1]) / (1.0 + th[9]),
                sigmoid(th[19]) * (inp.beta[i] - y[2]) / (1.0 + th[10]),
            ];
            let a = w.atan2(u);
            let b = (v / vt).clamp(-1.0, 1.0).asin();
            let ((sa, ca_), (sb, cb_)) = (a.sin_cos(), b.sin_cos());
            x[0] += ca_ * cb_ * d[0] - vt * sa * cb_ * d[1] - vt * ca_ * sb * d[2];
            x[1] += sb * d[0] + vt * cb_ * d[2];
            x[2] += sa * cb_ * d[0] + vt * ca_ * cb_ * d[1] - vt * sa * sb * d[2];
        }
        let h = inp.t[i + 1] - inp.t[i];
        let (a0, w0) = inputs(i);
        let (a1, w1) = inputs(i + 1);
        let am = [
            0.5 * (a0[0] + a1[0]),
            0.5 * (a0[1] + a1[1]),
            0.5 * (a0[2] + a1[2]),
        ];
        let wm = [
            0.5 * (w0[0] + w1[0]),
            0.5 * (w0[1] + w1[1]),
            0.5 * (w0[2] + w1[2]),
        ];
        let k1 = rhs(&x, a0, w0);
        let x2: State = std::array::from_fn(|k| x[k] + 0.5 * h * k1[k]);
        let k2 = rhs(&x2, am, wm);
        let x3: State = std::array::from_fn(|k| x[k] + 0.5 * h * k2[k]);
        let k3 = rhs(&x3, am, wm);
        let x4: State = std::array::from_fn(|k| x[k] + h * k3[k]);
        let k4 = rhs(&x4, a1, w1);
        x = std::array::from_fn(|k| x[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]));
    }
    out
}

fn wrap_pi(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    a - tau * ((a + std::f64::consts::PI) / tau).floor()
}

fn residuals(meas: &[&[f64]; 6], sim: &[Vec<f64>; 6]) -> [Vec<f64>; 6] {
    std::array::from_fn(|k| {
        meas[k]
            .iter()
            .zip(&sim[k])
            .map(|(m, s)| if k == 5 { wrap_pi(m - s) } else { m - s })
            .collect()
    })
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Output sensitivities dy/dθ: forward differences through the simulation for the input
/// biases and initial states; exact for the output-only parameters, which enter linearly
/// ($\alpha_E = (1+k_\alpha)\alpha + b_\alpha$, $\beta_E = (1+k_\beta)\beta + b_\beta$,
/// $V_E = (1+\lambda_V)V$, thesis Eq. 2.24), saving five of the seventeen simulations.
fn sensitivities(
    inp: &CompatInput<'_>,
    th: &[f64],
    sim: &[Vec<f64>; 6],
    steps: &[f64; 20],
    free: &[usize],
    gusts: bool,
) -> Vec<[Vec<f64>; 6]> {
    let n = inp.t.len();
    free.iter()
        .map(|&j| {
            if !gusts && (6..=10).contains(&j) {
                let mut d: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; n]);
                // the simulated angle before its error: (y - b) / (1 + k)
                let angle = |k: usize, b: f64, s: f64| -> Vec<f64> {
                    sim[k].iter().map(|y| (y - b) / (1.0 + s)).collect()
                };
                match j {
                    6 => d[1].fill(1.0),
                    7 => d[2].fill(1.0),
                    8 => {
                        let s = 1.0 / (1.0 + th[8]);
                        for (o, v) in d[0].iter_mut().zip(&sim[0]) {
                            *o = v * s;
                        }
                    }
                    9 => d[1] = angle(1, th[6], th[9]),
                    _ => d[2] = angle(2, th[7], th[10]),
                }
                return d;
            }
            let mut tp = th.to_vec();
            tp[j] += steps[j];
            let sp = simulate(inp, &tp, gusts);
            std::array::from_fn(|k| {
                sp[k]
                    .iter()
                    .zip(&sim[k])
                    .map(|(a, b)| if k == 5 { wrap_pi(a - b) } else { a - b } / steps[j])
                    .collect()
            })
        })
        .collect()
}

/// Indices of the vane scale factors in [`PARAM_NAMES`].
pub const SCALE_FACTORS: [usize; 2] = [9, 10];

/// Run the compatibility check on one maneuver; the vane scale factors $k_\alpha$, $k_\beta$
/// are estimated only with `scale_factors` (they need the angle to vary within the maneuver,
/// and otherwise stay 0); with `gusts` the innovations form with its three gains (module
/// notes) replaces output error.
///
/// # Errors
/// `TooLittleData` for fewer than 20 samples; `InvalidInput` for unequal lengths, a
/// non-positive first airspeed or non-finite samples; `NoConvergence` is never returned (the
/// result says whether it converged).
pub fn check(
    inp: &CompatInput<'_>,
    max_iter: usize,
    scale_factors: bool,
    gusts: bool,
) -> Result<CompatResult> {
    let n = inp.t.len();
    let place = "data compatibility check";
    if n < 20 {
        return Err(AeroError::too_little(
            place,
            format!("{n} samples; need at least 20"),
        ));
    }
    let all: [&[f64]; 12] = [
        inp.accel[0],
        inp.accel[1],
        inp.accel[2],
        inp.rates[0],
        inp.rates[1],
        inp.rates[2],
        inp.tas,
        inp.alpha,
        inp.beta,
        inp.euler[0],
        inp.euler[1],
        inp.euler[2],
    ];
    if all.iter().any(|c| c.len() != n) {
        return Err(AeroError::invalid(place, "channels of unequal length"));
    }
    if all.iter().any(|c| c.iter().any(|v| !v.is_finite())) || inp.t.iter().any(|v| !v.is_finite())
    {
        return Err(AeroError::invalid(
            place,
            "non-finite samples; validate the record first",
        ));
    }
    if inp.tas[0] <= 0.0 {
        return Err(AeroError::invalid(
            place,
            "first airspeed sample is not positive",
        ));
    }
    let meas: [&[f64]; 6] = [
        inp.tas,
        inp.alpha,
        inp.beta,
        inp.euler[0],
        inp.euler[1],
        inp.euler[2],
    ];
    let (v0, a0, b0) = (inp.tas[0], inp.alpha[0], inp.beta[0]);
    let mut th = vec![0.0; PARAM_NAMES.len()];
    th[11] = v0 * a0.cos() * b0.cos();
    th[12] = v0 * b0.sin();
    th[13] = v0 * a0.sin() * b0.cos();
    th[14] = inp.euler[0][0];
    th[15] = inp.euler[1][0];
    th[16] = inp.euler[2][0];
    if gusts {
        let g0 = (GAIN_START / (1.0 - GAIN_START)).ln();
        for j in GAINS {
            th[j] = g0;
        }
    }
    let free: Vec<usize> = (0..th.len())
        .filter(|j| scale_factors || !SCALE_FACTORS.contains(j))
        .filter(|j| gusts || !GAINS.contains(j))
        .collect();
    let np = free.len();
    let no = 6;
    // initial output noise scales: 0.5 m/s, 0.2 deg
    let mut sig = [0.5, 3.5e-3, 3.5e-3, 3.5e-3, 3.5e-3, 3.5e-3];
    let mut sim = simulate(inp, &th, gusts);
    let mut res = residuals(&meas, &sim);
    let rms_before: Vec<f64> = res.iter().map(|r| rms(r)).collect();
    let cost = |res: &[Vec<f64>; 6], sig: &[f64; 6]| -> f64 {
        (0..no)
            .map(|k| res[k].iter().map(|e| e * e).sum::<f64>() / (sig[k] * sig[k]))
            .sum::<f64>()
    };
    let steps = [
        1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-3, 1e-3, 1e-3, 1e-6,
        1e-6, 1e-6, 1e-3, 1e-3, 1e-3,
    ];
    let mut info = DMatrix::<f64>::zeros(np, np);
    let mut converged = false;
    let mut iterations = 0;
    let mut lm = 0.0_f64;
    for it in 0..max_iter {
        iterations = it + 1;
        // sensitivities dy/dth by forward differences
        let sens = sensitivities(inp, &th, &sim, &steps, &free, gusts);
        info.fill(0.0);
        let mut grad = DVector::<f64>::zeros(np);
        for k in 0..no {
            let wk = 1.0 / (sig[k] * sig[k]);
            for a in 0..np {
                let sa = &sens[a][k];
                grad[a] += wk * sa.iter().zip(&res[k]).map(|(x, e)| x * e).sum::<f64>();
                for b in a..np {
                    let v = wk * sa.iter().zip(&sens[b][k]).map(|(x, y)| x * y).sum::<f64>();
                    info[(a, b)] += v;
                    if a != b {
                        info[(b, a)] += v;
                    }
                }
            }
        }
        let j0 = cost(&res, &sig);
        let mut accepted = false;
        for _ in 0..8 {
            let mut m = info.clone();
            for d in 0..np {
                m[(d, d)] += lm * info[(d, d)].max(1e-12) + 1e-12 * info[(d, d)].abs().max(1.0);
            }
            let Some(step) = m.cholesky().map(|c| c.solve(&grad)) else {
                lm = (lm * 10.0).max(1e-6);
                continue;
            };
            let mut cand = th.clone();
            for (d, &j) in free.iter().enumerate() {
                cand[j] += step[d];
            }
            let sim_c = simulate(inp, &cand, gusts);
            let res_c = residuals(&meas, &sim_c);
            let jc = cost(&res_c, &sig);
            if jc.is_finite() && jc <= j0 {
                // a step far inside every parameter's Cramér-Rao bound changes nothing that
                // the data can resolve: converged (saves the slow tail that the noise
                // re-weighting causes)
                let resolved = info.clone().cholesky().is_some_and(|c| {
                    let inv = c.inverse();
                    (0..np).all(|d| step[d].abs() < STEP_TOL * inv[(d, d)].abs().sqrt())
                });
                th = cand;
                sim = sim_c;
                res = res_c;
                lm *= 0.1;
                if lm < 1e-9 {
                    lm = 0.0;
                }
                accepted = true;
                let rel = (j0 - jc) / j0.max(1e-300);
                if rel < 1e-7 || resolved {
                    converged = true;
                }
                break;
            }
            lm = (lm * 10.0).max(1e-4);
        }
        // re-estimate the output noise from the residuals (floor keeps weights finite)
        for k in 0..no {
            let floor = if k == 0 { 1e-4 } else { 1e-7 };
            sig[k] = rms(&res[k]).max(floor);
        }
        if !accepted || converged {
            converged = true;
            break;
        }
    }
    // Cramér-Rao bounds at the final weights
    let mut m = DMatrix::<f64>::zeros(np, np);
    {
        let sens = sensitivities(inp, &th, &sim, &steps, &free, gusts);
        for k in 0..no {
            let wk = 1.0 / (sig[k] * sig[k]);
            for a in 0..np {
                for b in a..np {
                    let v = wk
                        * sens[a][k]
                            .iter()
                            .zip(&sens[b][k])
                            .map(|(x, y)| x * y)
                            .sum::<f64>();
                    m[(a, b)] += v;
                    m[(b, a)] = m[(a, b)];
                }
            }
        }
    }
    let mut std_err = vec![f64::NAN; th.len()];
    // A gain the data leave without information (saturated at 0 or 1: its logit far out) is
    // held at its value for the bounds of the others; its own bound is infinite.
    let keep: Vec<usize> = (0..np)
        .filter(|&d| !(GAINS.contains(&free[d]) && (th[free[d]].abs() > 12.0 || m[(d, d)] <= 0.0)))
        .collect();
    let sub = DMatrix::from_fn(keep.len(), keep.len(), |a, b| m[(keep[a], keep[b])]);
    for &j in &free {
        std_err[j] = f64::INFINITY;
    }
    if let Some(inv) = sub.try_inverse() {
        for (a, &d) in keep.iter().enumerate() {
            std_err[free[d]] = inv[(a, a)].abs().sqrt();
        }
    }
    let estimated = (0..th.len()).map(|j| free.contains(&j)).collect();
    let rms_after = res.iter().map(|r| rms(r)).collect();
    if gusts {
        // logits to gains, their errors by the delta method
        for j in GAINS {
            let k = sigmoid(th[j]);
            th[j] = k;
            std_err[j] *= k * (1.0 - k);
        }
    }
    Ok(CompatResult {
        params: th,
        std_err,
        estimated,
        rms_before,
        rms_after,
        iterations,
        converged,
    })
}

/// Simulated outputs (V m/s, alpha, beta, phi, theta, psi rad) for given parameters, e.g. to
/// plot the reconstruction against the measurements; with positive gains
/// (`params[GAINS]`, as [`check`] reports them) the one-step predictions of the innovations
/// form.
pub fn reconstruct(inp: &CompatInput<'_>, params: &[f64]) -> Result<[Vec<f64>; 6]> {
    if params.len() != PARAM_NAMES.len() {
        return Err(AeroError::invalid(
            "compatibility reconstruction",
            format!(
                "{} parameters given, {} expected",
                params.len(),
                PARAM_NAMES.len()
            ),
        ));
    }
    // the gains as check() reports them: the innovations form when any is positive
    let gusts = GAINS.iter().any(|&j| params[j] > 0.0);
    let mut th = params.to_vec();
    if gusts {
        for j in GAINS {
            let k = th[j].clamp(1e-300, 1.0 - 1e-16);
            th[j] = (k / (1.0 - k)).ln();
        }
    }
    Ok(simulate(inp, &th, gusts))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smooth rates (rad/s) and specific forces (m/s²) over 60 s at 50 Hz, the side force's
    /// amplitude `ay_amp`: inputs whose consistent outputs `simulate()` itself gives.
    fn motion(ay_amp: f64) -> [Vec<f64>; 7] {
        let t: Vec<f64> = (0..3001).map(|i| i as f64 * 0.02).collect();
        let f = |g: &dyn Fn(f64) -> f64| -> Vec<f64> { t.iter().map(|&s| g(s)).collect() };
        [
            f(&|s| s),
            f(&|s| 0.1 * (0.5 * s).sin()),
            f(&|s| 0.05 * (0.7 * s).sin()),
            f(&|s| 0.04 * (0.3 * s).cos()),
            f(&|s| 1.0 + 0.5 * (0.2 * s).sin()),
            f(&|s| ay_amp * (0.4 * s).sin()),
            f(&|s| -9.8 - 2.0 * (0.25 * s).sin()),
        ]
    }

    /// The truth the tests invert: `motion(ay_amp)` flown from u = 70, w = 4 m/s, theta 0.05,
    /// psi 1 rad; its inputs and the outputs the vanes `vanes` read (no sensor error).
    fn truth(ay_amp: f64, vanes: Vanes) -> ([Vec<f64>; 7], [Vec<f64>; 6]) {
        let m = motion(ay_amp);
        let [t, p, q, r, ax, ay, az] = &m;
        let inp = CompatInput {
            t,
            accel: [ax, ay, az],
            rates: [p, q, r],
            tas: t,
            alpha: t,
            beta: t,
            euler: [t, t, t],
            vanes,
        };
        let mut th = vec![0.0; PARAM_NAMES.len()];
        th[11] = 70.0;
        th[13] = 4.0;
        th[15] = 0.05;
        th[16] = 1.0;
        let y = simulate(&inp, &th, false);
        (m, y)
    }

    /// The readings of `truth(0.8, vanes)` with scale errors `k` and biases `b` (rad) on the
    /// vanes.
    struct Scaled {
        m: [Vec<f64>; 7],
        y: [Vec<f64>; 6],
        alpha: Vec<f64>,
        beta: Vec<f64>,
        vanes: Vanes,
    }

    impl Scaled {
        fn new(vanes: Vanes, k: [f64; 2], b: [f64; 2]) -> Self {
            let (m, y) = truth(0.8, vanes);
            let alpha = y[1].iter().map(|v| (1.0 + k[0]) * v + b[0]).collect();
            let beta = y[2].iter().map(|v| (1.0 + k[1]) * v + b[1]).collect();
            Scaled {
                m,
                y,
                alpha,
                beta,
                vanes,
            }
        }

        fn input(&self) -> CompatInput<'_> {
            let [t, p, q, r, ax, ay, az] = &self.m;
            CompatInput {
                t,
                accel: [ax, ay, az],
                rates: [p, q, r],
                tas: &self.y[0],
                alpha: &self.alpha,
                beta: &self.beta,
                euler: [&self.y[3], &self.y[4], &self.y[5]],
                vanes: self.vanes,
            }
        }
    }

    /// Scale errors `k` and biases `b` (rad) put on the readings of `truth(0.8, vanes)`: the
    /// check with scale factors gives all four back (1e-5, and 1e-6 rad; with `gusts`, the
    /// innovations form, ten times those).
    fn assert_scale_recovered(vanes: Vanes, k: [f64; 2], b: [f64; 2], gusts: bool) -> CompatResult {
        let data = Scaled::new(vanes, k, b);
        let inp = data.input();
        let (res, f) = if gusts {
            (check(&inp, 60, true, true).unwrap(), 10.0)
        } else {
            (check(&inp, 40, true, false).unwrap(), 1.0)
        };
        for (name, want, tol) in [
            ("k_alpha", k[0], 1e-5),
            ("k_beta", k[1], 1e-5),
            ("b_alpha_rad", b[0], 1e-6),
            ("b_beta_rad", b[1], 1e-6),
        ] {
            let got = res.params[PARAM_NAMES.iter().position(|n| *n == name).unwrap()];
            assert!((got - want).abs() < f * tol, "{name} {got}");
        }
        res
    }

    /// Closed-form motion: build consistent inputs by integrating a known truth finely,
    /// then inject biases and check they come back.
    #[test]
    fn recovers_alpha_and_ax_biases() {
        let ([t, p, q, r, ax, ay, az], y) = truth(0.3, Vanes::AT_CG);
        let (b_alpha, b_ax) = (1.0_f64.to_radians(), 0.2);
        let alpha_m: Vec<f64> = y[1].iter().map(|v| v + b_alpha).collect();
        let ax_m: Vec<f64> = ax.iter().map(|v| v + b_ax).collect();
        let inp = CompatInput {
            t: &t,
            accel: [&ax_m, &ay, &az],
            rates: [&p, &q, &r],
            tas: &y[0],
            alpha: &alpha_m,
            beta: &y[2],
            euler: [&y[3], &y[4], &y[5]],
            vanes: Vanes::AT_CG,
        };
        let res = check(&inp, 30, false, false).unwrap();
        assert!(
            (res.params[6] - b_alpha).abs() < 1e-5,
            "b_alpha {}",
            res.params[6]
        );
        assert!(
            (res.params[0] - b_ax).abs() < 1e-4,
            "b_ax {}",
            res.params[0]
        );
        assert!(res.rms_after[1] < 1e-5 && res.rms_before[1] > 1e-2);
    }

    /// Vane scale factors (upwash 1.06, sidewash 0.92) and biases on an alpha sweep with
    /// sideslip, exact data: all four come back, and without the scale terms the biases
    /// could not absorb them (the residual is the check's evidence).
    #[test]
    fn recovers_vane_scale_factors_and_biases() {
        let (_, y) = truth(0.8, Vanes::AT_CG);
        let spread = |v: &[f64]| {
            let (lo, hi) = v
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(*x), b.max(*x)));
            hi - lo
        };
        assert!(
            spread(&y[1]) > 0.1 && spread(&y[2]) > 0.05,
            "the angles must vary"
        );
        let b = [0.5_f64.to_radians(), -0.3_f64.to_radians()];
        let res = assert_scale_recovered(Vanes::AT_CG, [0.06, -0.08], b, false);
        assert!(res.rms_after[1] < 1e-6 && res.rms_after[2] < 1e-6);
        // every estimated parameter has a finite bound (the gains are not estimated here)
        assert!(res
            .std_err
            .iter()
            .zip(&res.estimated)
            .all(|(s, e)| !e || s.is_finite()));
    }

    /// Vanes on a nose boom 8 m ahead (the rates' ω × r terms are several tenths of a degree)
    /// and a flank-angle yaw vane: scale factors and biases of the readings come back.
    #[test]
    fn recovers_scale_factors_of_boom_vanes_and_a_flank_vane() {
        let vanes = Vanes {
            r_alpha: [8.0, -0.4, 0.5],
            r_beta: [8.2, 0.0, -0.6],
            flank: true,
        };
        let (_, y) = truth(0.8, vanes);
        let (_, at_cg) = truth(0.8, Vanes::AT_CG);
        let most = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .fold(0.0f64, |m, (x, z)| m.max((x - z).abs()))
        };
        assert!(most(&y[1], &at_cg[1]) > 0.003 && most(&y[2], &at_cg[2]) > 0.003);
        let b = [0.4_f64.to_radians(), 0.6_f64.to_radians()];
        assert_scale_recovered(vanes, [0.07, 0.05], b, false);
    }

    /// The innovations form on calm (exact) data: the gains stay near zero and the scale
    /// factors and biases come back as with output error.
    #[test]
    fn gust_predictor_on_calm_data_is_output_error() {
        let vanes = Vanes::AT_CG;
        let (k, b) = ([0.06, -0.08], [0.5_f64.to_radians(), -0.3_f64.to_radians()]);
        let res = assert_scale_recovered(vanes, k, b, true);
        let data = Scaled::new(vanes, k, b);
        let inp = data.input();
        assert!(GAINS
            .iter()
            .all(|&j| res.estimated[j] && (0.0..0.05).contains(&res.params[j])));
        // the reconstruction with the reported gains is the predictor the fit ended on
        let y2 = reconstruct(&inp, &res.params).unwrap();
        let worst = y2[2]
            .iter()
            .zip(&data.beta)
            .fold(0.0f64, |m, (a, z)| m.max((a - z).abs()));
        assert!(worst < 1e-4, "{worst}");
    }
}
