//! Parameter covariance corrected for coloured residuals (Morelli & Klein,
//! "Aircraft System Identification", Eq. 5.80; SIDPAC `r_colores.m`):
//!
//! ```text
//! Cov(θ) = (XᵀX)⁻¹ M (XᵀX)⁻¹,   M = Σ_i Σ_j x_i R_vv(i−j) x_jᵀ
//! ```
//!
//! with `x_i` the i-th row of the regressor matrix and `R_vv(k) = (1/N) Σ_t
//! v(t) v(t+k)` the *biased* sample autocorrelation of the residuals `v`
//! (mean not removed, as MATLAB `xcorr(v, 'biased')` in `r_colores`). No
//! `s²` factor: the autocorrelation at lag 0 already carries the residual
//! variance.
//!
//! The double sum is never formed (it is O(p² N²)). It is the quadratic
//! form `Xᵀ T X` with `T` the symmetric Toeplitz matrix of `R_vv`; with
//! every sequence zero-padded to a length `L >= 2N-1` the circular
//! convolution equals the linear one, and by Parseval
//!
//! ```text
//! M_ab = (1/L) Σ_k conj(X_a[k]) S[k] X_b[k],   S = DFT_L(R_vv) = |V|²/N,
//! ```
//!
//! where `X_a`, `V` are the length-`L` DFTs of column `a` and of `v`. So one
//! real FFT per column plus one for the residuals, then one weighted Gram
//! product of the half spectra: O(p N log N + p² N) time, O(p N) memory.
//! With a maximum lag `K`, `R_vv(k)` is set to zero for `|k| > K` (a
//! truncated, not tapered, estimate: `S` is then recomputed from the
//! truncated sequence and may have negative values).

use std::sync::{Arc, Mutex, OnceLock};

use faer::Mat;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

use super::pool::{give_cplx, give_real, take_cplx, take_real};
use crate::error::{AeroError, Result};

/// Smallest `2^a 3^b 5^c 7^d` not below `n` (fast lengths for rustfft).
pub fn fast_len(n: usize) -> usize {
    let mut best = n.next_power_of_two();
    let mut p7 = 1usize;
    while p7 < best {
        let mut p5 = p7;
        while p5 < best {
            let mut p3 = p5;
            while p3 < best {
                let mut v = p3;
                while v < n {
                    v *= 2;
                }
                if v < best {
                    best = v;
                }
                p3 *= 3;
            }
            p5 *= 5;
        }
        p7 *= 7;
    }
    best
}

type Fwd = Arc<dyn RealToComplex<f64>>;
type Inv = Arc<dyn ComplexToReal<f64>>;

/// One planner for the process: FFT plans (twiddles) are cached by length,
/// so repeated fits on the same number of rows skip the planning.
fn plans(l: usize, inverse: bool) -> (Fwd, Option<Inv>) {
    static PLANNER: OnceLock<Mutex<RealFftPlanner<f64>>> = OnceLock::new();
    let mut pl = PLANNER
        .get_or_init(|| Mutex::new(RealFftPlanner::new()))
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let fwd = pl.plan_fft_forward(l);
    let inv = inverse.then(|| pl.plan_fft_inverse(l));
    (fwd, inv)
}

/// Per-worker FFT scratch, back to the pool on drop.
struct Scratch(Vec<Complex<f64>>);

impl Drop for Scratch {
    fn drop(&mut self) {
        give_cplx(std::mem::take(&mut self.0));
    }
}

/// Bins of the half spectrum per block of the Gram product: fixed (so the
/// summation order does not depend on the number of threads) and small
/// enough for a block of the weighted spectra (`2 × GRAM_BLOCK × p` values)
/// to stay in the L2 cache.
const GRAM_BLOCK: usize = 1024;

fn fft_err(e: impl std::fmt::Display) -> AeroError {
    AeroError::invalid("coloured-residual covariance", format!("FFT failed: {e}"))
}

/// Transform length for `n` samples: the smallest fast length `L >= 2n - 1`
/// (zero padding that makes the circular correlation linear).
pub fn padded_len(n: usize) -> usize {
    fast_len((2 * n).saturating_sub(1).max(1))
}

/// The middle matrix `M = Xᵀ T X` of the coloured-residual covariance
/// (module docs), `p × p`.
///
/// `fill_col(b, out)` writes column `b` of the regressor matrix (its `N`
/// rows, in time order) into `out[..N]`. `v` holds the `N` residuals.
/// `max_lag` truncates the autocorrelation (`None`: all lags).
pub fn toeplitz_gram<F>(
    p: usize,
    fill_col: F,
    v: &[f64],
    max_lag: Option<usize>,
) -> Result<Mat<f64>>
where
    F: Fn(usize, &mut [f64]) + Sync,
{
    let n = v.len();
    if n == 0 || p == 0 {
        return Ok(Mat::zeros(p, p));
    }
    let l = padded_len(n);
    let cols: Vec<Vec<f64>> = (0..p)
        .map(|b| {
            let mut c = take_real(l);
            fill_col(b, &mut c[..n]);
            c
        })
        .collect();
    toeplitz_gram_cols(cols, v, max_lag)
}

