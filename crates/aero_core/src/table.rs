//! Gridded N-D lookup tables (1 to [`MAX_DIMS`] dimensions) with multilinear
//! interpolation, as flight simulators store aerodynamic databases.
//!
//! Breakpoints are strictly increasing per axis; values are stored row-major,
//! the last axis fastest (the DAVE-ML `griddedTableDef` order). Along each axis
//! and on each side, an input outside the breakpoints either *holds* the end
//! value (the default, as qualified simulator models do, thesis Section 3.4) or
//! is *extrapolated linearly* from the end segment. Optional input limits
//! (min/max) clamp the input before anything else, as DAVE-ML's
//! `independentVarRef min/max` do.
//!
//! For a point $x$ with bracketing breakpoints $x_i \le x \le x_{i+1}$ on each
//! axis, the fraction is $f = (x - x_i)/(x_{i+1}-x_i)$ and the value is the
//! tensor product of 1-D linear interpolations,
//! $$ y = \sum_{c \in \{0,1\}^n} \prod_k \big((1-f_k)^{1-c_k} f_k^{c_k}\big)\, v_{i+c}, $$
//! computed as $2^n - 1$ lerps of the form $(1-f)a + fb$, which returns the node
//! value exactly at a node.
//!
//! A NaN input gives a NaN output; nothing here panics on user data.

use crate::error::{AeroError, Result};
use std::sync::Arc;

/// The largest number of table dimensions.
pub const MAX_DIMS: usize = 8;

/// What an axis does with an input beyond its end breakpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Extrapolation {
    /// Hold the end value (qualified simulator models; DAVE-ML `extrapolate="neither"`).
    #[default]
    Hold,
    /// Continue the end segment's slope.
    Linear,
}

impl std::str::FromStr for Extrapolation {
    type Err = AeroError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "hold" => Ok(Extrapolation::Hold),
            "linear" => Ok(Extrapolation::Linear),
            other => Err(AeroError::invalid(
                "extrapolation",
                format!("unknown policy '{other}'; valid values are 'hold' and 'linear'"),
            )),
        }
    }
}

/// One axis of a table: its breakpoints and its out-of-range policy.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Name of the independent variable (for messages and exports).
    pub name: String,
    /// Shared between clones: many tables of a DAVE-ML file use one
    /// breakpoint set.
    breakpoints: Arc<Vec<f64>>,
    /// Policy below the first breakpoint.
    pub below: Extrapolation,
    /// Policy above the last breakpoint.
    pub above: Extrapolation,
    /// Lower input limit applied before interpolation, if any.
    pub min: Option<f64>,
    /// Upper input limit applied before interpolation, if any.
    pub max: Option<f64>,
    /// `(first breakpoint, 1/spacing)` when the breakpoints are uniformly
    /// spaced: the segment index is then computed, not searched.
    uniform: Option<(f64, f64)>,
}

impl Axis {
    /// An axis with strictly increasing, finite breakpoints, holding at both ends.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the axis and the offending index when
    /// the breakpoints are empty, not finite or not strictly increasing.
    pub fn new(name: impl Into<String>, breakpoints: Vec<f64>) -> Result<Self> {
        let name = name.into();
        if breakpoints.is_empty() {
            return Err(AeroError::invalid(
                format!("axis '{name}'"),
                "has no breakpoints; give at least one",
            ));
        }
        for (i, b) in breakpoints.iter().enumerate() {
            if !b.is_finite() {
                return Err(AeroError::invalid(
                    format!("axis '{name}', breakpoint {i}"),
                    format!("is {b}; breakpoints must be finite"),
                ));
            }
            if i > 0 && *b <= breakpoints[i - 1] {
                return Err(AeroError::invalid(
                    format!("axis '{name}', breakpoint {i}"),
                    format!(
                        "{b} does not exceed breakpoint {} ({}); breakpoints must be strictly increasing",
                        i - 1,
                        breakpoints[i - 1]
                    ),
                ));
            }
        }
        let uniform = uniform_spacing(&breakpoints);
        Ok(Axis {
            name,
            breakpoints: Arc::new(breakpoints),
            below: Extrapolation::Hold,
            above: Extrapolation::Hold,
            min: None,
            max: None,
            uniform,
        })
    }

    /// Set the policy on both sides.
    pub fn with_extrapolation(mut self, below: Extrapolation, above: Extrapolation) -> Self {
        self.below = below;
        self.above = above;
        self
    }

    /// Set input limits applied before interpolation (`None` for no limit).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when `min > max` or a limit is NaN.
    pub fn with_limits(mut self, min: Option<f64>, max: Option<f64>) -> Result<Self> {
        if min.is_some_and(f64::is_nan) || max.is_some_and(f64::is_nan) {
            return Err(AeroError::invalid(
                format!("axis '{}'", self.name),
                "input limits must not be NaN",
            ));
        }
        if let (Some(lo), Some(hi)) = (min, max) {
            if lo > hi {
                return Err(AeroError::invalid(
                    format!("axis '{}'", self.name),
                    format!("lower limit {lo} exceeds upper limit {hi}"),
                ));
            }
        }
        self.min = min;
        self.max = max;
        Ok(self)
    }

    /// The breakpoints.
    pub fn breakpoints(&self) -> &[f64] {
        &self.breakpoints
    }

    /// Index `i` of the segment and fraction `f` for input `x`, so that the
    /// value is `(1-f) v[i] + f v[i+1]`. For a single-breakpoint axis `i = 0`,
    /// `f = 0`. Returns `None` for NaN.
    #[inline(always)]
    pub fn locate(&self, x: f64) -> Option<(usize, f64)> {
        if x.is_nan() {
            return None;
        }
        // Input limits first (no limit is an infinite one).
        let x = clamp_to(
            x,
            self.min.unwrap_or(f64::NEG_INFINITY),
            self.max.unwrap_or(f64::INFINITY),
        );
        let bp = &self.breakpoints;
        let n = bp.len();
        if n == 1 {
            return Some((0, 0.0));
        }
        // The segment of the input clamped into the breakpoints' range ...
        let i = self.segment(clamp_to(x, bp[0], bp[n - 1]));
        // ... and the fraction of the unclamped input: inside the range it lies
        // in [0, 1] (exactly 0 or 1 at nodes); outside, holding clamps it to the
        // end node and linear extrapolation keeps it.
        let f = (x - bp[i]) / (bp[i + 1] - bp[i]);
        let lo = if self.below == Extrapolation::Hold {
            0.0
        } else {
            f64::NEG_INFINITY
        };
        let hi = if self.above == Extrapolation::Hold {
            1.0
        } else {
            f64::INFINITY
        };
        Some((i, clamp_to(f, lo, hi)))
    }

