//! Error metrics for calibration residuals and the repeatability floor of a dataset.
//!
//! * [`ErrorStats::of`] summarises a residual vector (RMSE, sample std, mean, max |r|, MAE).
//! * [`repeatability`] estimates the measurement repeatability from configurations that were
//!   visited more than once: rows whose joint vectors agree to within a tolerance on every joint
//!   are grouped (single linkage), and the pooled within-group standard deviation of the measured
//!   length is the noise floor no calibration model can beat.

use std::collections::BTreeMap;

/// Summary statistics of a residual vector.
///
/// Only finite residuals are used; `n` counts them, so `n < residuals.len()` flags NaN/∞ input.
/// With `n == 0` every field is zero; with `n == 1`, `std` is zero.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorStats {
    /// Number of (finite) residuals used.
    pub n: usize,
    /// Root mean square, `sqrt(Σ r² / n)`.
    pub rmse: f64,
    /// Sample standard deviation (`n − 1` denominator) of the residuals.
    pub std: f64,
    /// Arithmetic mean of the residuals.
    pub mean: f64,
    /// Largest absolute residual, `max |r|`.
    pub max: f64,
    /// Mean absolute residual, `Σ |r| / n`.
    pub mae: f64,
}

impl ErrorStats {
    /// Statistics of `residuals`, ignoring non-finite entries (see the type docs).
    pub fn of(residuals: &[f64]) -> ErrorStats {
        let finite = || residuals.iter().copied().filter(|r| r.is_finite());
        let n = finite().count();
        if n == 0 {
            return ErrorStats::default();
        }
        let nf = n as f64;
        let mean = finite().sum::<f64>() / nf;
        let (mut ss, mut sa, mut sdev, mut max) = (0.0, 0.0, 0.0, 0.0f64);
        for r in finite() {
            ss += r * r;
            sa += r.abs();
            sdev += (r - mean) * (r - mean);
            max = max.max(r.abs());
        }
        let std = if n > 1 { (sdev / (nf - 1.0)).sqrt() } else { 0.0 };
        ErrorStats { n, rmse: (ss / nf).sqrt(), std, mean, max, mae: sa / nf }
    }
}

/// Repeatability floor estimated from repeated configurations, see [`repeatability`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Repeatability {
    /// Pooled within-group standard deviation, `sqrt(Σ_g Σ_i (l_i − mean_g)² / Σ_g (n_g − 1))`.
    pub pooled_std: f64,
    /// Number of groups with at least two members.
    pub groups: usize,
    /// Number of rows in those groups.
    pub rows: usize,
    /// Largest `max − min` of `l` within a group.
    pub max_spread: f64,
    /// Where a reading holds several values (a point's x, y, z; a pose's origin and axes), each
    /// value's own pooled standard deviation, in the reading's order; empty for one value.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub per_value_std: Vec<f64>,
}

/// The rows `rows` of `q_deg` (degrees; rows with a non-finite angle are left out) grouped as
/// [`repeatability`] groups them: linked within `tol_deg` on every joint, single linkage. Each
/// group in row order, the groups in the order of their first row.
pub fn configuration_groups<Q: AsRef<[f64]>>(q_deg: &[Q], rows: &[usize], tol_deg: f64) -> Vec<Vec<usize>> {
    let q_deg: Vec<&[f64]> = q_deg.iter().map(|q| q.as_ref()).collect();
    let rows: Vec<usize> = rows.iter().copied().filter(|&i| q_deg[i].iter().all(|v| v.is_finite())).collect();
    let max_abs = rows.iter().flat_map(|&i| q_deg[i].iter()).fold(0.0f64, |m, v| m.max(v.abs()));
    let mut uf = UnionFind::new(q_deg.len());
    if !(tol_deg.is_finite() && tol_deg > 0.0) || tol_deg < 1e-12 * max_abs {
        link_exact(&q_deg, &rows, &mut uf);
    } else {
        link_grid(&q_deg, &rows, tol_deg, &mut uf);
    }
    let mut members: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &i in &rows {
        members.entry(uf.find(i)).or_default().push(i);
    }
    let mut groups: Vec<Vec<usize>> = members.into_values().collect();
    groups.sort_by_key(|g| g[0]);
    groups
}

