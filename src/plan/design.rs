//! Optimal design over a candidate pool: choose `n` candidates (each a block of `d` rows of a
//! scaled identification Jacobian) that maximise an observability index of the stacked rows.
//!
//! The information matrix of a design S is M = Σ_{c∈S} A_cᵀA_c (+ a tiny ridge so that a design
//! still rank-deficient has a determinant). A greedy pass adds, one at a time, the candidate
//! that raises log det M most: log det(M + AᵀA) − log det M = log det(I + A M⁻¹ Aᵀ), a d×d
//! determinant through the Cholesky factor of M. An exchange pass then visits each chosen
//! candidate in turn and swaps it for the unchosen one that makes the design best (Fedorov's
//! exchange), until a sweep swaps nothing. For the D criterion every candidate is judged
//! exactly by the same determinant, for the I criterion exactly by the Woodbury update of
//! trace(M⁻¹W) ([`Criterion::gains`]); for the others the exchange judges the few candidates with
//! the largest determinant gain (a shortlist) by the criterion itself, from the eigenvalues of
//! the exchanged design's M.
//!
//! The criteria are the observability indices of the calibration literature (Sun and
//! Hollerbach's O1..O5 numbering), computed from the singular values σ of the stacked scaled
//! Jacobian; each names itself, so the list stays open.

use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;
use serde::Serialize;

/// An observability index: larger is better.
pub trait Criterion: Sync {
    /// Its name on the command line.
    fn name(&self) -> &'static str;
    /// Its index in the literature (O1, O3, ...) and what it measures.
    fn describe(&self) -> &'static str;
    /// Its value for a design with information matrix `info` (the ridge included) of `rows`
    /// stacked rows, drawn from `pool`.
    fn value(&self, info: &DMatrix<f64>, rows: usize, pool: &Pool) -> f64;
    /// Every candidate's exact improvement of the criterion when added to a design of
    /// information `m` (−∞ for the `taken` ones), where the criterion can tell it cheaply; `None`
    /// lets the exchange judge a shortlist of the largest determinant gains instead.
    fn gains(&self, _pool: &Pool, _m: &DMatrix<f64>, _taken: &[bool]) -> Option<Vec<f64>> {
        None
    }
}

/// An index of the singular values `sv` of the stacked scaled Jacobian of `rows` rows (O1, O3,
/// O4, O5): their [`Criterion::value`] is this of the design's singular values.
pub trait SingularIndex {
    /// The index of `sv`.
    fn of_sv(&self, sv: &[f64], rows: usize) -> f64;
}

/// O1: the geometric mean of the singular values over √m, D-optimality (the volume of the
/// parameters' confidence ellipsoid).
pub struct DOptimal;
/// O3: the smallest singular value (the worst-determined parameter combination).
pub struct MinSingular;
/// O4: the noise amplification index σ_min²/σ_max.
pub struct NoiseAmplification;
/// O5: 1/Σ(1/σ), A-optimality-like (the parameters' summed variance).
pub struct AOptimal;
/// I-optimal: the mean variance over the pool's poses of what the pool's [`Pool::mean`] stands
/// for, per unit noise variance, trace(M⁻¹ W) / [`Pool::target_dim`] (its value is the
/// negative, so that larger is better). A plan's pool holds the calibrated arm's tool point,
/// its base registered ([`super::PoolDesign`]): the accuracy a plan promises over the workspace the
/// pool stands for.
pub struct IOptimal;

impl Criterion for DOptimal {
    fn name(&self) -> &'static str {
        "d"
    }
    fn describe(&self) -> &'static str {
        "O1, D-optimal: (Π σ)^(1/p) / √m"
    }
    fn value(&self, info: &DMatrix<f64>, rows: usize, _pool: &Pool) -> f64 {
        self.of_sv(&singular_values(info), rows)
    }
}

impl SingularIndex for DOptimal {
    fn of_sv(&self, sv: &[f64], rows: usize) -> f64 {
        let p = sv.len().max(1) as f64;
        (sv.iter().map(|s| s.max(1e-300).ln()).sum::<f64>() / p).exp() / (rows.max(1) as f64).sqrt()
    }
}

