//! The pipeline's stages between the split and the result: the noise estimate, the outlier
//! screen, the uncertainty, the metrics, the data's floor and the truth comparison.

use super::options::*;
use super::result::*;
use super::split::*;
use crate::calib::correctors::Correct;
use crate::calib::fit::identify::identify;
use crate::calib::fit::robust::{Outlier, ScreenRule};
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::dataset::truth::TruthFile;
use crate::dataset::Dataset;
use crate::error::Result;
use crate::optim::{covariance, LeastSquares, LevenbergMarquardt, NoObserver};
use crate::stats::metrics::ErrorStats;
use nalgebra::DMatrix;

/// Stage "noise estimate": the standard deviation of one reading, mm, from the data alone: the
/// pooled spread of repeated configurations when at least five repeat, else the residual
/// spread of a Levenberg–Marquardt fit corrected for the parameters it used.
pub fn estimate_noise(fit: &ReadingFit, x0: &[f64], fixed: &[bool], repeat: Option<&crate::stats::metrics::Repeatability>) -> f64 {
    if let Some(r) = repeat.filter(|r| r.groups >= 5 && r.pooled_std > 0.0) {
        return r.pooled_std;
    }
    let x = LevenbergMarquardt::budget(100).minimize(fit, x0, fixed, &mut NoObserver).x;
    residual_sigma(fit, &x, fixed)
}

/// The parameters' covariance at `x`: `σ²·(JᵀJ)⁻¹` with σ the residual spread
/// ([`covariance`]), or, for a reading whose values fall in groups with their own noise (a
/// pose's position and axes), the same least-squares estimate's covariance with each group's
/// own residual variance: `(JᵀJ)⁻¹·(Σ_g σ_g²·J_gᵀJ_g)·(JᵀJ)⁻¹`.
pub fn grouped_covariance(fit: &ReadingFit, x: &[f64], fixed: &[bool]) -> Option<DMatrix<f64>> {
    let cov = covariance(fit, x, fixed)?;
    let groups = fit.model.measurement.def().value_groups();
    let d = fit.data.dim;
    let n_groups = fit.model.measurement.n_value_groups();
    if n_groups < 2 || groups.len() != d {
        return Some(cov);
    }
    let r = fit.residuals_mm(x);
    let (m, n) = (r.len(), fit.model.n_params());
    let n_free = fixed.iter().filter(|f| !**f).count();
    let sigma2 = r.iter().map(|v| v * v).sum::<f64>() / m.saturating_sub(n_free).max(1) as f64;
    if !(sigma2 > 0.0) {
        return Some(cov);
    }
    let unit = &cov / sigma2;
    let mut jac = DMatrix::zeros(m, n);
    LeastSquares::jacobian(fit, x, &mut jac);
    let mut b = DMatrix::<f64>::zeros(n, n);
    for g in 0..n_groups {
        let rows: Vec<usize> = (0..m).filter(|i| groups[i % d] == g).collect();
        // The group's share of the degrees of freedom the fit used.
        let dof = rows.len() as f64 * (1.0 - n_free as f64 / m as f64);
        let s2 = rows.iter().map(|&i| r[i] * r[i]).sum::<f64>() / dof.max(1.0);
        let jg = jac.select_rows(&rows);
        b += jg.transpose() * jg * s2;
    }
    Some(&unit * b * &unit)
}

/// √(2·cost / (m − n_free)), the residual standard deviation of a least-squares fit, mm.
pub fn residual_sigma(fit: &ReadingFit, x: &[f64], fixed: &[bool]) -> f64 {
    let dof = fit.data.y.len().saturating_sub(fixed.iter().filter(|f| !**f).count()).max(1);
    (2.0 * LeastSquares::cost(fit, x) / dof as f64).sqrt()
}

/// Residuals (mm) of the model at `x` with the corrector's correction taken off.
pub(super) fn residuals_with(fit: &ReadingFit, x: &[f64], corrector: Option<&dyn Correct>) -> Vec<f64> {
    let mut r = fit.residuals_mm(x);
    if let Some(c) = corrector {
        let d = fit.data.dim;
        if d == 1 {
            for (i, ri) in r.iter_mut().enumerate() {
                *ri -= c.correction_mm(&fit.data.q[i], &fit.data.inputs[i]);
            }
        } else {
            let mut corr = vec![0.0; d];
            for (i, ri) in r.chunks_mut(d).enumerate() {
                c.corrections_mm(&fit.data.q[i], &fit.data.inputs[i], &mut corr);
                ri.iter_mut().zip(&corr).for_each(|(v, c)| *v -= c);
            }
        }
    }
    r
}

