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
//! For long records with all lags the length-`L` transforms are split in
//! two cache-sized steps (four-step FFT, `L = L₁ L₂`) and the Gram product
//! is accumulated row by row of the spectra while they are in cache, so no
//! full spectrum is stored (`fourstep_gram`: same arithmetic, about 25%
//! less time at N = 10⁶ than transforms of the full length).
//! With a maximum lag `K`, `R_vv(k)` is set to zero for `|k| > K` (a
//! truncated, not tapered, estimate: `S` is then recomputed from the
//! truncated sequence and may have negative values).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

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

/// FFT plans cached by length, each made by a **fresh** planner.
///
/// rustfft's planner builds a transform from the inner transforms it has
/// already cached, so the decomposition chosen for a length (and the last
/// bits of its result) depended on which lengths the process-wide planner
/// had planned before; with bins fitted in parallel that order follows the
/// threads' timing, and `std_err_colored` differed in the last digit from run
/// to run (20 of the 300 fast lengths of the test below, 1,000 to 60,000,
/// gave other bits after a warmed planner). A plan made by a fresh planner
/// is a function of its length alone; the cache only saves the planning. It
/// is emptied when the cached lengths sum past [`PLAN_CACHE_MAX`] (results
/// do not depend on it).
struct PlanCache<V> {
    plans: BTreeMap<usize, V>,
    total_len: usize,
}

/// Largest sum of the cached transforms' lengths (about 16 bytes of twiddles
/// per unit of length and kind of plan).
const PLAN_CACHE_MAX: usize = 1 << 23;

impl<V: Clone> PlanCache<V> {
    const fn new() -> Self {
        PlanCache {
            plans: BTreeMap::new(),
            total_len: 0,
        }
    }

    fn get(&mut self, len: usize, make: impl FnOnce() -> V) -> V {
        if let Some(v) = self.plans.get(&len) {
            return v.clone();
        }
        if self.total_len + len > PLAN_CACHE_MAX {
            self.plans.clear();
            self.total_len = 0;
        }
        let v = make();
        self.plans.insert(len, v.clone());
        self.total_len += len;
        v
    }
}

type PlanMap<V> = Mutex<PlanCache<V>>;