impl Criterion for IOptimal {
    fn name(&self) -> &'static str {
        "i"
    }
    fn describe(&self) -> &'static str {
        "I-optimal: mean variance of the predicted tool point over the pool, base registered, trace(M⁻¹ W)/3"
    }
    fn value(&self, info: &DMatrix<f64>, _rows: usize, pool: &Pool) -> f64 {
        -prediction_variance(info, pool)
    }
    /// Adding candidate A to M lowers trace(M⁻¹W) by trace((I + A M⁻¹Aᵀ)⁻¹ A M⁻¹WM⁻¹ Aᵀ)
    /// (Woodbury): with B = A M⁻¹, trace((I + B Aᵀ)⁻¹ B W Bᵀ), about 2·d·p² per candidate.
    fn gains(&self, pool: &Pool, m: &DMatrix<f64>, taken: &[bool]) -> Option<Vec<f64>> {
        let (d, p) = (pool.d, pool.p);
        let l = cholesky(m);
        let minv = nalgebra::Cholesky::pack_dirty(l).inverse();
        let (mi, w) = (minv.as_slice(), pool.mean.as_slice());
        let gains = (0..pool.len())
            .into_par_iter()
            .map_init(
                || (vec![0.0; d * p], vec![0.0; d * p]),
                |(b, bw), c| {
                    if taken[c] {
                        return f64::NEG_INFINITY;
                    }
                    let a = pool.block(c);
                    // B = A M⁻¹ and BW (M⁻¹, W symmetric: column j is row j).
                    for r in 0..d {
                        let ar = &a[r * p..(r + 1) * p];
                        for j in 0..p {
                            b[r * p + j] = ar.iter().zip(&mi[j * p..(j + 1) * p]).map(|(x, y)| x * y).sum();
                        }
                        for j in 0..p {
                            bw[r * p + j] = b[r * p..(r + 1) * p].iter().zip(&w[j * p..(j + 1) * p]).map(|(x, y)| x * y).sum();
                        }
                    }
                    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(u, v)| u * v).sum::<f64>();
                    let u = DMatrix::from_fn(d, d, |r, s| dot(&b[r * p..(r + 1) * p], &a[s * p..(s + 1) * p]) + if r == s { 1.0 } else { 0.0 });
                    let v = DMatrix::from_fn(d, d, |r, s| dot(&bw[r * p..(r + 1) * p], &b[s * p..(s + 1) * p]));
                    match u.cholesky() {
                        Some(ch) => ch.solve(&v).trace() / pool.target_dim as f64,
                        None => f64::NEG_INFINITY,
                    }
                },
            )
            .collect();
        Some(gains)
    }
}

impl Criterion for MinSingular {
    fn name(&self) -> &'static str {
        "min-sv"
    }
    fn describe(&self) -> &'static str {
        "O3, the smallest singular value"
    }
    fn value(&self, info: &DMatrix<f64>, rows: usize, _pool: &Pool) -> f64 {
        self.of_sv(&singular_values(info), rows)
    }
}

impl SingularIndex for MinSingular {
    fn of_sv(&self, sv: &[f64], _rows: usize) -> f64 {
        sv.iter().copied().fold(f64::INFINITY, f64::min)
    }
}

impl Criterion for NoiseAmplification {
    fn name(&self) -> &'static str {
        "noise"
    }
    fn describe(&self) -> &'static str {
        "O4, noise amplification: σ_min² / σ_max"
    }
    fn value(&self, info: &DMatrix<f64>, rows: usize, _pool: &Pool) -> f64 {
        self.of_sv(&singular_values(info), rows)
    }
}

impl SingularIndex for NoiseAmplification {
    fn of_sv(&self, sv: &[f64], _rows: usize) -> f64 {
        let (lo, hi) = sv.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), s| (lo.min(*s), hi.max(*s)));
        if hi > 0.0 {
            lo * lo / hi
        } else {
            0.0
        }
    }
}

impl Criterion for AOptimal {
    fn name(&self) -> &'static str {
        "a"
    }
    fn describe(&self) -> &'static str {
        "O5: 1 / Σ (1/σ)"
    }
    fn value(&self, info: &DMatrix<f64>, rows: usize, _pool: &Pool) -> f64 {
        self.of_sv(&singular_values(info), rows)
    }
}