/// Statistics of the residuals without the `share` with the largest |r| (their count rounded up).
pub fn trimmed_stats(r: &[f64], share: f64) -> ErrorStats {
    let mut v: Vec<f64> = r.to_vec();
    v.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    let drop = (share * v.len() as f64).ceil() as usize;
    v.truncate(v.len().saturating_sub(drop));
    ErrorStats::of(&v)
}

pub(super) fn stats(fit: &ReadingFit, x: &[f64], corrector: Option<&dyn Correct>) -> ErrorStats {
    ErrorStats::of(&residuals_with(fit, x, corrector))
}

/// The outlier screen needs this many training rows per identifiable parameter.
pub const SCREEN_ROWS_PER_PARAM: usize = 3;

/// Stage "outliers": the training rows far off a robust fit ([`crate::calib::fit::robust::screen`], the
/// identifiable parameters refitted with the Cauchy loss at each pass) are taken out of the split;
/// readings in a reading step are corrected by its offset, in training and test rows alike; the
/// second value says whether the training rows changed (the pipeline then places a nominal
/// model's instrument again on the rows kept). `None` when the screen is off. The screen's scale is never taken below the
/// angle-resolution part of the training rows' floor: where a sweep's rows share the angles'
/// rounding their residuals' robust scale can fall far below the rounding itself, and the
/// screen would flag good rows (as `diagnose` does, see docs/diagnose.md).
pub fn outlier_stage(
    model: &CalibModel,
    split: &mut SplitData,
    data: &Dataset,
    opts: &CalibOptions,
) -> Result<(Option<crate::calib::fit::robust::Screen>, bool)> {
    if opts.screen.outlier_k <= 0.0 {
        return Ok((None, false));
    }
    // With few rows per parameter a fit nearly interpolates them: the residuals' robust scale
    // then says nothing about the noise, and the screen would flag good rows.
    let n_free = identify(&ReadingFit { model, data: &split.train }, &model.nominal, opts.rank_tol).fixed_mask.iter().filter(|f| !**f).count();
    // Counted in reading values: a tracker's row gives three.
    if split.train.y.len() < SCREEN_ROWS_PER_PARAM * n_free {
        return Ok((None, false));
    }
    let screen = {
        let m = model;
        let refit = |d: &Samples, x: &[f64]| crate::calib::fit::robust::screen_fit(m, d, x, opts.rank_tol);
        let rule = screen_rule(m, data, &split.train, opts.screen.outlier_k, opts.screen.reading_steps, opts.floor.angle_step_deg);
        crate::calib::fit::robust::screen(m, &m.nominal, &split.train, &split.train_idx, rule, &refit)
    };
    if !screen.steps.is_empty() {
        split.test = crate::calib::fit::robust::apply_steps_nearest(&split.test, &split.test_idx, &split.train_idx, &screen.steps);
    }
    let changed = !screen.outliers.is_empty() || !screen.steps.is_empty();
    if changed {
        split.train_idx = screen.keep.iter().map(|&i| split.train_idx[i]).collect();
        split.train = screen.corrected.subset(&screen.keep);
    }
    Ok((Some(screen), changed))
}

