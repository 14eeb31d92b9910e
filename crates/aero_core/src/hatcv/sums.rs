//! Sums of the per-maneuver block Gram matrices, written out dense on the local layout: a
//! group's `Σ G_m` and `Σ b_m` (the profiled-out `F_m F_m'` subtracted), per fold and flap.

use super::{check_folds, members, Blocks, Layout};
use crate::error::{AeroError, Result};

/// `Σ_m G_m` and `Σ_m b_m` over the maneuvers `ms`, dense on the local layout (`p × p`
/// row-major, `p`), the profiled-out `F_m F_m'` subtracted.
pub fn gram_sum(blocks: &Blocks<'_>, ms: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let Layout {
        knots: kn,
        aero: rn,
        global: gn,
    } = blocks.layout;
    let p = blocks.layout.n_local();
    let kr = kn * rn;
    let mut g = vec![0.0; p * p];
    let mut x = vec![0.0; p];
    for &m in ms {
        let b = blocks.block_of(m);
        for r in 0..rn {
            for q in 0..rn {
                let d = &blocks.diag[((b * rn + r) * rn + q) * kn..][..kn];
                for (k, v) in d.iter().enumerate() {
                    g[(k * rn + r) * p + k * rn + q] += v;
                }
                let o = &blocks.off[((b * rn + r) * rn + q) * (kn - 1)..][..kn - 1];
                for (k, v) in o.iter().enumerate() {
                    g[(k * rn + r) * p + (k + 1) * rn + q] += v;
                    g[((k + 1) * rn + q) * p + k * rn + r] += v;
                }
            }
            for h in 0..gn {
                let c = &blocks.cross[((b * rn + r) * gn + h) * kn..][..kn];
                for (k, v) in c.iter().enumerate() {
                    g[(k * rn + r) * p + kr + h] += v;
                    g[(kr + h) * p + k * rn + r] += v;
                }
            }
        }
        for a in 0..gn {
            for h in 0..gn {
                g[(kr + a) * p + kr + h] += blocks.glob[(b * gn + a) * gn + h];
            }
        }
        for (xv, bv) in x.iter_mut().zip(&blocks.xty[m * p..(m + 1) * p]) {
            *xv += bv;
        }
        if let Some(lr) = blocks.lowrank {
            let l = lr.owner.len();
            for j in lr.columns_of(m) {
                for a in 0..p {
                    let fa = lr.factors[a * l + j];
                    if fa == 0.0 {
                        continue;
                    }
                    for c in 0..p {
                        g[a * p + c] -= fa * lr.factors[c * l + j];
                    }
                }
            }
        }
    }
    (g, x)
}

/// [`gram_sum`] checked against the blocks (maneuver indices in range).
pub fn gram_sum_checked(blocks: &Blocks<'_>, ms: &[usize]) -> Result<(Vec<f64>, Vec<f64>)> {
    blocks.check()?;
    if let Some(&bad) = ms.iter().find(|&&m| m >= blocks.n_maneuvers()) {
        return Err(AeroError::invalid(
            "maneuvers",
            format!("index {bad} is past the design"),
        ));
    }
    Ok(gram_sum(blocks, ms))
}

/// Per fold and flap, [`gram_sum`] of its maneuvers (`folds[m]`, `flap[m]`): `Q × F × p × p`
/// and `Q × F × p`, the groups summed in parallel (each in maneuver order).
pub fn fold_sums(
    blocks: &Blocks<'_>,
    folds: &[usize],
    flap: &[usize],
    n_folds: usize,
    n_flaps: usize,
) -> Result<(Vec<f64>, Vec<f64>)> {
    blocks.check()?;
    let m = blocks.n_maneuvers();
    check_folds(m, folds, flap, n_folds, n_flaps)?;
    let group = |i: usize| -> (Vec<f64>, Vec<f64>) {
        let (q, f) = (i / n_flaps, i % n_flaps);
        let ms = members(folds, flap, q, f);
        gram_sum(blocks, &ms)
    };
    #[cfg(feature = "parallel")]
    let parts: Vec<_> = {
        use rayon::prelude::*;
        (0..n_folds * n_flaps).into_par_iter().map(group).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let parts: Vec<_> = (0..n_folds * n_flaps).map(group).collect();
    let mut g = Vec::with_capacity(parts.len() * blocks.layout.n_local().pow(2));
    let mut x = Vec::with_capacity(parts.len() * blocks.layout.n_local());
    for (gi, xi) in parts {
        g.extend(gi);
        x.extend(xi);
    }
    Ok((g, x))
}