/// Repeatability floor of `l` over repeated joint configurations `q_deg` (degrees).
///
/// Two rows are *linked* when their joint vectors differ by at most `tol_deg` on every joint
/// (Chebyshev distance ≤ `tol_deg`); groups are the connected components of that relation
/// (single linkage), so a chain of near-identical configurations forms one group even when its
/// ends are further apart than `tol_deg`. Only groups with ≥ 2 rows contribute.
///
/// Rows with a non-finite joint angle or length are skipped. `tol_deg == 0` groups exactly equal
/// joint vectors; a tolerance so small relative to the angles that a `tol_deg` grid is not
/// representable (below `1e-12 · max |q|`) is treated as 0 as well.
///
/// Complexity: O(n log n) for the sort plus the comparisons between rows whose angles on the
/// sorting joint lie within `tol_deg` of each other (see `link_grid`). Any number of joints.
///
/// Returns `None` when the lengths differ, `tol_deg` is negative or not finite, or no group has
/// two or more members.
pub fn repeatability<Q: AsRef<[f64]>>(q_deg: &[Q], l: &[f64], tol_deg: f64) -> Option<Repeatability> {
    let q_deg: Vec<&[f64]> = q_deg.iter().map(|q| q.as_ref()).collect();
    let q_deg = q_deg.as_slice();
    if q_deg.len() != l.len() || !tol_deg.is_finite() || tol_deg < 0.0 {
        return None;
    }
    let rows: Vec<usize> = (0..l.len()).filter(|&i| l[i].is_finite() && q_deg[i].iter().all(|v| v.is_finite())).collect();
    if rows.len() < 2 {
        return None;
    }
    let max_abs = rows.iter().flat_map(|&i| q_deg[i].iter()).fold(0.0f64, |m, v| m.max(v.abs()));
    let mut uf = UnionFind::new(l.len());
    if tol_deg == 0.0 || tol_deg < 1e-12 * max_abs {
        link_exact(q_deg, &rows, &mut uf);
    } else {
        link_grid(q_deg, &rows, tol_deg, &mut uf);
    }

    // Collect components in row order (deterministic summation order).
    let mut members: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &i in &rows {
        members.entry(uf.find(i)).or_default().push(i);
    }
    let (mut ss, mut dof, mut groups, mut nrows, mut max_spread) = (0.0, 0usize, 0usize, 0usize, 0.0f64);
    for g in members.values().filter(|g| g.len() >= 2) {
        let mean = g.iter().map(|&i| l[i]).sum::<f64>() / g.len() as f64;
        ss += g.iter().map(|&i| (l[i] - mean).powi(2)).sum::<f64>();
        dof += g.len() - 1;
        groups += 1;
        nrows += g.len();
        let (lo, hi) = g.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &i| (lo.min(l[i]), hi.max(l[i])));
        max_spread = max_spread.max(hi - lo);
    }
    if groups == 0 {
        return None;
    }
    Some(Repeatability { pooled_std: (ss / dof as f64).sqrt(), groups, rows: nrows, max_spread, per_value_std: Vec::new() })
}

/// Union rows whose joint vectors are exactly equal (sort lexicographically, link neighbours).
fn link_exact(q: &[&[f64]], rows: &[usize], uf: &mut UnionFind) {
    let mut sorted = rows.to_vec();
    // `+ 0.0` maps −0 to +0 so that both sort together.
    sorted.sort_by(|&a, &b| q[a].iter().zip(q[b]).map(|(x, y)| (x + 0.0).total_cmp(&(y + 0.0))).find(|o| o.is_ne()).unwrap_or(std::cmp::Ordering::Equal));
    for w in sorted.windows(2) {
        if q[w[0]] == q[w[1]] {
            uf.union(w[0], w[1]);
        }
    }
}

/// Union rows whose joint vectors are within `tol` on every joint: rows sorted along the joint
/// with the most distinct values, each compared with the rows after it until that joint differs
/// by more than `tol` (near-equal configurations are neighbours in that order).
fn link_grid(q: &[&[f64]], rows: &[usize], tol: f64, uf: &mut UnionFind) {
    let distinct = |k: usize| {
        let mut v: Vec<f64> = rows.iter().map(|&i| q[i][k]).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v.len()
    };
    let joints = rows.first().map_or(0, |&i| q[i].len());
    let axis = (0..joints).max_by_key(|&k| (distinct(k), std::cmp::Reverse(k))).unwrap_or(0);
    let mut sorted = rows.to_vec();
    sorted.sort_by(|&a, &b| q[a][axis].total_cmp(&q[b][axis]).then(a.cmp(&b)));
    let near = |a: usize, b: usize| q[a].iter().zip(q[b]).all(|(x, y)| (x - y).abs() <= tol);
    for (n, &i) in sorted.iter().enumerate() {
        for &j in &sorted[n + 1..] {
            if q[j][axis] - q[i][axis] > tol {
                break;
            }
            if near(i, j) {
                uf.union(i, j);
            }
        }
    }
}