/// Test rows beyond `k` robust standard deviations of the calibrated model's training
/// residuals (around their median); none when `k` is 0. A row of several values (a point) is
/// out when any of them is, and is reported by its farthest value.
pub(super) fn test_outlier_stage(
    fit: &ReadingFit,
    test: &Samples,
    test_r: &[f64],
    test_idx: &[usize],
    x: &[f64],
    corrector: Option<&dyn Correct>,
    k: f64,
) -> Vec<Outlier> {
    if k <= 0.0 || test_r.is_empty() {
        return Vec::new();
    }
    let r = residuals_with(fit, x, corrector);
    let d = fit.data.dim.max(1);
    // Each instrument's rows on their own scale, over the values they hold.
    let train = fit.data;
    let by_instrument: Vec<(f64, f64)> = (0..2).map(|g| crate::stats::robust_scale(&train.values_of(&r, g, 0..train.len()))).collect();
    // Each value against its group's scale (a pose's axes have their own), reported by the
    // value farthest out.
    let groups = fit.model.measurement.def().value_groups();
    let group = |k: usize| groups.get(k).copied().unwrap_or(0);
    let stats = crate::calib::fit::robust::group_scales(&r, d, groups, &(0..r.len() / d).collect::<Vec<_>>());
    let n_groups = stats.len();
    test_r
        .chunks(d)
        .zip(test_idx)
        .enumerate()
        .filter_map(|(j, (vs, &i))| {
            if n_groups == 1 {
                let (med, scale) = by_instrument[test.instrument(j)];
                let vs = &vs[..test.width(j)];
                let v = crate::calib::fit::robust::farthest_from(vs, med);
                return (!((v - med).abs() <= k * scale)).then(|| Outlier { row: i + 1, residual_mm: v, robust_z: (v - med) / scale });
            }
            let (z, v) = vs.iter().enumerate().map(|(c, v)| ((v - stats[group(c)].0) / stats[group(c)].1, *v)).fold((0.0_f64, f64::NAN), |a, b| {
                if b.0.abs() > a.0.abs() || a.1.is_nan() {
                    b
                } else {
                    a
                }
            });
            (!(z.abs() <= k)).then(|| Outlier { row: i + 1, residual_mm: v, robust_z: z })
        })
        .collect()
}

/// Stage "metrics": RMSE / STD / MAX before (start) and after, on training and test rows.
pub fn metrics_stage(fit: &ReadingFit, test_fit: &ReadingFit, x0: &[f64], x: &[f64], corrector: Option<&dyn Correct>) -> Metrics {
    let has_test = !test_fit.data.is_empty();
    let d = test_fit.data.dim;
    let position = |x: &[f64], c: Option<&dyn Correct>| ErrorStats::of(&crate::stats::position_errors(&residuals_with(test_fit, x, c), d));
    Metrics {
        train_before: stats(fit, x0, None),
        test_before: has_test.then(|| stats(test_fit, x0, None)),
        train_after: stats(fit, x, corrector),
        test_after: has_test.then(|| stats(test_fit, x, corrector)),
        test_after_inliers: None,
        test_after_trimmed: None,
        test_position_before: (has_test && d > 1).then(|| position(x0, None)),
        test_position_after: (has_test && d > 1).then(|| position(x, corrector)),
    }
}

/// Stage "truth comparison": each identifiable parameter against its truth-equivalent value
/// (computed from the truth, see [`crate::calib::pipeline::equivalent`]), with z = error / standard uncertainty.
/// Returns the truth-equivalent vector (internal units) where it could be computed.
pub fn truth_stage(
    model: &CalibModel,
    spec: &ModelSpec,
    truth: Option<&TruthFile>,
    data: &Dataset,
    split: &SplitData,
    x0: &[f64],
    fixed: &[bool],
) -> Option<Vec<f64>> {
    let (t, robot) = (truth?, spec.robot()?);
    if t.poses.len() != data.rows.len() {
        return None;
    }
    // The noise-free readings of the training rows, of the model's kind (else no comparison).
    let y: Option<Vec<Vec<f64>>> = split.train_idx.iter().map(|&i| t.true_reading(i, model.measurement)).collect();
    // At the angles the arm stood at (the commanded ones; logged angles are rounded): the truth
    // carries no logging error.
    let commanded: Option<Vec<Vec<f64>>> = split
        .train_idx
        .iter()
        .map(|&i| Some(&t.poses[i].q_cmd_deg).filter(|q| q.len() == robot.dof()).map(|q| q.iter().map(|d| d.to_radians()).collect()))
        .collect();
    let clean = Samples { y: y?.concat(), q: commanded.unwrap_or_else(|| split.train.q.clone()), ..split.train.clone() };
    crate::calib::pipeline::equivalent::truth_equivalent(model, robot, t, &clean, x0, fixed)
}

