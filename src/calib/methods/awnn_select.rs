//! The wavelet network's layout and output layer, chosen by k-fold cross-validation on what a
//! geometric fit leaves on the training rows (the test rows are never seen). This is where
//! PSO-EKF-AWNN's network starts: Stage I's per-sample learning then adapts every parameter
//! from there (see [`super::psoekf`]).
//!
//! With the translations, dilations and projections of a [`Library`] layout fixed, the network
//! is linear in its output weights. The geometric fit's Jacobian columns `J` (at its solution)
//! are fitted alongside, unpenalised, so that the network takes only what no change of the
//! geometry could. For every candidate (layout, λ_n, ρ) the weights minimise
//!
//! ```text
//! Σ(y − Jδ − Ψw)² + λ_n·Σ(Ψw)² + λ‖w‖²
//! ```
//!
//! on k − 1 folds — one Cholesky solve — and predict the held-out fold ([`super::ridge_cv`]).
//! Each fold's targets are the residuals of the geometry fitted by LM *without* that fold
//! ([`GeometricFit`]): residuals of a fit on every row would tie the held-out rows to the others
//! through the fit's normal equations, and an interpolating network on 50 rows then looked 20 %
//! better in CV while it was worse on unseen poses.
//! `Ψ` holds every neuron's activation at every training row, `λ_n` weighs the network's output
//! magnitude (as in the Evo-NPH objective) and `λ = ρ·tr(ΨᵀΨ)/M` (ρ relative to the mean
//! squared activation, so it means the same for any layout). The candidate with the smallest
//! held-out RMSE wins, on a tie the smaller layout, and its weights are refitted on all
//! training rows — unless it does not beat the geometric columns alone in the same
//! cross-validation by more than one standard error of the per-row difference of squared
//! held-out residuals (a best-of-100 win on a few dozen rows is mostly luck): then the output
//! weights stay zero.
//!
//! **Several values per row** (a tracker's x, y, z; the residuals row after row): one network
//! per value with the same layout and the same (λ_n, ρ). The system couples the shared geometric
//! columns with one network block per value (value `c` of a row sees block `c` alone, so the
//! network blocks of the normal matrix are block-diagonal); the folds hold whole rows (every
//! value of a row held out together, as [`GeometricFit`] refits the geometry without them); the
//! candidates are scored on the held-out RMSE over every value, and the one-standard-error rule
//! compares each row's squared held-out residuals summed over its values. Then, per value, the
//! same rule on that value's residuals alone: a value whose network does not improve it keeps
//! zero output weights (the shared penalty, chosen for the values with something to learn, would
//! otherwise let its network fit noise). With one value this is exactly the rule above.
//!
//! Candidates (documented in the README): [`LIBRARIES`] × [`NEURAL`] × [`RIDGES`], 100
//! candidates, 500 Cholesky solves.

use crate::calib::correctors::awnn::{Activation, Awnn, Feature, Library};
use crate::calib::effects::RowInputs;
use crate::calib::methods::ridge_cv::{one_se_win, Folds, GeometricFit, FOLDS};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Candidate layouts, smallest first (neuron counts for six joints on q alone).
pub const LIBRARIES: [Library; 4] = [
    // 6 axes × 6 = 36
    Library { levels: &[2, 4], pairs: false },
    // 26 directions × 2 = 52
    Library { levels: &[2], pairs: true },
    // 26 × 6 = 156
    Library { levels: &[2, 4], pairs: true },
    // 26 × 9 = 234
    Library { levels: &[3, 6], pairs: true },
];
/// Candidate output-magnitude weights λ_n.
pub const NEURAL: [f64; 5] = [0.0, 0.5, 1.0, 2.0, 5.0];
/// Candidate ridge weights ρ (relative to the mean squared activation).
pub const RIDGES: [f64; 5] = [1e-5, 1e-4, 1e-3, 1e-2, 1e-1];

