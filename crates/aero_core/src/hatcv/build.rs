//! Reduction of the rows to per-maneuver block Gram matrices ([`super::Blocks`] layout):
//! `G_m = D_m'D_m`, `b_m = D_m'y_m`, `y_m'y_m` of the hat-basis design `D` without forming
//! it. Rows are grouped by (maneuver, knot interval) with a counting sort (stable: rows keep
//! their order within a group); each group's `Z'Z`, `Z = [(1 − w)x, w x, g, y]`, is summed row
//! by row and added to the blocks of its two knots. Maneuvers are reduced in parallel, each
//! by one task in row order: the same bytes with any number of threads.

use crate::error::{AeroError, Result};

/// The hat grid in alpha: knots `k0 + step·[0, 1, …, n − 1]`, deg.
#[derive(Clone, Copy, Debug)]
pub struct HatGrid {
    pub k0: f64,
    pub step: f64,
    pub n: usize,
}

impl HatGrid {
    /// Interval `j` (knots `j`, `j + 1`) and the weight of knot `j + 1` at `alpha_deg`
    /// (clamped to the grid), as `aerodelta.diagnosis.cv.HatGrid.locate`.
    pub fn locate(&self, alpha_deg: f64) -> (usize, f64) {
        let u = (alpha_deg - self.k0) / self.step;
        let top = (self.n - 2) as f64;
        let jf = u.floor().clamp(0.0, top);
        let j = jf as usize;
        (j, (u - jf).clamp(0.0, 1.0))
    }
}

/// A group of global columns: dense (`n × cols`, row-major) or one sparse column (its rows
/// and values; a row listed twice keeps its last value).
#[derive(Clone, Copy, Debug)]
pub enum GlobalBlock<'a> {
    Dense {
        data: &'a [f64],
        cols: usize,
    },
    Sparse {
        rows: &'a [usize],
        values: &'a [f64],
    },
}

impl GlobalBlock<'_> {
    fn cols(&self) -> usize {
        match self {
            GlobalBlock::Dense { cols, .. } => *cols,
            GlobalBlock::Sparse { .. } => 1,
        }
    }
}

/// The rows of one coefficient's gap and its regressors.
#[derive(Clone, Copy, Debug)]
pub struct Rows<'a> {
    /// Gap per row.
    pub y: &'a [f64],
    /// Maneuver code per row, `0..n_maneuvers`.
    pub maneuver: &'a [usize],
    /// Angle of attack per row, deg.
    pub alpha_deg: &'a [f64],
    /// Aerodynamic regressors, `n × R` row-major.
    pub aero: &'a [f64],
    /// `R`.
    pub n_aero: usize,
}

/// Per-maneuver block statistics, owned (C order, the layout of [`super::Blocks`]).
#[derive(Clone, Debug, Default)]
pub struct BlockStats {
    pub diag: Vec<f64>,
    pub off: Vec<f64>,
    pub cross: Vec<f64>,
    pub glob: Vec<f64>,
    pub xty: Vec<f64>,
    pub yty: Vec<f64>,
}

fn check(rows: &Rows<'_>, globals: &[GlobalBlock<'_>], grid: &HatGrid, m_n: usize) -> Result<()> {
    let n = rows.y.len();
    if grid.n < 2 || grid.step.is_nan() || grid.step <= 0.0 || !grid.k0.is_finite() {
        return Err(AeroError::invalid(
            "hat grid",
            "needs at least 2 knots and a positive step",
        ));
    }
    if rows.maneuver.len() != n || rows.alpha_deg.len() != n || rows.aero.len() != n * rows.n_aero {
        return Err(AeroError::invalid(
            "rows",
            format!(
                "{n} gaps but {} maneuver codes, {} alphas and {} aerodynamic values ({} per row)",
                rows.maneuver.len(),
                rows.alpha_deg.len(),
                rows.aero.len(),
                rows.n_aero
            ),
        ));
    }
    if let Some(i) = rows.maneuver.iter().position(|&m| m >= m_n) {
        return Err(AeroError::invalid(
            format!("row {i}"),
            format!("maneuver code {} is not below {m_n}", rows.maneuver[i]),
        ));
    }
    if let Some(i) = rows.alpha_deg.iter().position(|a| !a.is_finite()) {
        return Err(AeroError::invalid(
            format!("row {i}"),
            "alpha_deg is not finite",
        ));
    }
    for (b, blk) in globals.iter().enumerate() {
        match blk {
            GlobalBlock::Dense { data, cols } if data.len() != n * cols => {
                return Err(AeroError::invalid(
                    format!("global block {b}"),
                    format!("has {} numbers for {n} rows of {cols}", data.len()),
                ));
            }
            GlobalBlock::Sparse { rows: r, values } => {
                if r.len() != values.len() {
                    return Err(AeroError::invalid(
                        format!("global block {b}"),
                        format!("{} rows but {} values", r.len(), values.len()),
                    ));
                }
                if let Some(&bad) = r.iter().find(|&&i| i >= n) {
                    return Err(AeroError::invalid(
                        format!("global block {b}"),
                        format!("row {bad} is past the {n} rows"),
                    ));
                }
            }
            GlobalBlock::Dense { .. } => {}
        }
    }
    Ok(())
}

