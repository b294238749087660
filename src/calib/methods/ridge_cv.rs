//! k-fold cross-validation of penalised linear least squares, `y ≈ B·w` with normal matrix
//! `A(BᵀB)` (the penalty is the caller's: a ridge, roughness rows, ...). Shared by the network
//! choices of Evo-NPH ([`crate::calib::methods::gkan_select`]) and PSO-EKF-AWNN ([`crate::calib::methods::awnn_select`]).
//!
//! Folds interleave the rows (row i in fold i mod k, [`crate::stats::folds::interleaved`]), so each fold spans the whole
//! acquisition (time and temperature). Each fold's training Gram matrix is the total minus the
//! fold's own, so a candidate penalty costs one Cholesky solve per fold.
//!
//! When the targets are what a fitted model leaves, the model must be fitted without the fold
//! too ([`Folds::with_fold_targets`]): residuals of a least-squares fit on every row satisfy
//! `Jᵀy = 0`, as many linear constraints as the model has parameters, which tie the held-out
//! rows' residuals to the others' — a flexible basis then "predicts" them, most of all when a
//! fold has about as many rows as the model has parameters.

use crate::calib::fit::ReadingFit;
use crate::optim::{LeastSquares, LevenbergMarquardt, NoObserver};
use nalgebra::{Cholesky, DMatrix, DVector};
use rayon::prelude::*;

/// Folds of the networks' cross-validations.
pub const FOLDS: usize = 5;

/// What the geometry leaves on the training rows, for the network's choice: the residuals (mm)
/// of the geometric fit on every row, the Jacobian of the free parameters there, and per fold
/// of [`FOLDS`] the residuals on every row of the fit without that fold's rows.
pub struct GeometricFit {
    /// Residuals of the geometric fit on every training row, mm.
    pub residuals: Vec<f64>,
    /// Jacobian of those residuals with respect to the free parameters, at that fit.
    pub jacobian: DMatrix<f64>,
    /// Per fold, the residuals on every row of the fit made without that fold's rows, mm.
    pub per_fold: Vec<Vec<f64>>,
}

impl GeometricFit {
    /// Fits the geometry of `fit` by `lm` from `x0` on every row, then once per fold without
    /// that fold's rows (starting from the all-rows solution).
    pub fn new(fit: &ReadingFit, lm: &LevenbergMarquardt, x0: &[f64], fixed: &[bool]) -> GeometricFit {
        let all = lm.minimize(fit, x0, fixed, &mut NoObserver);
        let residuals = fit.residuals_mm(&all.x);
        let mut jac = DMatrix::zeros(fit.data.y.len(), all.x.len());
        LeastSquares::jacobian(fit, &all.x, &mut jac);
        let free: Vec<usize> = (0..all.x.len()).filter(|k| !fixed[*k]).collect();
        let d = fit.data;
        let n = d.len();
        let per_fold = (0..FOLDS)
            .into_par_iter()
            .map(|f| {
                let keep = crate::stats::folds::others(n, &crate::stats::folds::interleaved(n, FOLDS)[f]);
                let sub = d.subset(&keep);
                let x = lm.minimize(&ReadingFit { model: fit.model, data: &sub }, &all.x, fixed, &mut NoObserver).x;
                fit.residuals_mm(&x)
            })
            .collect();
        GeometricFit { residuals, jacobian: jac.select_columns(&free), per_fold }
    }
}

/// The one-standard-error rule of the networks' choices: whether the per-row changes `d` of
/// the squared held-out residual (a candidate's against no network's) are negative on average
/// by more than their standard error (a best-of-many win on noise is not).
pub fn one_se_win(d: &[f64]) -> bool {
    let nr = d.len() as f64;
    let mean = d.iter().sum::<f64>() / nr;
    let se = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (nr * (nr - 1.0))).sqrt();
    mean + se < 0.0
}

/// One fold: Gram matrix and right-hand side of the other folds' rows, the fold's rows, and
/// the targets of every row as this fold sees them.
struct Part {
    gram: DMatrix<f64>,
    rhs: DVector<f64>,
    rows: Vec<usize>,
    y: Vec<f64>,
}

/// A basis matrix, its targets and the per-fold normal equations.
pub struct Folds {
    basis: DMatrix<f64>,
    gram: DMatrix<f64>,
    rhs: DVector<f64>,
    parts: Vec<Part>,
}

impl Folds {
    /// `basis` has one row per target in `y`; `k` folds (at least 2), every fold with the same
    /// targets.
    pub fn new(basis: DMatrix<f64>, y: &[f64], k: usize) -> Folds {
        let per_fold = vec![y.to_vec(); k.max(2)];
        Folds::with_fold_targets(basis, y, &per_fold)
    }

    /// As [`new`](Self::new) with `per_fold.len()` folds, fold `f` training on and predicting
    /// `per_fold[f]` (e.g. the residuals of a model fitted without fold `f`); `y` is what the
    /// fit on every row ([`fit_all`](Self::fit_all)) uses.
    pub fn with_fold_targets(basis: DMatrix<f64>, y: &[f64], per_fold: &[Vec<f64>]) -> Folds {
        Folds::by_row(basis, y, per_fold, 1)
    }