    /// The last segment index `i <= n-2` with `bp[i] <= x`, for `x` within
    /// the breakpoints' range.
    #[inline(always)]
    fn segment(&self, x: f64) -> usize {
        let bp = &self.breakpoints;
        let n = bp.len();
        match self.uniform {
            Some((x0, inv_h)) => {
                // Computed guess, then an exact fix-up against the breakpoints,
                // so the result is the same as the search's.
                let mut i = (((x - x0) * inv_h) as usize).min(n - 2);
                while i > 0 && bp[i] > x {
                    i -= 1;
                }
                while i + 2 < n && bp[i + 1] <= x {
                    i += 1;
                }
                i
            }
            None => {
                // Branchless binary search (conditional moves, no mispredictions
                // on random inputs): invariant bp[base] <= x.
                let mut base = 0usize;
                let mut len = n - 1;
                while len > 1 {
                    let half = len / 2;
                    if bp[base + half] <= x {
                        base += half;
                    }
                    len -= half;
                }
                base
            }
        }
    }
}

/// `x` clamped to `[lo, hi]` by two comparisons (one `min`/`max` instruction
/// each; `x` is never NaN here, so no NaN handling is needed).
#[inline(always)]
fn clamp_to(x: f64, lo: f64, hi: f64) -> f64 {
    let x = if x < lo { lo } else { x };
    if x > hi {
        hi
    } else {
        x
    }
}

/// `(x0, 1/h)` when `bp` is uniformly spaced to within 1e-9 of the spacing.
fn uniform_spacing(bp: &[f64]) -> Option<(f64, f64)> {
    let n = bp.len();
    if n < 3 {
        return None;
    }
    let h = (bp[n - 1] - bp[0]) / (n - 1) as f64;
    let uniform = bp
        .iter()
        .enumerate()
        .all(|(i, &b)| (b - (bp[0] + i as f64 * h)).abs() <= 1e-9 * h);
    uniform.then_some((bp[0], 1.0 / h))
}

/// A gridded table of 1 to [`MAX_DIMS`] dimensions.
///
/// ```
/// use aero_core::table::{Axis, Table};
/// let t = Table::new(
///     vec![Axis::new("alpha", vec![0.0, 10.0]).unwrap(), Axis::new("beta", vec![-5.0, 5.0]).unwrap()],
///     vec![0.0, 1.0, 2.0, 3.0],
/// ).unwrap();
/// // bilinear: at the centre the mean of the four corners
/// assert!((t.eval(&[5.0, 0.0]) - 1.5).abs() < 1e-15);
/// // holds beyond the ends by default
/// assert_eq!(t.eval(&[20.0, 5.0]), 3.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    axes: Vec<Axis>,
    /// Shared between clones and between the tables of a DAVE-ML file that
    /// reference one `griddedTableDef`.
    values: Arc<Vec<f64>>,
    strides: [usize; MAX_DIMS],
    /// Offset of each of the 2^n cell corners from the cell's first node
    /// (bit n-1-k of the corner index selects the upper node on axis k).
    corner_offsets: Vec<usize>,
}

impl Table {
    /// Build a table from its axes and its values (row-major, last axis fastest).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when there are no axes or more than
    /// [`MAX_DIMS`], or when the number of values differs from the product of
    /// the breakpoint counts (the message gives both).
    pub fn new(axes: Vec<Axis>, values: Vec<f64>) -> Result<Self> {
        Self::from_shared(axes, Arc::new(values))
    }

    /// [`Table::new`] with values shared with other tables (no copy).
    ///
    /// # Errors
    /// As [`Table::new`].
    pub fn from_shared(axes: Vec<Axis>, values: Arc<Vec<f64>>) -> Result<Self> {
        if axes.is_empty() || axes.len() > MAX_DIMS {
            return Err(AeroError::invalid(
                "table",
                format!("has {} axes; a table has 1 to {MAX_DIMS} axes", axes.len()),
            ));
        }
        let expected = axes
            .iter()
            .try_fold(1usize, |p, a| p.checked_mul(a.breakpoints.len()));
        if expected != Some(values.len()) {
            let shape: Vec<String> = axes
                .iter()
                .map(|a| format!("{}:{}", crate::text::shown(&a.name), a.breakpoints.len()))
                .collect();
            let need =
                expected.map_or_else(|| "more than memory can hold".into(), |n| n.to_string());
            return Err(AeroError::invalid(
                "table",
                format!(
                    "has {} values but its breakpoints ({}) need {need}",
                    values.len(),
                    shape.join(" x ")
                ),
            ));
        }
        let mut strides = [0usize; MAX_DIMS];
        let mut s = 1usize;
        for k in (0..axes.len()).rev() {
            strides[k] = s;
            s *= axes[k].breakpoints.len();
        }
        let n = axes.len();
        let corner_offsets = (0..1usize << n)
            .map(|c| {
                (0..n)
                    .filter(|&k| (c >> (n - 1 - k)) & 1 == 1 && axes[k].breakpoints.len() > 1)
                    .map(|k| strides[k])
                    .sum()
            })
            .collect();
        Ok(Table {
            axes,
            values,
            strides,
            corner_offsets,
        })
    }

    /// Number of dimensions.
    pub fn ndim(&self) -> usize {
        self.axes.len()
    }

    /// The axes.
    pub fn axes(&self) -> &[Axis] {
        &self.axes
    }

    /// Mutable access to the axes' policies and limits (breakpoints stay fixed).
    pub fn axis_mut(&mut self, k: usize) -> Option<&mut Axis> {
        self.axes.get_mut(k)
    }

    /// The values, row-major with the last axis fastest.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Shape: breakpoints per axis.
    pub fn shape(&self) -> Vec<usize> {
        self.axes.iter().map(|a| a.breakpoints.len()).collect()
    }

    /// Evaluate at one point without allocating: the real-time path.
    ///
    /// `x` must hold one value per axis; a wrong length or any NaN gives NaN.
    #[inline]
    pub fn eval(&self, x: &[f64]) -> f64 {
        if x.len() != self.axes.len() {
            return f64::NAN;
        }
        // Dispatch on the dimension so the corner buffer is exactly 2^n long.
        match x.len() {
            1 => self.eval_n::<1, 2>(x),
            2 => self.eval_n::<2, 4>(x),
            3 => self.eval_n::<3, 8>(x),
            4 => self.eval_n::<4, 16>(x),
            5 => self.eval_n::<5, 32>(x),
            6 => self.eval_n::<6, 64>(x),
            7 => self.eval_n::<7, 128>(x),
            8 => self.eval_n::<8, 256>(x),
            _ => f64::NAN,
        }
    }

