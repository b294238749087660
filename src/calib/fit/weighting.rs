//! Weights of the fit from an instrument's per-row standard deviations (a tracker's `sx, sy,
//! sz`): weighted least squares with variance components.
//!
//! A residual's variance is the instrument's own for that row, σᵢ², plus what the model and
//! the set-up leave in every row alike, τ² (unmodelled effects, the robot's repeatability).
//! Weighting by 1/σᵢ² alone would let a tracker's micrometres decide the fit where the model's
//! tenths of a millimetre dominate; weighting by 1/(τ² + σᵢ²) is inverse-variance weighting
//! where the instrument's noise dominates (the twin, a well-modelled arm) and equal weights
//! where the model's error does. τ² is the data's: the robust variance of a first fit's
//! position residuals less the mean instrument variance, clamped at zero.
//!
//! The weights apply to a tracker's position values; a pose's axes have no per-row standard
//! deviation and keep equal weights. Each weight is relative to the median one, so weighted
//! residuals stay in millimetres of a typical row.

use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::dataset::Dataset;
use crate::measurement::Measurement;
use serde::{Deserialize, Serialize};

/// How the fit weighted its training rows (the result file's `weighting`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Weighting {
    /// Training rows with per-row standard deviations.
    pub rows_with_std: usize,
    /// Training rows.
    pub rows: usize,
    /// RMS of the instrument's per-row standard deviations over those rows, mm.
    pub instrument_rms_mm: f64,
    /// Robust standard deviation of the first fit's position residuals, mm.
    pub residual_sd_mm: f64,
    /// What the model and the set-up add to every row, τ (mm): the weights are 1/(τ² + σᵢ²).
    pub floor_mm: f64,
    /// Largest over smallest weight of a position value.
    pub weight_span: f64,
}

/// Weight factors (square roots of relative weights, one per model value of `data`, row-major)
/// for the training rows `rows` of `dataset`, from their per-row standard deviations and the
/// residuals `r_mm` (mm, unweighted, one per value) of a first fit of a `measurement`'s model. `None` when no
/// row gives a standard deviation.
pub fn weights(measurement: Measurement, dataset: &Dataset, rows: &[usize], data: &Samples, r_mm: &[f64]) -> Option<(Vec<f64>, Weighting)> {
    let d = data.dim;
    if !has_row_std(measurement, dataset, rows) {
        return None;
    }
    let given: Vec<f64> = rows.iter().filter_map(|&i| dataset.rows[i].std_mm).flat_map(|s| s.map(|v| v * v)).collect();
    let mean_var = given.iter().sum::<f64>() / given.len() as f64;
    // The position values' residuals (a pose's origin is its first three values).
    let pos: Vec<f64> = (0..rows.len()).flat_map(|i| r_mm[i * d..i * d + 3].iter().copied()).collect();
    let (_, sd) = crate::stats::robust_scale(&pos);
    let tau2 = (sd * sd - mean_var).max(0.0);
    let var: Vec<f64> = rows
        .iter()
        .flat_map(|&i| match dataset.rows[i].std_mm {
            Some(s) => s.map(|v| tau2 + v * v),
            None => [tau2 + mean_var; 3],
        })
        .collect();
    let mut sorted = var.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let mut w = vec![1.0; rows.len() * d];
    for (i, v) in var.chunks(3).enumerate() {
        for k in 0..3 {
            w[i * d + k] = (median / v[k]).sqrt();
        }
    }
    let weighting = Weighting {
        rows_with_std: rows.iter().filter(|&&i| dataset.rows[i].std_mm.is_some()).count(),
        rows: rows.len(),
        instrument_rms_mm: mean_var.sqrt(),
        residual_sd_mm: sd,
        floor_mm: tau2.sqrt(),
        weight_span: sorted[sorted.len() - 1] / sorted[0],
    };
    Some((w, weighting))
}

/// Whether some row of `rows` gives the standard deviations of a tracker's position.
fn has_row_std(measurement: Measurement, dataset: &Dataset, rows: &[usize]) -> bool {
    measurement.file_lengths() == 3 && rows.iter().any(|&i| dataset.rows[i].std_mm.is_some())
}

/// [`weights`] for the training samples of a calibration: the first fit is the outlier screen's
/// robust one ([`crate::calib::fit::robust::screen_fit`]) from the model's nominal values.
pub fn training_weights(model: &CalibModel, dataset: &Dataset, rows: &[usize], data: &Samples, rank_tol: f64) -> Option<(Vec<f64>, Weighting)> {
    if !has_row_std(model.measurement, dataset, rows) {
        return None;
    }
    let plain = data.unweighted();
    let x = crate::calib::fit::robust::screen_fit(model, &plain, &model.nominal, rank_tol);
    let r = ReadingFit { model, data: &plain }.residuals_mm(&x);
    weights(model.measurement, dataset, rows, &plain, &r)
}

