//! Gaussian radial-basis-function (RBF) network regression, used to model calibration residuals
//! as a smooth function of the joint angles.
//!
//! # Model
//!
//! ```text
//! f(x) = b + Σ_j w_j · exp(−‖x/s − c_j‖² / (2 σ_j²))
//! ```
//!
//! where `x/s` divides every input coordinate by [`RbfNetwork::input_scale`] (the per-dimension
//! standard deviation of the training inputs; 1 for constant dimensions), and the centres `c_j`
//! and widths `σ_j` live in those scaled coordinates.
//!
//! # Fitting ([`RbfNetwork::fit`])
//!
//! 1. Centres: k-means++ seeding (ChaCha8 seeded with [`RbfOptions::seed`]) followed by at most
//!    [`RbfOptions::kmeans_iters`] Lloyd iterations on the scaled inputs. Seeding stops early when
//!    every remaining point coincides with a centre, so there are never duplicate centres (and
//!    never more centres than distinct inputs). Empty clusters keep their previous centre.
//! 2. Widths: `σ_j = width_factor × mean distance from c_j to its 2 nearest other centres`
//!    (1 other centre when there are only two). Non-positive widths, and the single-centre case,
//!    fall back to a global width: the mean of the valid per-centre widths, else the RMS distance
//!    of the scaled inputs to their mean, else 1.
//! 3. Weights and bias: ridge regression on the design `Φ = [φ_j(x_i) | 1]`, solving
//!    `(ΦᵀΦ + λ·D)[w; b] = Φᵀy` by Cholesky, with `D = diag(1, …, 1, 0)` (the bias is not
//!    penalised) and `λ = ridge × mean diagonal of the RBF block of ΦᵀΦ`. Should the factorisation
//!    fail (e.g. `ridge = 0` with collinear columns), `λ` is raised geometrically from
//!    `1e-12 × mean diagonal` until it succeeds.
//!
//! Everything is deterministic given the seed; [`RbfNetwork::fit_cv`] evaluates candidates in
//! parallel but each candidate is independent, so results do not depend on the thread count.

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// One cross-validation row: `(centers, ridge, cv_rmse)`.
pub type CvRow = (usize, f64, f64);

/// A fitted Gaussian RBF network, see the module docs.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct RbfNetwork {
    /// Centres in scaled input coordinates (input divided by `input_scale`).
    pub centers: Vec<Vec<f64>>,
    /// Gaussian width `σ_j` of each centre (scaled coordinates).
    pub widths: Vec<f64>,
    /// Output weight of each centre.
    pub weights: Vec<f64>,
    /// Constant term.
    pub bias: f64,
    /// Inputs are divided by this (per dimension) before distances are taken.
    pub input_scale: Vec<f64>,
}

/// Options of [`RbfNetwork::fit`].
#[derive(Clone, Debug, PartialEq)]
pub struct RbfOptions {
    /// Requested number of centres (capped by the number of distinct inputs).
    pub centers: usize,
    /// Ridge penalty relative to the mean diagonal of the RBF block of `ΦᵀΦ` (≥ 0).
    pub ridge: f64,
    /// Multiplier on the nearest-centre distance that sets each Gaussian width (> 0). The default
    /// 1.5 gave 2–3× lower test error than 1.0 on smooth 2-D targets (σ = spacing is too narrow
    /// for the Gaussians to blend); larger values trade accuracy for conditioning.
    pub width_factor: f64,
    /// Seed of the k-means++ initialisation.
    pub seed: u64,
    /// Maximum number of Lloyd iterations after seeding.
    pub kmeans_iters: usize,
}

impl Default for RbfOptions {
    fn default() -> Self {
        RbfOptions { centers: 30, ridge: 1e-6, width_factor: 1.5, seed: 0, kmeans_iters: 50 }
    }
}

/// Number of cross-validation folds used by [`RbfNetwork::fit_cv`].
pub const CV_FOLDS: usize = 5;

