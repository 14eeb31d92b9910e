//! Unit and sign plausibility of a campaign's channels from kinematic consistency.
//!
//! Each checked channel is compared with what the other channels say it must be (body axes x
//! forward, y right, z down; air-relative velocity $u = V\cos\alpha\cos\beta$,
//! $v = V\sin\beta$, $w = V\sin\alpha\cos\beta$; a steady wind does not change the
//! equations; $g$ = 9.80665 m/s²):
//!
//! - accelerometers (specific force) over windows of [`WINDOW_S`] (thesis Eq. 3.1a-c): the
//!   change of the body velocity component less the integral of its rotational and gravity
//!   terms ($rv - qw - g\sin\theta$, $pw - ru + g\cos\theta\sin\phi$,
//!   $qu - pv + g\cos\theta\cos\phi$) against the integral of the measured specific force;
//!   the slope is $1/k$. Gravity dominates: in level flight $a_z \approx -g$, so a z axis
//!   pointing up reads $-1$ times the kinematic force and load factors in g declared as m/s²
//!   read $1/9.81$ times it;
//! - airspeed, angle of attack, sideslip and altitude over windows of [`WINDOW_S`]: the change
//!   of the measured channel against the integral (trapezoids) of its kinematic rate,
//!   $\dot V = (a + g_b)\cdot(u, v, w)/V$,
//!   $\dot\alpha = (u\dot w - w\dot u)/(u^2 + w^2)$,
//!   $\dot\beta = (\dot v - \sin\beta\,\dot V)/(V\cos\beta)$,
//!   $\dot h = u\sin\theta - v\sin\phi\cos\theta - w\cos\phi\cos\theta$
//!   with $\dot u = rv - qw + a_x - g\sin\theta$,
//!   $\dot v = pw - ru + a_y + g\cos\theta\sin\phi$,
//!   $\dot w = qu - pv + a_z + g\cos\theta\cos\phi$. Differences over windows cancel constant
//!   sensor biases; the integral does not see gusts (they move the air, not the aircraft), so
//!   turbulence is noise on the measured side and does not bias the scale.
//!
//! The scale $k$ (measured = $k$ · kinematic) is the least-squares slope through the origin
//! pooled over the campaign (for the accelerometers the slope is $1/k$, so that the gusts stay
//! on the measured side); its standard error is cluster-robust (by maneuver, and by blocks
//! of [`WINDOW_S`] within a maneuver; the larger is used), because neighbouring samples share
//! the same gust. A channel is *plausible* when $k$ is within 20 % of 1 (0.8-1.25: sensor
//! calibration, upwash and the approximations above stay well inside it), or when the data
//! cannot say otherwise ($k$ within [`Z`] standard errors of that band). Otherwise the scale is
//! far from physical: it is matched (within 10 %) against the candidate ratios the caller
//! gives (unit mistakes and sign flips: 1/57.3 for radians declared as degrees, 1.944 for knots
//! declared as m/s, -1 for an axis of the other sign, ...). Checks run in order
//! accelerometers, airspeed, angles, altitude; a channel found to hold a named mistake is
//! corrected by that ratio for the later checks, so that every mistake is found in one pass.

use crate::error::{AeroError, Result};

/// Standard gravity, m/s².
pub const G0: f64 = 9.80665;
/// Window of the integrated checks and block of the standard errors, s.
pub const WINDOW_S: f64 = 3.0;
/// Plausible band of the scale: within 20 % of 1.
pub const BAND: f64 = 1.25;
/// A far scale within 10 % of a candidate ratio is that mistake.
pub const MATCH: f64 = 1.10;
/// Standard errors by which a scale must lie outside the band to be judged far.
pub const Z: f64 = 4.0;
/// Fewest blocks of [`WINDOW_S`] for a verdict.
pub const MIN_BLOCKS: usize = 5;

