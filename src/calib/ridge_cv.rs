//! k-fold cross-validation of penalised linear least squares, `y ≈ B·w` with normal matrix
//! `A(BᵀB)` (the penalty is the caller's: a ridge, roughness rows, ...). Shared by the network
//! choices of Evo-NPH ([`super::gkan_select`]) and PSO-EKF-AWNN ([`super::awnn_select`]).
//!
//! Folds interleave the rows (row i in fold i mod k), so each fold spans the whole acquisition
//! (time and temperature). Each fold's training Gram matrix is the total minus the fold's own,
//! so a candidate penalty costs one Cholesky solve per fold.

use nalgebra::{Cholesky, DMatrix, DVector};

/// A basis matrix, its targets and the per-fold normal equations.
pub struct Folds {
    basis: DMatrix<f64>,
    y: Vec<f64>,
    gram: DMatrix<f64>,
    rhs: DVector<f64>,
    /// Per fold: Gram and right-hand side of the other folds, and the fold's rows.
    parts: Vec<(DMatrix<f64>, DVector<f64>, Vec<usize>)>,
}

impl Folds {
    /// `basis` has one row per target in `y`; `k` folds (at least 2).
    pub fn new(basis: DMatrix<f64>, y: &[f64], k: usize) -> Folds {
        let n = y.len();
        let k = k.max(2);
        let gram = basis.transpose() * &basis;
        let rhs = basis.transpose() * DVector::from_column_slice(y);
        let parts = (0..k)
            .map(|f| {
                let rows: Vec<usize> = (0..n).filter(|i| i % k == f).collect();
                let bf = basis.select_rows(&rows);
                let yf = DVector::from_iterator(rows.len(), rows.iter().map(|&i| y[i]));
                (&gram - bf.transpose() * &bf, &rhs - bf.transpose() * yf, rows)
            })
            .collect();
        Folds { basis, y: y.to_vec(), gram, rhs, parts }
    }

    /// The Gram matrix `BᵀB` over every row.
    pub fn gram(&self) -> &DMatrix<f64> {
        &self.gram
    }

    /// Held-out RMSE over all folds of the fit whose normal matrix is `system(Gram of the
    /// other folds)`; infinite when a system is not positive definite.
    pub fn cv_rmse(&self, system: impl Fn(&DMatrix<f64>) -> DMatrix<f64>) -> f64 {
        self.cv_residuals(system).map_or(f64::INFINITY, |r| (r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64).sqrt())
    }

    /// Every row's held-out residual (target minus the prediction of the fit on the other
    /// folds); `None` when a system is not positive definite.
    pub fn cv_residuals(&self, system: impl Fn(&DMatrix<f64>) -> DMatrix<f64>) -> Option<Vec<f64>> {
        let mut r = vec![0.0; self.y.len()];
        for (g, b, rows) in &self.parts {
            let w = Cholesky::new(system(g))?.solve(b);
            for &i in rows {
                r[i] = self.y[i] - self.basis.row(i).dot(&w.transpose());
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
