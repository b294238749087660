//! Robust estimation for measured data: gross outliers and runs of them are found with a
//! robust scale and kept out, and an optional heavy-tailed loss down-weights what remains.
//!
//! * [`screen`]: rows whose residual is more than `k` robust standard deviations (1.4826·MAD)
//!   from the median residual of a fit on the rows kept so far, iterated with refits until the
//!   set is stable (at most four passes). Flagged rows close together form [`OutlierRun`]s: on a
//!   real arm a run is one disturbed stretch of the acquisition (a bumped cable, a glitch of the
//!   reader), not independent bad luck.
//! * [`Loss`] and [`irls`]: Huber or Cauchy by iteratively reweighted least squares, the
//!   weights from the residuals over a robust scale re-estimated at every pass.

use super::model::CalibModel;
use super::optim::{LeastSquares, LevenbergMarquardt, NoObserver, Observer, Report};
use super::problem::{LengthFit, Samples};
use super::stats::median;
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A row kept out of the fit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Outlier {
    /// Data row, 1-based (the first row after the header is 1).
    pub row: usize,
    pub residual_mm: f64,
    /// Distance from the median residual in robust standard deviations.
    pub robust_z: f64,
}

/// Outlier rows close together in acquisition order (gaps of at most [`RUN_GAP`] rows).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct OutlierRun {
    /// First and last data row, 1-based.
    pub first_row: usize,
    pub last_row: usize,
    /// Median residual of the run, mm.
    pub median_residual_mm: f64,
}

/// What [`screen`] found.
#[derive(Clone, Debug)]
pub struct Screen {
    /// Indices (into the screened samples) of the rows kept.
    pub keep: Vec<usize>,
    pub outliers: Vec<Outlier>,
    /// Runs of at least two outlier rows close together ([`runs`]).
    pub runs: Vec<OutlierRun>,
    /// The fit on the kept rows.
    pub x: Vec<f64>,
    /// Robust standard deviation of the kept rows' residuals (1.4826·MAD), mm, and their median.
    pub scale_mm: f64,
    pub median_mm: f64,
}

/// The fit of the outlier screen: the identifiable parameters of `model` on `data` from `x`,
/// with the Cauchy loss. A least-squares fit bends towards a run of bad rows until none of them
/// stands out (on RobotCali a disturbed stretch of ~80 rows 4 mm off left the median absolute
/// deviation at 1.2 mm and no row beyond six of it); the Cauchy fit follows the good rows.
pub fn screen_fit(model: &CalibModel, data: &Samples, x: &[f64], rank_tol: f64) -> Vec<f64> {
    let fit = LengthFit { model, data };
    let fixed = super::run::identify(&fit, x, rank_tol).fixed_mask;
    let lm = LevenbergMarquardt { max_iter: 200, ftol: 1e-9, xtol: 1e-9, ..Default::default() };
    irls(&lm, &fit, x, &fixed, Loss::Cauchy, &mut NoObserver).x
}

/// Screens `data` (whose row `i` is data row `rows[i]`, 0-based) for outliers of the model
/// fitted from `x0`; `refit` fits the model to a subset from a start (see [`screen_fit`]). See
/// the module docs.
pub fn screen(model: &CalibModel, x0: &[f64], data: &Samples, rows: &[usize], k: f64, refit: &dyn Fn(&Samples, &[f64]) -> Vec<f64>) -> Screen {
    let n = data.len();
    let mut keep: Vec<usize> = (0..n).collect();
    let mut x = x0.to_vec();
    let mut flagged: Vec<usize> = Vec::new();
    let (mut scale, mut med) = (f64::NAN, 0.0);
    let mut r = Vec::new();
    for _ in 0..4 {
        x = refit(&data.subset(&keep), &x);
        r = LengthFit { model, data }.residuals_mm(&x);
        let kept_r: Vec<f64> = keep.iter().map(|&i| r[i]).collect();
        med = median(&kept_r);
        scale = 1.4826 * median(&kept_r.iter().map(|v| (v - med).abs()).collect::<Vec<f64>>());
        if !(scale > 0.0) || k <= 0.0 {
            flagged.clear();
            break;
        }
        flagged = (0..n).filter(|&i| !((r[i] - med).abs() <= k * scale)).collect();
        let new_keep: Vec<usize> = (0..n).filter(|i| flagged.binary_search(i).is_err()).collect();
        if new_keep == keep {
            break;
        }
        keep = new_keep;
    }
    let outliers: Vec<Outlier> = flagged.iter().map(|&i| Outlier { row: rows[i] + 1, residual_mm: r[i], robust_z: (r[i] - med) / scale }).collect();
    Screen { runs: runs(&outliers), keep, outliers, x, scale_mm: scale, median_mm: med }
}