/// The repeatability of the readings over repeated configurations: for several values per row
/// (a point), pooled over the values (each coordinate's within-group variance, averaged).
pub fn reading_repeatability(data: &Dataset) -> Option<crate::stats::metrics::Repeatability> {
    // Repeats belong together only under one set of conditions: a configuration measured at
    // another station, with another mount, under another payload or in another declared block
    // is no repeat (what separates them would raise the floor that then hides it). Each
    // condition joins the angles as a coordinate far beyond any angle.
    let (stations, mounts) = (data.stations(), data.mounts());
    let blocks = crate::dataset::Stations::of_labels(data.rows.iter().map(|r| r.block.as_deref()));
    let apart = 1e3;
    let keyed: Vec<Vec<f64>> = data
        .rows
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let mut q = r.q_deg.clone();
            q.extend([
                stations.of_row[i] as f64 * apart,
                mounts.of_row[i] as f64 * apart,
                blocks.of_row[i] as f64 * apart,
                r.payload_kg.unwrap_or(0.0) * apart,
            ]);
            q
        })
        .collect();
    let q_deg: Vec<&[f64]> = keyed.iter().map(Vec::as_slice).collect();
    // The values as the model reads them (a pose's origin and axes).
    let values: Vec<Vec<f64>> = data.rows.iter().map(|r| r.values_mm().unwrap_or_default()).collect();
    let dim = values.first().map_or(1, |v| v.len()).max(1);
    let per: Vec<crate::stats::metrics::Repeatability> = (0..dim)
        .filter_map(|c| {
            let v: Vec<f64> = values.iter().map(|r| r.get(c).copied().unwrap_or(f64::NAN)).collect();
            crate::stats::metrics::repeatability(&q_deg, &v, 1e-6)
        })
        .collect();
    let first = per.first()?.clone();
    if dim == 1 {
        return Some(first).filter(|r| r.groups > 0);
    }
    let pooled_std = (per.iter().map(|r| r.pooled_std.powi(2)).sum::<f64>() / per.len() as f64).sqrt();
    let max_spread = per.iter().map(|r| r.max_spread).fold(0.0, f64::max);
    let per_value_std = per.iter().map(|r| r.pooled_std).collect();
    Some(crate::stats::metrics::Repeatability { pooled_std, max_spread, per_value_std, ..first }).filter(|r| r.groups > 0)
}

/// The outlier screens' rule (`k` robust standard deviations, reading steps if `steps`) for
/// `model` at its nominal parameters on `rows` of `data`: its scale never below the
/// angle-resolution part of their floor, what the angles' logging alone puts on a reading.
pub fn screen_rule(model: &CalibModel, data: &Dataset, rows: &Samples, k: f64, steps: bool, angle_step_deg: Option<f64>) -> ScreenRule {
    let floor = floor_stage(model, &model.nominal, data, rows, &FloorOptions { angle_step_deg, ..Default::default() }, None);
    let min_scale_mm = floor.part(crate::calib::fit::floor::FloorKind::AngleResolution);
    ScreenRule { k, steps, min_scale_mm }
}

/// No model predicts unseen rows better than the data's floor: a held-out RMSE (of the test rows
/// that are not outliers) below it by more than its sampling error over the test rows' blocks
/// means the test rows shared errors with training rows (rows of one sweep on both sides of a
/// random split share its rounding). The warning, if so; none for a pose's angles, which the
/// floor does not hold.
pub(super) fn leak_warning(data: &Dataset, split: &SplitData, test_r: &[f64], test_outliers: &[Outlier], floor_mm: f64) -> Option<String> {
    let d = split.test.dim.max(1);
    if split.test.is_empty() || !(floor_mm > 0.0) || data.measurement().is_some_and(|m| m.file_lengths() != d) {
        return None;
    }
    let mut kept: Vec<usize> = (0..split.test.len()).filter(|&i| !test_outliers.iter().any(|o| o.row == split.test_idx[i] + 1)).collect();
    kept.sort_by_key(|&i| split.test_idx[i]);
    let r: Vec<f64> = kept.iter().flat_map(|&i| test_r[i * d..(i + 1) * d].iter().copied()).collect();
    let rows: Vec<usize> = kept.iter().map(|&i| split.test_idx[i]).collect();
    let groups = split.blocks.ids_of(&rows);
    (!r.is_empty() && crate::stats::short_of_floor(&r, d, Some(&groups), floor_mm)).then(|| {
        format!(
            "the held-out RMSE of the test rows that are not outliers ({:.4} mm) is below the data's floor ({floor_mm:.4} mm) by more than its \
             sampling error: the test rows share errors with the training rows (the split leaks: rows of one sweep or one logging error on both sides), \
             so it is optimistic; hold out whole blocks (--split-by blocks) or declare them in a block column",
            crate::stats::rms(&r)
        )
    })
}

