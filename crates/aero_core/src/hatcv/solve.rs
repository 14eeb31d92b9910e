//! Penalised least squares on a model's columns of the local layout, per flap, by the Schur
//! complement of the shared global block.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::{Mat, Par};

use super::{Columns, Layout};
use crate::error::{AeroError, Result};

/// Numpy's `lstsq` with its default cutoff: the minimum-norm least-squares solution of
/// `a x = b` (`n × n`, row-major) over the singular values above `ε·n·σ_max`.
fn lstsq(a: &[f64], n: usize, b: &[f64], nrhs: usize) -> Vec<f64> {
    let am = Mat::from_fn(n, n, |i, j| a[i * n + j]);
    let mut x = vec![0.0; n * nrhs];
    let Ok(svd) = am.thin_svd() else {
        return x;
    };
    let (u, s, v) = (svd.U(), svd.S(), svd.V());
    let smax = (0..n).map(|i| s[i]).fold(0.0_f64, f64::max);
    let cut = f64::EPSILON * n as f64 * smax;
    for i in 0..n {
        let si = s[i];
        if si <= cut || si == 0.0 {
            continue;
        }
        for c in 0..nrhs {
            let ub: f64 = (0..n).map(|r| u[(r, i)] * b[r * nrhs + c]).sum::<f64>() / si;
            for r in 0..n {
                x[r * nrhs + c] += v[(r, i)] * ub;
            }
        }
    }
    x
}

/// Solve `a x = b` (`a` symmetric positive definite, `n × n` row-major; `b` `n × nrhs`
/// row-major) by Cholesky; the minimum-norm least-squares solution ([`lstsq`]) when the
/// factorisation meets a non-positive pivot.
pub(super) fn spd_solve(a: &[f64], n: usize, b: &[f64], nrhs: usize) -> Vec<f64> {
    let mut l = Mat::from_fn(n, n, |i, j| a[i * n + j]);
    let mut mem = MemBuffer::new(
        faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(
            n,
            Par::Seq,
            Default::default(),
        ),
    );
    let factored = faer::linalg::cholesky::llt::factor::cholesky_in_place(
        l.as_mut(),
        Default::default(),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    if factored.is_err() {
        return lstsq(a, n, b, nrhs);
    }
    let mut rhs = Mat::from_fn(n, nrhs, |i, c| b[i * nrhs + c]);
    faer::linalg::cholesky::llt::solve::solve_in_place(
        l.as_ref(),
        rhs.as_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(faer::dyn_stack::StackReq::EMPTY)),
    );
    let x: Vec<f64> = (0..n * nrhs).map(|i| rhs[(i / nrhs, i % nrhs)]).collect();
    if x.iter().all(|v| v.is_finite()) {
        x
    } else {
        lstsq(a, n, b, nrhs)
    }
}