/// Most data rows between two outliers of one run: rows held out for testing, or a row of the
/// stretch that happens to read close, do not end it.
pub const RUN_GAP: usize = 3;

/// Runs of at least two outliers at most [`RUN_GAP`] data rows apart.
pub fn runs(outliers: &[Outlier]) -> Vec<OutlierRun> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < outliers.len() {
        let mut j = i;
        while j + 1 < outliers.len() && outliers[j + 1].row <= outliers[j].row + 1 + RUN_GAP {
            j += 1;
        }
        if j > i {
            let res: Vec<f64> = outliers[i..=j].iter().map(|o| o.residual_mm).collect();
            out.push(OutlierRun { first_row: outliers[i].row, last_row: outliers[j].row, median_residual_mm: median(&res) });
        }
        i = j + 1;
    }
    out
}

/// The loss a least-squares fit minimises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Loss {
    /// Squared residuals.
    #[default]
    L2,
    /// Quadratic within 1.345 robust standard deviations, linear beyond (95 % efficient on
    /// Gaussian noise).
    Huber,
    /// log(1 + (r/c)²) with c = 2.385 robust standard deviations: far residuals count for
    /// almost nothing.
    Cauchy,
}

impl Loss {
    pub fn parse(s: &str) -> Result<Loss> {
        match s.trim().to_ascii_lowercase().as_str() {
            "l2" | "squared" => Ok(Loss::L2),
            "huber" => Ok(Loss::Huber),
            "cauchy" => Ok(Loss::Cauchy),
            other => Err(Error::Invalid(format!("unknown loss '{other}' (expected l2, huber or cauchy)"))),
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Loss::L2 => "l2",
            Loss::Huber => "huber",
            Loss::Cauchy => "cauchy",
        }
    }
    /// IRLS weight of a residual `u` in robust standard deviations.
    fn weight(self, u: f64) -> f64 {
        match self {
            Loss::L2 => 1.0,
            Loss::Huber => {
                let c = 1.345;
                if u.abs() <= c {
                    1.0
                } else {
                    c / u.abs()
                }
            }
            Loss::Cauchy => {
                let c = 2.385;
                1.0 / (1.0 + (u / c).powi(2))
            }
        }
    }
}

/// A least-squares problem with each residual scaled by the square root of its weight.
struct Weighted<'a, P: LeastSquares> {
    inner: &'a P,
    sqrt_w: Vec<f64>,
}

impl<P: LeastSquares> LeastSquares for Weighted<'_, P> {
    fn n_params(&self) -> usize {
        self.inner.n_params()
    }
    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        self.inner.residuals(x, r);
        r.iter_mut().zip(&self.sqrt_w).for_each(|(v, w)| *v *= w);
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        self.inner.jacobian(x, j);
        for (i, w) in self.sqrt_w.iter().enumerate() {
            j.row_mut(i).scale_mut(*w);
        }
    }
}

/// Passes of [`irls`]: the weights settle in a few.
const IRLS_PASSES: usize = 6;

