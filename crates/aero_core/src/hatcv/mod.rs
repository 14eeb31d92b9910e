//! Cross-validated penalised least squares on a hat basis in alpha, from per-maneuver Gram
//! matrices held in block form: the engine of the gap diagnosis (`aerodelta.diagnosis.cv`).
//!
//! The gap of one coefficient is modelled as `Σ θ_{f,k,r} h_k(α) x_r + Σ θ_g x_g`: per flap
//! `f`, piecewise-linear hat functions `h_k` on a knot grid times the aerodynamic regressors
//! `x_r` (the continuous counterpart of the thesis's per-bin Δ parameters, Eq. 3.10), plus
//! global (measurement) regressors shared by every flap. A flap's *local layout* is the
//! columns `k·R + r` (`K` knots, `R` aerodynamic regressors) then the `G` global ones.
//!
//! A row touches two neighbouring knots, so a maneuver's Gram matrix `G_m` is
//! block-tridiagonal in the knots and is held as its non-zero blocks ([`Blocks`]):
//! `2KR² + KRG + G²` numbers instead of `(KR + G)²`. A maneuver's held-out squared error
//! under parameters `θ` is `y_m'y_m − 2θ'b_m + θ'G_mθ` (cross-validation by whole maneuvers
//! from sufficient statistics), evaluated on the blocks directly ([`quadratic_forms`]).
//! The training fits are penalised least squares solved by the Schur complement of the
//! global block: per flap a Cholesky solve of its alpha-dependent block, then one small
//! least-squares solve for the shared global parameters ([`penalised_solve`]).
//!
//! Per-maneuver nuisance columns profiled out (Frisch-Waugh-Lovell) leave a low-rank term,
//! `G_m = blocks_m − F_m F_m'` ([`LowRank`]).

mod build;
mod profile;
mod solve;
mod sums;

pub use build::{build_blocks, BlockStats, GlobalBlock, HatGrid, Rows};
pub use profile::{profile_out, Profiled};
pub use solve::{penalised_solve, solve_flaps};
pub use sums::{fold_sums, gram_sum, gram_sum_checked};

use crate::error::{AeroError, Result};

/// The shape of a flap's local layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Knots `K` of the hat grid in alpha.
    pub knots: usize,
    /// Alpha-dependent (aerodynamic) regressors `R`.
    pub aero: usize,
    /// Global regressors `G`.
    pub global: usize,
}

impl Layout {
    /// Columns of the local layout, `K·R + G`.
    pub fn n_local(&self) -> usize {
        self.knots * self.aero + self.global
    }
}

/// Profiled-out per-maneuver nuisance: `G_m` loses `F_m F_m'`, the columns of `F_m` being
/// those of `factors` (`n_local × L`, row-major) whose `owner` is `m` (ascending owners).
#[derive(Clone, Copy, Debug)]
pub struct LowRank<'a> {
    pub factors: &'a [f64],
    pub owner: &'a [usize],
}

/// Per-maneuver sufficient statistics in block form (the layout of
/// `aerodelta.diagnosis.cv.Design`, C order):
///
/// - `diag[b, r, s, k]` = `G[kR + r, kR + s]`;
/// - `off[b, r, s, k]` = `G[kR + r, (k+1)R + s]` (`k < K − 1`; its transpose below);
/// - `cross[b, r, g, k]` = `G[kR + r, KR + g]`;
/// - `glob[b, g, h]` = `G[KR + g, KR + h]`;
///
/// `b` being maneuver `m`'s block row (`block_row[m]`, or `m`); `xty` (`M × n_local`) and
/// `yty` (`M`) per maneuver.
#[derive(Clone, Copy, Debug)]
pub struct Blocks<'a> {
    pub layout: Layout,
    pub diag: &'a [f64],
    pub off: &'a [f64],
    pub cross: &'a [f64],
    pub glob: &'a [f64],
    pub xty: &'a [f64],
    pub yty: &'a [f64],
    pub block_row: Option<&'a [usize]>,
    pub lowrank: Option<LowRank<'a>>,
}

