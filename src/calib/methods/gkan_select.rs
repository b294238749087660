//! The GKAN's size and penalty weights of the Evo-NPH objective, chosen by k-fold
//! cross-validation on the training rows only (the test rows are never seen).
//!
//! With several reading values per row (a tracker's point) there is one network per value, all
//! of the candidate's shape and weights, each fitted to its value's residuals; a row's values
//! share its fold, and the score is the held-out RMSE over every value.
//!
//! The geometry is first fitted alone by Levenberg–Marquardt; its training residuals `y` are what
//! a network has to explain (each fold is scored on the residuals of the geometry fitted without
//! it, [`GeometricFit`]). For every candidate (shape, λ_n, λ_s) the network's coefficients
//! minimise the objective's network part on k − 1 folds — `Σ(y − Bw)² + λ_n Σ(Bw)² + λ_s ‖Pw‖²`
//! with `P` the roughness and ridge rows ([`penalty_rows`]), one Cholesky solve since it is
//! quadratic in w — and predict the held-out fold. The candidate with the smallest held-out RMSE
//! over all folds wins; on a tie the smaller network. It is kept only if it beats no network
//! (the geometry's own held-out residuals) by more than one standard error of the per-row
//! difference of squared held-out residuals; otherwise the method runs on the geometry alone.
//! Folds interleave the rows
//! ([`super::ridge_cv`]).
//!
//! Candidates (documented in the README): shapes grid/edge grid 3/1 (196 coefficients), 4/2 (292,
//! the paper's scale) and 6/3 (414), chain edges among joints 1–5; λ_n ∈ {0.05, 0.2, 1, 5};
//! λ_s ∈ {0.0002, 0.002, 0.02, 0.2}: 48 candidates, 240 Cholesky solves, 0.6–0.8 s for 500
//! rows. The geometric weight is not searched: it is the tolerance prior (σ²/N, σ from the
//! data).

use super::lm::LmSolver;
use super::solver::Problem;
use crate::calib::correctors::gkan::{Gkan, GkanShape};
use crate::calib::methods::ridge_cv::{one_se_win, Folds, GeometricFit};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Candidate network shapes, smallest first.
pub const SHAPES: [GkanShape; 3] = [
    GkanShape { grid: 3, edge_grid: 1, chain_joints: 5 },
    GkanShape { grid: 4, edge_grid: 2, chain_joints: 5 },
    GkanShape { grid: 6, edge_grid: 3, chain_joints: 5 },
];
/// Candidate neural-magnitude weights λ_n.
pub const NEURAL: [f64; 4] = [0.05, 0.2, 1.0, 5.0];
/// Candidate roughness weights λ_s.
pub const ROUGHNESS: [f64; 4] = [0.0002, 0.002, 0.02, 0.2];
pub use crate::calib::methods::ridge_cv::FOLDS;

/// Weights of the objective of Evo-NPH (see [`super::evonph`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvoWeights {
    /// Multiplier of the MAP weight σ²/N of the geometric term.
    pub geometry: f64,
    /// Weight λ_n of the neural-magnitude term.
    pub neural: f64,
    /// Weight λ_s of the roughness term.
    pub roughness: f64,
}

impl Default for EvoWeights {
    fn default() -> Self {
        EvoWeights { geometry: 1.0, neural: 0.05, roughness: 0.02 }
    }
}

/// Weight of the ridge rows added to the roughness rows (κ = 0.01 on the squares): edge
/// functions could otherwise trade constants among themselves.
const RIDGE: f64 = 0.1;

/// The roughness rows of `net` followed by one ridge row per coefficient.
pub fn penalty_rows(net: &Gkan) -> Vec<[(usize, f64); 3]> {
    let mut rows = net.roughness_rows();
    rows.extend((0..net.n_coef()).map(|k| [(k, RIDGE), (k, 0.0), (k, 0.0)]));
    rows
}

/// `PᵀP` of [`penalty_rows`] as a dense matrix of `nw` × `nw`.
pub fn penalty_gram(rows: &[[(usize, f64); 3]], nw: usize) -> DMatrix<f64> {
    let mut r = DMatrix::zeros(nw, nw);
    for row in rows {
        for &(i, vi) in row {
            for &(j, vj) in row {
                r[(i, j)] += vi * vj;
            }
        }
    }
    r
}

/// One candidate's cross-validated score.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// The network's shape.
    pub shape: GkanShape,
    /// Its number of coefficients.
    pub coefficients: usize,
    /// Neural-magnitude weight λ_n.
    pub neural: f64,
    /// Roughness weight λ_s.
    pub roughness: f64,
    /// Held-out RMSE over all folds, mm.
    pub cv_rmse_mm: f64,
}

/// The chosen candidate, every candidate's score, and the geometry-only baseline.
#[derive(Clone, Debug)]
pub struct Selection {
    /// The candidate with the smallest held-out RMSE (on a tie the smaller network).
    pub chosen: Candidate,
    /// Every candidate's score.
    pub candidates: Vec<Candidate>,
    /// Held-out RMSE of no network at all (the LM residuals), mm.
    pub no_network_rmse_mm: f64,
    /// Whether the chosen candidate beat no network by more than one standard error of the
    /// per-row difference of squared held-out residuals; if not, the method runs without a
    /// network (its coefficients stay zero).
    pub fitted: bool,
}

