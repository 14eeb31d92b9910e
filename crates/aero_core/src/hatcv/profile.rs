//! Per-maneuver nuisance columns profiled out of the block statistics (Frisch-Waugh-Lovell):
//! the last global columns are regressors whose amplitudes are free per maneuver (a roll-off
//! event's moment, a random draw: thesis Section 3.4.3). Each maneuver's `G`, `b`, `y'y` are
//! replaced by those of its data projected off its own nuisance columns:
//! `G_DD − G_DN G_NN⁺ G_ND`, `b_D − G_DN G_NN⁺ b_N`, `y'y − b_N' G_NN⁺ b_N`. The blocks keep
//! `G_DD` and the correction is kept as `F F'` with `F = G_DN V Λ^{-1/2}` (`V Λ V'` the
//! eigendecomposition of `G_NN` over the eigenvalues above `1e-10` of the largest), the
//! [`super::LowRank`] term; columns a maneuver does not use (zero diagonal) drop out.

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::{Blocks, Layout};
use crate::error::{AeroError, Result};

/// What [`profile_out`] returns: the new `xty` (`M × p_keep`), `yty` (`M`), and the
/// low-rank factors (`p_keep × L`, row-major) with the maneuver of each column (ascending).
#[derive(Clone, Debug, Default)]
pub struct Profiled {
    pub xty: Vec<f64>,
    pub yty: Vec<f64>,
    pub factors: Vec<f64>,
    pub owner: Vec<usize>,
}

/// Relative cutoff of the nuisance Gram matrix's eigenvalues.
const RCOND: f64 = 1e-10;

