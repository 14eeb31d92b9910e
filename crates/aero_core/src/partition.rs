//! Alpha partitioning into bins (thesis Section 3.3.1, after Batterson).
//!
//! The data of one flap setting are split by angle of attack into contiguous
//! bins, each of which gets its own equation-error regression (thesis Eq. 3.5-3.11).
//! The thesis uses 0.2 deg bins where the data allow and wider bins at high
//! alpha where data are sparse, with "roughly 10 times the data points as there
//! are parameters to identify" in every bin (Section 3.3.1, step 2).
//!
//! # Algorithm (deterministic)
//! 1. Range $[\alpha_{lo}, \alpha_{hi}]$: the data's min and max, or a user range
//!    (samples outside it get bin index −1).
//! 2. Fine grid: the outer edges are $\alpha_{lo}$ and $\alpha_{hi}$; the interior
//!    edges are the multiples $a + k w$ of the nominal width $w$ (default
//!    0.2 deg, anchor $a$ default 0, so edges fall on 12.0, 12.2, ... deg) lying
//!    more than $w/2$ inside the range. End bins thus absorb partial cells and
//!    are between $w/2$ and $3w/2$ wide; on data spanning whole cells the fine
//!    grid is exactly the $w$ grid.
//! 3. Requirement: a bin is *filled* when it holds at least
//!    `min_points_per_param × n_params` samples and, if maneuver ids are given,
//!    samples from at least `min_maneuvers` distinct maneuvers (samples of one
//!    maneuver are correlated, so many points from one pass are weak evidence).
//! 4. Greedy merging: repeatedly take the under-filled bin with the fewest
//!    samples (ties: lowest alpha) and merge it with its *lighter* neighbour
//!    (fewer samples; ties: fewer maneuvers, then narrower, then the lower-alpha
//!    side). With a width cap, a merge that would exceed it is not made; a bin
//!    that cannot merge with either neighbour stays and is reported as
//!    under-filled, as is a single bin holding too few samples in total.
//!
//! Samples are assigned as `numpy.histogram` does: bin $i$ holds
//! $e_i \le \alpha < e_{i+1}$, the last bin also holds $\alpha = e_{last}$.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::error::{AeroError, Result};

/// Bin index of a sample outside the partitioned range.
pub const OUTSIDE: i64 = -1;

/// Settings of [`partition_alpha`].
#[derive(Debug, Clone, PartialEq)]
pub struct PartitionOptions {
    /// Nominal (finest) bin width, deg (thesis: 0.2).
    pub width_deg: f64,
    /// Required samples per identified parameter (thesis: about 10).
    pub min_points_per_param: usize,
    /// Required distinct maneuvers per bin (needs maneuver ids when above 1).
    pub min_maneuvers: usize,
    /// Range to partition, deg; `None` for the data's min and max.
    pub range_deg: Option<(f64, f64)>,
    /// Largest bin width, deg; bins that would need to grow past it are
    /// reported as under-filled instead. `None` for no cap.
    pub max_width_deg: Option<f64>,
    /// Interior edges lie on `anchor_deg + k * width_deg`.
    pub anchor_deg: f64,
}

impl Default for PartitionOptions {
    fn default() -> Self {
        PartitionOptions {
            width_deg: 0.2,
            min_points_per_param: 10,
            min_maneuvers: 1,
            range_deg: None,
            max_width_deg: None,
            anchor_deg: 0.0,
        }
    }
}

/// The bins of one partition, contiguous over the range.
#[derive(Debug, Clone, PartialEq)]
pub struct AlphaBins {
    /// Bin edges, deg, strictly increasing (bins + 1 values).
    pub edges: Vec<f64>,
    /// Samples per bin.
    pub counts: Vec<usize>,
    /// Distinct maneuvers per bin (`None` without maneuver ids).
    pub maneuvers: Option<Vec<usize>>,
    /// Bin of each sample, or [`OUTSIDE`] (−1) outside the range.
    pub index: Vec<i64>,
    /// Per bin, whether it misses the requirement (see the module doc).
    pub underfilled: Vec<bool>,
    /// Samples each bin must hold: `min_points_per_param × n_params`.
    pub required_points: usize,
    /// Distinct maneuvers each bin must hold.
    pub required_maneuvers: usize,
}