/// Reduce the rows to per-maneuver block statistics on the grid (module doc); `m_n`
/// maneuvers (a maneuver without rows gets zeros).
pub fn build_blocks(
    rows: &Rows<'_>,
    globals: &[GlobalBlock<'_>],
    grid: &HatGrid,
    m_n: usize,
) -> Result<BlockStats> {
    check(rows, globals, grid, m_n)?;
    let n = rows.y.len();
    let (r_n, k_n) = (rows.n_aero, grid.n);
    let g_n: usize = globals.iter().map(GlobalBlock::cols).sum();
    let p = k_n * r_n + g_n;
    // sparse entries by row (CSR), columns in order
    let mut sp_count = vec![0usize; n + 1];
    let mut col0 = 0;
    let mut sparse_cols = Vec::new();
    for blk in globals {
        if let GlobalBlock::Sparse { rows: r, values } = blk {
            for &i in r.iter() {
                sp_count[i + 1] += 1;
            }
            sparse_cols.push((col0, *r, *values));
        }
        col0 += blk.cols();
    }
    for i in 0..n {
        sp_count[i + 1] += sp_count[i];
    }
    let mut sp_fill = sp_count.clone();
    let mut sp_entries = vec![(0usize, 0.0f64); sp_count[n]];
    for &(c, r, v) in &sparse_cols {
        for (&i, &x) in r.iter().zip(v) {
            sp_entries[sp_fill[i]] = (c, x);
            sp_fill[i] += 1;
        }
    }
    // rows grouped by maneuver then knot interval (counting sort, stable)
    let loc: Vec<(usize, f64)> = rows.alpha_deg.iter().map(|&a| grid.locate(a)).collect();
    let seg_n = k_n - 1;
    let key = |i: usize| rows.maneuver[i] * seg_n + loc[i].0;
    let mut start = vec![0usize; m_n * seg_n + 1];
    for i in 0..n {
        start[key(i) + 1] += 1;
    }
    for s in 0..m_n * seg_n {
        start[s + 1] += start[s];
    }
    let mut fill = start.clone();
    let mut order = vec![0usize; n];
    for i in 0..n {
        let k = key(i);
        order[fill[k]] = i;
        fill[k] += 1;
    }
    // per maneuver, chunks of at least one number (an empty block gets a placeholder, so
    // that every maneuver has a chunk in each array; dropped at the end)
    let (dl, ol, cl, gl) = (
        r_n * r_n * k_n,
        r_n * r_n * (k_n - 1),
        r_n * g_n * k_n,
        g_n * g_n,
    );
    let chunk = |len: usize| len.max(1);
    let mut out = BlockStats {
        diag: vec![0.0; m_n * chunk(dl)],
        off: vec![0.0; m_n * chunk(ol)],
        cross: vec![0.0; m_n * chunk(cl)],
        glob: vec![0.0; m_n * chunk(gl)],
        xty: vec![0.0; m_n * chunk(p)],
        yty: vec![0.0; m_n],
    };
    let width = 2 * r_n + g_n + 1;
    let reduce = |m: usize,
                  diag: &mut [f64],
                  off: &mut [f64],
                  cross: &mut [f64],
                  glob: &mut [f64],
                  xty: &mut [f64],
                  yty: &mut f64| {
        let mut s = vec![0.0; width * width];
        let mut z = vec![0.0; width];
        for j in 0..seg_n {
            let seg = &order[start[m * seg_n + j]..start[m * seg_n + j + 1]];
            if seg.is_empty() {
                continue;
            }
            s.iter_mut().for_each(|v| *v = 0.0);
            for &i in seg {
                let w1 = loc[i].1;
                let x = &rows.aero[i * r_n..(i + 1) * r_n];
                for r in 0..r_n {
                    z[r] = x[r] * (1.0 - w1);
                    z[r_n + r] = x[r] * w1;
                }
                let mut c = 2 * r_n;
                for blk in globals {
                    match blk {
                        GlobalBlock::Dense { data, cols } => {
                            z[c..c + cols].copy_from_slice(&data[i * cols..(i + 1) * cols]);
                            c += cols;
                        }
                        GlobalBlock::Sparse { .. } => {
                            z[c] = 0.0;
                            c += 1;
                        }
                    }
                }
                for &(gc, v) in &sp_entries[sp_count[i]..sp_count[i + 1]] {
                    z[2 * r_n + gc] = v;
                }
                z[width - 1] = rows.y[i];
                // upper triangle of Z'Z
                for a in 0..width {
                    let za = z[a];
                    let row = &mut s[a * width..(a + 1) * width];
                    for (sv, zb) in row[a..].iter_mut().zip(&z[a..]) {
                        *sv += za * zb;
                    }
                }
            }
            let at = |a: usize, b: usize| {
                if a <= b {
                    s[a * width + b]
                } else {
                    s[b * width + a]
                }
            };
            let (i0, i1, ig, iy) = (0, r_n, 2 * r_n, width - 1);
            for r in 0..r_n {
                for q in 0..r_n {
                    diag[(r * r_n + q) * k_n + j] += at(i0 + r, i0 + q);
                    diag[(r * r_n + q) * k_n + j + 1] += at(i1 + r, i1 + q);
                    off[(r * r_n + q) * (k_n - 1) + j] += at(i0 + r, i1 + q);
                }
                for g in 0..g_n {
                    cross[(r * g_n + g) * k_n + j] += at(i0 + r, ig + g);
                    cross[(r * g_n + g) * k_n + j + 1] += at(i1 + r, ig + g);
                }
                xty[j * r_n + r] += at(i0 + r, iy);
                xty[(j + 1) * r_n + r] += at(i1 + r, iy);
            }
            for g in 0..g_n {
                for h in 0..g_n {
                    glob[g * g_n + h] += at(ig + g, ig + h);
                }
                xty[k_n * r_n + g] += at(ig + g, iy);
            }
            *yty += at(iy, iy);
        }
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        out.yty
            .par_iter_mut()
            .zip(out.xty.par_chunks_mut(chunk(p)))
            .zip(out.diag.par_chunks_mut(chunk(dl)))
            .zip(out.off.par_chunks_mut(chunk(ol)))
            .zip(out.cross.par_chunks_mut(chunk(cl)))
            .zip(out.glob.par_chunks_mut(chunk(gl)))
            .enumerate()
            .for_each(|(m, (((((yty, xty), diag), off), cross), glob))| {
                reduce(m, diag, off, cross, glob, xty, yty);
            });
    }
    #[cfg(not(feature = "parallel"))]
    {
        out.yty
            .iter_mut()
            .zip(out.xty.chunks_mut(chunk(p)))
            .zip(out.diag.chunks_mut(chunk(dl)))
            .zip(out.off.chunks_mut(chunk(ol)))
            .zip(out.cross.chunks_mut(chunk(cl)))
            .zip(out.glob.chunks_mut(chunk(gl)))
            .enumerate()
            .for_each(|(m, (((((yty, xty), diag), off), cross), glob))| {
                reduce(m, diag, off, cross, glob, xty, yty);
            });
    }
    for (v, len) in [
        (&mut out.diag, dl),
        (&mut out.off, ol),
        (&mut out.cross, cl),
        (&mut out.glob, gl),
        (&mut out.xty, p),
    ] {
        if len == 0 {
            v.clear();
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dense local design row of row `i` (hat weights times the regressors, then the
    /// global columns), written out.
    fn dense_row(rows: &Rows<'_>, glob: &[f64], g_n: usize, grid: &HatGrid, i: usize) -> Vec<f64> {
        let r_n = rows.n_aero;
        let mut x = vec![0.0; grid.n * r_n + g_n];
        let (j, w1) = grid.locate(rows.alpha_deg[i]);
        for r in 0..r_n {
            x[j * r_n + r] += (1.0 - w1) * rows.aero[i * r_n + r];
            x[(j + 1) * r_n + r] += w1 * rows.aero[i * r_n + r];
        }
        x[grid.n * r_n..].copy_from_slice(&glob[i * g_n..(i + 1) * g_n]);
        x
    }

    #[test]
    fn blocks_are_the_dense_gram_matrices_with_sparse_columns_as_dense() {
        let (n, m_n, r_n) = (300, 4, 2);
        let grid = HatGrid {
            k0: -2.0,
            step: 1.5,
            n: 8,
        };
        let mut seed = 12345u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let y: Vec<f64> = (0..n).map(|_| rnd() - 0.5).collect();
        let maneuver: Vec<usize> = (0..n).map(|i| (i * 7 + i / 13) % (m_n - 1)).collect(); // m 3 has none
        let alpha: Vec<f64> = (0..n).map(|_| -3.0 + 14.0 * rnd()).collect(); // past both ends
        let aero: Vec<f64> = (0..n * r_n).map(|_| rnd() - 0.5).collect();
        let dense_g: Vec<f64> = (0..n).map(|_| rnd() - 0.5).collect();
        let sp_rows: Vec<usize> = (0..n).filter(|i| i % 5 == 0).collect();
        let sp_vals: Vec<f64> = sp_rows.iter().map(|&i| 0.1 * i as f64).collect();
        let rows = Rows {
            y: &y,
            maneuver: &maneuver,
            alpha_deg: &alpha,
            aero: &aero,
            n_aero: r_n,
        };
        let globals = [
            GlobalBlock::Dense {
                data: &dense_g,
                cols: 1,
            },
            GlobalBlock::Sparse {
                rows: &sp_rows,
                values: &sp_vals,
            },
        ];
        let out = build_blocks(&rows, &globals, &grid, m_n).unwrap();
        let g_n = 2;
        let glob_all: Vec<f64> = (0..n)
            .flat_map(|i| [dense_g[i], if i % 5 == 0 { 0.1 * i as f64 } else { 0.0 }])
            .collect();
        let p = grid.n * r_n + g_n;
        let blocks = super::super::Blocks {
            layout: super::super::Layout {
                knots: grid.n,
                aero: r_n,
                global: g_n,
            },
            diag: &out.diag,
            off: &out.off,
            cross: &out.cross,
            glob: &out.glob,
            xty: &out.xty,
            yty: &out.yty,
            block_row: None,
            lowrank: None,
        };
        blocks.check().unwrap();
        for m in 0..m_n {
            let mut g = vec![0.0; p * p];
            let mut b = vec![0.0; p];
            let mut yy = 0.0;
            for i in (0..n).filter(|&i| maneuver[i] == m) {
                let x = dense_row(&rows, &glob_all, g_n, &grid, i);
                for a in 0..p {
                    b[a] += x[a] * y[i];
                    for c in 0..p {
                        g[a * p + c] += x[a] * x[c];
                    }
                }
                yy += y[i] * y[i];
            }
            assert!((out.yty[m] - yy).abs() <= 1e-12 * (1.0 + yy));
            for (a, want) in b.iter().enumerate() {
                assert!((out.xty[m * p + a] - want).abs() <= 1e-12, "xty {m} {a}");
            }
            // every entry of G, read from its block
            let kr = grid.n * r_n;
            let entry = |a: usize, c: usize| -> f64 {
                let (ka, ra, kc, rc) = (a / r_n, a % r_n, c / r_n, c % r_n);
                match (a < kr, c < kr) {
                    (true, true) if ka == kc => out.diag[((m * r_n + ra) * r_n + rc) * grid.n + ka],
                    (true, true) if kc == ka + 1 => {
                        out.off[((m * r_n + ra) * r_n + rc) * (grid.n - 1) + ka]
                    }
                    (true, true) if ka == kc + 1 => {
                        out.off[((m * r_n + rc) * r_n + ra) * (grid.n - 1) + kc]
                    }
                    (true, true) => 0.0,
                    (true, false) => out.cross[((m * r_n + ra) * g_n + (c - kr)) * grid.n + ka],
                    (false, true) => out.cross[((m * r_n + rc) * g_n + (a - kr)) * grid.n + kc],
                    (false, false) => out.glob[(m * g_n + a - kr) * g_n + c - kr],
                }
            };
            for a in 0..p {
                for c in 0..p {
                    assert!((entry(a, c) - g[a * p + c]).abs() <= 1e-12, "G {m} {a} {c}");
                }
            }
        }
        assert!(out.yty[3] == 0.0 && out.diag[3 * r_n * r_n * grid.n..].iter().all(|&v| v == 0.0));
    }

    #[test]
    fn bad_rows_are_named() {
        let grid = HatGrid {
            k0: 0.0,
            step: 1.0,
            n: 3,
        };
        let rows = Rows {
            y: &[1.0, 2.0],
            maneuver: &[0, 5],
            alpha_deg: &[1.0, 1.0],
            aero: &[],
            n_aero: 0,
        };
        let err = build_blocks(&rows, &[], &grid, 2).unwrap_err().to_string();
        assert!(err.starts_with("row 1:"), "{err}");
        let rows = Rows {
            y: &[1.0],
            maneuver: &[0],
            alpha_deg: &[f64::NAN],
            aero: &[],
            n_aero: 0,
        };
        let err = build_blocks(&rows, &[], &grid, 1).unwrap_err().to_string();
        assert!(err.contains("alpha_deg is not finite"), "{err}");
    }
}