/// One candidate's cross-validated score.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Layout of the neurons.
    pub library: Library,
    /// Number of neurons of that layout.
    pub neurons: usize,
    /// Output-magnitude weight λ_n.
    pub neural: f64,
    /// Ridge weight ρ (relative to the mean squared activation).
    pub ridge: f64,
    /// Held-out RMSE over all folds, mm.
    pub cv_rmse_mm: f64,
}

/// The chosen network (output layer fitted on every training row), every candidate's score and
/// the held-out RMSE of no network at all.
#[derive(Clone, Debug)]
pub struct Selection {
    /// One network per reading value (one for a cable length), the same layout for all.
    pub nets: Vec<Awnn>,
    /// The candidate with the smallest held-out RMSE.
    pub chosen: Candidate,
    /// Every candidate's score.
    pub candidates: Vec<Candidate>,
    /// Held-out RMSE of the geometric columns alone, mm.
    pub no_network_rmse_mm: f64,
    /// Whether the chosen candidate beat the geometry alone by more than one standard error; if
    /// not, `nets` keep the chosen layout with zero output weights.
    pub fitted: bool,
    /// Per reading value, whether its network kept its fitted output weights (with several
    /// values each must also beat the geometry alone on its own value by one standard error).
    pub value_fitted: Vec<bool>,
}

impl Selection {
    /// One line for reports.
    pub fn summary(&self) -> String {
        let text = self.summary_one();
        if self.nets.len() > 1 {
            let zero: Vec<String> = self.value_fitted.iter().enumerate().filter(|(_, f)| !**f).map(|(c, _)| (c + 1).to_string()).collect();
            let zero = if self.fitted && !zero.is_empty() {
                format!(" (value {} left at zero output weights by the same rule)", zero.join(", "))
            } else {
                String::new()
            };
            format!("one network per reading value ({}), each {text}{zero}", self.nets.len())
        } else {
            text
        }
    }

    fn summary_one(&self) -> String {
        let c = &self.chosen;
        if !self.fitted {
            return format!(
                "no network layout beat the geometry alone by one standard error in {FOLDS}-fold CV on the training rows (best {:.4} mm, {} neurons; geometry alone {:.4} mm): {} neurons with zero output weights",
                c.cv_rmse_mm,
                c.neurons,
                self.no_network_rmse_mm,
                c.neurons
            );
        }
        format!(
            "{} neurons ({}), λ_n {}, ridge ρ {} chosen by {FOLDS}-fold CV on the training rows (held-out {:.4} mm, no network {:.4} mm)",
            c.neurons,
            c.library.label(),
            c.neural,
            c.ridge,
            c.cv_rmse_mm,
            self.no_network_rmse_mm
        )
    }
}