impl SingularIndex for AOptimal {
    fn of_sv(&self, sv: &[f64], _rows: usize) -> f64 {
        1.0 / sv.iter().map(|s| 1.0 / s.max(1e-300)).sum::<f64>()
    }
}

/// trace(M⁻¹ W) / [`Pool::target_dim`]: the mean variance of a predicted value (the tool point's coordinates in a plan) over the pool's poses, per
/// unit noise variance.
pub fn prediction_variance(info: &DMatrix<f64>, pool: &Pool) -> f64 {
    let l = cholesky(info);
    let x = nalgebra::Cholesky::pack_dirty(l).solve(&pool.mean);
    x.trace() / pool.target_dim as f64
}

/// Every criterion, the default first.
pub const CRITERIA: [&dyn Criterion; 5] = [&IOptimal, &DOptimal, &MinSingular, &NoiseAmplification, &AOptimal];

/// The criterion named `name`.
pub fn criterion(name: &str) -> crate::Result<&'static dyn Criterion> {
    CRITERIA
        .iter()
        .copied()
        .find(|c| c.name() == name)
        .ok_or_else(|| crate::Error::Invalid(format!("unknown criterion '{name}' (expected one of: {})", CRITERIA.map(|c| c.name()).join(", "))))
}

/// The candidates: `d` rows of `p` scaled Jacobian values each, candidate after candidate.
pub struct Pool {
    /// Row-major blocks: candidate c's row r is `rows[(c·d + r)·p ..][..p]`.
    pub rows: Vec<f64>,
    /// Rows per candidate.
    pub d: usize,
    /// Columns (parameters).
    pub p: usize,
    /// The mean information per candidate, Σ A_cᵀA_c / C, of what the plan promises accuracy on
    /// (the I criterion's W): the readings' by default, [`Pool::with_target`] sets another.
    pub mean: DMatrix<f64>,
    /// The number of values per pose `mean` stands for (the I criterion's mean variance is per
    /// value).
    pub target_dim: usize,
}