    /// Multilinear interpolation in `N` dimensions with `M = 2^N` corners.
    #[inline(always)]
    fn eval_n<const N: usize, const M: usize>(&self, x: &[f64]) -> f64 {
        let mut base = 0usize;
        let mut frac = [0.0f64; N];
        for k in 0..N {
            let Some((i, f)) = self.axes[k].locate(x[k]) else {
                return f64::NAN;
            };
            base += i * self.strides[k];
            frac[k] = f;
        }
        // Gather the 2^N corners, then reduce axis by axis, last axis first.
        let mut corners = [0.0f64; M];
        for (slot, off) in corners.iter_mut().zip(&self.corner_offsets) {
            *slot = self.values[base + off];
        }
        let mut len = M;
        for k in (0..N).rev() {
            let f = frac[k];
            let g = 1.0 - f;
            len /= 2;
            for j in 0..len {
                corners[j] = g * corners[2 * j] + f * corners[2 * j + 1];
            }
        }
        corners[0]
    }

    /// Evaluate at many points given as one column per axis, writing into `out`.
    ///
    /// Runs in parallel over chunks of points with the `parallel` feature; the
    /// result is identical to calling [`Table::eval`] on each point.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when the number of columns differs from the
    /// number of axes or the columns and `out` differ in length.
    pub fn eval_columns(&self, columns: &[&[f64]], out: &mut [f64]) -> Result<()> {
        let n = self.ndim();
        if columns.len() != n {
            return Err(AeroError::invalid(
                "table lookup",
                format!("got {} input columns for a {n}-D table", columns.len()),
            ));
        }
        for (k, c) in columns.iter().enumerate() {
            if c.len() != out.len() {
                return Err(AeroError::invalid(
                    format!("table lookup, column {k} ('{}')", self.axes[k].name),
                    format!("has {} points but the output has {}", c.len(), out.len()),
                ));
            }
        }
        let work = |start: usize, chunk: &mut [f64]| {
            // One dispatch on the dimension per chunk, then column-wise blocks.
            match n {
                1 => self.eval_chunk::<1, 2>(Source::Columns(columns), start, chunk),
                2 => self.eval_chunk::<2, 4>(Source::Columns(columns), start, chunk),
                3 => self.eval_chunk::<3, 8>(Source::Columns(columns), start, chunk),
                4 => self.eval_chunk::<4, 16>(Source::Columns(columns), start, chunk),
                5 => self.eval_chunk::<5, 32>(Source::Columns(columns), start, chunk),
                6 => self.eval_chunk::<6, 64>(Source::Columns(columns), start, chunk),
                7 => self.eval_chunk::<7, 128>(Source::Columns(columns), start, chunk),
                _ => self.eval_chunk::<8, 256>(Source::Columns(columns), start, chunk),
            }
        };
        run_chunks(out, work);
        Ok(())
    }

    /// Evaluate the points of `src` from row `start` on into `out`, block by
    /// block: every axis is located for all points of a block first (one tight
    /// loop per axis, its constants hoisted), then the corners are gathered and
    /// reduced. Same operations, in the same order, as [`Table::eval`], so the
    /// results are bit-identical.
    fn eval_chunk<const N: usize, const M: usize>(
        &self,
        src: Source<'_>,
        start: usize,
        out: &mut [f64],
    ) {
        let kernels: [AxisKernel<'_>; N] =
            std::array::from_fn(|k| AxisKernel::new(&self.axes[k], self.strides[k], k == 0));
        let mut offsets = [0usize; M];
        for (o, &c) in offsets.iter_mut().zip(&self.corner_offsets) {
            *o = c;
        }
        let span = offsets.iter().copied().max().unwrap_or(0);
        #[cfg(target_arch = "x86_64")]
        let simd = avx2::available(&self.axes, self.values.len());
        let mut base = [0usize; BLOCK];
        let mut nan = [false; BLOCK];
        let mut frac = [[0.0f64; BLOCK]; N];
        let mut rows = [[0.0f64; BLOCK]; N];
        for (b, o) in out.chunks_mut(BLOCK).enumerate() {
            let s0 = start + b * BLOCK;
            let len = o.len();
            if let Source::Rows(pts) = src {
                // transpose the block's rows once into per-axis buffers
                let blk = &pts[s0 * N..(s0 + len) * N];
                #[cfg(target_arch = "x86_64")]
                let transposed = simd && N == 4 && {
                    avx2::transpose4(blk, &mut rows);
                    true
                };
                #[cfg(not(target_arch = "x86_64"))]
                let transposed = false;
                if !transposed {
                    for (j, r) in blk.chunks_exact(N).enumerate() {
                        for (col, &x) in rows.iter_mut().zip(r) {
                            col[j] = x;
                        }
                    }
                }
            }
            for (k, kern) in kernels.iter().enumerate() {
                let xs: &[f64] = match src {
                    Source::Columns(cols) => &cols[k][s0..s0 + len],
                    Source::Rows(_) => &rows[k][..len],
                };
                let (bs, fs, ns) = (&mut base[..len], &mut frac[k][..len], &mut nan[..len]);
                #[cfg(target_arch = "x86_64")]
                if simd && kern.bp.len() >= 2 {
                    avx2::locate(kern, xs, bs, fs, ns);
                    continue;
                }
                kern.locate_block(xs, bs, fs, ns);
            }
            #[cfg(target_arch = "x86_64")]
            if simd {
                avx2::reduce::<N, M>(&self.values, &offsets, &base[..len], &frac, &nan[..len], o);
                continue;
            }
            for (j, o) in o.iter_mut().enumerate() {
                *o = block_point(
                    &self.values,
                    span,
                    &offsets,
                    &base[..len],
                    &frac,
                    &nan[..len],
                    j,
                );
            }
        }
    }

    /// Evaluate at many points given row-major as an `(npoints, ndim)` array.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when `points.len()` is not `out.len() * ndim`.
    pub fn eval_rows(&self, points: &[f64], out: &mut [f64]) -> Result<()> {
        let n = self.ndim();
        if points.len() != out.len() * n {
            return Err(AeroError::invalid(
                "table lookup",
                format!(
                    "points hold {} values, not {} points x {n} axes",
                    points.len(),
                    out.len()
                ),
            ));
        }
        let work = |start: usize, chunk: &mut [f64]| {
            let src = Source::Rows(points);
            match n {
                1 => self.eval_chunk::<1, 2>(src, start, chunk),
                2 => self.eval_chunk::<2, 4>(src, start, chunk),
                3 => self.eval_chunk::<3, 8>(src, start, chunk),
                4 => self.eval_chunk::<4, 16>(src, start, chunk),
                5 => self.eval_chunk::<5, 32>(src, start, chunk),
                6 => self.eval_chunk::<6, 64>(src, start, chunk),
                7 => self.eval_chunk::<7, 128>(src, start, chunk),
                _ => self.eval_chunk::<8, 256>(src, start, chunk),
            }
        };
        run_chunks(out, work);
        Ok(())
    }
}

/// AVX2 versions of the batch locate and of the gather-and-reduce, chosen at
/// run time when the CPU has AVX2. Same operations in the same order as the
/// scalar path (compare-based clamps map to `max_pd`/`min_pd` operand for
/// operand, no fused multiply-adds), so results are bit-identical; lanes a
/// computed index guess cannot settle in one step each way (never for truly
/// uniform axes) and NaN inputs take the scalar path.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod avx2 {
    use super::{Axis, AxisKernel, BLOCK};
    use std::arch::x86_64::*;