/// Checked channels, in the order they are checked.
pub const CHECKS: [&str; 7] = ["az", "ax", "ay", "tas", "alpha", "beta", "h"];

/// A campaign's channels stored back to back (SI, rad, at the CG as declared).
#[derive(Debug, Clone, Copy)]
pub struct PlausInput<'a> {
    /// Maneuver boundaries, `offsets[m]..offsets[m+1]`, first 0, last the length.
    pub offsets: &'a [usize],
    /// Time, s.
    pub t: &'a [f64],
    /// Specific force, m/s².
    pub accel: [&'a [f64]; 3],
    /// Body rates, rad/s.
    pub rates: [&'a [f64]; 3],
    /// True airspeed, m/s.
    pub tas: &'a [f64],
    /// Angle of attack, rad.
    pub alpha: &'a [f64],
    /// Sideslip, rad.
    pub beta: &'a [f64],
    /// Roll and pitch attitude, rad.
    pub euler: [&'a [f64]; 2],
    /// Vane minus CG angle of attack and sideslip, rad (the lever-arm terms the vane transfer
    /// removed; zeros for angles measured at the CG). A unit mistake scales the vane reading,
    /// not the lever-arm term, so the check compares the vane channel.
    pub vane_offset: [&'a [f64]; 2],
    /// Altitude, m (optional).
    pub h: Option<&'a [f64]>,
}

/// Verdict of one check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Within the band, or not far from it by [`Z`] standard errors.
    Plausible,
    /// Too little excitation or data to judge.
    NotJudged,
    /// Far from physical and within 10 % of candidate `usize`.
    Mistake(usize),
    /// Far from physical, no candidate matches.
    Far,
}

/// Scale estimate of one channel.
#[derive(Debug, Clone)]
pub struct ScaleCheck {
    /// Channel, one of [`CHECKS`].
    pub channel: &'static str,
    /// Pooled scale (measured / kinematic).
    pub k: f64,
    /// Its standard error.
    pub se: f64,
    /// Blocks of [`WINDOW_S`] that entered.
    pub blocks: usize,
    /// Verdict on the pooled scale.
    pub verdict: Verdict,
    /// Per maneuver: scale, standard error, verdict (NaN, NotJudged when unexcited).
    pub per_maneuver: Vec<(f64, f64, Verdict)>,
}

/// One-sided tail of the standard normal beyond [`Z`], `1 - Φ(4)`.
const Z_TAIL: f64 = 3.167_124_183_311_986e-5;

/// Standard errors by which a scale must lie outside the band to be judged far, when its
/// cluster-robust standard error rests on `clusters` clusters: the Student t quantile with
/// `clusters - 1` degrees of freedom at the tail of [`Z`] (the small-sample reference of a
/// cluster-robust variance, Cameron & Miller 2015, Section VI.C). [`Z`] itself for many
/// clusters; 7.0 for the 10 blocks of a 30-s maneuver, where a normal critical value of 4
/// refused a JSBSim DHC-6 maneuver flown in turbulence (lateral specific force barely
/// excited, the air-data velocity change moved by the gusts: k = -0.92 over its blocks).
pub fn critical(clusters: usize) -> f64 {
    if clusters < 2 {
        return f64::INFINITY;
    }
    crate::lsq::stats::student_t_ppf(1.0 - Z_TAIL, (clusters - 1) as f64)
}

/// Judge a scale `k` ± `se` over `blocks` blocks, its standard error resting on `clusters`
/// clusters ([`critical`]), against `candidates`.
pub fn judge(k: f64, se: f64, blocks: usize, clusters: usize, candidates: &[f64]) -> Verdict {
    if !k.is_finite() || !se.is_finite() || blocks < MIN_BLOCKS {
        return Verdict::NotJudged;
    }
    let z = critical(clusters);
    let far = if k <= 0.0 {
        -k > z * se
    } else {
        let lo = BAND.recip();
        k - z * se > BAND || k + z * se < lo
    };
    if !far {
        return Verdict::Plausible;
    }
    let tol = MATCH.ln();
    candidates
        .iter()
        .enumerate()
        .filter(|(_, &r)| r != 0.0 && r.signum() == k.signum() && (k / r).ln().abs() < tol)
        .min_by(|a, b| {
            let da = (k / a.1).ln().abs();
            let db = (k / b.1).ln().abs();
            da.total_cmp(&db)
        })
        .map_or(Verdict::Far, |(i, _)| Verdict::Mistake(i))
}

/// Pairs (kinematic x, measured y) with their maneuver and block.
#[derive(Default)]
struct Pairs {
    x: Vec<f64>,
    y: Vec<f64>,
    man: Vec<usize>,
    block: Vec<usize>,
}

impl Pairs {
    fn push(&mut self, x: f64, y: f64, man: usize, block: usize) {
        if x.is_finite() && y.is_finite() {
            self.x.push(x);
            self.y.push(y);
            self.man.push(man);
            self.block.push(block);
        }
    }
}

/// Slope through the origin and its cluster-robust standard error over the given indices;
/// clusters by `key`. Returns (k, se, clusters).
fn slope(p: &Pairs, idx: &[usize], key: &dyn Fn(usize) -> usize) -> (f64, f64, usize) {
    let sxx: f64 = idx.iter().map(|&i| p.x[i] * p.x[i]).sum();
    let sxy: f64 = idx.iter().map(|&i| p.x[i] * p.y[i]).sum();
    let syy: f64 = idx.iter().map(|&i| p.y[i] * p.y[i]).sum();
    // a channel that does not move at all (a stuck or unrecorded sensor: the sensor health
    // checks report it) says nothing about its unit
    if idx.is_empty() || sxx <= 0.0 || syy <= 0.0 {
        return (f64::NAN, f64::NAN, 0);
    }
    let k = sxy / sxx;
    let mut acc: std::collections::BTreeMap<usize, f64> = std::collections::BTreeMap::new();
    for &i in idx {
        *acc.entry(key(i)).or_insert(0.0) += p.x[i] * (p.y[i] - k * p.x[i]);
    }
    let g = acc.len();
    let s: f64 = acc.values().map(|v| v * v).sum();
    // small-sample correction of the cluster-robust variance
    let c = if g > 1 {
        g as f64 / (g as f64 - 1.0)
    } else {
        1.0
    };
    (k, (c * s).sqrt() / sxx, g)
}

/// Invert a slope y = x / k into k with its standard error.
fn inverted((s, se, g): (f64, f64, usize)) -> (f64, f64, usize) {
    (1.0 / s, se / (s * s), g)
}

fn estimate(
    channel: &'static str,
    p: &Pairs,
    nm: usize,
    candidates: &[f64],
    inverse: bool,
) -> ScaleCheck {
    let all: Vec<usize> = (0..p.x.len()).collect();
    let nb = 1usize << 32;
    let fit = |idx: &[usize], key: &dyn Fn(usize) -> usize| {
        let r = slope(p, idx, key);
        if inverse {
            inverted(r)
        } else {
            r
        }
    };
    let (k, se_b, blocks) = fit(&all, &|i| p.man[i] * nb + p.block[i]);
    let (_, se_m, mans) = fit(&all, &|i| p.man[i]);
    let se = if mans > 1 { se_b.max(se_m) } else { se_b };
    let mut by_man: Vec<Vec<usize>> = vec![Vec::new(); nm];
    for i in all {
        by_man[p.man[i]].push(i);
    }
    let per_maneuver = by_man
        .iter()
        .map(|idx| {
            let (km, sem, bm) = fit(idx, &|i| p.block[i]);
            (km, sem, judge(km, sem, bm, bm, candidates))
        })
        .collect();
    ScaleCheck {
        channel,
        k,
        se,
        blocks,
        // the campaign's verdict: the larger of two cluster-robust errors, the critical value
        // of the many blocks (a campaign of two long maneuvers must still be judged)
        verdict: judge(k, se, blocks, blocks, candidates),
        per_maneuver,
    }
}

/// Channels with the corrections found so far divided out.
struct Corrected {
    accel: [Vec<f64>; 3],
    tas: Vec<f64>,
    alpha: Vec<f64>,
    beta: Vec<f64>,
}

impl Corrected {
    fn vel(&self, i: usize) -> [f64; 3] {
        let (v, a, b) = (self.tas[i], self.alpha[i], self.beta[i]);
        [v * a.cos() * b.cos(), v * b.sin(), v * a.sin() * b.cos()]
    }
}

/// Kinematic body-axis accelerations $(\dot u, \dot v, \dot w)$ at sample `i`.
fn body_acc(inp: &PlausInput<'_>, c: &Corrected, i: usize) -> [f64; 3] {
    let [u, v, w] = c.vel(i);
    let (p, q, r) = (inp.rates[0][i], inp.rates[1][i], inp.rates[2][i]);
    let (sf, cf) = inp.euler[0][i].sin_cos();
    let (st, ct) = inp.euler[1][i].sin_cos();
    [
        r * v - q * w + c.accel[0][i] - G0 * st,
        p * w - r * u + c.accel[1][i] + G0 * ct * sf,
        q * u - p * v + c.accel[2][i] + G0 * ct * cf,
    ]
}

fn maneuver_ranges(inp: &PlausInput<'_>) -> Vec<(usize, usize, f64)> {
    inp.offsets
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let dt = if b > a + 1 {
                (inp.t[b - 1] - inp.t[a]) / (b - a - 1) as f64
            } else {
                f64::NAN
            };
            (a, b, dt)
        })
        .collect()
}