/// [`toeplitz_gram`] on columns given as buffers: `cols[b][..N]` holds
/// column `b` (`N = v.len()`); each buffer is then zero-padded to
/// [`padded_len`]`(N)` and transformed in place (its contents are lost; it
/// goes back to the work-buffer pool).
///
/// The `p + 1` transforms (columns and residuals) run as one parallel batch;
/// the half spectra are kept as computed (no reordering copy) and the Gram
/// product reads them block by block.
pub fn toeplitz_gram_cols(
    mut cols: Vec<Vec<f64>>,
    v: &[f64],
    max_lag: Option<usize>,
) -> Result<Mat<f64>> {
    let n = v.len();
    let p = cols.len();
    if n == 0 || p == 0 {
        for c in cols {
            give_real(c);
        }
        return Ok(Mat::zeros(p, p));
    }
    if let Some(b) = cols.iter().position(|c| c.len() < n) {
        return Err(AeroError::invalid(
            "coloured-residual covariance",
            format!("column {b} has {} values for {n} residuals", cols[b].len()),
        ));
    }
    let l = padded_len(n);
    let kh = l / 2 + 1;
    let truncate = max_lag.is_some_and(|k| k + 1 < n);
    let (r2c, c2r) = plans(l, truncate);

    // Half spectra of the p columns (0..p) and of the residuals (index p),
    // every sequence zero-padded to L; the residuals get a pooled buffer.
    cols.push(take_real(l));
    let mut specs: Vec<Vec<Complex<f64>>> = (0..=p).map(|_| take_cplx(kh)).collect();
    // Per-worker scratch, recycled: the scratch of a long mixed-radix FFT
    // is as long as the transform, and rayon may create several per call.
    let new_scratch = || Scratch(take_cplx(r2c.get_scratch_len()));
    let one = |scratch: &mut Scratch,
               b: usize,
               buf: &mut Vec<f64>,
               out: &mut Vec<Complex<f64>>|
     -> Result<()> {
        if b == p {
            buf[..n].copy_from_slice(v);
        }
        buf.resize(l, 0.0);
        buf[n..].fill(0.0);
        r2c.process_with_scratch(buf, out, &mut scratch.0)
            .map_err(fft_err)
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        cols.par_iter_mut()
            .zip(specs.par_iter_mut())
            .enumerate()
            .with_max_len(1)
            .try_for_each_init(new_scratch, |sc, (b, (buf, out))| one(sc, b, buf, out))?;
    }
    #[cfg(not(feature = "parallel"))]
    {
        let mut sc = new_scratch();
        for (b, (buf, out)) in cols.iter_mut().zip(specs.iter_mut()).enumerate() {
            one(&mut sc, b, buf, out)?;
        }
    }
    for c in cols {
        give_real(c);
    }
    let mut spec = specs.pop().unwrap_or_default();

    // Residual power spectrum S = |V|² / N  (DFT of the biased autocorrelation).
    let inv_n = 1.0 / n as f64;
    let mut s = take_real(kh);
    for (sk, c) in s.iter_mut().zip(&spec) {
        *sk = c.norm_sqr() * inv_n;
    }

    if let (Some(k), Some(c2r)) = (max_lag, c2r) {
        {
            // Back to lags, zero |lag| > k, forward again.
            let mut sc: Vec<Complex<f64>> = s.iter().map(|&x| Complex::new(x, 0.0)).collect();
            let mut r = vec![0.0; l];
            c2r.process(&mut sc, &mut r).map_err(fft_err)?;
            let inv_l = 1.0 / l as f64;
            for (tau, val) in r.iter_mut().enumerate() {
                let lag = tau.min(l - tau);
                *val = if lag <= k { *val * inv_l } else { 0.0 };
            }
            r2c.process(&mut r, &mut spec).map_err(fft_err)?;
            for (sk, c) in s.iter_mut().zip(&spec) {
                *sk = c.re;
            }
        }
    }
    give_cplx(spec);

    // Parseval weights over the half spectrum: interior bins count twice.
    let inv_l = 1.0 / l as f64;
    for (k, sk) in s.iter_mut().enumerate() {
        let twice = k != 0 && !(l % 2 == 0 && k == l / 2);
        *sk *= inv_l * if twice { 2.0 } else { 1.0 };
    }
    let w = s;
    let all_nonneg = w.iter().all(|&x| x >= 0.0);

    // Gram product by blocks of bins: with S >= 0 the block matrix holds
    // the real and imaginary parts scaled by √w (M = AᵀA); otherwise the
    // left factor is scaled by w and the right one not. Only the lower
    // triangle of each block Gram is formed (the product is symmetric).
    let sw: Vec<f64> = if all_nonneg {
        w.iter().map(|x| x.sqrt()).collect()
    } else {
        w.clone()
    };
    // `buf` holds the two block factors, column-major `2 rn × p` each.
    let gram_block = |buf: &mut Vec<f64>, s0: usize, e0: usize| -> Mat<f64> {
        use faer::linalg::matmul::triangular::{matmul, BlockStructure};
        use faer::MatRef;
        let rn = e0 - s0;
        let len = 2 * rn * p;
        buf.resize(2 * len, 0.0);
        let (lhs, rhs) = buf.split_at_mut(len);
        for (b, col) in lhs.chunks_exact_mut(2 * rn).enumerate() {
            let (re, im) = col.split_at_mut(rn);
            let sp = &specs[b][s0..e0];
            for (((r, i), c), f) in re.iter_mut().zip(im.iter_mut()).zip(sp).zip(&sw[s0..e0]) {
                *r = c.re * f;
                *i = c.im * f;
            }
        }
        if !all_nonneg {
            for (b, col) in rhs.chunks_exact_mut(2 * rn).enumerate() {
                let (re, im) = col.split_at_mut(rn);
                for ((r, i), c) in re.iter_mut().zip(im.iter_mut()).zip(&specs[b][s0..e0]) {
                    *r = c.re;
                    *i = c.im;
                }
            }
        }
        let l_m = MatRef::from_column_major_slice(lhs, 2 * rn, p);
        let r_m = if all_nonneg {
            l_m
        } else {
            MatRef::from_column_major_slice(rhs, 2 * rn, p)
        };
        let mut g = Mat::<f64>::zeros(p, p);
        matmul(
            g.as_mut(),
            BlockStructure::TriangularLower,
            faer::Accum::Replace,
            l_m.transpose(),
            BlockStructure::Rectangular,
            r_m,
            BlockStructure::Rectangular,
            1.0,
            faer::Par::Seq,
        );
        g
    };
    let nblocks = kh.div_ceil(GRAM_BLOCK);
    let run = |buf: &mut Vec<f64>, c: usize| {
        gram_block(buf, c * GRAM_BLOCK, ((c + 1) * GRAM_BLOCK).min(kh))
    };
    #[cfg(feature = "parallel")]
    let grams: Vec<Mat<f64>> = {
        use rayon::prelude::*;
        (0..nblocks)
            .into_par_iter()
            .map_init(Vec::new, run)
            .collect()
    };
    #[cfg(not(feature = "parallel"))]
    let grams: Vec<Mat<f64>> = {
        let mut buf = Vec::new();
        (0..nblocks).map(|c| run(&mut buf, c)).collect()
    };
    let mut m = Mat::<f64>::zeros(p, p);
    for g in &grams {
        m += g;
    }
    for sp in specs {
        give_cplx(sp);
    }
    give_real(w);
    // Mirror the lower triangle.
    Ok(Mat::from_fn(p, p, |a, b| m[(a.max(b), a.min(b))]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direct O(N²) double sum, the definition.
    fn direct(x: &[Vec<f64>], v: &[f64], max_lag: Option<usize>) -> Vec<Vec<f64>> {
        let n = v.len();
        let p = x.len();
        let r: Vec<f64> = (0..n)
            .map(|k| (0..n - k).map(|t| v[t] * v[t + k]).sum::<f64>() / n as f64)
            .collect();
        let mut m = vec![vec![0.0; p]; p];
        for a in 0..p {
            for b in 0..p {
                let mut acc = 0.0;
                for i in 0..n {
                    for j in 0..n {
                        let lag = i.abs_diff(j);
                        if max_lag.is_some_and(|k| lag > k) {
                            continue;
                        }
                        acc += x[a][i] * r[lag] * x[b][j];
                    }
                }
                m[a][b] = acc;
            }
        }
        m
    }

    #[test]
    fn fast_len_is_smooth_and_not_below() {
        for n in [1, 2, 7, 11, 13, 97, 1000, 1_999_999, 2_000_001] {
            let l = fast_len(n);
            assert!(l >= n);
            let mut r = l;
            for f in [2, 3, 5, 7] {
                while r % f == 0 {
                    r /= f;
                }
            }
            assert_eq!(r, 1, "{l}");
        }
        assert_eq!(fast_len(1_999_999), 2_000_000);
    }

    #[test]
    fn fft_gram_matches_double_sum() {
        let n = 53;
        let x: Vec<Vec<f64>> = (0..3)
            .map(|a| {
                (0..n)
                    .map(|i| ((i * (a + 2)) as f64 * 0.37).sin() + a as f64)
                    .collect()
            })
            .collect();
        let v: Vec<f64> = (0..n)
            .map(|i| ((i as f64) * 0.21).cos() * 0.3 + 0.01 * i as f64)
            .collect();
        for lag in [None, Some(0), Some(5), Some(60)] {
            let m = toeplitz_gram(3, |b, out| out.copy_from_slice(&x[b]), &v, lag).unwrap();
            let d = direct(&x, &v, lag);
            for a in 0..3 {
                for b in 0..3 {
                    let tol = 1e-11 * d[a][a].abs().max(d[b][b].abs());
                    assert!(
                        (m[(a, b)] - d[a][b]).abs() <= tol,
                        "{lag:?} {a} {b} {} {}",
                        m[(a, b)],
                        d[a][b]
                    );
                }
            }
        }
    }
}