/// The columns of a model on the local layout: alpha-dependent ones (`k·R + r`) and global
/// ones (`K·R + g`), each ascending.
#[derive(Clone, Debug, Default)]
pub struct Columns {
    pub aero: Vec<usize>,
    pub global: Vec<usize>,
}

impl LowRank<'_> {
    /// The factor columns of maneuver `m` (the owners are ascending).
    pub fn columns_of(&self, m: usize) -> std::ops::Range<usize> {
        self.owner.partition_point(|&o| o < m)..self.owner.partition_point(|&o| o <= m)
    }
}

/// The maneuvers of fold `q` at flap `f`, ascending.
pub(crate) fn members(folds: &[usize], flap: &[usize], q: usize, f: usize) -> Vec<usize> {
    (0..folds.len())
        .filter(|&i| folds[i] == q && flap[i] == f)
        .collect()
}

impl Blocks<'_> {
    /// The block row of maneuver `m`.
    pub fn block_of(&self, m: usize) -> usize {
        self.block_row.map_or(m, |rows| rows[m])
    }

    /// Maneuvers `M`.
    pub fn n_maneuvers(&self) -> usize {
        self.yty.len()
    }

    fn n_blocks(&self) -> usize {
        let Layout { knots, aero, .. } = self.layout;
        if aero > 0 && knots > 0 {
            self.diag.len() / (aero * aero * knots)
        } else if self.layout.global > 0 {
            self.glob.len() / (self.layout.global * self.layout.global)
        } else {
            usize::MAX
        }
    }

    /// Check the arrays' sizes against the layout, one line naming the array.
    pub fn check(&self) -> Result<()> {
        let Layout {
            knots: k,
            aero: r,
            global: g,
        } = self.layout;
        if k < 2 {
            return Err(AeroError::invalid("hat grid", "needs at least 2 knots"));
        }
        let m = self.n_maneuvers();
        let p = self.layout.n_local();
        let nb = match self.block_row {
            Some(rows) => {
                if rows.len() != m {
                    return Err(AeroError::invalid(
                        "block_rows",
                        format!("has {} entries for {m} maneuvers", rows.len()),
                    ));
                }
                if r == 0 && g == 0 {
                    0
                } else {
                    self.n_blocks()
                }
            }
            None => m,
        };
        let sizes = [
            ("diag", self.diag.len(), nb * r * r * k),
            ("off", self.off.len(), nb * r * r * (k - 1)),
            ("cross", self.cross.len(), nb * r * g * k),
            ("glob", self.glob.len(), nb * g * g),
            ("xty", self.xty.len(), m * p),
        ];
        for (name, got, want) in sizes {
            if got != want {
                return Err(AeroError::invalid(
                    name,
                    format!("has {got} numbers where the layout needs {want}"),
                ));
            }
        }
        if let Some(rows) = self.block_row {
            if let Some(&bad) = rows.iter().find(|&&b| b >= nb) {
                return Err(AeroError::invalid(
                    "block_rows",
                    format!("row {bad} is past the {nb} block rows"),
                ));
            }
        }
        if let Some(lr) = self.lowrank {
            let l = lr.owner.len();
            if lr.factors.len() != p * l {
                return Err(AeroError::invalid(
                    "lowrank",
                    format!(
                        "has {} numbers where {p} x {l} are needed",
                        lr.factors.len()
                    ),
                ));
            }
            if lr.owner.windows(2).any(|w| w[1] < w[0]) || lr.owner.iter().any(|&o| o >= m) {
                return Err(AeroError::invalid(
                    "lowrank_of",
                    "must be ascending maneuver indices of this design",
                ));
            }
        }
        Ok(())
    }
}

impl Columns {
    /// Check the columns against the layout (ascending, in range, each in its part).
    pub fn check(&self, layout: &Layout) -> Result<()> {
        let kr = layout.knots * layout.aero;
        let ok_a = self.aero.windows(2).all(|w| w[0] < w[1]) && self.aero.iter().all(|&c| c < kr);
        let ok_g = self.global.windows(2).all(|w| w[0] < w[1])
            && self.global.iter().all(|&c| c >= kr && c < layout.n_local());
        if !ok_a {
            return Err(AeroError::invalid(
                "aero columns",
                format!("must be ascending local columns below {kr}"),
            ));
        }
        if !ok_g {
            return Err(AeroError::invalid(
                "global columns",
                format!(
                    "must be ascending local columns in {kr}..{}",
                    layout.n_local()
                ),
            ));
        }
        Ok(())
    }
}