    /// Whether the AVX2 path can run: CPU support, and every index and stride
    /// fits 32 bits (breakpoint gathers, 32x32-bit offset products).
    pub(super) fn available(axes: &[Axis], nvalues: usize) -> bool {
        std::arch::is_x86_feature_detected!("avx2")
            && nvalues < (1usize << 32)
            && axes.iter().all(|a| a.breakpoints.len() < (1usize << 30))
    }

    /// 4 lanes of 64-bit compare masks → 4 lanes of 32-bit masks.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn narrow(m: __m256d) -> __m128i {
        let idx = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(_mm256_castpd_si256(m), idx))
    }

    /// Locate a block of inputs on one axis (its breakpoints: at least 2).
    pub(super) fn locate(
        k: &AxisKernel<'_>,
        xs: &[f64],
        base: &mut [usize],
        frac: &mut [f64],
        nan: &mut [bool],
    ) {
        // SAFETY: `available` checked AVX2 support before this path was chosen.
        unsafe { locate_avx2(k, xs, base, frac, nan) }
    }

    #[target_feature(enable = "avx2")]
    fn locate_avx2(
        k: &AxisKernel<'_>,
        xs: &[f64],
        base: &mut [usize],
        frac: &mut [f64],
        nan: &mut [bool],
    ) {
        let bp = k.bp;
        let n = bp.len();
        let len = xs
            .len()
            .min(base.len())
            .min(frac.len())
            .min(nan.len())
            .min(BLOCK);
        let (lo, hi) = (_mm256_set1_pd(k.min), _mm256_set1_pd(k.max));
        let (b0, bn) = (_mm256_set1_pd(bp[0]), _mm256_set1_pd(bp[n - 1]));
        let (flo, fhi) = (_mm256_set1_pd(k.flo), _mm256_set1_pd(k.fhi));
        let zero = _mm_setzero_si128();
        let nm2 = _mm_set1_epi32((n - 2) as i32);
        let stride = _mm256_set1_epi64x(k.stride as i64);
        let p0 = bp.as_ptr();
        let mut j = 0;
        while j + 4 <= len {
            // SAFETY: 4 lanes from a 4-element subslice.
            let x = unsafe { _mm256_loadu_pd(xs[j..j + 4].as_ptr()) };
            // clamp_to(x, lo, hi): (x < lo ? lo : x) = max_pd(lo, x), then min_pd(hi, ·)
            let x1 = _mm256_min_pd(hi, _mm256_max_pd(lo, x));
            let xc = _mm256_min_pd(bn, _mm256_max_pd(b0, x1));
            let mut i;
            // SAFETY (gathers below): every index is clamped to [0, n-2], so
            // `i` and `i + 1` address breakpoints inside `bp`.
            match k.uniform {
                Some((x0, inv_h)) => {
                    // the computed guess; lanes it does not settle take the scalar fix-up
                    let t =
                        _mm256_mul_pd(_mm256_sub_pd(xc, _mm256_set1_pd(x0)), _mm256_set1_pd(inv_h));
                    i = _mm_min_epi32(_mm_max_epi32(_mm256_cvttpd_epi32(t), zero), nm2);
                }
                None => {
                    i = zero;
                    let mut l = n - 1;
                    while l > 1 {
                        let half = l / 2;
                        let h = _mm_set1_epi32(half as i32);
                        let v = unsafe { _mm256_i32gather_pd::<8>(p0, _mm_add_epi32(i, h)) };
                        let m = narrow(_mm256_cmp_pd::<_CMP_LE_OQ>(v, xc));
                        i = _mm_add_epi32(i, _mm_and_si128(m, h));
                        l -= half;
                    }
                }
            }
            let a = unsafe { _mm256_i32gather_pd::<8>(p0, i) };
            let b = unsafe { _mm256_i32gather_pd::<8>(p0.add(1), i) };
            // settled: (i == 0 or bp[i] <= xc) and (i == n-2 or bp[i+1] > xc); NaN never
            let ok_lo = _mm_or_si128(
                _mm_cmpeq_epi32(i, zero),
                narrow(_mm256_cmp_pd::<_CMP_LE_OQ>(a, xc)),
            );
            let ok_hi = _mm_or_si128(
                _mm_cmpeq_epi32(i, nm2),
                narrow(_mm256_cmp_pd::<_CMP_GT_OQ>(b, xc)),
            );
            let ok = _mm_movemask_ps(_mm_castsi128_ps(_mm_and_si128(ok_lo, ok_hi)));
            let f = _mm256_div_pd(_mm256_sub_pd(x1, a), _mm256_sub_pd(b, a));
            let f = _mm256_min_pd(fhi, _mm256_max_pd(flo, f));
            if ok == 0b1111 {
                let off = _mm256_mul_epu32(_mm256_cvtepi32_epi64(i), stride);
                let bp4 = base[j..j + 4].as_mut_ptr().cast::<__m256i>();
                // SAFETY: 4 lanes to and from 4-element subslices (usize is 64-bit here).
                unsafe {
                    _mm256_storeu_pd(frac[j..j + 4].as_mut_ptr(), f);
                    if k.first {
                        _mm256_storeu_si256(bp4, off);
                    } else {
                        _mm256_storeu_si256(bp4, _mm256_add_epi64(_mm256_loadu_si256(bp4), off));
                    }
                }
                if k.first {
                    nan[j..j + 4].fill(false);
                }
            } else {
                let mut fl = [0.0f64; 4];
                let mut il = [0i32; 4];
                // SAFETY: both stores write 4 lanes into 4-element local arrays.
                unsafe {
                    _mm256_storeu_pd(fl.as_mut_ptr(), f);
                    _mm_storeu_si128(il.as_mut_ptr().cast(), i);
                }
                for l in 0..4 {
                    let xj = xs[j + l];
                    let (il, fl) = if ok & (1 << l) != 0 {
                        (il[l] as usize, fl[l])
                    } else {
                        k.locate_one(xj)
                    };
                    k.put(j + l, xj, (il, fl), base, frac, nan);
                }
            }
            j += 4;
        }
        for (jj, &x) in xs.iter().enumerate().take(len).skip(j) {
            k.put(jj, x, k.locate_one(x), base, frac, nan);
        }
    }

    /// Transpose row-major 4-D points into the four per-axis buffers
    /// (4 points per step: four 256-bit loads, an in-register 4x4 transpose).
    pub(super) fn transpose4<const N: usize>(blk: &[f64], rows: &mut [[f64; BLOCK]; N]) {
        // SAFETY: `available` checked AVX2 support before this path was chosen.
        unsafe { transpose4_avx2(blk, rows) }
    }

    #[target_feature(enable = "avx2")]
    fn transpose4_avx2<const N: usize>(blk: &[f64], rows: &mut [[f64; BLOCK]; N]) {
        if N != 4 {
            return;
        }
        let len = (blk.len() / 4).min(BLOCK);
        let mut j = 0;
        while j + 4 <= len {
            let r = &blk[4 * j..4 * j + 16];
            // SAFETY: four 4-lane loads from a 16-element subslice.
            let (a, b, c, d) = unsafe {
                (
                    _mm256_loadu_pd(r.as_ptr()),
                    _mm256_loadu_pd(r[4..].as_ptr()),
                    _mm256_loadu_pd(r[8..].as_ptr()),
                    _mm256_loadu_pd(r[12..].as_ptr()),
                )
            };
            // a = [a0 a1 a2 a3] (point j), b (j+1), c (j+2), d (j+3)
            let t0 = _mm256_unpacklo_pd(a, b); // a0 b0 a2 b2
            let t1 = _mm256_unpackhi_pd(a, b); // a1 b1 a3 b3
            let t2 = _mm256_unpacklo_pd(c, d); // c0 d0 c2 d2
            let t3 = _mm256_unpackhi_pd(c, d); // c1 d1 c3 d3
            let x0 = _mm256_permute2f128_pd::<0x20>(t0, t2); // a0 b0 c0 d0
            let x1 = _mm256_permute2f128_pd::<0x20>(t1, t3); // a1 b1 c1 d1
            let x2 = _mm256_permute2f128_pd::<0x31>(t0, t2); // a2 b2 c2 d2
            let x3 = _mm256_permute2f128_pd::<0x31>(t1, t3); // a3 b3 c3 d3
                                                             // SAFETY: 4 lanes into 4-element subslices of the buffers.
            unsafe {
                _mm256_storeu_pd(rows[0][j..j + 4].as_mut_ptr(), x0);
                _mm256_storeu_pd(rows[1][j..j + 4].as_mut_ptr(), x1);
                _mm256_storeu_pd(rows[2][j..j + 4].as_mut_ptr(), x2);
                _mm256_storeu_pd(rows[3][j..j + 4].as_mut_ptr(), x3);
            }
            j += 4;
        }
        for jj in j..len {
            for (k, col) in rows.iter_mut().enumerate() {
                col[jj] = blk[4 * jj + k];
            }
        }
    }

    /// Gather the 2^N corners of each point's cell and reduce them axis by
    /// axis, last axis first, four points at a time.
    pub(super) fn reduce<const N: usize, const M: usize>(
        values: &[f64],
        offsets: &[usize; M],
        base: &[usize],
        frac: &[[f64; BLOCK]; N],
        nan: &[bool],
        out: &mut [f64],
    ) {
        // SAFETY: `available` checked AVX2 support before this path was chosen.
        unsafe { reduce_avx2::<N, M>(values, offsets, base, frac, nan, out) }
    }

    #[target_feature(enable = "avx2")]
    fn reduce_avx2<const N: usize, const M: usize>(
        values: &[f64],
        offsets: &[usize; M],
        base: &[usize],
        frac: &[[f64; BLOCK]; N],
        nan: &[bool],
        out: &mut [f64],
    ) {
        let len = out.len().min(base.len()).min(nan.len()).min(BLOCK);
        let span = offsets.iter().copied().max().unwrap_or(0);
        let paired = M >= 2 && offsets.chunks(2).all(|c| c[1] == c[0] + 1);
        let onev = _mm256_set1_pd(1.0);
        let mut j = 0;
        while j + 4 <= len {
            // every cell of a located point lies inside the values (segments
            // are clamped to [0, n-2]); checked here once per point anyway
            let inside = base[j..j + 4].iter().all(|&b| b + span < values.len());
            if !inside {
                break;
            }
            if paired {
                // Corners 2q and 2q+1 are adjacent values (last axis, stride 1):
                // one 128-bit load per pair and point, transposed to lanes in
                // point order (0, 2, 1, 3); the fractions follow the same order.
                let mut c = [_mm256_setzero_pd(); M];
                let vp = values.as_ptr();
                for (q, slot) in c.iter_mut().take(M / 2).enumerate() {
                    let off = offsets[2 * q];
                    // SAFETY: base + off + 1 <= base + span < values.len() (checked above).
                    let (p0, p1, p2, p3) = unsafe {
                        (
                            _mm_loadu_pd(vp.add(base[j] + off)),
                            _mm_loadu_pd(vp.add(base[j + 1] + off)),
                            _mm_loadu_pd(vp.add(base[j + 2] + off)),
                            _mm_loadu_pd(vp.add(base[j + 3] + off)),
                        )
                    };
                    let a = _mm256_set_m128d(p1, p0);
                    let b = _mm256_set_m128d(p3, p2);
                    let (lo, hi) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
                    // SAFETY: 4 lanes from a 4-element subslice.
                    let f = unsafe { _mm256_loadu_pd(frac[N - 1][j..j + 4].as_ptr()) };
                    let f = _mm256_permute4x64_pd::<0b11_01_10_00>(f);
                    let g = _mm256_sub_pd(onev, f);
                    *slot = _mm256_add_pd(_mm256_mul_pd(g, lo), _mm256_mul_pd(f, hi));
                }
                let mut m = M / 2;
                for fk in frac.iter().rev().skip(1) {
                    // SAFETY: 4 lanes from a 4-element subslice.
                    let f = unsafe { _mm256_loadu_pd(fk[j..j + 4].as_ptr()) };
                    let f = _mm256_permute4x64_pd::<0b11_01_10_00>(f);
                    let g = _mm256_sub_pd(onev, f);
                    m /= 2;
                    for q in 0..m {
                        c[q] = _mm256_add_pd(
                            _mm256_mul_pd(g, c[2 * q]),
                            _mm256_mul_pd(f, c[2 * q + 1]),
                        );
                    }
                }
                let r4 = _mm256_permute4x64_pd::<0b11_01_10_00>(c[0]);
                let mut r = [0.0f64; 4];
                // SAFETY: 4 lanes into a 4-element local array.
                unsafe { _mm256_storeu_pd(r.as_mut_ptr(), r4) };
                for l in 0..4 {
                    out[j + l] = if nan[j + l] { f64::NAN } else { r[l] };
                }
                j += 4;
                continue;
            }
            let bv = _mm256_setr_epi64x(
                base[j] as i64,
                base[j + 1] as i64,
                base[j + 2] as i64,
                base[j + 3] as i64,
            );
            let mut c = [_mm256_setzero_pd(); M];
            for (slot, &off) in c.iter_mut().zip(offsets) {
                let idx = _mm256_add_epi64(bv, _mm256_set1_epi64x(off as i64));
                // SAFETY: base + off <= base + span < values.len() (checked above).
                *slot = unsafe { _mm256_i64gather_pd::<8>(values.as_ptr(), idx) };
            }
            let mut m = M;
            for fk in frac.iter().rev() {
                // SAFETY: 4 lanes from a 4-element subslice.
                let f = unsafe { _mm256_loadu_pd(fk[j..j + 4].as_ptr()) };
                let g = _mm256_sub_pd(onev, f);
                m /= 2;
                for q in 0..m {
                    c[q] =
                        _mm256_add_pd(_mm256_mul_pd(g, c[2 * q]), _mm256_mul_pd(f, c[2 * q + 1]));
                }
            }
            let mut r = [0.0f64; 4];
            // SAFETY: 4 lanes into a 4-element local array.
            unsafe { _mm256_storeu_pd(r.as_mut_ptr(), c[0]) };
            for l in 0..4 {
                out[j + l] = if nan[j + l] { f64::NAN } else { r[l] };
            }
            j += 4;
        }
        for (jj, o) in out.iter_mut().enumerate().take(len).skip(j) {
            *o = super::block_point(values, span, offsets, base, frac, nan, jj);
        }
    }
}