impl Pool {
    /// The pool of `rows` (see [`Pool::rows`]).
    pub fn new(rows: Vec<f64>, d: usize, p: usize) -> Pool {
        let mut pool = Pool { rows, d, p, mean: DMatrix::zeros(p, p), target_dim: d };
        let c = pool.len();
        let mut m = DMatrix::zeros(p, p);
        (0..c).for_each(|k| pool.add(&mut m, k, 1.0));
        pool.mean = m / c.max(1) as f64;
        pool
    }
    /// The pool judged by the I criterion on `mean`, the mean information per pose of `dim`
    /// values other than the readings (the tool point's, for instance).
    pub fn with_target(mut self, mean: DMatrix<f64>, dim: usize) -> Pool {
        assert_eq!((mean.nrows(), mean.ncols()), (self.p, self.p), "the target's information has the design's columns");
        self.mean = mean;
        self.target_dim = dim;
        self
    }
    /// Number of candidates.
    pub fn len(&self) -> usize {
        self.rows.len() / (self.d * self.p).max(1)
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn block(&self, c: usize) -> &[f64] {
        &self.rows[c * self.d * self.p..(c + 1) * self.d * self.p]
    }
    /// M += s·A_cᵀA_c.
    fn add(&self, m: &mut DMatrix<f64>, c: usize, s: f64) {
        let p = self.p;
        for row in self.block(c).chunks(p) {
            for i in 0..p {
                let v = s * row[i];
                if v != 0.0 {
                    for j in 0..p {
                        m[(i, j)] += v * row[j];
                    }
                }
            }
        }
    }
    /// The information matrix of `set` with the ridge.
    pub fn information(&self, set: &[usize]) -> DMatrix<f64> {
        let mut m = DMatrix::identity(self.p, self.p) * RIDGE;
        set.iter().for_each(|&c| self.add(&mut m, c, 1.0));
        m
    }
}

/// Added to the information matrix's diagonal (the scaled rows are about 1 per column).
pub const RIDGE: f64 = 1e-9;

/// Shortlist of the exchange for a criterion other than D.
const SHORTLIST: usize = 64;

/// The singular values of the stacked rows of a design with information matrix `m`.
pub fn singular_values(m: &DMatrix<f64>) -> Vec<f64> {
    let mut sv: Vec<f64> = SymmetricEigen::new(m.clone()).eigenvalues.iter().map(|l| (l - RIDGE).max(0.0).sqrt()).collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    sv
}

/// log det(I + A L⁻ᵀL⁻¹ Aᵀ) for candidate block `a` (d rows of p) and the lower Cholesky factor
/// `l` of M: the raise of log det M that adding the candidate brings. `z` is scratch (d·p).
fn gain(l: &DMatrix<f64>, a: &[f64], d: usize, p: usize, z: &mut [f64]) -> f64 {
    // z_r = L⁻¹ a_rᵀ by forward substitution.
    for r in 0..d {
        let (ar, zr) = (&a[r * p..(r + 1) * p], &mut z[r * p..(r + 1) * p]);
        for i in 0..p {
            let mut s = ar[i];
            for k in 0..i {
                s -= l[(i, k)] * zr[k];
            }
            zr[i] = s / l[(i, i)];
        }
    }
    // G = I + Z Zᵀ (d×d), its log-determinant by Cholesky.
    let mut g = [0.0; 81];
    for r in 0..d {
        for c in 0..=r {
            let dot: f64 = z[r * p..(r + 1) * p].iter().zip(&z[c * p..(c + 1) * p]).map(|(x, y)| x * y).sum();
            g[r * d + c] = dot + if r == c { 1.0 } else { 0.0 };
        }
    }
    let mut logdet = 0.0;
    for j in 0..d {
        let mut s = g[j * d + j];
        for k in 0..j {
            s -= g[j * d + k] * g[j * d + k];
        }
        let ljj = s.max(1e-300).sqrt();
        logdet += 2.0 * ljj.ln();
        g[j * d + j] = ljj;
        for i in j + 1..d {
            let mut s = g[i * d + j];
            for k in 0..j {
                s -= g[i * d + k] * g[j * d + k];
            }
            g[i * d + j] = s / ljj;
        }
    }
    logdet
}

/// Each candidate's determinant gain given M (its Cholesky factor `l`); chosen ones get −∞.
fn gains(pool: &Pool, l: &DMatrix<f64>, chosen: &[bool]) -> Vec<f64> {
    let (d, p) = (pool.d, pool.p);
    (0..pool.len()).into_par_iter().map_init(|| vec![0.0; d * p], |z, c| if chosen[c] { f64::NEG_INFINITY } else { gain(l, pool.block(c), d, p, z) }).collect()
}

fn cholesky(m: &DMatrix<f64>) -> DMatrix<f64> {
    match m.clone().cholesky() {
        Some(c) => c.l(),
        // Rounding may leave a removal a hair indefinite: a larger ridge settles it.
        None => (m + DMatrix::identity(m.nrows(), m.ncols()) * 1e-6).cholesky().map_or_else(|| DMatrix::identity(m.nrows(), m.ncols()), |c| c.l()),
    }
}

fn argmax(v: &[f64]) -> Option<usize> {
    v.iter().enumerate().filter(|(_, g)| g.is_finite()).max_by(|a, b| a.1.total_cmp(b.1)).map(|(i, _)| i)
}

/// The design found, with how the search went.
#[derive(Clone, Debug, Serialize)]
pub struct Design {
    /// The chosen candidates (indices into the pool), in the order they hold in the design.
    pub chosen: Vec<usize>,
    /// The criterion's value of the design.
    pub value: f64,
    /// Exchange sweeps run, and swaps made.
    pub sweeps: usize,
    /// Swaps made by the exchange.
    pub exchanges: usize,
}

/// The criterion's value of `set`.
pub fn value_of(pool: &Pool, set: &[usize], crit: &dyn Criterion) -> f64 {
    crit.value(&pool.information(set), set.len() * pool.d, pool)
}

/// Chooses `n` of the pool's candidates that maximise `crit`: greedy D-optimal start, then
/// exchange sweeps (at most `max_sweeps`) until none swaps. `stop` is asked between steps.
pub fn design(pool: &Pool, n: usize, crit: &dyn Criterion, max_sweeps: usize) -> Design {
    exchange(pool, greedy(pool, n), crit, max_sweeps)
}

/// `d` with no group `g` held by fewer than `min[g]` rows: the rows of every group (`group[c]`,
/// candidate `c`'s) that `d` holds too few of are left out, and their places refilled one at a
/// time by the candidate that raises log det M most among the groups it holds enough of (where
/// it holds none, the group it holds most of). A placement needs its rows before
/// a calibration can place it at all (a socket's ball turned about it three times, a face
/// touched six times): a design that spends two rows on a socket spends them on nothing. The
/// groups left out, with the rows they had.
pub fn with_full_groups(pool: &Pool, d: &mut Design, group: &[usize], min: &[usize], crit: &dyn Criterion) -> Vec<(usize, usize)> {
    let n = d.chosen.len();
    let count = |chosen: &[usize], g: usize| chosen.iter().filter(|&&c| group[c] == g).count();
    let mut groups: Vec<usize> = d.chosen.iter().map(|&c| group[c]).collect();
    groups.sort_unstable();
    groups.dedup();
    let short: Vec<(usize, usize)> = groups.iter().map(|&g| (g, count(&d.chosen, g))).filter(|&(g, k)| k < min[g]).collect();
    if short.is_empty() {
        return short;
    }
    let mut full: Vec<usize> = groups.iter().copied().filter(|g| !short.iter().any(|(s, _)| s == g)).collect();
    if full.is_empty() {
        full.extend(groups.iter().copied().max_by_key(|&g| (count(&d.chosen, g), std::cmp::Reverse(g))));
    }
    d.chosen.retain(|&c| full.contains(&group[c]));
    let mut taken = vec![false; pool.len()];
    d.chosen.iter().for_each(|&c| taken[c] = true);
    // Candidates of other groups are out of the running.
    (0..pool.len()).filter(|&c| !full.contains(&group[c])).for_each(|c| taken[c] = true);
    let mut m = pool.information(&d.chosen);
    while d.chosen.len() < n {
        crate::progress::check_stop();
        let Some(c) = argmax(&gains(pool, &cholesky(&m), &taken)) else { break };
        d.chosen.push(c);
        taken[c] = true;
        pool.add(&mut m, c, 1.0);
    }
    d.value = value_of(pool, &d.chosen, crit);
    short
}

/// The greedy D-optimal start: `n` candidates added one at a time, each the one that raises
/// log det M most.
fn greedy(pool: &Pool, n: usize) -> Vec<usize> {
    let n = n.min(pool.len());
    let mut chosen = Vec::with_capacity(n);
    let mut taken = vec![false; pool.len()];
    let mut m = pool.information(&[]);
    for _ in 0..n {
        crate::progress::check_stop();
        let g = gains(pool, &cholesky(&m), &taken);
        let Some(c) = argmax(&g) else { break };
        chosen.push(c);
        taken[c] = true;
        pool.add(&mut m, c, 1.0);
    }
    chosen
}

/// Fedorov's exchange from the set `start` (distinct candidates): sweeps (at most
/// `max_sweeps`) that swap each chosen candidate for the one that makes the design best, until
/// a sweep swaps nothing.
fn exchange(pool: &Pool, start: Vec<usize>, crit: &dyn Criterion, max_sweeps: usize) -> Design {
    let n = start.len();
    let mut chosen = start;
    let mut taken = vec![false; pool.len()];
    chosen.iter().for_each(|&c| taken[c] = true);
    let mut m = pool.information(&chosen);
    let is_d = crit.name() == DOptimal.name();
    let score = |m: &DMatrix<f64>| if is_d { logdet(m) } else { crit.value(m, n * pool.d, pool) };
    let mut current = score(&m);
    let (mut sweeps, mut exchanges) = (0, 0);
    while sweeps < max_sweeps {
        sweeps += 1;
        let mut swapped = false;
        for k in 0..chosen.len() {
            crate::progress::check_stop();
            let out = chosen[k];
            let mut minus = m.clone();
            pool.add(&mut minus, out, -1.0);
            let exact = if is_d { None } else { crit.gains(pool, &minus, &taken) };
            let g = if exact.is_none() { gains(pool, &cholesky(&minus), &taken) } else { Vec::new() };
            let best = if is_d {
                argmax(&g).map(|c| (c, logdet(&minus) + g[c]))
            } else if let Some(exact) = exact {
                argmax(&exact).map(|c| {
                    let mut t = minus.clone();
                    pool.add(&mut t, c, 1.0);
                    (c, score(&t))
                })
            } else {
                let mut order: Vec<usize> = (0..g.len()).filter(|&c| g[c].is_finite()).collect();
                let keep = SHORTLIST.min(order.len());
                if keep > 0 {
                    order.select_nth_unstable_by(keep - 1, |a, b| g[*b].total_cmp(&g[*a]));
                }
                order[..keep]
                    .iter()
                    .map(|&c| {
                        let mut t = minus.clone();
                        pool.add(&mut t, c, 1.0);
                        (c, score(&t))
                    })
                    .max_by(|a, b| a.1.total_cmp(&b.1))
            };
            if let Some((c, v)) = best {
                if v > current + 1e-9 * current.abs().max(1e-12) {
                    taken[out] = false;
                    taken[c] = true;
                    chosen[k] = c;
                    m = minus;
                    pool.add(&mut m, c, 1.0);
                    current = score(&m);
                    exchanges += 1;
                    swapped = true;
                }
            }
        }
        if !swapped {
            break;
        }
    }
    let value = value_of(pool, &chosen, crit);
    Design { chosen, value, sweeps, exchanges }
}

fn logdet(m: &DMatrix<f64>) -> f64 {
    let l = cholesky(m);
    (0..l.nrows()).map(|i| 2.0 * l[(i, i)].max(1e-300).ln()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_pool(c: usize, d: usize, p: usize, seed: u64) -> Pool {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        // Half the candidates are weak (scaled by 0.1): a design should avoid them.
        let rows = (0..c * d * p).map(|_| rng.random::<f64>() * 2.0 - 1.0).enumerate().map(|(i, v)| if (i / (d * p)) % 2 == 0 { v } else { 0.1 * v }).collect();
        Pool::new(rows, d, p)
    }

    #[test]
    fn the_gain_is_the_change_of_log_det() {
        let pool = random_pool(30, 3, 5, 1);
        let set = [0, 2, 4];
        let m = pool.information(&set);
        let mut z = vec![0.0; 15];
        let g = gain(&cholesky(&m), pool.block(7), 3, 5, &mut z);
        let mut m2 = m.clone();
        pool.add(&mut m2, 7, 1.0);
        assert!((logdet(&m2) - logdet(&m) - g).abs() < 1e-9, "{} vs {g}", logdet(&m2) - logdet(&m));
    }

    #[test]
    fn every_criterion_beats_random_designs_and_the_exchange_only_improves() {
        let pool = random_pool(400, 2, 6, 2);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for crit in CRITERIA {
            let best = design(&pool, 8, crit, 10);
            assert_eq!(best.chosen.len(), 8);
            let mut sorted = best.chosen.clone();
            sorted.sort();
            sorted.dedup();
            assert_eq!(sorted.len(), 8, "a candidate chosen twice");
            let greedy = design(&pool, 8, crit, 0);
            assert!(best.value >= greedy.value - 1e-12, "{}: exchange {} below greedy {}", crit.name(), best.value, greedy.value);
            for _ in 0..50 {
                let mut set: Vec<usize> = (0..pool.len()).collect();
                for i in 0..8 {
                    let j = rng.random_range(i..set.len());
                    set.swap(i, j);
                }
                assert!(best.value > value_of(&pool, &set[..8], crit), "{}: a random design beats the plan", crit.name());
            }
        }
    }

    #[test]
    fn the_exact_i_gains_are_the_change_of_the_mean_prediction_variance() {
        for (d, p) in [(1, 5), (3, 6)] {
            let pool = random_pool(60, d, p, 4);
            let set = [0, 2, 4, 6, 8, 10];
            let m = pool.information(&set);
            let mut taken = vec![false; pool.len()];
            set.iter().for_each(|&c| taken[c] = true);
            let g = IOptimal.gains(&pool, &m, &taken).expect("the I criterion tells every candidate's gain");
            assert!(set.iter().all(|&c| g[c] == f64::NEG_INFINITY));
            let before = prediction_variance(&m, &pool);
            for c in [1, 7, 33, 59] {
                let mut m2 = m.clone();
                pool.add(&mut m2, c, 1.0);
                let direct = before - prediction_variance(&m2, &pool);
                assert!((direct - g[c]).abs() < 1e-9 * before, "d={d} candidate {c}: {direct} vs {}", g[c]);
            }
        }
    }
}