/// Penalised least squares on the columns `cols`, per flap the local parameter vector
/// (zero off `cols`). `grams[f]` (`n_local × n_local`, row-major, the penalty included) and
/// `xtys[f]` are flap `f`'s normal equations.
///
/// The flaps' alpha-dependent blocks are independent given the global parameters, so the
/// system is solved by the Schur complement of the global block: per flap
/// `A_f⁻¹ [b_f, C_f]` (Cholesky), then `S = Σ_f (G_gg,f − C_f'A_f⁻¹C_f)` solved in least
/// squares for the shared global parameters. An alpha-dependent column whose diagonal is
/// under `1e-12` of the block's largest (a knot no data reach) stays at zero, and so does a
/// global one whose Schur diagonal is.
pub fn penalised_solve(
    grams: &[&[f64]],
    xtys: &[&[f64]],
    p: usize,
    cols: &Columns,
) -> Vec<Vec<f64>> {
    let ng = cols.global.len();
    let mut s_mat = vec![0.0; ng * ng];
    let mut s_rhs = vec![0.0; ng];
    let mut parts: Vec<(Vec<usize>, Vec<f64>)> = Vec::with_capacity(grams.len());
    for (gm, xv) in grams.iter().zip(xtys) {
        let dmax = cols
            .aero
            .iter()
            .map(|&c| gm[c * p + c])
            .fold(0.0_f64, f64::max);
        let tol = 1e-12 * dmax.max(1e-300);
        let ac: Vec<usize> = cols
            .aero
            .iter()
            .copied()
            .filter(|&c| gm[c * p + c] > tol)
            .collect();
        for (i, &gi) in cols.global.iter().enumerate() {
            for (j, &gj) in cols.global.iter().enumerate() {
                s_mat[i * ng + j] += gm[gi * p + gj];
            }
            s_rhs[i] += xv[gi];
        }
        let na = ac.len();
        let sol = if na > 0 {
            let a: Vec<f64> = ac
                .iter()
                .flat_map(|&i| ac.iter().map(move |&j| gm[i * p + j]))
                .collect();
            let w = ng + 1;
            let mut rhs = vec![0.0; na * w];
            for (i, &ci) in ac.iter().enumerate() {
                rhs[i * w] = xv[ci];
                for (j, &gj) in cols.global.iter().enumerate() {
                    rhs[i * w + 1 + j] = gm[ci * p + gj];
                }
            }
            let sol = spd_solve(&a, na, &rhs, w);
            // S -= C' A⁻¹ C, s -= C' A⁻¹ b
            for (i, &gi) in cols.global.iter().enumerate() {
                let mut sr = 0.0;
                for (r, &cr) in ac.iter().enumerate() {
                    sr += gm[cr * p + gi] * sol[r * w];
                }
                s_rhs[i] -= sr;
                for j in 0..ng {
                    let mut sm = 0.0;
                    for (r, &cr) in ac.iter().enumerate() {
                        sm += gm[cr * p + gi] * sol[r * w + 1 + j];
                    }
                    s_mat[i * ng + j] -= sm;
                }
            }
            sol
        } else {
            Vec::new()
        };
        parts.push((ac, sol));
    }
    let mut th_g = vec![0.0; ng];
    if ng > 0 {
        let dmax = (0..ng)
            .map(|i| s_mat[i * ng + i].abs())
            .fold(0.0_f64, f64::max);
        let live: Vec<usize> = (0..ng)
            .filter(|&i| s_mat[i * ng + i] > 1e-12 * dmax.max(1e-300))
            .collect();
        if !live.is_empty() {
            let nl = live.len();
            let sm: Vec<f64> = live
                .iter()
                .flat_map(|&i| live.iter().map(move |&j| (i, j)))
                .map(|(i, j)| s_mat[i * ng + j])
                .collect();
            let sr: Vec<f64> = live.iter().map(|&i| s_rhs[i]).collect();
            let x = lstsq(&sm, nl, &sr, 1);
            for (k, &i) in live.iter().enumerate() {
                th_g[i] = x[k];
            }
        }
    }
    parts
        .into_iter()
        .map(|(ac, sol)| {
            let mut th = vec![0.0; p];
            let w = ng + 1;
            for (i, &c) in ac.iter().enumerate() {
                let corr: f64 = (0..ng).map(|j| sol[i * w + 1 + j] * th_g[j]).sum();
                th[c] = sol[i * w] - corr;
            }
            for (j, &c) in cols.global.iter().enumerate() {
                th[c] = th_g[j];
            }
            th
        })
        .collect()
}

/// [`penalised_solve`] on flat arrays, checked: `grams` (`F × p × p`) and `xtys` (`F × p`)
/// row-major with `p` the layout's `n_local`; the parameters flat, `F × p`.
pub fn solve_flaps(
    grams: &[f64],
    xtys: &[f64],
    layout: &Layout,
    cols: &Columns,
) -> Result<Vec<f64>> {
    let p = layout.n_local();
    cols.check(layout)?;
    if p == 0 || xtys.len() % p != 0 || grams.len() != xtys.len() * p {
        return Err(AeroError::invalid(
            "grams",
            format!(
                "{} and {} numbers are not flaps x {p} x {p} and flaps x {p}",
                grams.len(),
                xtys.len()
            ),
        ));
    }
    let nf = xtys.len() / p;
    let gs: Vec<&[f64]> = (0..nf).map(|f| &grams[f * p * p..][..p * p]).collect();
    let xs: Vec<&[f64]> = (0..nf).map(|f| &xtys[f * p..][..p]).collect();
    Ok(penalised_solve(&gs, &xs, p, cols).concat())
}