/// Multilinear value at point `j` of a located block (the portable reduction, also the
/// AVX2 path's tail): the cell's `M` corners from `values[base[j]..]` at `offsets`, collapsed
/// one axis at a time, last axis first, with the fractions `frac[k][j]`; NaN when the point
/// was flagged in `nan` or its cell falls outside `values` (never, by construction).
#[inline(always)]
fn block_point<const N: usize, const M: usize>(
    values: &[f64],
    span: usize,
    offsets: &[usize; M],
    base: &[usize],
    frac: &[[f64; BLOCK]; N],
    nan: &[bool],
    j: usize,
) -> f64 {
    let b = base[j];
    // one bounds check for the whole cell (always inside by construction)
    let (Some(cell), false) = (values.get(b..=b + span), nan[j]) else {
        return f64::NAN;
    };
    let mut corners = [0.0f64; M];
    for (slot, &off) in corners.iter_mut().zip(offsets) {
        *slot = cell[off];
    }
    let mut m = M;
    for fk in frac.iter().rev() {
        let f = fk[j];
        let g = 1.0 - f;
        m /= 2;
        for i in 0..m {
            corners[i] = g * corners[2 * i] + f * corners[2 * i + 1];
        }
    }
    corners[0]
}

/// Where the batch path reads its points.
#[derive(Clone, Copy)]
enum Source<'a> {
    /// One slice per axis.
    Columns(&'a [&'a [f64]]),
    /// Row-major `(npoints, ndim)`.
    Rows(&'a [f64]),
}