/// Each of `m` maneuvers has a fold below `n_folds` and a flap below `n_flaps`.
pub(crate) fn check_folds(
    m: usize,
    folds: &[usize],
    flap: &[usize],
    n_folds: usize,
    n_flaps: usize,
) -> Result<()> {
    if folds.len() != m || flap.len() != m {
        return Err(AeroError::invalid(
            "folds",
            format!(
                "fold and flap per maneuver: {} and {} for {m} maneuvers",
                folds.len(),
                flap.len()
            ),
        ));
    }
    if let Some(&bad) = folds.iter().find(|&&q| q >= n_folds) {
        return Err(AeroError::invalid(
            "folds",
            format!("fold {bad} of {n_folds}"),
        ));
    }
    if let Some(&bad) = flap.iter().find(|&&f| f >= n_flaps) {
        return Err(AeroError::invalid(
            "flap",
            format!("flap {bad} of {n_flaps}"),
        ));
    }
    Ok(())
}

/// `θ'G_mθ − 2θ'b_m` for each maneuver of `ms` (its flap's local `θ`, zero off `cols`), from
/// the blocks; into `out` (one per maneuver of `ms`). Per-maneuver nuisance profiled out
/// subtracts `(θ'F_m)²` per column of `F_m`.
pub fn quadratic_forms(
    blocks: &Blocks<'_>,
    ms: &[usize],
    theta: &[f64],
    cols: &Columns,
    out: &mut [f64],
) {
    let Layout {
        knots: kn,
        aero: rn,
        global: gn,
    } = blocks.layout;
    let p = blocks.layout.n_local();
    let kr = kn * rn;
    // the model's aerodynamic regressors, and θ on them as a[i][k]
    let mut ridx: Vec<usize> = cols.aero.iter().map(|c| c % rn.max(1)).collect();
    ridx.sort_unstable();
    ridx.dedup();
    let a: Vec<Vec<f64>> = ridx
        .iter()
        .map(|&r| (0..kn).map(|k| theta[k * rn + r]).collect())
        .collect();
    let gidx: Vec<usize> = cols.global.iter().map(|c| c - kr).collect();
    let gv: Vec<f64> = cols.global.iter().map(|&c| theta[c]).collect();
    let idx: Vec<usize> = cols.aero.iter().chain(&cols.global).copied().collect();
    for (o, &m) in out.iter_mut().zip(ms) {
        let b = blocks.block_of(m);
        let xrow = &blocks.xty[m * p..(m + 1) * p];
        let lin: f64 = idx.iter().map(|&c| xrow[c] * theta[c]).sum();
        let mut q = -2.0 * lin;
        for (i, &ri) in ridx.iter().enumerate() {
            for (j, &rj) in ridx.iter().enumerate() {
                let d = &blocks.diag[((b * rn + ri) * rn + rj) * kn..][..kn];
                let mut s: f64 = d
                    .iter()
                    .zip(&a[i])
                    .zip(&a[j])
                    .map(|((g, x), y)| g * x * y)
                    .sum();
                let ob = &blocks.off[((b * rn + ri) * rn + rj) * (kn - 1)..][..kn - 1];
                let so: f64 = ob
                    .iter()
                    .zip(&a[i][..kn - 1])
                    .zip(&a[j][1..])
                    .map(|((g, x), y)| g * x * y)
                    .sum();
                s += 2.0 * so;
                q += s;
            }
            for (gj, &g) in gidx.iter().enumerate() {
                let c = &blocks.cross[((b * rn + ri) * gn + g) * kn..][..kn];
                let s: f64 = c.iter().zip(&a[i]).map(|(g, x)| g * x).sum();
                q += 2.0 * s * gv[gj];
            }
        }
        for (gi, &g) in gidx.iter().enumerate() {
            let row = &blocks.glob[(b * gn + g) * gn..][..gn];
            let s: f64 = gidx.iter().zip(&gv).map(|(&h, v)| row[h] * v).sum();
            q += gv[gi] * s;
        }
        if let Some(lr) = blocks.lowrank {
            let l = lr.owner.len();
            for j in lr.columns_of(m) {
                let v: f64 = idx.iter().map(|&c| theta[c] * lr.factors[c * l + j]).sum();
                q -= v * v;
            }
        }
        *o = q;
    }
}