/// Window pairs of an accelerometer check: the integral of the measured specific force
/// (x) against the change of the velocity component less the integral of the rotational and
/// gravity terms (y): y = x / k. The gusts move the air-relative velocity, so they stay on the
/// y side (noise, no bias of the slope), and a small specific force (ay in coordinated flight)
/// leaves x small: not judged rather than biased.
fn accel_pairs(inp: &PlausInput<'_>, c: &Corrected, axis: usize) -> Pairs {
    let comp: Vec<f64> = (0..inp.t.len()).map(|i| c.vel(i)[axis]).collect();
    window_pairs_with(
        inp,
        &comp,
        |i| c.accel[axis][i],
        |i| body_acc(inp, c, i)[axis] - c.accel[axis][i],
        None,
    )
}

/// Window pairs of an integrated check: change of `meas` against the integral of `rate`.
fn window_pairs(inp: &PlausInput<'_>, meas: &[f64], rate: impl Fn(usize) -> f64) -> Pairs {
    window_pairs_with(inp, meas, rate, |_| 0.0, None)
}

/// Window pairs: x = integral of `rate` plus the change of `x_add`, y = change of `meas` less
/// the integral of `sub`.
fn window_pairs_with(
    inp: &PlausInput<'_>,
    meas: &[f64],
    rate: impl Fn(usize) -> f64,
    sub: impl Fn(usize) -> f64,
    x_add: Option<&[f64]>,
) -> Pairs {
    let mut out = Pairs::default();
    for (m, (a, b, dt)) in maneuver_ranges(inp).into_iter().enumerate() {
        if dt.is_nan() || dt <= 0.0 {
            continue;
        }
        let len = (WINDOW_S / dt).round().max(1.0) as usize;
        let mut s = a;
        let (mut prev, mut prev_sub) = (rate(s), sub(s));
        let (mut integ, mut integ_sub) = (0.0, 0.0);
        let mut start = a;
        let mut block = 0;
        s += 1;
        while s < b {
            let (cur, cur_sub) = (rate(s), sub(s));
            let h = inp.t[s] - inp.t[s - 1];
            integ += 0.5 * (prev + cur) * h;
            integ_sub += 0.5 * (prev_sub + cur_sub) * h;
            prev = cur;
            prev_sub = cur_sub;
            if s - start == len {
                let dx = x_add.map_or(0.0, |x| x[s] - x[start]);
                out.push(integ + dx, meas[s] - meas[start] - integ_sub, m, block);
                block += 1;
                start = s;
                integ = 0.0;
                integ_sub = 0.0;
            }
            s += 1;
        }
    }
    out
}