/// Chooses the layout and fits the output layer (see the module docs) to what the geometry
/// leaves on the training rows `qs`/`inputs`. The geometric Jacobian's columns are fitted
/// alongside the network, unpenalised, so that the network takes only what a change of the
/// geometry could not; each fold is scored on the residuals of the geometry fitted without it.
pub fn select(qs: &[Vec<f64>], inputs: &[RowInputs], extra: &[Feature], activation: Activation, g: &GeometricFit) -> Result<Selection> {
    let (y, geometry) = (&g.residuals[..], &g.jacobian);
    let n = y.len();
    let rows = qs.len();
    if rows == 0 || n % rows != 0 {
        return Err(Error::Calibration(format!("{n} residuals for {rows} training rows: not a whole number of reading values per row")));
    }
    // Reading values per row: one network each, value c of row i at y[i·dim + c].
    let dim = n / rows;
    if rows < 2 * FOLDS {
        return Err(Error::Calibration(format!("{rows} training rows are too few to choose the network by {FOLDS}-fold cross-validation")));
    }
    if g.per_fold.len() != FOLDS || g.per_fold.iter().any(|f| f.len() != n) {
        return Err(Error::Calibration("the out-of-fold geometric fits do not match the training rows".into()));
    }
    if !y.iter().chain(g.per_fold.iter().flatten()).all(|v| v.is_finite()) {
        return Err(Error::Calibration("the geometric fit before the network choice gave non-finite residuals".into()));
    }
    if geometry.nrows() != n {
        return Err(Error::Calibration("the geometric Jacobian does not match the training rows".into()));
    }
    // Geometric columns scaled to the norm of a unit-RMS column; zero columns dropped.
    let cols: Vec<_> = geometry.column_iter().filter(|c| c.norm() > 0.0).map(|c| c * ((n as f64).sqrt() / c.norm())).collect();
    let ng = cols.len();
    let geo = DMatrix::from_fn(n, ng, |i, k| cols[k][i]);
    // A tiny ridge on the geometric block keeps a rank-deficient Jacobian solvable.
    let geo_ridge = 1e-9 * n as f64;
    let baseline =
        if ng == 0 { Some(y.to_vec()) } else { Folds::by_row(geo.clone(), y, &g.per_fold, dim).cv_residuals(|g| system(g, ng, 0.0, 0.0, geo_ridge)) }
            .ok_or_else(|| Error::Calibration("the geometric columns alone could not be fitted in the cross-validation".into()))?;
    let no_network_rmse_mm = rms(&baseline);
    let mut best: Option<(Candidate, Folds, Awnn, f64)> = None;
    let mut candidates = Vec::new();
    for library in LIBRARIES {
        let net = Awnn::library(qs, inputs, extra, &library, activation).map_err(Error::Calibration)?;
        let m = net.neurons();
        // Geometric columns shared by every value, then one block of network columns per value
        // (value c's rows see network c alone).
        let mut basis = DMatrix::zeros(n, ng + dim * m);
        basis.columns_mut(0, ng).copy_from(&geo);
        let hidden = net.hidden_matrix(qs, inputs);
        if dim == 1 {
            basis.columns_mut(ng, m).copy_from(&hidden);
        } else {
            for i in 0..rows {
                for c in 0..dim {
                    basis.view_mut((i * dim + c, ng + c * m), (1, m)).copy_from(&hidden.row(i));
                }
            }
        }
        let folds = Folds::by_row(basis, y, &g.per_fold, dim);
        let scale = (folds.gram().view((ng, ng), (dim * m, dim * m)).trace() / (dim * m) as f64).max(1e-12);
        let grid: Vec<(f64, f64)> = NEURAL.iter().flat_map(|&a| RIDGES.iter().map(move |&b| (a, b))).collect();
        let scores: Vec<f64> = grid.par_iter().map(|&(ln, rho)| folds.cv_rmse(|g| system(g, ng, ln, rho * scale, geo_ridge))).collect();
        let mut here = None::<Candidate>;
        for (&(neural, ridge), &cv_rmse_mm) in grid.iter().zip(&scores) {
            let c = Candidate { library, neurons: m, neural, ridge, cv_rmse_mm };
            candidates.push(c);
            if cv_rmse_mm.is_finite() && here.is_none_or(|h| cv_rmse_mm < h.cv_rmse_mm) {
                here = Some(c);
            }
        }
        if let Some(c) = here {
            if best.as_ref().is_none_or(|(b, ..)| c.cv_rmse_mm < b.cv_rmse_mm) {
                best = Some((c, folds, net, scale));
            }
        }
    }
    let (chosen, folds, net, scale) = best.ok_or_else(|| Error::Calibration("no network layout could be fitted in the cross-validation".into()))?;
    let chosen_system = |g: &DMatrix<f64>| system(g, ng, chosen.neural, chosen.ridge * scale, geo_ridge);
    let w = folds.fit_all(chosen_system).ok_or_else(|| Error::Calibration("the chosen network's output layer could not be fitted".into()))?;
    // One-standard-error rule against the geometry alone: the per-row change of the squared
    // held-out residual (summed over the row's values) must be negative by more than its
    // standard error, else a win is the best of many candidates on noise.
    let r = folds.cv_residuals(chosen_system).unwrap_or_else(|| baseline.clone());
    let change: Vec<f64> = r.iter().zip(&baseline).map(|(a, b)| a * a - b * b).collect();
    let fitted = one_se_win(&change.chunks(dim).map(|row| row.iter().sum()).collect::<Vec<f64>>());
    // With several values, the same rule per value too: a value whose own held-out residuals
    // the network does not improve by one standard error keeps zero output weights (the layout
    // and penalty are shared, chosen for the values with something to learn).
    let value_fitted: Vec<bool> = (0..dim).map(|c| fitted && (dim == 1 || one_se_win(&crate::stats::value_column(&change, dim, c)))).collect();
    let m = net.neurons();
    let nets = (0..dim)
        .map(|c| {
            let mut v = net.clone();
            if value_fitted[c] {
                v.weights = w.iter().skip(ng + c * m).take(m).copied().collect();
            } else {
                // The one-standard-error rule: no output, and none learned later.
                v.frozen = true;
            }
            v
        })
        .collect();
    Ok(Selection { nets, chosen, candidates, no_network_rmse_mm, fitted, value_fitted })
}