/// Stage "floor": the data's own floor for the model at `x` over `rows` (the rows of `data`):
/// the repeatability given, the joint angles' logging step (the options', else read from the
/// data's decimals) and the readings' logging step. See [`crate::calib::fit::floor`].
pub fn floor_stage(
    model: &CalibModel,
    x: &[f64],
    data: &Dataset,
    rows: &Samples,
    floor: &FloorOptions,
    repeat: Option<&crate::stats::metrics::Repeatability>,
) -> crate::calib::fit::floor::NoiseFloor {
    let (angle_step_deg, instrument_accuracy_mm) = (floor.angle_step_deg, floor.instrument_accuracy_mm);
    use crate::calib::fit::floor::{logging_step, Step};
    let angle_step = match angle_step_deg {
        Some(v) => Some(Step::Given(v)),
        None => logging_step(data.rows.iter().flat_map(|r| r.q_deg.iter().copied())).map(Step::Detected),
    };
    // The lengths' step (a pose's angles are logged in degrees: its position columns only).
    let lengths = data.measurement().map_or(0, |m| m.file_lengths());
    let reading_step = logging_step(data.rows.iter().flat_map(|r| r.reading_mm.iter().take(lengths).copied()));
    // The rows' own standard deviations, RMS per coordinate over the rows that give them.
    let stds: Vec<f64> = data.rows.iter().filter_map(|r| r.std_mm).flatten().collect();
    let row_std_mm = (!stds.is_empty()).then(|| crate::stats::rms(&stds));
    let instrument = crate::calib::fit::floor::InstrumentNoise { row_std_mm, accuracy_mm: instrument_accuracy_mm };
    crate::calib::fit::floor::noise_floor(
        model,
        x,
        rows,
        crate::calib::fit::floor::FloorInputs { angle_step, reading_step_mm: reading_step, repeat, instrument },
    )
}

#[cfg(test)]
mod tests {
    use crate::dataset::{Dataset, Row};

    /// Ten configurations measured twice at each of two stations (the second reading 0.01 mm
    /// off the first, the second station 5 mm off the first), then twice more under a payload
    /// (0.3 mm off): repeats are pooled within a station and a payload only.
    #[test]
    fn repeats_are_pooled_within_a_station_and_a_payload_only() {
        let mut rows = Vec::new();
        for (station, payload, offset) in [("a", 0.0, 0.0), ("b", 0.0, 5.0), ("a", 3.0, 0.3)] {
            for k in 0..10 {
                for rep in 0..2 {
                    rows.push(Row {
                        q_deg: vec![k as f64 * 7.0, 10.0, -20.0, 0.0, 30.0, 0.0],
                        reading_mm: vec![400.0 + k as f64 + offset + 0.01 * rep as f64],
                        station: Some(station.into()),
                        payload_kg: Some(payload),
                        ..Default::default()
                    });
                }
            }
        }
        let data = Dataset { rows, source: "test".into() };
        let r = super::reading_repeatability(&data).unwrap();
        // Each pair differs by 0.01 mm: a pooled std of 0.01 / √2.
        assert!((r.pooled_std - 0.01 / 2f64.sqrt()).abs() < 1e-9, "{r:?}");
        assert_eq!((r.groups, r.rows), (30, 60));
        // Read as one station without payloads, the offsets join the repeats.
        let mut one = data.clone();
        one.rows.iter_mut().for_each(|r| {
            r.station = None;
            r.payload_kg = None;
        });
        assert!(super::reading_repeatability(&one).unwrap().pooled_std > 1.0);
    }
}