/// Candidate ratios (measured / true) of each check, in the order of [`CHECKS`].
pub type Candidates<'a> = [&'a [f64]; 7];

/// Run every check of [`CHECKS`] over the campaign.
///
/// # Errors
/// `InvalidInput` for channels of unequal length, offsets that do not cover them, or
/// non-finite samples.
pub fn check(inp: &PlausInput<'_>, candidates: &Candidates<'_>) -> Result<Vec<ScaleCheck>> {
    let place = "plausibility check";
    let n = inp.t.len();
    let mut chans: Vec<&[f64]> = vec![
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
        inp.vane_offset[0],
        inp.vane_offset[1],
        inp.t,
    ];
    if let Some(h) = inp.h {
        chans.push(h);
    }
    if chans.iter().any(|c| c.len() != n) {
        return Err(AeroError::invalid(place, "channels of unequal length"));
    }
    let o = inp.offsets;
    if o.first() != Some(&0) || o.last() != Some(&n) || o.windows(2).any(|w| w[0] > w[1]) {
        return Err(AeroError::invalid(
            place,
            "offsets must rise from 0 to the length",
        ));
    }
    if chans.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return Err(AeroError::invalid(
            place,
            "non-finite samples; validate the records first",
        ));
    }
    let nm = o.len() - 1;
    let mut c = Corrected {
        accel: [
            inp.accel[0].to_vec(),
            inp.accel[1].to_vec(),
            inp.accel[2].to_vec(),
        ],
        tas: inp.tas.to_vec(),
        alpha: inp.alpha.to_vec(),
        beta: inp.beta.to_vec(),
    };
    let correct = |x: &mut Vec<f64>, r: &ScaleCheck, cand: &[f64]| {
        if let Verdict::Mistake(j) = r.verdict {
            let f = cand[j];
            x.iter_mut().for_each(|v| *v /= f);
        }
    };
    let mut out = Vec::with_capacity(CHECKS.len());
    // accelerometers: az first (gravity), then ax, ay
    for (ci, axis) in [(0usize, 2usize), (1, 0), (2, 1)] {
        let pairs = accel_pairs(inp, &c, axis);
        let r = estimate(CHECKS[ci], &pairs, nm, candidates[ci], true);
        correct(&mut c.accel[axis], &r, candidates[ci]);
        out.push(r);
    }
    // airspeed: V-dot does not depend on V itself
    let vdot = |c: &Corrected, i: usize| -> f64 {
        let [u, v, w] = c.vel(i);
        let d = body_acc(inp, c, i);
        (u * d[0] + v * d[1] + w * d[2]) / c.tas[i]
    };
    let meas_tas = c.tas.clone();
    let pairs = window_pairs(inp, &meas_tas, |i| vdot(&c, i));
    let r = estimate(CHECKS[3], &pairs, nm, candidates[3], false);
    correct(&mut c.tas, &r, candidates[3]);
    out.push(r);
    // a named angle mistake scales the vane reading: vane = (cg + offset) / ratio
    let correct_angle = |x: &mut Vec<f64>, off: &[f64], r: &ScaleCheck, cand: &[f64]| {
        if let Verdict::Mistake(j) = r.verdict {
            let f = cand[j];
            x.iter_mut()
                .zip(off)
                .for_each(|(v, o)| *v = (*v + o) / f - o);
        }
    };
    // angle of attack (the vane channel against the kinematic change at the CG plus the
    // change of the lever-arm term)
    let [off_a, off_b] = inp.vane_offset;
    let alpha_vane: Vec<f64> = c.alpha.iter().zip(off_a).map(|(a, o)| a + o).collect();
    let pairs = window_pairs_with(
        inp,
        &alpha_vane,
        |i| {
            let [u, _, w] = c.vel(i);
            let d = body_acc(inp, &c, i);
            (u * d[2] - w * d[0]) / (u * u + w * w)
        },
        |_| 0.0,
        Some(off_a),
    );
    let r = estimate(CHECKS[4], &pairs, nm, candidates[4], false);
    correct_angle(&mut c.alpha, off_a, &r, candidates[4]);
    out.push(r);
    // sideslip
    let beta_vane: Vec<f64> = c.beta.iter().zip(off_b).map(|(a, o)| a + o).collect();
    let pairs = window_pairs_with(
        inp,
        &beta_vane,
        |i| {
            let d = body_acc(inp, &c, i);
            let b = c.beta[i];
            (d[1] - b.sin() * vdot(&c, i)) / (c.tas[i] * b.cos())
        },
        |_| 0.0,
        Some(off_b),
    );
    let r = estimate(CHECKS[5], &pairs, nm, candidates[5], false);
    correct_angle(&mut c.beta, off_b, &r, candidates[5]);
    out.push(r);
    // altitude
    if let Some(h) = inp.h {
        let pairs = window_pairs(inp, h, |i| {
            let [u, v, w] = c.vel(i);
            let (sf, cf) = inp.euler[0][i].sin_cos();
            let (st, ct) = inp.euler[1][i].sin_cos();
            u * st - v * sf * ct - w * cf * ct
        });
        out.push(estimate(CHECKS[6], &pairs, nm, candidates[6], false));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn critical_value_is_student_t_at_the_tail_of_z() {
        // scipy.stats.t.ppf(1 - scipy.stats.norm.sf(4), df)
        for (clusters, want) in [
            (5, 17.448_227_992_362_295),
            (10, 6.998_639_109_583_918),
            (50, 4.375_255_452_275_371),
            (1001, 4.017_064_306_722_094),
        ] {
            let got = critical(clusters);
            assert!(
                (got / want - 1.0).abs() < 1e-9,
                "{clusters}: {got} vs {want}"
            );
        }
        assert!(critical(1).is_infinite());
    }

    #[test]
    fn judge_bands_and_candidates() {
        let cand = [1.0 / 57.29578, -1.0];
        assert_eq!(judge(1.1, 0.01, 50, 50, &cand), Verdict::Plausible);
        assert_eq!(judge(0.0176, 0.0005, 50, 50, &cand), Verdict::Mistake(0));
        assert_eq!(judge(-0.97, 0.02, 50, 50, &cand), Verdict::Mistake(1));
        assert_eq!(judge(2.6, 0.05, 50, 50, &cand), Verdict::Far);
        // far but uncertain: not judged far
        assert_eq!(judge(2.0, 0.5, 50, 50, &cand), Verdict::Plausible);
        assert_eq!(judge(0.0176, 0.0005, 2, 2, &cand), Verdict::NotJudged);
        // a sign flip 6 standard errors out is a mistake with many clusters, not with the 10
        // blocks of one short maneuver (t with 9 degrees of freedom)
        assert_eq!(judge(-0.92, 0.15, 200, 200, &cand), Verdict::Mistake(1));
        assert_eq!(judge(-0.92, 0.15, 10, 10, &cand), Verdict::Plausible);
    }

    /// A pull-up and a decelerating level segment, built from exact kinematics: every scale
    /// comes back as 1; knots declared as m/s, radians as degrees and a flipped az are named.
    #[test]
    fn finds_scales_of_consistent_and_mislabelled_channels() {
        let dt = 0.02;
        let n = 3000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        // truth: alpha(t), V(t), theta(t), level wings, q = theta-dot, gamma = theta - alpha
        let alpha: Vec<f64> = t
            .iter()
            .map(|&s| 0.08 + 0.06 * (0.3 * s).sin() + 0.02 * (1.1 * s).sin())
            .collect();
        let tas: Vec<f64> = t
            .iter()
            .map(|&s| 70.0 - 0.3 * s + 3.0 * (0.2 * s).sin())
            .collect();
        let gam: Vec<f64> = t.iter().map(|&s| 0.05 * (0.25 * s).sin()).collect();
        let theta: Vec<f64> = alpha.iter().zip(&gam).map(|(a, g)| a + g).collect();
        let d = |x: &[f64], i: usize| -> f64 {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            (x[b] - x[a]) / (t[b] - t[a])
        };
        let q: Vec<f64> = (0..n).map(|i| d(&theta, i)).collect();
        let zero = vec![0.0; n];
        // specific force from u-dot, w-dot (v = p = r = 0, phi = 0)
        let (mut ax, mut az) = (vec![0.0; n], vec![0.0; n]);
        let u: Vec<f64> = (0..n).map(|i| tas[i] * alpha[i].cos()).collect();
        let w: Vec<f64> = (0..n).map(|i| tas[i] * alpha[i].sin()).collect();
        for i in 0..n {
            ax[i] = d(&u, i) + q[i] * w[i] + G0 * theta[i].sin();
            az[i] = d(&w, i) - q[i] * u[i] - G0 * theta[i].cos();
        }
        let mut h = vec![1000.0; n];
        for i in 1..n {
            let hd = |j: usize| u[j] * theta[j].sin() - w[j] * theta[j].cos();
            h[i] = h[i - 1] + 0.5 * (hd(i) + hd(i - 1)) * dt;
        }
        let offsets = [0, 1500, n];
        let cands: Vec<f64> = vec![1.0 / 57.29578, 57.29578, -1.0, 1.943844, 3.28084];
        let cs: Candidates<'_> = [&cands; 7];
        let run = |ax: &[f64], az: &[f64], tas: &[f64], alpha: &[f64], h: &[f64]| {
            let inp = PlausInput {
                offsets: &offsets,
                t: &t,
                accel: [ax, &zero, az],
                rates: [&zero, &q, &zero],
                tas,
                alpha,
                beta: &zero,
                euler: [&zero, &theta],
                vane_offset: [&zero, &zero],
                h: Some(h),
            };
            check(&inp, &cs).unwrap()
        };
        let ok = run(&ax, &az, &tas, &alpha, &h);
        for r in &ok {
            if r.channel == "ay" || r.channel == "beta" {
                assert_eq!(
                    r.verdict,
                    Verdict::NotJudged,
                    "{}: {:?}",
                    r.channel,
                    r.verdict
                );
                continue;
            }
            assert!((r.k - 1.0).abs() < 0.02, "{} k = {}", r.channel, r.k);
            assert_eq!(r.verdict, Verdict::Plausible, "{}", r.channel);
        }
        let kt: Vec<f64> = tas.iter().map(|v| v * 1.943844).collect();
        let rad: Vec<f64> = alpha.iter().map(|v| v / 57.29578).collect();
        let up: Vec<f64> = az.iter().map(|v| -v).collect();
        let hft: Vec<f64> = h.iter().map(|v| v * 3.28084).collect();
        let bad = run(&ax, &up, &kt, &rad, &hft);
        let v = |c: &str| bad.iter().find(|r| r.channel == c).unwrap().verdict;
        assert_eq!(v("az"), Verdict::Mistake(2));
        assert_eq!(v("tas"), Verdict::Mistake(3));
        assert_eq!(v("alpha"), Verdict::Mistake(0));
        assert_eq!(v("h"), Verdict::Mistake(4));
        assert_eq!(v("ax"), Verdict::Plausible);
    }
}