/// Minimises `loss` by iteratively reweighted least squares: LM on the weighted problem, the
/// weights recomputed from the residuals (over their robust scale) before each pass. With
/// [`Loss::L2`] it is one plain LM run. The report's cost is the plain least-squares cost at the
/// solution; iterations and evaluations add up over the passes.
pub fn irls<P: LeastSquares>(lm: &LevenbergMarquardt, p: &P, x0: &[f64], fixed: &[bool], loss: Loss, obs: &mut dyn Observer) -> Report {
    if loss == Loss::L2 {
        return lm.minimize(p, x0, fixed, obs);
    }
    let mut r = vec![0.0; p.n_residuals()];
    let mut x = x0.to_vec();
    let (mut iterations, mut evaluations) = (0, 0);
    let mut last = None;
    for pass in 0..IRLS_PASSES {
        p.residuals(&x, &mut r);
        let med = median(&r);
        let scale = 1.4826 * median(&r.iter().map(|v| (v - med).abs()).collect::<Vec<f64>>());
        // The first pass is plain least squares: weights from the start's residuals (far from
        // any fit) would only cost passes.
        let sqrt_w: Vec<f64> = r.iter().map(|v| if scale > 0.0 && pass > 0 { loss.weight((v - med) / scale).sqrt() } else { 1.0 }).collect();
        let wp = Weighted { inner: p, sqrt_w };
        let rep = if pass + 1 == IRLS_PASSES { lm.minimize(&wp, &x, fixed, obs) } else { lm.minimize(&wp, &x, fixed, &mut NoObserver) };
        iterations += rep.iterations;
        evaluations += rep.evaluations;
        // Weights that no longer move the fit (LM done within its first steps) have settled.
        let settled = rep.iterations <= 3;
        x = rep.x.clone();
        last = Some(rep);
        if settled {
            break;
        }
    }
    let mut rep = last.expect("at least one pass");
    rep.cost = p.cost(&x);
    rep.iterations = iterations;
    rep.evaluations = evaluations;
    rep.reason = format!("{} ({} loss by IRLS)", rep.reason, loss.name());
    rep
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = a + b·t with a few gross outliers.
    struct Line {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl LeastSquares for Line {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn residuals(&self, x: &[f64], r: &mut [f64]) {
            for i in 0..self.t.len() {
                r[i] = self.y[i] - x[0] - x[1] * self.t[i];
            }
        }
    }

    #[test]
    fn robust_losses_resist_gross_outliers() {
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
        let mut y: Vec<f64> = t.iter().enumerate().map(|(i, t)| 1.0 + 0.5 * t + 0.01 * (((i * 37) % 17) as f64 - 8.0) / 8.0).collect();
        for i in [10, 11, 12, 50, 77] {
            y[i] += 5.0;
        }
        let p = Line { t, y };
        let lm = LevenbergMarquardt::default();
        let l2 = irls(&lm, &p, &[0.0, 0.0], &[], Loss::L2, &mut NoObserver);
        assert!((l2.x[0] - 1.0).abs() > 0.1, "plain least squares is pulled by the outliers: {:?}", l2.x);
        for loss in [Loss::Huber, Loss::Cauchy] {
            let rep = irls(&lm, &p, &[0.0, 0.0], &[], loss, &mut NoObserver);
            let tol = if loss == Loss::Cauchy { 0.005 } else { 0.05 };
            assert!((rep.x[0] - 1.0).abs() < tol && (rep.x[1] - 0.5).abs() < tol, "{loss:?}: {:?}", rep.x);
            assert!(rep.reason.contains(loss.name()));
        }
        assert!(Loss::parse("tukey").is_err());
    }

    #[test]
    fn runs_group_nearby_rows() {
        let o = |row, r| Outlier { row, residual_mm: r, robust_z: 10.0 };
        let found = runs(&[o(1, 1.0), o(7, 5.0), o(8, 7.0), o(9, 6.0), o(20, 1.0), o(24, 2.0), o(25, 4.0), o(40, 1.0)]);
        assert_eq!(
            found,
            vec![OutlierRun { first_row: 7, last_row: 9, median_residual_mm: 6.0 }, OutlierRun { first_row: 20, last_row: 25, median_residual_mm: 2.0 }]
        );
    }
}