impl Selection {
    /// The objective's weights of the chosen candidate, with `geometry` as the geometric weight.
    pub fn weights(&self, geometry: f64) -> EvoWeights {
        EvoWeights { geometry, neural: self.chosen.neural, roughness: self.chosen.roughness }
    }
    /// One line for reports.
    pub fn summary(&self) -> String {
        let c = &self.chosen;
        if !self.fitted {
            return format!(
                "no GKAN beat the geometry alone by one standard error in {FOLDS}-fold CV on the training rows (best: grid {}/{}, held-out {:.4} mm; no network {:.4} mm): geometry only, the network's {} coefficients zero",
                c.shape.grid, c.shape.edge_grid, c.cv_rmse_mm, self.no_network_rmse_mm, c.coefficients
            );
        }
        format!(
            "GKAN grid {}/{} ({} coefficients), λ_n {}, λ_s {} chosen by {FOLDS}-fold CV on the training rows (held-out {:.4} mm, no network {:.4} mm)",
            c.shape.grid, c.shape.edge_grid, c.coefficients, c.neural, c.roughness, c.cv_rmse_mm, self.no_network_rmse_mm
        )
    }
}

/// Chooses the shape and penalty weights for problem `p` (see the module docs).
pub fn select(p: &Problem) -> Result<Selection> {
    let fit = p.fit;
    let n = fit.data.len();
    if n < 2 * FOLDS {
        return Err(Error::Calibration(format!("{n} training rows are too few to choose the network by {FOLDS}-fold cross-validation")));
    }
    let g = GeometricFit::new(fit, &LmSolver::default().lm, p.x0, p.fixed);
    let y = &g.residuals;
    if !y.iter().chain(g.per_fold.iter().flatten()).all(|v| v.is_finite()) {
        return Err(Error::Calibration("the geometric fit before the network choice gave non-finite residuals".into()));
    }
    // Value v is value v % d of row v / d; a row's values share its fold.
    let d = fit.data.dim;
    let nv = y.len();
    let no_network_rmse_mm = ((0..nv).map(|v| g.per_fold[(v / d) % FOLDS][v].powi(2)).sum::<f64>() / nv as f64).sqrt();
    // One network per value: value c's targets, on every row and as each fold sees them.
    let column = |v: &[f64], c: usize| crate::stats::value_column(v, d, c);
    let targets: Vec<(Vec<f64>, Vec<Vec<f64>>)> = (0..d).map(|c| (column(y, c), g.per_fold.iter().map(|f| column(f, c)).collect())).collect();
    let (lo, hi) = Gkan::range_of(&fit.data.q);
    let mut candidates = Vec::new();
    // Every value's held-out residuals of the best candidate so far (value order).
    let mut best_residuals: Option<(f64, Vec<f64>)> = None;
    for shape in SHAPES {
        let net = Gkan::new(shape, lo.clone(), hi.clone());
        let nw = net.n_coef();
        let mut basis = DMatrix::zeros(n, nw);
        let mut row = vec![0.0; nw];
        for i in 0..n {
            net.basis_row(&fit.data.q[i], &mut row);
            for k in 0..nw {
                basis[(i, k)] = row[k];
            }
        }
        let pen = penalty_gram(&penalty_rows(&net), nw);
        let folds: Vec<Folds> = targets.iter().map(|(yc, per_fold)| Folds::with_fold_targets(basis.clone(), yc, per_fold)).collect();
        let grid: Vec<(f64, f64)> = NEURAL.iter().flat_map(|&a| ROUGHNESS.iter().map(move |&b| (a, b))).collect();
        let scores: Vec<f64> = grid
            .par_iter()
            .map(|&(ln, ls)| {
                let system = |g: &DMatrix<f64>| g * (1.0 + ln) + &pen * ls;
                if let [one] = folds.as_slice() {
                    return one.cv_rmse(system);
                }
                let mut all = Vec::with_capacity(nv);
                for f in &folds {
                    match f.cv_residuals(system) {
                        Some(r) => all.extend(r),
                        None => return f64::INFINITY,
                    }
                }
                crate::stats::rms(&all)
            })
            .collect();
        for (&(neural, roughness), &cv_rmse_mm) in grid.iter().zip(&scores) {
            candidates.push(Candidate { shape, coefficients: nw, neural, roughness, cv_rmse_mm });
        }
        // The shape's best, if it is the best so far (strictly: a tie goes to the smaller shape).
        let here = grid.iter().zip(&scores).filter(|(_, s)| s.is_finite()).fold(None::<((f64, f64), f64)>, |b, (&g, &s)| match b {
            Some((_, bs)) if bs <= s => b,
            _ => Some((g, s)),
        });
        if let Some(((ln, ls), score)) = here {
            if best_residuals.as_ref().is_none_or(|(b, _)| score < *b) {
                let mut r = vec![0.0; nv];
                for (c, f) in folds.iter().enumerate() {
                    if let Some(rc) = f.cv_residuals(|g| g * (1.0 + ln) + &pen * ls) {
                        for (i, v) in rc.into_iter().enumerate() {
                            r[i * d + c] = v;
                        }
                    }
                }
                best_residuals = Some((score, r));
            }
        }
    }
    let chosen = candidates
        .iter()
        .filter(|c| c.cv_rmse_mm.is_finite())
        .fold(None::<Candidate>, |best, c| match best {
            Some(b) if b.cv_rmse_mm <= c.cv_rmse_mm => Some(b),
            _ => Some(*c),
        })
        .ok_or_else(|| Error::Calibration("no network candidate could be fitted in the cross-validation".into()))?;
    // One-standard-error rule against no network: the per-row change of the squared held-out
    // residual (summed over the row's values) must be negative by more than its standard error,
    // else the win is the best of 48 candidates on noise.
    let fitted = best_residuals.is_some_and(|(_, r)| {
        one_se_win(&(0..n).map(|i| (0..d).map(|c| r[i * d + c].powi(2) - g.per_fold[i % FOLDS][i * d + c].powi(2)).sum::<f64>()).collect::<Vec<f64>>())
    });
    Ok(Selection { chosen, candidates, no_network_rmse_mm, fitted })
}