/// Disjoint-set forest with path halving and union by size.
struct UnionFind {
    parent: Vec<usize>,
    size: Vec<usize>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind { parent: (0..n).collect(), size: vec![1; n] }
    }
    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }
    fn union(&mut self, a: usize, b: usize) {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        if self.size[a] < self.size[b] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b] = a;
        self.size[a] += self.size[b];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn error_stats_known_vector() {
        let s = ErrorStats::of(&[1.0, -2.0, 3.0, -4.0]);
        assert_eq!(s.n, 4);
        assert!(close(s.mean, -0.5, 1e-15));
        assert!(close(s.rmse, (30.0f64 / 4.0).sqrt(), 1e-15));
        // Σ(r − mean)² = 2.25 + 2.25 + 12.25 + 12.25 = 29
        assert!(close(s.std, (29.0f64 / 3.0).sqrt(), 1e-15));
        assert!(close(s.max, 4.0, 0.0));
        assert!(close(s.mae, 2.5, 1e-15));
    }

    #[test]
    fn error_stats_degenerate() {
        assert_eq!(ErrorStats::of(&[]), ErrorStats::default());
        let s = ErrorStats::of(&[f64::NAN, 2.0, f64::INFINITY]);
        assert_eq!(s.n, 1);
        assert_eq!((s.rmse, s.std, s.mean, s.max, s.mae), (2.0, 0.0, 2.0, 2.0, 2.0));
    }

    #[test]
    fn repeatability_known_std() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.05).unwrap();
        let (mut q, mut l) = (Vec::new(), Vec::new());
        let (mut ss, mut dof) = (0.0, 0);
        for g in 0..200 {
            let base: [f64; 6] = std::array::from_fn(|_| rng.random_range(-170.0..170.0));
            let lg = 1000.0 + g as f64;
            let mut vals = Vec::new();
            for _ in 0..5 {
                // Joint jitter well below the tolerance.
                q.push(base.map(|v| v + rng.random_range(-0.001..0.001)));
                vals.push(lg + noise.sample(&mut rng));
            }
            let m = vals.iter().sum::<f64>() / 5.0;
            ss += vals.iter().map(|v| (v - m).powi(2)).sum::<f64>();
            dof += 4;
            l.extend(vals);
        }
        // A few singletons that must not form groups.
        for _ in 0..10 {
            q.push(std::array::from_fn(|_| rng.random_range(-170.0..170.0)));
            l.push(5.0);
        }
        let r = repeatability(&q, &l, 0.01).unwrap();
        assert_eq!(r.groups, 200);
        assert_eq!(r.rows, 1000);
        assert!(close(r.pooled_std, (ss / dof as f64).sqrt(), 1e-12));
        assert!(close(r.pooled_std, 0.05, 0.005), "{}", r.pooled_std);
        assert!(r.max_spread > 0.0 && r.max_spread < 0.5);
    }

    #[test]
    fn repeatability_boundary_straddling() {
        // With tol = 0.1 the values 0.0999 and 0.1001 fall in different grid cells on several
        // joints, yet are within tolerance and must group.
        let a = [0.0999, 0.1999, -0.0001, 10.0, 0.0, 0.0];
        let b = [0.1001, 0.2001, 0.0001, 10.0, 0.0, 0.0];
        let c = [5.0; 6];
        let r = repeatability(&[a, c, b], &[1.0, 7.0, 3.0], 0.1).unwrap();
        assert_eq!((r.groups, r.rows), (1, 2));
        assert!(close(r.pooled_std, 2f64.sqrt(), 1e-12));
        assert!(close(r.max_spread, 2.0, 1e-12));
        // Chain linkage: x0 - x1 - x2 each within tol, ends not.
        let chain = [[0.0; 6], [0.08, 0.0, 0.0, 0.0, 0.0, 0.0], [0.16, 0.0, 0.0, 0.0, 0.0, 0.0]];
        let r = repeatability(&chain, &[0.0, 1.0, 2.0], 0.1).unwrap();
        assert_eq!((r.groups, r.rows), (1, 3));
        // Just outside the tolerance on one joint: no group.
        let far = [[0.0; 6], [0.0, 0.0, 0.0, 0.0, 0.0, 0.1001]];
        assert_eq!(repeatability(&far, &[0.0, 1.0], 0.1), None);
    }

    #[test]
    fn repeatability_exact_and_degenerate() {
        let q = [[1.0; 6], [2.0; 6], [1.0; 6], [-0.0; 6], [0.0; 6]];
        let l = [1.0, 2.0, 2.0, 4.0, 6.0];
        let r = repeatability(&q, &l, 0.0).unwrap();
        assert_eq!((r.groups, r.rows), (2, 4));
        // ss = 0.5 + 2 over dof 2
        assert!(close(r.pooled_std, (2.5f64 / 2.0).sqrt(), 1e-12));
        assert_eq!(repeatability(&q, &l[..4], 0.1), None);
        assert_eq!(repeatability(&q, &l, -1.0), None);
        assert_eq!(repeatability(&q, &l, f64::NAN), None);
        assert_eq!(repeatability::<[f64; 6]>(&[], &[], 0.1), None);
        assert_eq!(repeatability(&[[f64::NAN; 6], [f64::NAN; 6]], &[1.0, 2.0], 0.1), None);
    }
}