/// One axis's constants for the batch locate, hoisted out of the point loop:
/// the same operations as [`Axis::locate`], without its per-point branches on
/// the axis's policies.
struct AxisKernel<'a> {
    bp: &'a [f64],
    min: f64,
    max: f64,
    uniform: Option<(f64, f64)>,
    flo: f64,
    fhi: f64,
    stride: usize,
    first: bool,
}

impl<'a> AxisKernel<'a> {
    fn new(axis: &'a Axis, stride: usize, first: bool) -> Self {
        AxisKernel {
            bp: &axis.breakpoints,
            min: axis.min.unwrap_or(f64::NEG_INFINITY),
            max: axis.max.unwrap_or(f64::INFINITY),
            uniform: axis.uniform,
            flo: if axis.below == Extrapolation::Hold {
                0.0
            } else {
                f64::NEG_INFINITY
            },
            fhi: if axis.above == Extrapolation::Hold {
                1.0
            } else {
                f64::INFINITY
            },
            stride,
            first,
        }
    }

    /// Segment and fraction of one input (n >= 2), exactly as [`Axis::locate`]
    /// for a non-NaN input; a NaN input gives segment 0 (a valid cell).
    #[inline(always)]
    fn locate_one(&self, x: f64) -> (usize, f64) {
        let bp = self.bp;
        let n = bp.len();
        let x1 = clamp_to(x, self.min, self.max);
        let xc = clamp_to(x1, bp[0], bp[n - 1]);
        let mut i;
        match self.uniform {
            Some((x0, inv_h)) => {
                i = (((xc - x0) * inv_h) as usize).min(n - 2);
                while i > 0 && bp[i] > xc {
                    i -= 1;
                }
                while i + 2 < n && bp[i + 1] <= xc {
                    i += 1;
                }
            }
            None => {
                i = 0;
                let mut len = n - 1;
                while len > 1 {
                    let half = len / 2;
                    if bp[i + half] <= xc {
                        i += half;
                    }
                    len -= half;
                }
            }
        }
        let (a, b) = (bp[i], bp[i + 1]);
        (i, clamp_to((x1 - a) / (b - a), self.flo, self.fhi))
    }

    /// Store the located point `j` (the first axis overwrites `base` and `nan`).
    #[inline(always)]
    fn put(
        &self,
        j: usize,
        x: f64,
        (i, f): (usize, f64),
        base: &mut [usize],
        frac: &mut [f64],
        nan: &mut [bool],
    ) {
        if self.first {
            base[j] = i * self.stride;
            nan[j] = x.is_nan();
        } else {
            base[j] += i * self.stride;
            nan[j] |= x.is_nan();
        }
        frac[j] = f;
    }

    /// Segment offsets (`i · stride`, added to `base`), fractions and NaN flags
    /// of the inputs `xs` (the first axis overwrites `base` and `nan`).
    #[inline(always)]
    fn locate_block(&self, xs: &[f64], base: &mut [usize], frac: &mut [f64], nan: &mut [bool]) {
        let bp = self.bp;
        let n = bp.len();
        if n < 2 {
            for ((&x, b), (f, bad)) in xs
                .iter()
                .zip(base.iter_mut())
                .zip(frac.iter_mut().zip(nan.iter_mut()))
            {
                if self.first {
                    *b = 0;
                    *bad = x.is_nan();
                } else {
                    *bad |= x.is_nan();
                }
                *f = 0.0;
            }
            return;
        }
        for (j, &x) in xs.iter().enumerate() {
            self.put(j, x, self.locate_one(x), base, frac, nan);
        }
    }
}