impl RbfNetwork {
    /// Fit a network to samples `x[i] ↦ y[i]` (see the module docs for the method).
    ///
    /// Errors on empty input, mismatched lengths, rows of differing or zero dimension,
    /// non-finite values, `centers == 0`, a negative or non-finite `ridge`, a non-positive or
    /// non-finite `width_factor`, or a failed linear solve.
    pub fn fit(x: &[Vec<f64>], y: &[f64], opt: &RbfOptions) -> Result<RbfNetwork, String> {
        let dim = validate(x, y)?;
        if opt.centers == 0 {
            return Err("rbf: need at least one centre".into());
        }
        if !(opt.ridge >= 0.0 && opt.ridge.is_finite()) {
            return Err(format!("rbf: invalid ridge {}", opt.ridge));
        }
        if !(opt.width_factor > 0.0 && opt.width_factor.is_finite()) {
            return Err(format!("rbf: invalid width_factor {}", opt.width_factor));
        }
        let (mut net, xs) = RbfNetwork::basis(x, dim, opt);
        let (phi, a) = design(&net, &xs);
        let (weights, bias) = solve_weights(&phi, &a, y, opt.ridge)?;
        net.weights = weights;
        net.bias = bias;
        Ok(net)
    }

    /// Everything of a fit on inputs `x` (of dimension `dim`) but its weights: the input scale,
    /// the centres and the widths (they do not depend on the targets or the ridge), and the
    /// scaled inputs. `opt` is checked by the caller.
    fn basis(x: &[Vec<f64>], dim: usize, opt: &RbfOptions) -> (RbfNetwork, Vec<Vec<f64>>) {
        let n = x.len();

        // Per-dimension population std as the input scale.
        let input_scale: Vec<f64> = (0..dim)
            .map(|d| {
                let m = x.iter().map(|r| r[d]).sum::<f64>() / n as f64;
                let s = (x.iter().map(|r| (r[d] - m).powi(2)).sum::<f64>() / n as f64).sqrt();
                if s.is_finite() && s > 1e-12 * m.abs().max(1e-300) {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        let xs: Vec<Vec<f64>> = x.iter().map(|r| r.iter().zip(&input_scale).map(|(v, s)| v / s).collect()).collect();

        let mut rng = ChaCha8Rng::seed_from_u64(opt.seed);
        let mut centers = kmeans_pp(&xs, opt.centers, &mut rng);
        lloyd(&xs, &mut centers, opt.kmeans_iters);
        let widths = center_widths(&xs, &centers, opt.width_factor);
        (RbfNetwork { centers, widths, weights: Vec::new(), bias: 0.0, input_scale }, xs)
    }

    /// Predict at `x`. Returns `NaN` when `x` has the wrong dimension (or contains NaN).
    pub fn predict(&self, x: &[f64]) -> f64 {
        if x.len() != self.input_scale.len() {
            return f64::NAN;
        }
        let xs: Vec<f64> = x.iter().zip(&self.input_scale).map(|(v, s)| v / s).collect();
        output(&self.features(&xs), &self.weights, self.bias)
    }

    /// The candidate grid of `--method rbf` and of diagnose's RBF compensator: centres per
    /// network and ridge parameters, chosen by [`Self::fit_cv`].
    pub const CV_CENTRES: [usize; 4] = [5, 10, 20, 40];
    /// Candidate ridge parameters (see [`Self::CV_CENTRES`]).
    pub const CV_RIDGES: [f64; 3] = [1e-6, 1e-4, 1e-2];

    /// Choose the number of centres and the ridge by [`CV_FOLDS`]-fold cross-validation.
    ///
    /// The rows are shuffled with a ChaCha8 generator seeded by `seed` and dealt into
    /// `min(5, n)` folds; every `(centers, ridge)` pair is fitted on each training split (with
    /// [`RbfOptions::default`] width factor and iterations and the same `seed`) and scored by the
    /// RMSE over all held-out predictions. A candidate whose fit fails scores `+∞`. The best
    /// candidate (lowest CV RMSE; ties go to the earlier entry, centres-major order) is refitted
    /// on all data.
    ///
    /// Returns the refitted network and the table `(centers, ridge, cv_rmse)` in candidate order.
    /// Errors on invalid data (as [`fit`](Self::fit)), fewer than 2 rows, empty candidate lists,
    /// or when no candidate could be fitted.
    pub fn fit_cv(x: &[Vec<f64>], y: &[f64], centers: &[usize], ridges: &[f64], seed: u64) -> Result<(RbfNetwork, Vec<CvRow>), String> {
        RbfNetwork::fit_cv_many(x, &[y], centers, ridges, seed).pop().expect("one result per target column")
    }

    /// [`Self::fit_cv`] of every target column `ys[c]` on the same inputs `x`: the same networks
    /// and tables, bit for bit, as one [`Self::fit_cv`] per column, for less work. The folds,
    /// and so on each training split the centres and widths of a number of centres, depend on
    /// the inputs and the seed alone: they are made once per split and number of centres and
    /// serve every ridge and every column, as does the design's `ΦᵀΦ`.
    pub fn fit_cv_many(x: &[Vec<f64>], ys: &[&[f64]], centers: &[usize], ridges: &[f64], seed: u64) -> Vec<Result<(RbfNetwork, Vec<CvRow>), String>> {
        // Each column's own checks, in fit_cv's order.
        let checked: Vec<Result<(), String>> = ys
            .iter()
            .map(|y| {
                validate(x, y)?;
                if x.len() < 2 {
                    return Err("rbf: cross-validation needs at least 2 rows".into());
                }
                if centers.is_empty() || ridges.is_empty() {
                    return Err("rbf: empty candidate list".into());
                }
                Ok(())
            })
            .collect();
        let live: Vec<usize> = (0..ys.len()).filter(|&c| checked[c].is_ok()).collect();
        let n = x.len();
        // Per live column, the table in candidate order (centres-major).
        let mut tables: Vec<Vec<CvRow>> = vec![Vec::new(); live.len()];
        if !live.is_empty() {
            let dim = x[0].len();
            let splits: Vec<(Vec<usize>, Vec<usize>)> =
                crate::stats::folds::shuffled(n, CV_FOLDS.min(n), seed).into_iter().map(|test| (crate::stats::folds::others(n, &test), test)).collect();
            // Per number of centres: per live column and ridge, the CV row.
            let per_centres: Vec<Vec<Vec<CvRow>>> = centers
                .par_iter()
                .map(|&c| {
                    let opt = RbfOptions { centers: c, seed, ..RbfOptions::default() };
                    // Sum of squared held-out errors per (column, ridge); None once a fit failed.
                    let mut sse: Vec<Vec<Option<f64>>> = vec![vec![Some(0.0); ridges.len()]; live.len()];
                    if opt.centers == 0 {
                        sse.iter_mut().flatten().for_each(|s| *s = None);
                    }
                    for (train, test) in &splits {
                        if sse.iter().flatten().all(Option::is_none) {
                            break;
                        }
                        let xt: Vec<Vec<f64>> = train.iter().map(|&i| x[i].clone()).collect();
                        let (net, xs) = RbfNetwork::basis(&xt, dim, &opt);
                        let (phi, a) = design(&net, &xs);
                        // The held-out rows' activations, as `predict` computes them.
                        let feats: Vec<Vec<f64>> =
                            test.iter().map(|&i| net.features(&x[i].iter().zip(&net.input_scale).map(|(v, s)| v / s).collect::<Vec<f64>>())).collect();
                        for (sc, &col) in sse.iter_mut().zip(&live) {
                            let y = ys[col];
                            let yt: Vec<f64> = train.iter().map(|&i| y[i]).collect();
                            for (s, &r) in sc.iter_mut().zip(ridges) {
                                let Some(acc) = s else { continue };
                                let solved = if r >= 0.0 && r.is_finite() { solve_weights(&phi, &a, &yt, r).ok() } else { None };
                                match solved {
                                    Some((w, b)) => *acc += test.iter().zip(&feats).map(|(&i, f)| (output(f, &w, b) - y[i]).powi(2)).sum::<f64>(),
                                    None => *s = None,
                                }
                            }
                        }
                    }
                    sse.into_iter()
                        .map(|sc| {
                            sc.into_iter()
                                .zip(ridges)
                                .map(|(s, &r)| {
                                    let rmse = s.map_or(f64::INFINITY, |s| (s / n as f64).sqrt());
                                    (c, r, if rmse.is_finite() { rmse } else { f64::INFINITY })
                                })
                                .collect()
                        })
                        .collect()
                })
                .collect();
            for per_col in per_centres {
                for (t, rows) in tables.iter_mut().zip(per_col) {
                    t.extend(rows);
                }
            }
        }
        let mut tables = tables.into_iter();
        checked
            .into_iter()
            .zip(ys)
            .map(|(ok, y)| {
                ok?;
                let table = tables.next().expect("one table per live column");
                let best = table
                    .iter()
                    .filter(|t| t.2.is_finite())
                    .fold(None::<&CvRow>, |b, t| match b {
                        Some(b) if b.2 <= t.2 => Some(b),
                        _ => Some(t),
                    })
                    .ok_or("rbf: no cross-validation candidate could be fitted")?;
                let opt = RbfOptions { centers: best.0, ridge: best.1, seed, ..RbfOptions::default() };
                let net = RbfNetwork::fit(x, y, &opt)?;
                Ok((net, table))
            })
            .collect()
    }

    /// Gaussian activations at a point already in scaled coordinates.
    fn features(&self, xs: &[f64]) -> Vec<f64> {
        self.centers.iter().zip(&self.widths).map(|(c, s)| (-sq_dist(xs, c) / (2.0 * s * s)).exp()).collect()
    }
}

/// The design `Φ = [φ_j(x_i) | 1]` of `net`'s centres and widths on the scaled inputs `xs`,
/// and `ΦᵀΦ`.
fn design(net: &RbfNetwork, xs: &[Vec<f64>]) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (xs.len(), net.centers.len());
    let p = m + 1;
    let mut phi = DMatrix::<f64>::zeros(n, p);
    for (i, r) in xs.iter().enumerate() {
        for (j, v) in net.features(r).into_iter().enumerate() {
            phi[(i, j)] = v;
        }
        phi[(i, m)] = 1.0;
    }
    let a = phi.tr_mul(&phi);
    (phi, a)
}

/// Ridge solve for `[w; b]` on the design `phi` (with `a = ΦᵀΦ`) and targets `y` (bias
/// unpenalised).
fn solve_weights(phi: &DMatrix<f64>, a: &DMatrix<f64>, y: &[f64], ridge: f64) -> Result<(Vec<f64>, f64), String> {
    let m = phi.ncols() - 1;
    let rhs = phi.tr_mul(&DVector::from_column_slice(y));
    let mean_diag = ((0..m).map(|j| a[(j, j)]).sum::<f64>() / m.max(1) as f64).max(f64::MIN_POSITIVE);
    let mut lambda = ridge * mean_diag;
    for _ in 0..40 {
        let mut reg = a.clone();
        for j in 0..m {
            reg[(j, j)] += lambda;
        }
        if let Some(ch) = reg.cholesky() {
            let sol = ch.solve(&rhs);
            if sol.iter().all(|v| v.is_finite()) {
                return Ok((sol.as_slice()[..m].to_vec(), sol[m]));
            }
        }
        lambda = (lambda * 10.0).max(1e-12 * mean_diag);
    }
    Err("rbf: ridge system could not be solved".into())
}

/// A network's output from its activations `features`, weights and bias.
fn output(features: &[f64], weights: &[f64], bias: f64) -> f64 {
    bias + features.iter().zip(weights).map(|(p, w)| p * w).sum::<f64>()
}

/// Check shapes and finiteness; returns the input dimension.
fn validate(x: &[Vec<f64>], y: &[f64]) -> Result<usize, String> {
    if x.is_empty() {
        return Err("rbf: empty input".into());
    }
    if x.len() != y.len() {
        return Err(format!("rbf: {} inputs but {} targets", x.len(), y.len()));
    }
    let dim = x[0].len();
    if dim == 0 {
        return Err("rbf: zero-dimensional input".into());
    }
    if let Some(i) = x.iter().position(|r| r.len() != dim) {
        return Err(format!("rbf: row {i} has dimension {} instead of {dim}", x[i].len()));
    }
    if x.iter().flatten().chain(y).any(|v| !v.is_finite()) {
        return Err("rbf: non-finite value in input".into());
    }
    Ok(dim)
}

fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum()
}

/// k-means++ seeding: first centre uniform, then each next one with probability ∝ D²
/// (squared distance to the nearest chosen centre). Stops when all D² are zero.
fn kmeans_pp(xs: &[Vec<f64>], k: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let n = xs.len();
    let first = rng.random_range(0..n);
    let mut centers = vec![xs[first].clone()];
    let mut d2: Vec<f64> = xs.iter().map(|p| sq_dist(p, &xs[first])).collect();
    while centers.len() < k.min(n) {
        let total: f64 = d2.iter().sum();
        if total.is_nan() || total <= 0.0 || !total.is_finite() {
            break;
        }
        let u = rng.random::<f64>() * total;
        let mut acc = 0.0;
        // Fallback: the last point with positive D² (guards against round-off at the end).
        let mut pick = d2.iter().rposition(|&d| d > 0.0).unwrap_or(0);
        for (i, &d) in d2.iter().enumerate() {
            acc += d;
            if d > 0.0 && acc > u {
                pick = i;
                break;
            }
        }
        let c = xs[pick].clone();
        for (p, d) in xs.iter().zip(d2.iter_mut()) {
            *d = d.min(sq_dist(p, &c));
        }
        centers.push(c);
    }
    centers
}

/// Lloyd iterations; nearest-centre ties go to the lower index, empty clusters keep their centre.
fn lloyd(xs: &[Vec<f64>], centers: &mut [Vec<f64>], iters: usize) {
    let (n, k, dim) = (xs.len(), centers.len(), xs[0].len());
    let mut assign = vec![usize::MAX; n];
    for _ in 0..iters {
        let mut changed = false;
        for (i, p) in xs.iter().enumerate() {
            let mut best = (f64::INFINITY, 0);
            for (j, c) in centers.iter().enumerate() {
                let d = sq_dist(p, c);
                if d < best.0 {
                    best = (d, j);
                }
            }
            if assign[i] != best.1 {
                assign[i] = best.1;
                changed = true;
            }
        }
        if !changed {
            break;
        }
        let mut sums = vec![vec![0.0; dim]; k];
        let mut counts = vec![0usize; k];
        for (p, &a) in xs.iter().zip(&assign) {
            counts[a] += 1;
            for (s, v) in sums[a].iter_mut().zip(p) {
                *s += v;
            }
        }
        for ((c, s), &cnt) in centers.iter_mut().zip(sums).zip(&counts) {
            if cnt > 0 {
                *c = s.into_iter().map(|v| v / cnt as f64).collect();
            }
        }
    }
}

/// Per-centre widths (see the module docs).
fn center_widths(xs: &[Vec<f64>], centers: &[Vec<f64>], factor: f64) -> Vec<f64> {
    let k = centers.len();
    let nn = 2.min(k.saturating_sub(1));
    let raw: Vec<Option<f64>> = (0..k)
        .map(|j| {
            if nn == 0 {
                return None;
            }
            let mut d: Vec<f64> = (0..k).filter(|&o| o != j).map(|o| sq_dist(&centers[j], &centers[o]).sqrt()).collect();
            d.sort_by(f64::total_cmp);
            let w = factor * d[..nn].iter().sum::<f64>() / nn as f64;
            (w > 0.0 && w.is_finite()).then_some(w)
        })
        .collect();
    let valid: Vec<f64> = raw.iter().flatten().copied().collect();
    let global = if !valid.is_empty() {
        valid.iter().sum::<f64>() / valid.len() as f64
    } else {
        let dim = xs[0].len();
        let mean: Vec<f64> = (0..dim).map(|d| xs.iter().map(|r| r[d]).sum::<f64>() / xs.len() as f64).collect();
        let rms = (xs.iter().map(|r| sq_dist(r, &mean)).sum::<f64>() / xs.len() as f64).sqrt() * factor;
        if rms > 0.0 && rms.is_finite() {
            rms
        } else {
            1.0
        }
    };
    raw.into_iter().map(|w| w.unwrap_or(global)).collect()
}

impl crate::calib::correctors::correct::Correct for RbfNetwork {
    fn label(&self) -> String {
        format!("rbf ({} centres)", self.centers.len())
    }
    fn n_weights(&self) -> usize {
        self.centers.len() * (self.input_scale.len() + 2) + 1
    }
    fn correction_mm(&self, q: &[f64], _inp: &crate::calib::effects::RowInputs) -> f64 {
        self.predict(q)
    }
    fn correction_grad_mm(&self, q: &[f64], _inp: &crate::calib::effects::RowInputs, g: &mut [f64]) -> f64 {
        let d = self.input_scale.len();
        g.iter_mut().for_each(|v| *v = 0.0);
        let mut f = self.bias;
        for ((c, s), w) in self.centers.iter().zip(&self.widths).zip(&self.weights) {
            let mut d2 = 0.0;
            for k in 0..d {
                let e = q[k] / self.input_scale[k] - c[k];
                d2 += e * e;
            }
            let phi = w * (-d2 / (2.0 * s * s)).exp();
            f += phi;
            for k in 0..d {
                g[k] -= phi * (q[k] / self.input_scale[k] - c[k]) / (s * s * self.input_scale[k]);
            }
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn target(p: &[f64]) -> f64 {
        p[0].sin() + 0.5 * (2.0 * p[1]).cos()
    }

    fn sample(n: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let x: Vec<Vec<f64>> = (0..n).map(|_| vec![rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0)]).collect();
        let y = x.iter().map(|p| target(p)).collect();
        (x, y)
    }

    fn rmse(net: &RbfNetwork, x: &[Vec<f64>], y: &[f64]) -> f64 {
        (x.iter().zip(y).map(|(p, t)| (net.predict(p) - t).powi(2)).sum::<f64>() / y.len() as f64).sqrt()
    }

    #[test]
    fn fits_smooth_2d_function() {
        let (x, y) = sample(300, 1);
        let (xt, yt) = sample(500, 2);
        let net = RbfNetwork::fit(&x, &y, &RbfOptions { centers: 40, ..RbfOptions::default() }).unwrap();
        assert_eq!(net.centers.len(), 40);
        let e = rmse(&net, &xt, &yt);
        assert!(e < 0.02, "test rmse {e}");
    }

    #[test]
    fn deterministic_given_seed() {
        let (x, y) = sample(100, 3);
        let opt = RbfOptions { centers: 10, seed: 42, ..RbfOptions::default() };
        let a = RbfNetwork::fit(&x, &y, &opt).unwrap();
        let b = RbfNetwork::fit(&x, &y, &opt).unwrap();
        assert_eq!(a.centers, b.centers);
        assert_eq!(a.weights, b.weights);
        assert_eq!(a.bias, b.bias);
    }

    #[test]
    fn constant_function() {
        let (x, _) = sample(80, 4);
        let y = vec![3.7; x.len()];
        let net = RbfNetwork::fit(&x, &y, &RbfOptions { centers: 10, ..RbfOptions::default() }).unwrap();
        for p in x.iter().chain(&[vec![0.1, -0.3], vec![10.0, 10.0]]) {
            assert!((net.predict(p) - 3.7).abs() < 1e-9, "{}", net.predict(p));
        }
        // Identical inputs collapse to one centre; still solvable.
        let xi = vec![vec![1.0, 2.0]; 20];
        let net = RbfNetwork::fit(&xi, &[-1.5; 20], &RbfOptions { ridge: 0.0, ..RbfOptions::default() }).unwrap();
        assert_eq!(net.centers.len(), 1);
        assert!((net.predict(&[1.0, 2.0]) + 1.5).abs() < 1e-9);
    }

    #[test]
    fn fit_cv_picks_sensible_candidate() {
        let (x, y) = sample(200, 5);
        let (net, table) = RbfNetwork::fit_cv(&x, &y, &[2, 25], &[1e-8, 1e-4, 1e3], 9).unwrap();
        assert_eq!(table.len(), 6);
        let best = table.iter().min_by(|a, b| a.2.total_cmp(&b.2)).unwrap();
        assert_eq!(best.0, 25);
        assert!(best.1 < 1e3);
        assert_eq!(net.centers.len(), 25);
        let (xt, yt) = sample(200, 6);
        assert!(rmse(&net, &xt, &yt) < 0.05);
        // Reproducible.
        let (_, table2) = RbfNetwork::fit_cv(&x, &y, &[2, 25], &[1e-8, 1e-4, 1e3], 9).unwrap();
        assert_eq!(table, table2);
    }

    /// The shared bases give every column the table and network of a fit per candidate and
    /// split (the way fit_cv computed them one by one), bit for bit; a column that fails its
    /// checks fails alone.
    #[test]
    fn fit_cv_many_is_one_fit_per_candidate_split_and_column() {
        let (x, y0) = sample(120, 7);
        let y1: Vec<f64> = x.iter().map(|p| (p[0] * p[1]).tanh()).collect();
        let bad = vec![f64::NAN; x.len()];
        let (centres, ridges, seed) = ([3, 12], [1e-6, 1e-2, -1.0], 4);
        let out = RbfNetwork::fit_cv_many(&x, &[&y0, &bad, &y1], &centres, &ridges, seed);
        assert_eq!(out.len(), 3);
        assert!(out[1].is_err());
        let n = x.len();
        let splits = crate::stats::folds::shuffled(n, CV_FOLDS.min(n), seed);
        for (y, got) in [(&y0, &out[0]), (&y1, &out[2])] {
            let (net, table) = got.as_ref().unwrap();
            let mut want = Vec::new();
            for &c in &centres {
                for &r in &ridges {
                    let opt = RbfOptions { centers: c, ridge: r, seed, ..RbfOptions::default() };
                    let mut sse = 0.0;
                    for test in &splits {
                        let train = crate::stats::folds::others(n, test);
                        let xt: Vec<Vec<f64>> = train.iter().map(|&i| x[i].clone()).collect();
                        let yt: Vec<f64> = train.iter().map(|&i| y[i]).collect();
                        match RbfNetwork::fit(&xt, &yt, &opt) {
                            Ok(net) => sse += test.iter().map(|&i| (net.predict(&x[i]) - y[i]).powi(2)).sum::<f64>(),
                            Err(_) => sse = f64::INFINITY,
                        }
                    }
                    let rmse = (sse / n as f64).sqrt();
                    want.push((c, r, if rmse.is_finite() { rmse } else { f64::INFINITY }));
                }
            }
            let bits = |t: &[CvRow]| t.iter().map(|&(c, r, e)| (c, r.to_bits(), e.to_bits())).collect::<Vec<_>>();
            assert_eq!(bits(table), bits(&want));
            assert!(table.iter().any(|t| t.2.is_finite()) && table.iter().filter(|t| t.1 < 0.0).all(|t| t.2.is_infinite()));
            let best = want.iter().filter(|t| t.2.is_finite()).fold(None::<&CvRow>, |b, t| if b.is_some_and(|b| b.2 <= t.2) { b } else { Some(t) }).unwrap();
            let refit = RbfNetwork::fit(&x, y, &RbfOptions { centers: best.0, ridge: best.1, seed, ..RbfOptions::default() }).unwrap();
            assert_eq!((&net.centers, &net.widths, &net.weights, net.bias.to_bits()), (&refit.centers, &refit.widths, &refit.weights, refit.bias.to_bits()));
        }
    }

    #[test]
    fn degenerate_inputs_error() {
        let opt = RbfOptions::default();
        assert!(RbfNetwork::fit(&[], &[], &opt).is_err());
        assert!(RbfNetwork::fit(&[vec![1.0]], &[1.0, 2.0], &opt).is_err());
        assert!(RbfNetwork::fit(&[vec![1.0], vec![1.0, 2.0]], &[1.0, 2.0], &opt).is_err());
        assert!(RbfNetwork::fit(&[vec![]], &[1.0], &opt).is_err());
        assert!(RbfNetwork::fit(&[vec![f64::NAN]], &[1.0], &opt).is_err());
        assert!(RbfNetwork::fit(&[vec![1.0]], &[f64::INFINITY], &opt).is_err());
        assert!(RbfNetwork::fit(&[vec![1.0]], &[1.0], &RbfOptions { centers: 0, ..opt.clone() }).is_err());
        assert!(RbfNetwork::fit(&[vec![1.0]], &[1.0], &RbfOptions { ridge: -1.0, ..opt.clone() }).is_err());
        assert!(RbfNetwork::fit(&[vec![1.0]], &[1.0], &RbfOptions { width_factor: 0.0, ..opt.clone() }).is_err());
        assert!(RbfNetwork::fit_cv(&[vec![1.0]], &[1.0], &[3], &[1e-6], 0).is_err());
        assert!(RbfNetwork::fit_cv(&[vec![1.0], vec![2.0]], &[1.0, 2.0], &[], &[1e-6], 0).is_err());
        assert!(RbfNetwork::fit_cv(&[vec![1.0], vec![f64::NAN]], &[1.0, 2.0], &[3], &[1e-6], 0).is_err());
        // Wrong prediction dimension is NaN, not a panic.
        let net = RbfNetwork::fit(&[vec![1.0], vec![2.0]], &[1.0, 2.0], &opt).unwrap();
        assert!(net.predict(&[1.0, 2.0]).is_nan());
        assert!(net.predict(&[1.5]).is_finite());
    }
}