    /// As [`with_fold_targets`](Self::with_fold_targets) for targets of `dim` values per data
    /// row, row after row (a tracker's x, y, z): the folds hold whole rows, every value of a row
    /// in the same fold (row `i` in fold `i mod k`), as [`GeometricFit::new`] folds them.
    pub fn by_row(basis: DMatrix<f64>, y: &[f64], per_fold: &[Vec<f64>], dim: usize) -> Folds {
        let n = y.len();
        let dim = dim.max(1);
        let k = per_fold.len().max(2);
        let gram = basis.transpose() * &basis;
        let rhs = basis.transpose() * DVector::from_column_slice(y);
        let parts = per_fold
            .iter()
            .enumerate()
            .map(|(f, yf)| {
                let held = crate::stats::folds::interleaved(n / dim, k).swap_remove(f);
                let rows: Vec<usize> = held.iter().flat_map(|&r| r * dim..(r + 1) * dim).collect();
                let train = crate::stats::folds::others(n, &rows);
                let bt = basis.select_rows(&train);
                let yt = DVector::from_iterator(train.len(), train.iter().map(|&i| yf[i]));
                let bf = basis.select_rows(&rows);
                Part { gram: &gram - bf.transpose() * &bf, rhs: bt.transpose() * yt, rows, y: yf.clone() }
            })
            .collect();
        Folds { basis, gram, rhs, parts }
    }

    /// The Gram matrix `BᵀB` over every row.
    pub fn gram(&self) -> &DMatrix<f64> {
        &self.gram
    }

    /// Held-out RMSE over all folds of the fit whose normal matrix is `system(Gram of the
    /// other folds)`; infinite when a system is not positive definite.
    pub fn cv_rmse(&self, system: impl Fn(&DMatrix<f64>) -> DMatrix<f64>) -> f64 {
        self.cv_residuals(system).map_or(f64::INFINITY, |r| crate::stats::rms(&r))
    }

    /// Every row's held-out residual (target minus the prediction of the fit on the other
    /// folds); `None` when a system is not positive definite.
    pub fn cv_residuals(&self, system: impl Fn(&DMatrix<f64>) -> DMatrix<f64>) -> Option<Vec<f64>> {
        let mut r = vec![0.0; self.basis.nrows()];
        for part in &self.parts {
            let w = Cholesky::new(system(&part.gram))?.solve(&part.rhs);
            for &i in &part.rows {
                r[i] = part.y[i] - self.basis.row(i).dot(&w.transpose());
            }
        }
        Some(r)
    }

    /// The fit on every row with normal matrix `system(BᵀB)`; `None` when it is not positive
    /// definite.
    pub fn fit_all(&self, system: impl Fn(&DMatrix<f64>) -> DMatrix<f64>) -> Option<DVector<f64>> {
        Cholesky::new(system(&self.gram)).map(|c| c.solve(&self.rhs))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The held-out residuals from the Gram-subtraction shortcut equal those of an explicit
    /// ridge fit on each fold's training rows, with per-fold targets.
    #[test]
    fn held_out_residuals_match_explicit_fold_fits() {
        let n = 23;
        let basis = DMatrix::from_fn(n, 4, |i, k| ((i * 7 + k * 3) as f64 * 0.37).sin() + if k == 0 { 1.0 } else { 0.0 });
        let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
        let per_fold: Vec<Vec<f64>> = (0..3).map(|f| y.iter().map(|v| v + 0.01 * f as f64).collect()).collect();
        let folds = Folds::with_fold_targets(basis.clone(), &y, &per_fold);
        let ridge = |g: &DMatrix<f64>| g + DMatrix::identity(4, 4) * 0.3;
        let r = folds.cv_residuals(ridge).unwrap();
        for (f, yf) in per_fold.iter().enumerate() {
            let train: Vec<usize> = (0..n).filter(|i| i % 3 != f).collect();
            let bt = basis.select_rows(&train);
            let yt = DVector::from_iterator(train.len(), train.iter().map(|&i| yf[i]));
            let w = Cholesky::new(ridge(&(bt.transpose() * &bt))).unwrap().solve(&(bt.transpose() * yt));
            for i in crate::stats::folds::interleaved(n, 3).swap_remove(f) {
                let e = yf[i] - basis.row(i).dot(&w.transpose());
                assert!((e - r[i]).abs() < 1e-12, "row {i}: {e} vs {}", r[i]);
            }
        }
        let rmse = (r.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        assert!((folds.cv_rmse(ridge) - rmse).abs() < 1e-15);
    }

    /// With several values per row, a fold holds whole rows: every value of a held-out row is
    /// predicted by the fit on the other rows' values alone.
    #[test]
    fn folds_by_row_hold_every_value_of_a_row() {
        let (rows, dim, k) = (11, 3, 3);
        let n = rows * dim;
        let basis = DMatrix::from_fn(n, 4, |i, c| ((i * 5 + c * 3) as f64 * 0.41).sin() + if c == 0 { 1.0 } else { 0.0 });
        let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.13).cos()).collect();
        let folds = Folds::by_row(basis.clone(), &y, &vec![y.clone(); k], dim);
        let ridge = |g: &DMatrix<f64>| g + DMatrix::identity(4, 4) * 0.3;
        let r = folds.cv_residuals(ridge).unwrap();
        for f in 0..k {
            let train: Vec<usize> = (0..n).filter(|i| (i / dim) % k != f).collect();
            let bt = basis.select_rows(&train);
            let yt = DVector::from_iterator(train.len(), train.iter().map(|&i| y[i]));
            let w = Cholesky::new(ridge(&(bt.transpose() * &bt))).unwrap().solve(&(bt.transpose() * yt));
            for i in (0..n).filter(|i| (i / dim) % k == f) {
                let e = y[i] - basis.row(i).dot(&w.transpose());
                assert!((e - r[i]).abs() < 1e-12, "value {i}: {e} vs {}", r[i]);
            }
        }
    }
}