impl AlphaBins {
    /// Number of bins.
    pub fn len(&self) -> usize {
        self.counts.len()
    }

    /// Whether there are no bins (never true for a successful partition).
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// Bin centres, deg.
    pub fn centres(&self) -> Vec<f64> {
        self.edges.windows(2).map(|e| 0.5 * (e[0] + e[1])).collect()
    }

    /// Bin widths, deg.
    pub fn widths(&self) -> Vec<f64> {
        self.edges.windows(2).map(|e| e[1] - e[0]).collect()
    }
}

/// Partition alpha samples (deg) of one flap setting into bins holding enough
/// points for `n_params` parameters each (thesis Section 3.3.1); see the module
/// doc for the algorithm. `maneuver_id` gives each sample's maneuver.
///
/// ```
/// use aero_core::partition::{partition_alpha, PartitionOptions};
/// // 1400 samples uniform on [6, 20] deg: 20 per 0.2 deg cell, enough for 2 parameters.
/// let alpha: Vec<f64> = (0..1400).map(|i| 6.0 + (i as f64 + 0.5) * 0.01).collect();
/// let mut opts = PartitionOptions::default();
/// opts.range_deg = Some((6.0, 20.0));
/// let bins = partition_alpha(&alpha, 2, None, &opts).unwrap();
/// assert_eq!(bins.len(), 70);
/// assert!((bins.edges[1] - 6.2).abs() < 1e-12);
/// assert!(bins.counts.iter().all(|&c| c == 20));
/// ```
///
/// # Errors
/// - [`AeroError::TooLittleData`] with no samples, or none inside the range;
/// - [`AeroError::InvalidInput`] naming the row for a non-finite alpha, and for
///   `n_params == 0`, maneuver ids of the wrong length, `min_maneuvers > 1`
///   without maneuver ids, or a range that is not finite and increasing;
/// - [`AeroError::OutOfRange`] for a width that is not finite and positive, a
///   cap below the width, or a grid of more than 10 million fine bins.
pub fn partition_alpha(
    alpha_deg: &[f64],
    n_params: usize,
    maneuver_id: Option<&[u64]>,
    opts: &PartitionOptions,
) -> Result<AlphaBins> {
    const PLACE: &str = "alpha partition";
    let n = alpha_deg.len();
    if n == 0 {
        return Err(AeroError::too_little(
            PLACE,
            "no alpha samples; give the samples of one flap setting",
        ));
    }
    if let Some(i) = alpha_deg.iter().position(|a| !a.is_finite()) {
        return Err(AeroError::invalid(
            format!("{PLACE}, alpha_deg row {i}"),
            format!(
                "is {}; alpha must be finite (drop or fill the row)",
                alpha_deg[i]
            ),
        ));
    }
    if n_params == 0 {
        return Err(AeroError::invalid(
            PLACE,
            "n_params is 0; give the number of parameters each bin's regression identifies",
        ));
    }
    let w = opts.width_deg;
    if !(w.is_finite() && w > 0.0) {
        return Err(AeroError::out_of_range(
            format!("{PLACE}, width_deg"),
            format!("is {w}; the nominal bin width must be finite and > 0 (thesis: 0.2 deg)"),
        ));
    }
    if !opts.anchor_deg.is_finite() {
        return Err(AeroError::invalid(
            format!("{PLACE}, anchor_deg"),
            "must be finite",
        ));
    }
    if let Some(cap) = opts.max_width_deg {
        if cap.is_nan() || cap < w {
            return Err(AeroError::out_of_range(
                format!("{PLACE}, max_width_deg"),
                format!("is {cap}; the width cap must be at least the nominal width {w}"),
            ));
        }
    }
    if let Some(ids) = maneuver_id {
        if ids.len() != n {
            return Err(AeroError::invalid(
                format!("{PLACE}, maneuver_id"),
                format!("has {} entries for {n} alpha samples", ids.len()),
            ));
        }
    } else if opts.min_maneuvers > 1 {
        return Err(AeroError::invalid(
            format!("{PLACE}, min_maneuvers"),
            format!(
                "is {} but no maneuver ids were given; pass one maneuver id per sample",
                opts.min_maneuvers
            ),
        ));
    }

    let (lo, hi) = match opts.range_deg {
        Some((lo, hi)) => {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(AeroError::invalid(
                    format!("{PLACE}, alpha_range"),
                    format!("is ({lo}, {hi}); give finite bounds with lower < upper, deg"),
                ));
            }
            (lo, hi)
        }
        None => {
            let lo = alpha_deg.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = alpha_deg.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if lo == hi {
                (lo - 0.5 * w, hi + 0.5 * w)
            } else {
                (lo, hi)
            }
        }
    };
    let fine = fine_edges(lo, hi, w, opts.anchor_deg)?;
    let nfine = fine.len() - 1;
    let interior = &fine[1..nfine];

    // Fine bin of each sample, as numpy.histogram assigns it.
    let fine_index: Vec<Option<usize>> = alpha_deg
        .iter()
        .map(|&a| {
            (lo..=hi)
                .contains(&a)
                .then(|| interior.partition_point(|&e| e <= a))
        })
        .collect();
    let mut count = vec![0usize; nfine];
    for &b in fine_index.iter().flatten() {
        count[b] += 1;
    }
    if count.iter().all(|&c| c == 0) {
        return Err(AeroError::too_little(
            PLACE,
            format!("no alpha sample lies in the range [{lo}, {hi}] deg"),
        ));
    }
    let mut sets: Option<Vec<Vec<u64>>> = maneuver_id.map(|ids| {
        // consecutive samples mostly share their (fine bin, maneuver): repeats dropped before
        // the sort
        let mut pairs: Vec<(usize, u64)> = Vec::new();
        for (b, &id) in fine_index.iter().zip(ids) {
            if let Some(b) = *b {
                if pairs.last() != Some(&(b, id)) {
                    pairs.push((b, id));
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut sets = vec![Vec::new(); nfine];
        for (b, id) in pairs {
            sets[b].push(id);
        }
        sets
    });

    let req_pts = opts.min_points_per_param.saturating_mul(n_params);
    let req_man = if maneuver_id.is_some() {
        opts.min_maneuvers
    } else {
        0
    };
    let cap = opts.max_width_deg.map(|c| c * (1.0 + 1e-12) + 1e-12);

    // Bins as a doubly linked list over fine cells [start, end).
    let start: Vec<usize> = (0..nfine).collect();
    let mut end: Vec<usize> = (1..=nfine).collect();
    let mut prev: Vec<Option<usize>> = (0..nfine).map(|i| i.checked_sub(1)).collect();
    let mut next: Vec<Option<usize>> = (0..nfine)
        .map(|i| (i + 1 < nfine).then_some(i + 1))
        .collect();
    let mut alive = vec![true; nfine];
    let distinct = |sets: &Option<Vec<Vec<u64>>>, b: usize| sets.as_ref().map_or(0, |s| s[b].len());
    let filled = |count: &[usize], sets: &Option<Vec<Vec<u64>>>, b: usize| {
        count[b] >= req_pts && distinct(sets, b) >= req_man
    };

    let mut heap: BinaryHeap<Reverse<(usize, usize)>> = (0..nfine)
        .filter(|&b| !filled(&count, &sets, b))
        .map(|b| Reverse((count[b], b)))
        .collect();
    while let Some(Reverse((c, b))) = heap.pop() {
        if !alive[b] || count[b] != c || filled(&count, &sets, b) {
            continue;
        }
        let width_with = |o: usize| {
            let (s, e) = (start[b].min(start[o]), end[b].max(end[o]));
            fine[e] - fine[s]
        };
        let fits = |o: &usize| cap.is_none_or(|cap| width_with(*o) <= cap);
        let left = prev[b].filter(fits);
        let right = next[b].filter(fits);
        let key = |o: usize| (count[o], distinct(&sets, o), fine[end[o]] - fine[start[o]]);
        let other = match (left, right) {
            (None, None) => continue, // cannot grow: stays under-filled
            (Some(l), None) => l,
            (None, Some(r)) => r,
            (Some(l), Some(r)) => {
                let (kl, kr) = (key(l), key(r));
                if (kr.0, kr.1) < (kl.0, kl.1) || ((kr.0, kr.1) == (kl.0, kl.1) && kr.2 < kl.2) {
                    r
                } else {
                    l
                }
            }
        };
        // Keep the lower-alpha bin, absorb the upper one.
        let (keep, gone) = if start[other] < start[b] {
            (other, b)
        } else {
            (b, other)
        };
        end[keep] = end[gone];
        count[keep] += count[gone];
        count[gone] = 0;
        if let Some(s) = sets.as_mut() {
            let upper = std::mem::take(&mut s[gone]);
            s[keep] = merge_sorted(&s[keep], &upper);
        }
        next[keep] = next[gone];
        if let Some(nn) = next[gone] {
            prev[nn] = Some(keep);
        }
        alive[gone] = false;
        if !filled(&count, &sets, keep) {
            heap.push(Reverse((count[keep], keep)));
        }
    }

    // Collect the surviving bins in order.
    let mut order = Vec::new();
    let mut cur = Some(0usize);
    while let Some(b) = cur {
        order.push(b);
        cur = next[b];
    }
    let mut fine_to_bin = vec![0i64; nfine];
    let mut edges = Vec::with_capacity(order.len() + 1);
    edges.push(fine[0]);
    for (k, &b) in order.iter().enumerate() {
        for f in &mut fine_to_bin[start[b]..end[b]] {
            *f = k as i64;
        }
        edges.push(fine[end[b]]);
    }
    Ok(AlphaBins {
        edges,
        counts: order.iter().map(|&b| count[b]).collect(),
        maneuvers: sets
            .as_ref()
            .map(|s| order.iter().map(|&b| s[b].len()).collect()),
        index: fine_index
            .iter()
            .map(|b| b.map_or(OUTSIDE, |b| fine_to_bin[b]))
            .collect(),
        underfilled: order.iter().map(|&b| !filled(&count, &sets, b)).collect(),
        required_points: req_pts,
        required_maneuvers: req_man,
    })
}

/// Union of two sorted, deduplicated id lists.
fn merge_sorted(a: &[u64], b: &[u64]) -> Vec<u64> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => {
                out.push(a[i]);
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                out.push(b[j]);
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                out.push(a[i]);
                i += 1;
                j += 1;
            }
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// The fine grid over `[lo, hi]`: the outer edges, and the interior multiples
/// `anchor + k w` more than `w/2` inside. When `1/w` is an integer (0.2, 0.1,
/// 0.5 deg) edges are computed as `k / (1/w)` so they are the nearest doubles
/// to the decimal values (12.2, not 12.200000000000001).
fn fine_edges(lo: f64, hi: f64, w: f64, anchor: f64) -> Result<Vec<f64>> {
    let cells = (hi - lo) / w;
    if cells.is_nan() || cells > 1e7 {
        return Err(AeroError::out_of_range(
            "alpha partition, width_deg",
            format!(
                "{w} deg over [{lo}, {hi}] deg makes {cells:.3e} fine bins (limit 1e7); widen the bins"
            ),
        ));
    }
    let inv = 1.0 / w;
    let exact = (inv - inv.round()).abs() < 1e-9 * inv && inv.round() >= 1.0;
    let at = |k: f64| {
        if exact {
            anchor + k / inv.round()
        } else {
            anchor + k * w
        }
    };
    let kmin = ((lo + 0.5 * w - anchor) / w).floor() as i64 - 1;
    let kmax = ((hi - 0.5 * w - anchor) / w).ceil() as i64 + 1;
    let mut edges = vec![lo];
    for k in kmin..=kmax {
        let e = at(k as f64);
        if e > lo + 0.5 * w && e < hi - 0.5 * w {
            edges.push(e);
        }
    }
    edges.push(hi);
    Ok(edges)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::ChaCha8Rng;
    use rand_core::{Rng, SeedableRng};

    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn check_invariants(alpha: &[f64], bins: &AlphaBins) {
        assert!(bins.edges.windows(2).all(|e| e[1] > e[0]));
        let mut counts = vec![0usize; bins.len()];
        for (&a, &b) in alpha.iter().zip(&bins.index) {
            if b >= 0 {
                let b = b as usize;
                counts[b] += 1;
                assert!(a >= bins.edges[b]);
                assert!(a < bins.edges[b + 1] || (b + 1 == bins.len() && a == bins.edges[b + 1]));
            }
        }
        assert_eq!(counts, bins.counts);
    }

    #[test]
    fn dense_uniform_data_gives_the_fine_grid() {
        let alpha: Vec<f64> = (0..1400).map(|i| 6.0 + (i as f64 + 0.5) * 0.01).collect();
        let opts = PartitionOptions {
            range_deg: Some((6.0, 20.0)),
            ..Default::default()
        };
        let bins = partition_alpha(&alpha, 2, None, &opts).expect("partition");
        assert_eq!(bins.len(), 70);
        for (k, e) in bins.edges.iter().enumerate() {
            assert!((e - (6.0 + 0.2 * k as f64)).abs() < 1e-12);
        }
        assert!(bins.underfilled.iter().all(|&u| !u));
        check_invariants(&alpha, &bins);
    }

    #[test]
    fn sparse_tail_gets_wider_bins_all_filled() {
        // Dense 6-16 deg, density falling off to 26 deg.
        let mut u = uniform(1);
        let mut alpha: Vec<f64> = (0..5000).map(|_| 6.0 + 10.0 * u()).collect();
        alpha.extend((0..600).map(|_| 16.0 + 10.0 * u().powi(3)));
        let bins = partition_alpha(&alpha, 4, None, &PartitionOptions::default()).expect("p");
        check_invariants(&alpha, &bins);
        assert!(bins.counts.iter().all(|&c| c >= 40));
        assert!(bins.underfilled.iter().all(|&u| !u));
        let widths = bins.widths();
        let last = widths[widths.len() - 1];
        assert!(last > 1.0, "tail bin {last} deg");
        assert!(widths[5] < 0.21);
        assert_eq!(
            bins.edges[0],
            alpha.iter().copied().fold(f64::INFINITY, f64::min)
        );
    }

    #[test]
    fn min_maneuvers_and_cap_are_respected() {
        let mut u = uniform(2);
        let alpha: Vec<f64> = (0..3000).map(|_| 5.0 + 10.0 * u()).collect();
        // maneuver = which 1-deg slice, so a 0.2 deg bin sees one maneuver only.
        let ids: Vec<u64> = alpha.iter().map(|a| a.floor() as u64).collect();
        let opts = PartitionOptions {
            min_maneuvers: 3,
            ..Default::default()
        };
        let bins = partition_alpha(&alpha, 1, Some(&ids), &opts).expect("p");
        check_invariants(&alpha, &bins);
        let m = bins.maneuvers.as_ref().expect("maneuvers");
        assert!(m.iter().all(|&k| k >= 3));
        assert!(bins.underfilled.iter().all(|&u| !u));

        let capped = PartitionOptions {
            min_maneuvers: 3,
            max_width_deg: Some(1.0),
            ..Default::default()
        };
        let bins = partition_alpha(&alpha, 1, Some(&ids), &capped).expect("p");
        check_invariants(&alpha, &bins);
        assert!(bins.widths().iter().all(|&w| w <= 1.0 + 1e-9));
        assert!(bins.underfilled.iter().any(|&u| u));
    }

    #[test]
    fn too_few_points_overall_report_one_underfilled_bin() {
        let alpha = [1.0, 1.5, 2.0];
        let bins = partition_alpha(&alpha, 1, None, &PartitionOptions::default()).expect("p");
        assert_eq!(bins.len(), 1);
        assert_eq!(bins.underfilled, vec![true]);
        assert_eq!(bins.edges, vec![1.0, 2.0]);
        // All samples at one alpha: one nominal-width bin centred on it.
        let bins = partition_alpha(&[4.0; 50], 1, None, &PartitionOptions::default()).expect("p");
        assert_eq!(bins.len(), 1);
        assert!((bins.edges[0] - 3.9).abs() < 1e-12 && (bins.edges[1] - 4.1).abs() < 1e-12);
        assert_eq!(bins.counts, vec![50]);
    }

    #[test]
    fn range_excludes_outside_samples_and_is_deterministic() {
        let mut u = uniform(3);
        let alpha: Vec<f64> = (0..2000).map(|_| 20.0 * u()).collect();
        let opts = PartitionOptions {
            range_deg: Some((4.0, 12.0)),
            ..Default::default()
        };
        let a = partition_alpha(&alpha, 3, None, &opts).expect("p");
        let b = partition_alpha(&alpha, 3, None, &opts).expect("p");
        assert_eq!(a, b);
        assert_eq!(a.edges[0], 4.0);
        assert_eq!(a.edges[a.len()], 12.0);
        for (&x, &i) in alpha.iter().zip(&a.index) {
            assert_eq!(i == OUTSIDE, !(4.0..=12.0).contains(&x));
        }
        check_invariants(&alpha, &a);
    }

    proptest::proptest! {
        /// Without a cap, every bin is filled whenever the data can fill one bin;
        /// bins are contiguous, cover the data, and counts match the assignment.
        #[test]
        fn bins_are_filled_and_consistent(seed in 0u64..500, n in 2usize..3000, k in 1usize..8,
                                          tail in 0.5f64..4.0) {
            let mut u = uniform(seed);
            let alpha: Vec<f64> = (0..n).map(|_| 2.0 + 20.0 * u().powf(tail)).collect();
            let bins = partition_alpha(&alpha, k, None, &PartitionOptions::default()).expect("p");
            check_invariants(&alpha, &bins);
            let lo = alpha.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = alpha.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            proptest::prop_assert_eq!(bins.edges[0], lo);
            proptest::prop_assert_eq!(bins.edges[bins.len()], hi);
            proptest::prop_assert!(bins.index.iter().all(|&i| i >= 0));
            if n >= 10 * k {
                proptest::prop_assert!(bins.counts.iter().all(|&c| c >= 10 * k));
            } else {
                proptest::prop_assert_eq!(bins.len(), 1);
                proptest::prop_assert!(bins.underfilled[0]);
            }
            // Every edge but the outer two lies on the 0.2 deg grid.
            for e in &bins.edges[1..bins.len()] {
                proptest::prop_assert!((e * 5.0 - (e * 5.0).round()).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn errors_name_the_row() {
        let o = PartitionOptions::default();
        let e = partition_alpha(&[], 2, None, &o).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::TooLittleData);
        let e = partition_alpha(&[1.0, f64::NAN], 2, None, &o).unwrap_err();
        assert!(e.to_string().contains("row 1"), "{e}");
        let e = partition_alpha(&[1.0, 2.0], 0, None, &o).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::InvalidInput);
        let bad = PartitionOptions {
            width_deg: 0.0,
            ..Default::default()
        };
        assert!(partition_alpha(&[1.0, 2.0], 2, None, &bad).is_err());
        let bad = PartitionOptions {
            min_maneuvers: 2,
            ..Default::default()
        };
        assert!(partition_alpha(&[1.0, 2.0], 2, None, &bad).is_err());
    }
}