/// Largest ratio of two instruments' weights: a noise-free twin's contacts must not outweigh
/// every other row by orders of magnitude.
pub const MAX_INSTRUMENT_WEIGHT_RATIO: f64 = 100.0;

/// Weight factors (square roots of relative weights, one per model value, row-major) for rows
/// read by two instruments (faces touched beside sockets seated, a tracker's points beside
/// them): each instrument's rows weighted by the inverse of its own robust residual variance in
/// a first robust fit ([`crate::calib::fit::robust::screen_fit`]), the first instrument's rows
/// at 1; with each instrument's robust standard deviation (mm). `None` for rows of one
/// instrument.
pub fn instrument_weights(model: &CalibModel, data: &Samples, rank_tol: f64) -> Option<(Vec<f64>, [f64; 2])> {
    data.also?;
    if !(0..data.len()).any(|i| data.instrument(i) == 1) || !(0..data.len()).any(|i| data.instrument(i) == 0) {
        return None;
    }
    let plain = data.unweighted();
    let x = crate::calib::fit::robust::screen_fit(model, &plain, &model.nominal, rank_tol);
    let r = ReadingFit { model, data: &plain }.residuals_mm(&x);
    let d = data.dim;
    let sd = [0, 1].map(|g| crate::stats::robust_scale(&data.values_of(&r, g, 0..data.len())).1);
    if !(sd[0] > 0.0 && sd[1] > 0.0) {
        return None;
    }
    let ratio = (sd[0] / sd[1]).clamp(1.0 / MAX_INSTRUMENT_WEIGHT_RATIO, MAX_INSTRUMENT_WEIGHT_RATIO);
    let w = (0..data.len()).flat_map(|i| std::iter::repeat_n(if data.instrument(i) == 1 { ratio } else { 1.0 }, d)).collect();
    Some((w, sd))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Row;

    fn dataset(stds: &[Option<f64>]) -> Dataset {
        let rows = stds
            .iter()
            .map(|s| Row {
                q_deg: vec![0.0; 6],
                reading_mm: vec![1000.0, 0.0, 0.0],
                t_s: None,
                temp_c: None,
                split: None,
                std_mm: s.map(|v| [v; 3]),
                ..Default::default()
            })
            .collect();
        Dataset { rows, source: "mem".into() }
    }

    #[test]
    fn instrument_noise_alone_weights_by_its_inverse_variance() {
        // Residuals of sd 1 mm on half the rows and 0.1 mm on the other half, as their stds say.
        let stds: Vec<Option<f64>> = (0..400).map(|i| Some(if i % 2 == 0 { 1.0 } else { 0.1 })).collect();
        let ds = dataset(&stds);
        let rows: Vec<usize> = (0..400).collect();
        let data = Samples::readings(vec![vec![0.0; 6]; 400], vec![0.0; 1200], 3);
        // Residuals drawn at each row's sd (a fixed pattern of ±1.15 sd: robust sd ≈ the mixture's).
        let r: Vec<f64> = (0..1200).map(|k| stds[k / 3].unwrap() * if k % 2 == 0 { 0.6745 } else { -0.6745 }).collect();
        let (w, info) = weights(Measurement::Point, &ds, &rows, &data, &r).unwrap();
        // The robust sd of these residuals is below the mean instrument variance: no floor.
        assert_eq!(info.floor_mm, 0.0);
        assert!((w[3] / w[0] - 10.0).abs() < 1e-9, "{} {}", w[0], w[3]);
        assert!((info.weight_span - 100.0).abs() < 1e-9);
    }

    #[test]
    fn a_model_error_far_above_the_instrument_leaves_the_weights_nearly_equal() {
        let stds: Vec<Option<f64>> = (0..300).map(|i| if i == 7 { None } else { Some(0.005 + 0.03 * (i % 5) as f64 / 4.0) }).collect();
        let ds = dataset(&stds);
        let rows: Vec<usize> = (0..300).collect();
        let data = Samples::readings(vec![vec![0.0; 6]; 300], vec![0.0; 900], 3);
        let r: Vec<f64> = (0..900).map(|k| if k % 2 == 0 { 0.27 } else { -0.27 }).collect();
        let (w, info) = weights(Measurement::Point, &ds, &rows, &data, &r).unwrap();
        assert_eq!((info.rows_with_std, info.rows), (299, 300));
        assert!(info.floor_mm > 0.39 && info.floor_mm < 0.41, "{info:?}");
        assert!(info.weight_span < 1.01, "{info:?}");
        assert!(w.iter().all(|v| (v - 1.0).abs() < 0.01));
        // No standard deviation on any row: no weights.
        let none = dataset(&vec![None; 300]);
        assert!(weights(Measurement::Point, &none, &rows, &data, &r).is_none());
    }
}