/// Points per parallel task: large enough to amortise scheduling.
const CHUNK: usize = 8192;

/// Points per column-wise block of the batch path (its buffers stay in L1).
const BLOCK: usize = 256;

#[cfg(feature = "parallel")]
fn run_chunks(out: &mut [f64], work: impl Fn(usize, &mut [f64]) + Sync) {
    use rayon::prelude::*;
    if out.len() <= CHUNK {
        work(0, out);
        return;
    }
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, chunk)| work(c * CHUNK, chunk));
}

#[cfg(not(feature = "parallel"))]
fn run_chunks(out: &mut [f64], work: impl Fn(usize, &mut [f64])) {
    for (c, chunk) in out.chunks_mut(CHUNK).enumerate() {
        work(c * CHUNK, chunk);
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_breakpoint_product_past_usize_is_an_error_not_a_wrap() {
        let axis = |k: usize| Axis::new(format!("x{k}"), (0..256).map(f64::from).collect());
        let axes: Vec<Axis> = (0..8).map(|k| axis(k).expect("axis")).collect();
        // 256^8 = 2^64 wrapped to 0 and matched an empty value list.
        let e = Table::new(axes, Vec::new()).unwrap_err().to_string();
        assert!(e.contains("need more than memory can hold"), "{e}");
    }
    use super::*;
    use proptest::prelude::*;

    fn axis(name: &str, bp: &[f64]) -> Axis {
        Axis::new(name, bp.to_vec()).expect("valid axis")
    }

    /// A table of an affine function is reproduced exactly by multilinear interpolation.
    fn affine_table() -> Table {
        let a = axis("a", &[-2.0, 0.0, 1.0, 4.0]);
        let b = axis("b", &[0.0, 0.5, 3.0]);
        let c = axis("c", &[1.0, 2.0]);
        let mut v = Vec::new();
        for &x in a.breakpoints() {
            for &y in b.breakpoints() {
                for &z in c.breakpoints() {
                    v.push(1.0 + 2.0 * x - 3.0 * y + 0.5 * z);
                }
            }
        }
        Table::new(vec![a, b, c], v).expect("valid table")
    }

    /// The column-wise batch path equals point-by-point `eval` bit for bit,
    /// in every dimension, with NaNs, limits, hold and linear ends, and
    /// lengths that are not multiples of the block.
    /// The scalar and AVX2 block kernels locate exactly as `Axis::locate`, on
    /// uniform, nearly uniform (1e-10 jitter: the computed guess needs its
    /// fix-up), searched, limited and extrapolating axes, at nodes, between
    /// them, beyond the ends, at ±0, ±inf and NaN.
    #[test]
    fn block_kernels_locate_as_axis_locate() {
        let uniform: Vec<f64> = (0..30).map(|i| -10.0 + 45.0 * i as f64 / 29.0).collect();
        let jitter: Vec<f64> = (0..17)
            .map(|i| i as f64 * 0.5 + if i % 3 == 1 { 5e-11 } else { 0.0 })
            .collect();
        let axes = [
            axis("u", &uniform),
            axis("j", &jitter),
            axis("s", &[0.0, 5.0, 10.0, 15.0, 35.0]),
            axis("two", &[-1.0, 2.0])
                .with_extrapolation(Extrapolation::Linear, Extrapolation::Linear),
            axis("lim", &uniform)
                .with_extrapolation(Extrapolation::Linear, Extrapolation::Hold)
                .with_limits(Some(-0.0), Some(20.0))
                .expect("limits"),
        ];
        let mut xs: Vec<f64> = (0..1000).map(|i| -15.0 + 0.0517 * i as f64).collect();
        for a in &axes {
            xs.extend_from_slice(a.breakpoints());
        }
        xs.extend_from_slice(&[
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e300,
            -1e300,
        ]);
        for a in &axes {
            let k = AxisKernel::new(a, 3, true);
            for chunk in xs.chunks(BLOCK) {
                let n = chunk.len();
                let (mut b1, mut f1, mut n1) = ([0usize; BLOCK], [0.0f64; BLOCK], [false; BLOCK]);
                k.locate_block(chunk, &mut b1[..n], &mut f1[..n], &mut n1[..n]);
                #[cfg(target_arch = "x86_64")]
                let (b2, f2, n2) = {
                    let (mut b2, mut f2, mut n2) =
                        ([0usize; BLOCK], [0.0f64; BLOCK], [false; BLOCK]);
                    if avx2::available(std::slice::from_ref(a), 1) {
                        avx2::locate(&k, chunk, &mut b2[..n], &mut f2[..n], &mut n2[..n]);
                    } else {
                        (b2, f2, n2) = (b1, f1, n1);
                    }
                    (b2, f2, n2)
                };
                #[cfg(not(target_arch = "x86_64"))]
                let (b2, f2, n2) = (b1, f1, n1);
                for (j, &x) in chunk.iter().enumerate() {
                    let name = &a.name;
                    match a.locate(x) {
                        None => assert!(n1[j] && n2[j], "{name} {x}"),
                        Some((i, f)) => {
                            assert!(!n1[j] && !n2[j], "{name} {x}");
                            assert_eq!((b1[j], b2[j]), (3 * i, 3 * i), "{name} {x}");
                            assert_eq!(f1[j].to_bits(), f.to_bits(), "{name} {x}");
                            assert_eq!(f2[j].to_bits(), f.to_bits(), "{name} {x}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn batch_columns_equal_single_points() {
        for n in 1..=MAX_DIMS {
            let axes: Vec<Axis> = (0..n)
                .map(|k| {
                    let bp: Vec<f64> = if k % 2 == 0 {
                        (0..3 + k).map(|i| -1.0 + 0.5 * i as f64).collect()
                    } else {
                        vec![-2.0, -0.3, 0.1, 1.7]
                    };
                    let ext = if k % 3 == 1 {
                        Extrapolation::Linear
                    } else {
                        Extrapolation::Hold
                    };
                    let a = Axis::new(format!("x{k}"), bp)
                        .expect("axis")
                        .with_extrapolation(ext, Extrapolation::Linear);
                    if k == 2 {
                        a.with_limits(Some(-0.7), None).expect("limits")
                    } else {
                        a
                    }
                })
                .collect();
            let nv: usize = axes.iter().map(|a| a.breakpoints().len()).product();
            let vals = (0..nv).map(|i| ((i * 7919) % 113) as f64 * 0.37).collect();
            let t = Table::new(axes, vals).expect("table");
            let npts = 2 * BLOCK + 37;
            let cols: Vec<Vec<f64>> = (0..n)
                .map(|k| {
                    (0..npts)
                        .map(|i| {
                            if (i + k) % 97 == 0 {
                                f64::NAN
                            } else {
                                -3.0 + 6.0 * (((i * (k + 3) * 7919) % 1009) as f64 / 1009.0)
                            }
                        })
                        .collect()
                })
                .collect();
            let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
            let mut out = vec![0.0; npts];
            t.eval_columns(&refs, &mut out).expect("eval");
            let rows: Vec<f64> = (0..npts)
                .flat_map(|i| cols.iter().map(move |c| c[i]))
                .collect();
            let mut out_rows = vec![0.0; npts];
            t.eval_rows(&rows, &mut out_rows).expect("eval rows");
            for (i, (o, r)) in out.iter().zip(&out_rows).enumerate() {
                let x: Vec<f64> = cols.iter().map(|c| c[i]).collect();
                let want = t.eval(&x);
                for got in [o, r] {
                    assert!(
                        got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                        "n={n} point {i}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn affine_function_is_exact_inside() {
        let t = affine_table();
        for &(x, y, z) in &[(0.3, 1.7, 1.2), (-1.9, 2.9, 1.99), (3.5, 0.1, 1.5)] {
            let want = 1.0 + 2.0 * x - 3.0 * y + 0.5 * z;
            assert!((t.eval(&[x, y, z]) - want).abs() < 1e-13);
        }
    }

    #[test]
    fn hold_and_linear_at_every_edge() {
        let mut t = affine_table();
        // hold: clamp each coordinate to its range
        let held = t.eval(&[10.0, -1.0, 0.0]);
        assert!((held - (1.0 + 8.0 - 0.0 + 0.5)).abs() < 1e-13);
        for k in 0..3 {
            if let Some(ax) = t.axis_mut(k) {
                ax.below = Extrapolation::Linear;
                ax.above = Extrapolation::Linear;
            }
        }
        // linear: the affine function continues
        for &(x, y, z) in &[(10.0, -1.0, 0.0), (-5.0, 7.0, 3.0)] {
            let want = 1.0 + 2.0 * x - 3.0 * y + 0.5 * z;
            assert!((t.eval(&[x, y, z]) - want).abs() < 1e-12);
        }
    }

    #[test]
    fn limits_clamp_before_extrapolation() {
        let a = axis("a", &[0.0, 1.0])
            .with_extrapolation(Extrapolation::Linear, Extrapolation::Linear)
            .with_limits(Some(-1.0), Some(2.0))
            .expect("limits");
        let t = Table::new(vec![a], vec![0.0, 10.0]).expect("table");
        assert_eq!(t.eval(&[5.0]), 20.0);
        assert_eq!(t.eval(&[-3.0]), -10.0);
        assert_eq!(t.eval(&[1.5]), 15.0);
    }

    #[test]
    fn uniform_and_searched_axes_locate_identically() {
        let uni = axis("u", &[0.0, 0.1, 0.2, 0.30000000000000004, 0.4, 0.5]);
        assert!(uni.uniform.is_some());
        let mut searched = uni.clone();
        searched.uniform = None;
        for k in -20..=70 {
            let x = k as f64 * 0.01;
            assert_eq!(uni.locate(x), searched.locate(x), "x = {x}");
        }
        for &x in uni.breakpoints() {
            assert_eq!(uni.locate(x), searched.locate(x));
        }
        assert!(axis("n", &[0.0, 1.0, 3.0]).uniform.is_none());
    }

    #[test]
    fn nan_in_nan_out() {
        let t = affine_table();
        assert!(t.eval(&[f64::NAN, 0.0, 1.0]).is_nan());
        assert!(t.eval(&[0.0, 0.0]).is_nan());
    }

    #[test]
    fn construction_errors_name_axis_and_index() {
        let e = Axis::new("alpha", vec![0.0, 2.0, 2.0]).unwrap_err();
        assert!(e.to_string().contains("axis 'alpha', breakpoint 2"), "{e}");
        let e = Table::new(
            vec![axis("a", &[0.0, 1.0]), axis("b", &[0.0, 1.0, 2.0])],
            vec![0.0; 5],
        )
        .unwrap_err();
        assert!(e.to_string().contains("has 5 values"), "{e}");
        assert!(e.to_string().contains("need 6"), "{e}");
    }

    #[test]
    fn single_breakpoint_axis_is_constant_along_it() {
        let t = Table::new(
            vec![axis("a", &[0.0, 1.0]), axis("b", &[3.0])],
            vec![1.0, 2.0],
        )
        .expect("table");
        assert_eq!(t.eval(&[0.5, -100.0]), 1.5);
    }

    #[test]
    fn batch_paths_match_single_point() {
        let t = affine_table();
        let npts = 20_000;
        let xs: Vec<f64> = (0..npts)
            .map(|i| -3.0 + 8.0 * (i as f64) / npts as f64)
            .collect();
        let ys: Vec<f64> = (0..npts)
            .map(|i| ((i * 7) % 400) as f64 / 100.0 - 0.5)
            .collect();
        let zs: Vec<f64> = (0..npts)
            .map(|i| 0.5 + ((i * 13) % 300) as f64 / 100.0)
            .collect();
        let mut out = vec![0.0; npts];
        t.eval_columns(&[&xs, &ys, &zs], &mut out).expect("columns");
        let rows: Vec<f64> = (0..npts).flat_map(|i| [xs[i], ys[i], zs[i]]).collect();
        let mut out2 = vec![0.0; npts];
        t.eval_rows(&rows, &mut out2).expect("rows");
        for i in 0..npts {
            let one = t.eval(&[xs[i], ys[i], zs[i]]);
            assert_eq!(out[i].to_bits(), one.to_bits());
            assert_eq!(out2[i].to_bits(), one.to_bits());
        }
        assert!(t.eval_columns(&[&xs, &ys], &mut out).is_err());
    }

    proptest! {
        /// A table returns its own node values exactly at every node.
        #[test]
        fn hits_its_nodes(n0 in 2usize..6, n1 in 1usize..5, seed in 0u64..1000) {
            let bp0: Vec<f64> = (0..n0).map(|i| i as f64 * 1.5 - 2.0).collect();
            let bp1: Vec<f64> = (0..n1).map(|i| (i * i) as f64 + 0.25).collect();
            let vals: Vec<f64> = (0..n0 * n1)
                .map(|i| ((i as u64 * 2654435761 + seed) % 1000) as f64 / 37.0 - 10.0)
                .collect();
            let t = Table::new(vec![axis("x", &bp0), axis("y", &bp1)], vals.clone()).unwrap();
            for i in 0..n0 {
                for j in 0..n1 {
                    prop_assert_eq!(t.eval(&[bp0[i], bp1[j]]), vals[i * n1 + j]);
                }
            }
        }
    }
}