/// Profile the last `n_nuisance` global columns out of `blocks` (module doc). `blocks` must
/// own its rows (no `block_row`) and carry no low-rank term yet.
pub fn profile_out(blocks: &Blocks<'_>, n_nuisance: usize) -> Result<Profiled> {
    blocks.check()?;
    if blocks.block_row.is_some() || blocks.lowrank.is_some() {
        return Err(AeroError::invalid(
            "profile_out",
            "needs a design that owns its blocks and has no nuisance profiled out yet",
        ));
    }
    let Layout {
        knots: kn,
        aero: rn,
        global: gn,
    } = blocks.layout;
    if n_nuisance > gn {
        return Err(AeroError::invalid(
            "profile_out",
            format!("{n_nuisance} nuisance columns of {gn} global ones"),
        ));
    }
    let m_n = blocks.n_maneuvers();
    let p = blocks.layout.n_local();
    let kr = kn * rn;
    let g_keep = gn - n_nuisance;
    let p_keep = kr + g_keep;
    let mut out = Profiled {
        xty: Vec::with_capacity(m_n * p_keep),
        yty: blocks.yty.to_vec(),
        ..Profiled::default()
    };
    let mut cols: Vec<DVector<f64>> = Vec::new();
    for m in 0..m_n {
        let xrow = &blocks.xty[m * p..(m + 1) * p];
        let glob = &blocks.glob[m * gn * gn..(m + 1) * gn * gn];
        let live: Vec<usize> = (0..n_nuisance)
            .filter(|&j| glob[(g_keep + j) * gn + g_keep + j] > 0.0)
            .collect();
        let start = out.xty.len();
        out.xty.extend_from_slice(&xrow[..p_keep]);
        if live.is_empty() {
            continue;
        }
        let nl = live.len();
        let g_nn = DMatrix::from_fn(nl, nl, |a, b| {
            glob[(g_keep + live[a]) * gn + g_keep + live[b]]
        });
        let g_dn = DMatrix::from_fn(p_keep, nl, |row, j| {
            let c = g_keep + live[j];
            if row < kr {
                let (k, r) = (row / rn, row % rn);
                blocks.cross[((m * rn + r) * gn + c) * kn + k]
            } else {
                glob[(row - kr) * gn + c]
            }
        });
        let b_n = DVector::from_fn(nl, |j, _| xrow[kr + g_keep + live[j]]);
        let eig = SymmetricEigen::new(g_nn);
        let lmax = eig.eigenvalues.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        // eigenpairs in ascending order (numpy's eigh), those above the cutoff
        let mut order: Vec<usize> = (0..nl).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        let kept: Vec<usize> = order
            .into_iter()
            .filter(|&i| eig.eigenvalues[i] > RCOND * lmax)
            .collect();
        // G_NN⁺ b_N = V Λ⁻¹ V' b_N over the kept pairs
        let mut w = DVector::zeros(nl);
        for &i in &kept {
            let v = eig.eigenvectors.column(i);
            w += v * (v.dot(&b_n) / eig.eigenvalues[i]);
        }
        let corr = &g_dn * &w;
        for (x, c) in out.xty[start..].iter_mut().zip(corr.iter()) {
            *x -= c;
        }
        out.yty[m] = (blocks.yty[m] - b_n.dot(&w)).max(0.0);
        for &i in &kept {
            let f = &g_dn * eig.eigenvectors.column(i) / eig.eigenvalues[i].sqrt();
            cols.push(f);
            out.owner.push(m);
        }
    }
    let l = cols.len();
    out.factors = vec![0.0; p_keep * l];
    for (j, c) in cols.iter().enumerate() {
        for (a, v) in c.iter().enumerate() {
            out.factors[a * l + j] = *v;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::{quadratic_forms, Columns, LowRank};
    use super::*;

    #[test]
    fn profiled_statistics_are_those_of_the_projected_rows() {
        // one knot pair, one aerodynamic regressor, one kept global and two nuisance columns:
        // the dense rows of each maneuver, projected off their own nuisance columns
        let (kn, rn, gn, rows) = (2usize, 1usize, 3usize, 12usize);
        let layout = Layout {
            knots: kn,
            aero: rn,
            global: gn,
        };
        let p = layout.n_local();
        let m_n = 2;
        let mut seed = 99u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        let (mut diag, mut off, mut cross, mut glob) = (vec![], vec![], vec![], vec![]);
        let (mut xty, mut yty) = (vec![], vec![]);
        for m in 0..m_n {
            let x = DMatrix::from_fn(rows, p, |i, c| {
                // maneuver 1 does not use the second nuisance column
                if m == 1 && c == p - 1 {
                    0.0
                } else if c < kn * rn {
                    let w1 = (i as f64 + 0.5) / rows as f64;
                    (if c == 0 { 1.0 - w1 } else { w1 }) * (1.0 + (i % 3) as f64)
                } else {
                    rnd()
                }
            });
            let y = DVector::from_fn(rows, |_, _| rnd());
            let g = x.transpose() * &x;
            for k in 0..kn {
                diag.push(g[(k, k)]);
            }
            off.push(g[(0, 1)]);
            for h in 0..gn {
                for k in 0..kn {
                    cross.push(g[(k, kn + h)]);
                }
            }
            for a in 0..gn {
                for b in 0..gn {
                    glob.push(g[(kn + a, kn + b)]);
                }
            }
            xty.extend((x.transpose() * &y).iter().copied());
            yty.push(y.dot(&y));
            xs.push(x);
            ys.push(y);
        }
        let blocks = Blocks {
            layout,
            diag: &diag,
            off: &off,
            cross: &cross,
            glob: &glob,
            xty: &xty,
            yty: &yty,
            block_row: None,
            lowrank: None,
        };
        let pr = profile_out(&blocks, 2).unwrap();
        let p_keep = p - 2;
        assert_eq!(pr.owner.iter().filter(|&&o| o == 0).count(), 2);
        assert_eq!(pr.owner.iter().filter(|&&o| o == 1).count(), 1);
        // the profiled design on the kept columns: its quadratic forms equal the projected
        // rows' squared errors
        let kept_layout = Layout {
            knots: kn,
            aero: rn,
            global: 1,
        };
        let cross_k: Vec<f64> = (0..m_n)
            .flat_map(|m| cross[m * gn * kn..m * gn * kn + kn].to_vec())
            .collect();
        let glob_k: Vec<f64> = (0..m_n).map(|m| glob[m * gn * gn]).collect();
        let prof = Blocks {
            layout: kept_layout,
            diag: &diag,
            off: &off,
            cross: &cross_k,
            glob: &glob_k,
            xty: &pr.xty,
            yty: &pr.yty,
            block_row: None,
            lowrank: Some(LowRank {
                factors: &pr.factors,
                owner: &pr.owner,
            }),
        };
        let cols = Columns {
            aero: vec![0, 1],
            global: vec![2],
        };
        let theta = [0.3, -0.2, 0.7];
        let mut q = vec![0.0; m_n];
        quadratic_forms(&prof, &[0, 1], &theta, &cols, &mut q);
        for m in 0..m_n {
            let x = &xs[m];
            let nz: Vec<usize> = (p_keep..p).filter(|&c| x.column(c).norm() > 0.0).collect();
            let n = DMatrix::from_fn(rows, nz.len(), |i, j| x[(i, nz[j])]);
            let proj = DMatrix::identity(rows, rows)
                - &n * (n.transpose() * &n).try_inverse().unwrap() * n.transpose();
            let xd = x.columns(0, p_keep).into_owned();
            let e = &proj * (&ys[m] - &xd * DVector::from_column_slice(&theta));
            assert!((pr.yty[m] + q[m] - e.dot(&e)).abs() < 1e-10, "maneuver {m}");
        }
    }
}