use crate::stats::rms;

/// The normal matrix of the first `ng` (geometric) columns and the network's: the network
/// block gets `λ_n·G + λI` added (its output magnitude and a ridge), the geometric block a tiny
/// ridge.
fn system(g: &DMatrix<f64>, ng: usize, neural: f64, lambda: f64, geo_ridge: f64) -> DMatrix<f64> {
    let mut a = g.clone();
    let m = a.nrows() - ng;
    let block = g.view((ng, ng), (m, m)) * (1.0 + neural);
    a.view_mut((ng, ng), (m, m)).copy_from(&block);
    for k in 0..a.nrows() {
        a[(k, k)] += if k < ng { geo_ridge } else { lambda };
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `n` random poses and targets `field(q)` plus uniform noise of ±`noise` mm.
    fn rows(n: usize, noise: f64, seed: u64, field: impl Fn(&[f64]) -> f64) -> (Vec<Vec<f64>>, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let qs: Vec<Vec<f64>> = (0..n).map(|_| (0..6).map(|_| rng.random_range(-1.5..1.5)).collect()).collect();
        let y = qs.iter().map(|q| field(q) + noise * rng.random_range(-1.0..1.0)).collect();
        (qs, y)
    }

    /// Targets with no geometry fitted alongside.
    fn no_geometry(y: &[f64]) -> GeometricFit {
        GeometricFit { residuals: y.to_vec(), jacobian: DMatrix::zeros(y.len(), 0), per_fold: vec![y.to_vec(); FOLDS] }
    }

    fn held_out(sel: &Selection, field: impl Fn(&[f64]) -> f64) -> (f64, f64) {
        let (qs, _) = rows(400, 0.0, 99, |_| 0.0);
        let truth: Vec<f64> = qs.iter().map(|q| field(q)).collect();
        let rms = |v: &mut dyn Iterator<Item = f64>| {
            let v: Vec<f64> = v.collect();
            rms(&v)
        };
        let after = rms(&mut qs.iter().zip(&truth).map(|(q, t)| t - sel.nets[0].eval(q)));
        (after, rms(&mut truth.iter().copied()))
    }

    #[test]
    fn a_coupled_field_is_learned_and_noise_is_left_alone() {
        // The gravity-like coupling of joints 2 and 3: no single joint's function.
        let field = |q: &[f64]| 0.05 * (q[1] + q[2]).cos() * q[1].sin();
        let (qs, y) = rows(300, 0.01, 1, field);
        let inputs = vec![RowInputs::default(); qs.len()];
        let sel = select(&qs, &inputs, &[], Activation::MexicanHat, &no_geometry(&y)).unwrap();
        assert!(sel.chosen.library.pairs, "{}", sel.summary());
        assert!(sel.chosen.cv_rmse_mm < 0.5 * sel.no_network_rmse_mm, "{}", sel.summary());
        let (after, before) = held_out(&sel, field);
        assert!(after < 0.3 * before, "unseen poses: {after:.4} mm left of {before:.4} mm");
        // Pure noise: the chosen network explains (almost) nothing on unseen poses.
        let (qs, y) = rows(300, 0.01, 2, |_| 0.0);
        let sel = select(&qs, &inputs, &[], Activation::MexicanHat, &no_geometry(&y)).unwrap();
        let (after, _) = held_out(&sel, |_| 0.0);
        assert!(after < 0.3 * 0.01, "network output on unseen poses {after:.5} mm for pure noise of ±0.01 mm; {}", sel.summary());
    }

    /// Three values per row (a tracker's x, y, z), each with its own field: one network per
    /// value, each learning its value's field, folded by row; a value with nothing to learn
    /// gets (almost) nothing.
    #[test]
    fn one_network_per_reading_value() {
        let fields: [fn(&[f64]) -> f64; 3] = [|q: &[f64]| 0.05 * (q[1] + q[2]).cos() * q[1].sin(), |q: &[f64]| 0.04 * (q[0] - q[3]).sin(), |_: &[f64]| 0.0];
        let (qs, _) = rows(300, 0.0, 1, |_| 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let y: Vec<f64> = qs.iter().flat_map(|q| fields.iter().map(|f| f(q)).collect::<Vec<_>>()).map(|v| v + 0.01 * rng.random_range(-1.0..1.0)).collect();
        let inputs = vec![RowInputs::default(); qs.len()];
        let sel = select(&qs, &inputs, &[], Activation::MexicanHat, &no_geometry(&y)).unwrap();
        assert!(sel.fitted && sel.nets.len() == 3, "{}", sel.summary());
        assert_eq!(sel.value_fitted, [true, true, false], "{}", sel.summary());
        assert!(sel.nets[2].weights.iter().all(|w| *w == 0.0));
        assert!(sel.summary().starts_with("one network per reading value (3)"), "{}", sel.summary());
        assert!(sel.nets.iter().all(|n| n.neurons() == sel.chosen.neurons && n.projection == sel.nets[0].projection));
        for (c, f) in fields.iter().enumerate() {
            let one = Selection { nets: vec![sel.nets[c].clone()], ..sel.clone() };
            let (after, before) = held_out(&one, f);
            if c < 2 {
                assert!(after < 0.35 * before, "value {c}: unseen poses {after:.4} mm left of {before:.4} mm");
            } else {
                assert!(after < 0.3 * 0.01, "value {c}: output {after:.5} mm on unseen poses for pure noise");
            }
        }
        // Not a whole number of values per row.
        let e = select(&qs[..299], &inputs[..299], &[], Activation::MexicanHat, &no_geometry(&y)).unwrap_err().to_string();
        assert!(e.contains("not a whole number"), "{e}");
    }

    #[test]
    fn too_few_rows_or_bad_targets_are_refused() {
        let (qs, y) = rows(8, 0.01, 3, |_| 0.0);
        let inputs = vec![RowInputs::default(); qs.len()];
        let e = select(&qs, &inputs, &[], Activation::MexicanHat, &no_geometry(&y)).unwrap_err().to_string();
        assert!(e.contains("too few"), "{e}");
        let (qs, mut y) = rows(50, 0.01, 3, |_| 0.0);
        y[7] = f64::NAN;
        let inputs = vec![RowInputs::default(); qs.len()];
        let e = select(&qs, &inputs, &[], Activation::MexicanHat, &no_geometry(&y)).unwrap_err().to_string();
        assert!(e.contains("non-finite"), "{e}");
    }
}