fn locked<V>(m: &'static PlanMap<V>) -> std::sync::MutexGuard<'static, PlanCache<V>> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The forward (and, with `inverse`, the inverse) real transform of length
/// `l`, each made by a fresh planner ([`PlanCache`]).
fn plans(l: usize, inverse: bool) -> (Fwd, Option<Inv>) {
    static FWD: PlanMap<Fwd> = Mutex::new(PlanCache::new());
    static INV: PlanMap<Inv> = Mutex::new(PlanCache::new());
    let fwd = locked(&FWD).get(l, || RealFftPlanner::new().plan_fft_forward(l));
    let inv = inverse.then(|| locked(&INV).get(l, || RealFftPlanner::new().plan_fft_inverse(l)));
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
/// With all lags and at least `FOUR_STEP_MIN_N` (65 536) residuals the
/// transforms are factored in two cache-sized steps and the Gram product is
/// accumulated row by row of the spectra (`fourstep_gram`), so no
/// full-length spectrum is stored; otherwise (short records, truncated
/// lags) the `p + 1` padded transforms run as one parallel batch.
pub fn toeplitz_gram_cols(
    cols: Vec<Vec<f64>>,
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
    let truncate = max_lag.is_some_and(|k| k + 1 < n);
    if truncate || n < FOUR_STEP_MIN_N {
        return padded_gram(cols, v, max_lag);
    }
    let m = fourstep_gram(&cols, v, FOUR_STEP_L2);
    for c in cols {
        give_real(c);
    }
    m
}

/// [`toeplitz_gram_cols`] with one transform of length [`padded_len`]`(N)`
/// per series (checked arguments, `N > 0`, `p > 0`): the half spectra are
/// kept whole, then the Gram product reads them block by block.
fn padded_gram(mut cols: Vec<Vec<f64>>, v: &[f64], max_lag: Option<usize>) -> Result<Mat<f64>> {
    let n = v.len();
    let p = cols.len();
    let truncate = max_lag.is_some_and(|k| k + 1 < n);
    let l = padded_len(n);
    let kh = l / 2 + 1;
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

/// Row length `L₂` of the four-step transform ([`fourstep_gram`]): a row of
/// the 13 spectra (16 KiB each) stays in the L2 cache.
const FOUR_STEP_L2: usize = 1024;

/// Fewest residuals for which [`fourstep_gram`] is used (all lags only);
/// shorter records take the direct transforms.
const FOUR_STEP_MIN_N: usize = 1 << 16;

/// Columns `t₂` gathered together in the first step (one cache line of the
/// input per `t₁`).
const GROUP: usize = 32;

/// Smallest `2^a 3^b` with `a >= 1` not below `n`: the first-step length
/// of [`fourstep_gram`]. Radices 5 and 7 are left out: near 2000 a real
/// transform of length 1960 (2³·5·7²) costs 1.34 ns per point against 1.02
/// for 2016 or 2048 (rustfft 6.4, AVX2), more than the few percent of extra
/// length.
fn even_len_23(n: usize) -> usize {
    let mut best = n.max(2).next_power_of_two();
    let mut p3 = 1usize;
    while p3 < best {
        let mut v = 2 * p3;
        while v < n {
            v *= 2;
        }
        best = best.min(v);
        p3 *= 3;
    }
    best
}

/// Plans of the complex transforms of the second step, each made by a
/// fresh planner and cached by length ([`PlanCache`]).
fn cplx_plan(len: usize) -> Arc<dyn rustfft::Fft<f64>> {
    static PLANS: PlanMap<Arc<dyn rustfft::Fft<f64>>> = Mutex::new(PlanCache::new());
    locked(&PLANS).get(len, || rustfft::FftPlanner::new().plan_fft_forward(len))
}

/// The all-lag middle matrix `M` of [`toeplitz_gram_cols`] by a four-step
/// (Bailey) factorisation of the length-`L = L₁ L₂` transform, so that no
/// full spectrum is ever stored: with `t = L₂ t₁ + t₂` and
/// `k = k₁ + L₁ k₂`,
///
/// ```text
/// X[k₁ + L₁ k₂] = Σ_{t₂} ω_{L₂}^{t₂ k₂} · ω_L^{t₂ k₁} · Σ_{t₁} x[L₂ t₁ + t₂] ω_{L₁}^{t₁ k₁}
/// ```
///
/// (`ω_n = e^{-2πi/n}`). Step 1: for every `t₂`, a real length-`L₁`
/// transform over `t₁` (only `k₁ <= L₁/2` is kept: the input is real), times
/// the twiddle `ω_L^{t₂ k₁}`. Step 2: for every `k₁`, a complex length-`L₂`
/// transform over `t₂` gives the bins `k₁ + L₁ k₂` of every column and of
/// the residuals at once, and their Parseval contribution
/// `Σ_k S[k] conj(X_a[k]) X_b[k]` (module docs) is added while they are in
/// cache. Rows `k₁` and `L₁ − k₁` hold conjugate bins (`L − k`), so rows
/// `0 < k₁ < L₁/2` count twice and rows `0`, `L₁/2` once (their imaginary
/// parts cancel in pairs within the row). `S = |V|²/N >= 0`, so the weighted
/// Gram is `AᵀA` with `A` the real and imaginary parts scaled by `√S`.
///
/// `l2` must be a multiple of [`GROUP`]; `L₁` is the smallest even
/// `2^a 3^b` with `L₁ L₂ >= 2N − 1` ([`even_len_23`]).
fn fourstep_gram(cols: &[Vec<f64>], v: &[f64], l2: usize) -> Result<Mat<f64>> {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    use faer::MatRef;

    let n = v.len();
    let p = cols.len();
    let need = (2 * n).saturating_sub(1).max(1).div_ceil(l2);
    let l1 = even_len_23(need);
    let l = l1 * l2;
    let kh1 = l1 / 2 + 1;
    // Row stride of the first-step inputs: one cache line more than L₁, so
    // the GROUP rows written together do not share cache sets when L₁ is a
    // power of two.
    let ld1 = l1 + 8;
    let groups = l2 / GROUP;
    let (r2c, _) = plans(l1, false);
    let c2c = cplx_plan(l2);

    // Twiddles ω_L^e for e < L as lo[e mod 1024] · hi[e / 1024].
    let tw = |e: usize| {
        let a = -2.0 * std::f64::consts::PI * e as f64 / l as f64;
        Complex::new(a.cos(), a.sin())
    };
    let lo: Vec<Complex<f64>> = (0..1024).map(tw).collect();
    let hi: Vec<Complex<f64>> = (0..l.div_ceil(1024) + 1).map(|h| tw(h * 1024)).collect();

    // Step 1. `mid[c]` holds, for group g of GROUP consecutive t₂, the
    // block [k₁][j] (t₂ = GROUP g + j) of twiddled half spectra.
    let series = |c: usize| -> &[f64] {
        if c == p {
            v
        } else {
            &cols[c][..n]
        }
    };
    let mut mid: Vec<Vec<Complex<f64>>> =
        (0..=p).map(|_| take_cplx(groups * kh1 * GROUP)).collect();
    struct Step1 {
        inp: Vec<f64>,
        out: Vec<Complex<f64>>,
        scratch: Scratch,
    }
    let new_step1 = || Step1 {
        inp: vec![0.0; ld1 * GROUP],
        out: vec![Complex::new(0.0, 0.0); kh1 * GROUP],
        scratch: Scratch(take_cplx(r2c.get_scratch_len())),
    };
    let step1 = |w: &mut Step1, c: usize, g: usize, dst: &mut [Complex<f64>]| -> Result<()> {
        let x = series(c);
        let t0 = g * GROUP;
        // Gather: input j is x[L₂ t₁ + t₀ + j], zero where that is >= N.
        let full = if n >= t0 + GROUP {
            (n - t0 - GROUP) / l2 + 1
        } else {
            0
        };
        let full = full.min(l1);
        for t1 in 0..full {
            let s = l2 * t1 + t0;
            let xs = &x[s..s + GROUP];
            for (j, &val) in xs.iter().enumerate() {
                w.inp[j * ld1 + t1] = val;
            }
        }
        for t1 in full..l1 {
            let s = l2 * t1 + t0;
            for j in 0..GROUP {
                w.inp[j * ld1 + t1] = x.get(s + j).copied().unwrap_or(0.0);
            }
        }
        for (inp, out) in w.inp.chunks_exact_mut(ld1).zip(w.out.chunks_exact_mut(kh1)) {
            let inp = &mut inp[..l1];
            r2c.process_with_scratch(inp, out, &mut w.scratch.0)
                .map_err(fft_err)?;
        }
        for (k1, d) in dst.chunks_exact_mut(GROUP).enumerate() {
            for (j, dj) in d.iter_mut().enumerate() {
                *dj = w.out[j * kh1 + k1];
            }
        }
        Ok(())
    };
    {
        let mut tasks: Vec<(usize, usize, &mut [Complex<f64>])> =
            Vec::with_capacity((p + 1) * groups);
        for (c, m) in mid.iter_mut().enumerate() {
            for (g, chunk) in m.chunks_exact_mut(kh1 * GROUP).enumerate() {
                tasks.push((c, g, chunk));
            }
        }
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            tasks
                .into_par_iter()
                .try_for_each_init(new_step1, |w, (c, g, dst)| step1(w, c, g, dst))?;
        }
        #[cfg(not(feature = "parallel"))]
        {
            let mut w = new_step1();
            for (c, g, dst) in tasks {
                step1(&mut w, c, g, dst)?;
            }
        }
    }

    // Step 2, row k₁: transforms over t₂, weights, block Gram.
    let scale = 1.0 / (n as f64 * l as f64);
    struct Step2 {
        row: Vec<Complex<f64>>,
        tw: Vec<Complex<f64>>,
        sw: Vec<f64>,
        lhs: Vec<f64>,
        scratch: Vec<Complex<f64>>,
    }
    let new_step2 = || Step2 {
        row: vec![Complex::new(0.0, 0.0); l2],
        tw: vec![Complex::new(0.0, 0.0); l2],
        sw: vec![0.0; l2],
        lhs: vec![0.0; 2 * l2 * p],
        scratch: vec![Complex::new(0.0, 0.0); c2c.get_inplace_scratch_len()],
    };
    let step2 = |w: &mut Step2, k1: usize| -> Mat<f64> {
        let gather = |row: &mut [Complex<f64>], m: &[Complex<f64>]| {
            for (g, r) in row.chunks_exact_mut(GROUP).enumerate() {
                let at = (g * kh1 + k1) * GROUP;
                r.copy_from_slice(&m[at..at + GROUP]);
            }
        };
        // Row k₁ of one series, times the twiddles.
        let gather = |row: &mut [Complex<f64>], tw: &[Complex<f64>], m: &[Complex<f64>]| {
            gather(row, m);
            for (r, t) in row.iter_mut().zip(tw) {
                *r *= t;
            }
        };
        // Twiddles ω_L^{t₂ k₁} of this row.
        for (t2, t) in w.tw.iter_mut().enumerate() {
            let e = t2 * k1;
            *t = lo[e % 1024] * hi[e / 1024];
        }
        gather(&mut w.row, &w.tw, &mid[p]);
        c2c.process_with_scratch(&mut w.row, &mut w.scratch);
        let twice = if k1 == 0 || 2 * k1 == l1 { 1.0 } else { 2.0 };
        for (s, c) in w.sw.iter_mut().zip(&w.row) {
            *s = (c.norm_sqr() * scale * twice).sqrt();
        }
        for (b, col) in w.lhs.chunks_exact_mut(2 * l2).enumerate() {
            gather(&mut w.row, &w.tw, &mid[b]);
            c2c.process_with_scratch(&mut w.row, &mut w.scratch);
            let (re, im) = col.split_at_mut(l2);
            for (((r, i), c), f) in re.iter_mut().zip(im.iter_mut()).zip(&w.row).zip(&w.sw) {
                *r = c.re * f;
                *i = c.im * f;
            }
        }
        let a = MatRef::from_column_major_slice(&w.lhs, 2 * l2, p);
        let mut g = Mat::<f64>::zeros(p, p);
        matmul(
            g.as_mut(),
            BlockStructure::TriangularLower,
            faer::Accum::Replace,
            a.transpose(),
            BlockStructure::Rectangular,
            a,
            BlockStructure::Rectangular,
            1.0,
            faer::Par::Seq,
        );
        g
    };
    #[cfg(feature = "parallel")]
    let grams: Vec<Mat<f64>> = {
        use rayon::prelude::*;
        (0..kh1)
            .into_par_iter()
            .map_init(new_step2, step2)
            .collect()
    };
    #[cfg(not(feature = "parallel"))]
    let grams: Vec<Mat<f64>> = {
        let mut w = new_step2();
        (0..kh1).map(|k1| step2(&mut w, k1)).collect()
    };
    for m in mid {
        give_cplx(m);
    }
    let mut m = Mat::<f64>::zeros(p, p);
    for g in &grams {
        m += g;
    }
    Ok(Mat::from_fn(p, p, |a, b| m[(a.max(b), a.min(b))]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plan depends on its length only, not on what was planned before:
    /// after the cache has planned other lengths (longest first, and their
    /// doubles, which rustfft's planner would reuse as inner transforms), the
    /// transform of every length has the bits of a fresh planner's. With the
    /// process-wide planner this code had, 20 of these 300 lengths differed.
    #[test]
    fn plans_do_not_depend_on_what_was_planned_before() {
        let lens: Vec<usize> = (0..300).map(|i| padded_len(500 + i * 97)).collect();
        for &l in lens.iter().rev() {
            plans(l * 2, true);
            plans(l, false);
        }
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
        };
        let mut differ = Vec::new();
        for &l in &lens {
            let x: Vec<f64> = (0..l).map(|_| next()).collect();
            let run = |f: Fwd| {
                let mut b = x.clone();
                let mut o = vec![Complex::new(0.0, 0.0); l / 2 + 1];
                f.process(&mut b, &mut o).expect("fft");
                o
            };
            let cached = run(plans(l, false).0);
            let fresh = run(RealFftPlanner::new().plan_fft_forward(l));
            if cached != fresh {
                differ.push(l);
            }
        }
        assert!(differ.is_empty(), "lengths planned differently: {differ:?}");
    }

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
    fn even_len_23_is_smallest() {
        for n in 0..3000 {
            let l = even_len_23(n);
            let smooth = |mut r: usize| {
                if r % 2 != 0 {
                    return false;
                }
                for f in [2, 3] {
                    while r % f == 0 {
                        r /= f;
                    }
                }
                r == 1
            };
            assert!(l >= n.max(2) && smooth(l), "{n} {l}");
            assert!((n.max(2)..l).all(|m| !smooth(m)), "{n} {l}");
        }
        assert_eq!(even_len_23(1954), 2048);
        assert_eq!(even_len_23(5), 6);
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

    fn series(p: usize, n: usize) -> (Vec<Vec<f64>>, Vec<f64>) {
        let x: Vec<Vec<f64>> = (0..p)
            .map(|a| {
                (0..n)
                    .map(|i| ((i * (a + 2)) as f64 * 0.37).sin() + a as f64)
                    .collect()
            })
            .collect();
        let v: Vec<f64> = (0..n)
            .map(|i| ((i as f64) * 0.21).cos() * 0.3 + 0.01 * (i % 17) as f64)
            .collect();
        (x, v)
    }

    /// The four-step evaluation against the definition (`L₂ = 64`; `L₁` = 2,
    /// 4, 6 and 12).
    #[test]
    fn four_step_matches_double_sum() {
        for n in [53, 100, 150, 300] {
            let (x, v) = series(3, n);
            let m = fourstep_gram(&x, &v, 2 * GROUP).unwrap();
            let d = direct(&x, &v, None);
            for a in 0..3 {
                for b in 0..3 {
                    let tol = 1e-11 * d[a][a].abs().max(d[b][b].abs());
                    assert!(
                        (m[(a, b)] - d[a][b]).abs() <= tol,
                        "{n} {a} {b} {} {}",
                        m[(a, b)],
                        d[a][b]
                    );
                }
            }
        }
    }

    /// Above the four-step threshold the dispatcher agrees with the padded
    /// transforms (which match the definition above).
    #[test]
    fn four_step_matches_padded_transforms_on_a_long_record() {
        let n = FOUR_STEP_MIN_N + 123;
        let (x, v) = series(4, n);
        let m = toeplitz_gram(4, |b, out| out.copy_from_slice(&x[b]), &v, None).unwrap();
        let r = padded_gram(x.clone(), &v, None).unwrap();
        for a in 0..4 {
            for b in 0..4 {
                let tol = 1e-11 * r[(a, a)].abs().max(r[(b, b)].abs());
                assert!((m[(a, b)] - r[(a, b)]).abs() <= tol, "{a} {b}");
            }
        }
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