/// [`quadratic_forms`] checked against the blocks' layout: one value per maneuver of `ms`.
pub fn quadratic_forms_checked(
    blocks: &Blocks<'_>,
    ms: &[usize],
    theta: &[f64],
    cols: &Columns,
) -> Result<Vec<f64>> {
    blocks.check()?;
    cols.check(&blocks.layout)?;
    if theta.len() != blocks.layout.n_local() {
        return Err(AeroError::invalid(
            "theta",
            format!(
                "has {} numbers for {} columns",
                theta.len(),
                blocks.layout.n_local()
            ),
        ));
    }
    if let Some(&bad) = ms.iter().find(|&&m| m >= blocks.n_maneuvers()) {
        return Err(AeroError::invalid(
            "maneuvers",
            format!("index {bad} is past the design"),
        ));
    }
    let mut out = vec![0.0; ms.len()];
    quadratic_forms(blocks, ms, theta, cols, &mut out);
    Ok(out)
}

/// Held-out squared error per maneuver of the model on `cols`, each maneuver predicted by
/// the fit on the other folds (`y'y − 2θ'b + θ'Gθ` with its fold's `θ`), and the fits:
/// `thetas[(q·F + f)·p ..]`, fold `q`'s flap-`f` parameters.
///
/// `train_grams` (`Q × F × p × p`) and `train_xty` (`Q × F × p`) are each fold's penalised
/// training normal equations (total minus the fold's), `folds[m]` and `flap[m]` each
/// maneuver's fold and flap. Folds run in parallel (each its own, sequential, arithmetic:
/// the same bytes with any number of threads).
pub fn held_out(
    blocks: &Blocks<'_>,
    train_grams: &[f64],
    train_xty: &[f64],
    folds: &[usize],
    flap: &[usize],
    n_flaps: usize,
    cols: &Columns,
) -> Result<(Vec<f64>, Vec<f64>)> {
    blocks.check()?;
    cols.check(&blocks.layout)?;
    let m = blocks.n_maneuvers();
    let p = blocks.layout.n_local();
    if n_flaps == 0 || train_xty.len() % (n_flaps * p) != 0 {
        return Err(AeroError::invalid(
            "train_xty",
            "is not folds x flaps x columns",
        ));
    }
    let nq = train_xty.len() / (n_flaps * p);
    if train_grams.len() != nq * n_flaps * p * p {
        return Err(AeroError::invalid(
            "train_grams",
            format!(
                "has {} numbers where {nq} x {n_flaps} x {p} x {p} are needed",
                train_grams.len()
            ),
        ));
    }
    check_folds(m, folds, flap, nq, n_flaps)?;
    let fold_fit = |q: usize| -> (Vec<(usize, f64)>, Vec<Vec<f64>>) {
        let grams: Vec<&[f64]> = (0..n_flaps)
            .map(|f| &train_grams[(q * n_flaps + f) * p * p..][..p * p])
            .collect();
        let xtys: Vec<&[f64]> = (0..n_flaps)
            .map(|f| &train_xty[(q * n_flaps + f) * p..][..p])
            .collect();
        let thetas = penalised_solve(&grams, &xtys, p, cols);
        let mut sse = Vec::new();
        for (f, th) in thetas.iter().enumerate() {
            let ms = members(folds, flap, q, f);
            if ms.is_empty() {
                continue;
            }
            let mut out = vec![0.0; ms.len()];
            quadratic_forms(blocks, &ms, th, cols, &mut out);
            sse.extend(ms.iter().zip(&out).map(|(&i, v)| (i, blocks.yty[i] + v)));
        }
        (sse, thetas)
    };
    #[cfg(feature = "parallel")]
    let per_fold: Vec<_> = {
        use rayon::prelude::*;
        (0..nq).into_par_iter().map(fold_fit).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let per_fold: Vec<_> = (0..nq).map(fold_fit).collect();
    let mut sse = blocks.yty.to_vec();
    let mut thetas = Vec::with_capacity(nq * n_flaps * p);
    for (part, th) in per_fold {
        for (i, v) in part {
            sse[i] = v;
        }
        for t in th {
            thetas.extend(t);
        }
    }
    Ok((sse, thetas))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// Tiny deterministic generator for the test data (xorshift).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// Rows of a toy problem, their dense local design per maneuver, and its blocks.
    struct Toy {
        layout: Layout,
        dense: Vec<DMatrix<f64>>, // per maneuver, rows x p
        y: Vec<DVector<f64>>,
        diag: Vec<f64>,
        off: Vec<f64>,
        cross: Vec<f64>,
        glob: Vec<f64>,
        xty: Vec<f64>,
        yty: Vec<f64>,
    }

    fn toy(m: usize, rows: usize, layout: Layout, seed: u64) -> Toy {
        let Layout {
            knots: kn,
            aero: rn,
            global: gn,
        } = layout;
        let p = layout.n_local();
        let mut rng = Rng(seed);
        let mut t = Toy {
            layout,
            dense: Vec::new(),
            y: Vec::new(),
            diag: vec![0.0; m * rn * rn * kn],
            off: vec![0.0; m * rn * rn * (kn - 1)],
            cross: vec![0.0; m * rn * gn * kn],
            glob: vec![0.0; m * gn * gn],
            xty: vec![0.0; m * p],
            yty: vec![0.0; m],
        };
        for mi in 0..m {
            let mut x = DMatrix::zeros(rows, p);
            let mut y = DVector::zeros(rows);
            for i in 0..rows {
                let u = (rng.next() + 0.5) * (kn - 1) as f64;
                let j = (u.floor() as usize).min(kn - 2);
                let w1 = u - j as f64;
                for r in 0..rn {
                    let v = rng.next() * (1.0 + r as f64);
                    x[(i, j * rn + r)] += (1.0 - w1) * v;
                    x[(i, (j + 1) * rn + r)] += w1 * v;
                }
                for g in 0..gn {
                    x[(i, kn * rn + g)] = rng.next();
                }
                y[i] = rng.next();
            }
            let g = x.transpose() * &x;
            let b = x.transpose() * &y;
            for r in 0..rn {
                for s in 0..rn {
                    for k in 0..kn {
                        t.diag[((mi * rn + r) * rn + s) * kn + k] = g[(k * rn + r, k * rn + s)];
                        if k + 1 < kn {
                            t.off[((mi * rn + r) * rn + s) * (kn - 1) + k] =
                                g[(k * rn + r, (k + 1) * rn + s)];
                        }
                    }
                }
                for h in 0..gn {
                    for k in 0..kn {
                        t.cross[((mi * rn + r) * gn + h) * kn + k] = g[(k * rn + r, kn * rn + h)];
                    }
                }
            }
            for a in 0..gn {
                for h in 0..gn {
                    t.glob[(mi * gn + a) * gn + h] = g[(kn * rn + a, kn * rn + h)];
                }
            }
            for c in 0..p {
                t.xty[mi * p + c] = b[c];
            }
            t.yty[mi] = y.dot(&y);
            t.dense.push(x);
            t.y.push(y);
        }
        t
    }

    impl Toy {
        fn blocks(&self) -> Blocks<'_> {
            Blocks {
                layout: self.layout,
                diag: &self.diag,
                off: &self.off,
                cross: &self.cross,
                glob: &self.glob,
                xty: &self.xty,
                yty: &self.yty,
                block_row: None,
                lowrank: None,
            }
        }
    }

    fn all_columns(layout: &Layout, regs: &[usize], globs: &[usize]) -> Columns {
        let kr = layout.knots * layout.aero;
        let mut aero: Vec<usize> = (0..layout.knots)
            .flat_map(|k| regs.iter().map(move |&r| k * layout.aero + r))
            .collect();
        aero.sort_unstable();
        Columns {
            aero,
            global: globs.iter().map(|g| kr + g).collect(),
        }
    }

    #[test]
    fn quadratic_forms_equal_the_dense_squared_error() {
        let layout = Layout {
            knots: 6,
            aero: 3,
            global: 2,
        };
        let t = toy(4, 60, layout, 7);
        let cols = all_columns(&layout, &[0, 2], &[1]);
        let p = layout.n_local();
        let mut rng = Rng(99);
        let mut theta = vec![0.0; p];
        for &c in cols.aero.iter().chain(&cols.global) {
            theta[c] = rng.next();
        }
        let ms = [0, 2, 3];
        let mut out = vec![0.0; 3];
        quadratic_forms(&t.blocks(), &ms, &theta, &cols, &mut out);
        let th = DVector::from_vec(theta);
        for (o, &mi) in out.iter().zip(&ms) {
            let e = &t.y[mi] - &t.dense[mi] * &th;
            let want = e.dot(&e) - t.yty[mi];
            assert!((o - want).abs() <= 1e-10 * t.yty[mi], "{o} vs {want}");
        }
    }

    #[test]
    fn held_out_errors_equal_dense_refits_without_each_fold() {
        let layout = Layout {
            knots: 5,
            aero: 2,
            global: 2,
        };
        let m = 10;
        let t = toy(m, 40, layout, 3);
        let p = layout.n_local();
        let folds: Vec<usize> = (0..m).map(|i| i % 3).collect();
        let flap: Vec<usize> = (0..m).map(|i| usize::from(i >= 5)).collect();
        let cols = all_columns(&layout, &[1], &[0, 1]);
        // penalty: a ridge on the alpha-dependent columns only
        let ridge = 0.5;
        let mut tg = Vec::new();
        let mut tx = Vec::new();
        for q in 0..3 {
            for f in 0..2 {
                let mut g = DMatrix::<f64>::zeros(p, p);
                let mut b = DVector::<f64>::zeros(p);
                for i in (0..m).filter(|&i| folds[i] != q && flap[i] == f) {
                    g += t.dense[i].transpose() * &t.dense[i];
                    b += t.dense[i].transpose() * &t.y[i];
                }
                for c in 0..layout.knots * layout.aero {
                    g[(c, c)] += ridge;
                }
                tg.extend(g.transpose().iter().copied()); // row-major
                tx.extend(b.iter().copied());
            }
        }
        let (sse, thetas) = held_out(&t.blocks(), &tg, &tx, &folds, &flap, 2, &cols).unwrap();
        // reference: one dense penalised least squares over both flaps' columns side by side
        // (the global columns shared), refitted without each fold
        let kr = layout.knots * layout.aero;
        let idx: Vec<usize> = cols.aero.iter().chain(&cols.global).copied().collect();
        for q in 0..3 {
            let na = cols.aero.len();
            let n = 2 * na + cols.global.len();
            let mut a = DMatrix::<f64>::zeros(n, n);
            let mut b = DVector::<f64>::zeros(n);
            let place = |f: usize, c: usize| -> usize {
                if c < kr {
                    f * na + cols.aero.iter().position(|&x| x == c).unwrap()
                } else {
                    2 * na + cols.global.iter().position(|&x| x == c).unwrap()
                }
            };
            for i in (0..m).filter(|&i| folds[i] != q) {
                let x = &t.dense[i];
                for (ci, &c) in idx.iter().enumerate() {
                    let _ = ci;
                    for &d in &idx {
                        a[(place(flap[i], c), place(flap[i], d))] += x.column(c).dot(&x.column(d));
                    }
                    b[place(flap[i], c)] += x.column(c).dot(&t.y[i]);
                }
            }
            for f in 0..2 {
                for k in 0..na {
                    a[(f * na + k, f * na + k)] += ridge;
                }
            }
            let sol = a.lu().solve(&b).unwrap();
            for i in (0..m).filter(|&i| folds[i] == q) {
                let mut th = DVector::<f64>::zeros(p);
                for &c in &idx {
                    th[c] = sol[place(flap[i], c)];
                }
                let e = &t.y[i] - &t.dense[i] * &th;
                assert!(
                    (sse[i] - e.dot(&e)).abs() <= 1e-9 * t.yty[i],
                    "maneuver {i}"
                );
                let got = &thetas[(q * 2 + flap[i]) * p..][..p];
                for c in 0..p {
                    assert!(
                        (got[c] - th[c]).abs() <= 1e-8 * (1.0 + th[c].abs()),
                        "theta {c}"
                    );
                }
            }
        }
    }

    #[test]
    fn profiled_nuisance_is_subtracted_per_owner() {
        let layout = Layout {
            knots: 4,
            aero: 1,
            global: 1,
        };
        let t = toy(3, 30, layout, 11);
        let p = layout.n_local();
        let factors: Vec<f64> = (0..p * 3).map(|i| 0.1 * (i as f64 + 1.0)).collect();
        let owner = [0usize, 2, 2];
        let mut b = t.blocks();
        let theta: Vec<f64> = (0..p).map(|i| 0.3 - 0.1 * i as f64).collect();
        let cols = all_columns(&layout, &[0], &[0]);
        let mut plain = vec![0.0; 3];
        quadratic_forms(&b, &[0, 1, 2], &theta, &cols, &mut plain);
        b.lowrank = Some(LowRank {
            factors: &factors,
            owner: &owner,
        });
        let mut with = vec![0.0; 3];
        quadratic_forms(&b, &[0, 1, 2], &theta, &cols, &mut with);
        let v = |j: usize| -> f64 { (0..p).map(|c| theta[c] * factors[c * 3 + j]).sum() };
        assert!((plain[0] - v(0).powi(2) - with[0]).abs() < 1e-12);
        assert_eq!(plain[1], with[1]);
        assert!((plain[2] - v(1).powi(2) - v(2).powi(2) - with[2]).abs() < 1e-12);
    }

    #[test]
    fn fold_sums_are_the_dense_gram_matrices_of_each_fold_and_flap() {
        let layout = Layout {
            knots: 5,
            aero: 2,
            global: 2,
        };
        let m = 7;
        let t = toy(m, 30, layout, 17);
        let p = layout.n_local();
        let folds: Vec<usize> = (0..m).map(|i| i % 2).collect();
        let flap: Vec<usize> = (0..m).map(|i| usize::from(i >= 4)).collect();
        let factors: Vec<f64> = (0..p * 2).map(|i| 0.01 * (i as f64 - 7.0)).collect();
        let owner = [1usize, 5];
        let mut b = t.blocks();
        b.lowrank = Some(LowRank {
            factors: &factors,
            owner: &owner,
        });
        let (g, x) = fold_sums(&b, &folds, &flap, 2, 2).unwrap();
        for q in 0..2 {
            for f in 0..2 {
                let mut want = DMatrix::<f64>::zeros(p, p);
                let mut wx = DVector::<f64>::zeros(p);
                for i in (0..m).filter(|&i| folds[i] == q && flap[i] == f) {
                    want += t.dense[i].transpose() * &t.dense[i];
                    wx += t.dense[i].transpose() * &t.y[i];
                    for (j, &o) in owner.iter().enumerate() {
                        if o == i {
                            let fj = DVector::from_fn(p, |a, _| factors[a * 2 + j]);
                            want -= &fj * fj.transpose();
                        }
                    }
                }
                let gi = &g[(q * 2 + f) * p * p..][..p * p];
                for a in 0..p {
                    assert!((x[(q * 2 + f) * p + a] - wx[a]).abs() < 1e-10);
                    for c in 0..p {
                        assert!(
                            (gi[a * p + c] - want[(a, c)]).abs() < 1e-10,
                            "{q} {f} {a} {c}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn singular_block_falls_back_to_the_minimum_norm_solution() {
        // two identical columns: Cholesky fails, the minimum-norm solution splits evenly
        let a = [1.0, 1.0, 1.0, 1.0];
        let x = solve::spd_solve(&a, 2, &[2.0, 2.0], 1);
        assert!(
            (x[0] - 1.0).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12,
            "{x:?}"
        );
    }

    #[test]
    fn wrong_sizes_are_refused_by_name() {
        let layout = Layout {
            knots: 4,
            aero: 1,
            global: 1,
        };
        let t = toy(2, 10, layout, 5);
        let mut b = t.blocks();
        b.off = &t.off[1..];
        let err = b.check().unwrap_err().to_string();
        assert!(err.starts_with("off:"), "{err}");
    }
}
