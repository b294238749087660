//! The `calibrate` pipeline: the prepared rows and model, the solve, and the result assembled
//! from the stages.

use super::effect_blocks::*;
use super::options::*;
use super::result::*;
use super::split::*;
use super::stages::*;
use crate::calib::fit::identify::identify;
use crate::calib::fit::identify::Identifiability;
use crate::calib::fit::robust::{Loss, Outlier};
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::methods::{Method, Solver, SolverNeeds};
use crate::calib::methods::{Problem, Solution};
use crate::calib::model::CalibModel;
use crate::dataset::truth::TruthFile;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::optim::{covariance, History, LevenbergMarquardt, NoObserver};
use crate::stats::metrics::ErrorStats;
use nalgebra::DMatrix;
use std::time::Instant;

/// Runs a calibration with the method named in `opts` at its default settings. Example: the whole job (the twin's data, this call, the others) runs as a doctest in [`crate::prelude`].
pub fn calibrate(data: &Dataset, truth: Option<&TruthFile>, opts: &CalibOptions) -> Result<CalibResult> {
    let solver = match (opts.method, opts.loss) {
        (_, Loss::L2) => opts.method.solver(opts.effort),
        (m, loss) if m == Method::LM => Box::new(crate::calib::methods::LmSolver { loss, ..Default::default() }),
        (m, loss) => return Err(Error::Invalid(format!("--loss {} applies to --method lm, not {}", loss.name(), m.name()))),
    };
    calibrate_with(data, truth, opts, solver.as_ref())
}

/// The stages before a fit, as one value that a calibration, a diagnosis and the benchmarks
/// share instead of re-deriving them: the split, the model with its instrument placed (and the
/// requested effect blocks), the robust screen, the rows' inputs with their torque model (in
/// `split`) and the identifiability at the start. Built by [`prepare`].
pub struct Prepared {
    /// The train / test split with the rows' inputs and their torque model.
    pub split: SplitData,
    /// The model with its instrument placed and the requested effect blocks.
    pub model: CalibModel,
    /// The robust screen of the training rows (`None` when off or with too few rows).
    pub screen: Option<crate::calib::fit::robust::Screen>,
    /// Test rows whose reading a reading step corrected.
    pub test_rows_in_steps: usize,
    /// Which parameters the training poses determine, at the model's nominal.
    pub id: Identifiability,
    /// How the training rows are weighted (per-row standard deviations), `None` for equal weights.
    pub weighting: Option<crate::calib::fit::weighting::Weighting>,
    /// What the generic model's search did (`None` for a nominal arm).
    pub search: Option<super::generic::SearchReport>,
}

/// Stages "split", "placement", "outliers", "effects" and "identifiability" of a calibration
/// with `opts`, for a solver that needs `needs`.
pub fn prepare(data: &Dataset, opts: &CalibOptions, needs: SolverNeeds) -> Result<Prepared> {
    let row_inputs = needs.row_inputs;
    let measurement = reading_measurement(data)?;
    let mut split = split_stage(data, opts)?;
    // The position columns (a pose's orientation may stay the same throughout, as on an ISO
    // cube).
    let dim = measurement.file_lengths();
    let spread: Vec<f64> = (0..dim)
        .map(|c| {
            let (lo, hi) = data.rows.iter().map(|r| r.reading_mm[c]).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            hi - lo
        })
        .collect();
    // Every reading value must change with the pose: a tracker column written as a constant (a
    // coordinate lost in the export) is no measurement either.
    if let Some(c) = spread.iter().position(|s| *s < MIN_LENGTH_SPREAD_MM) {
        let first = &data.rows[0].reading_mm;
        let msg = if dim == 1 {
            format!("every row reads the same length (L = {} mm): a calibration needs lengths that change with the pose", first[0])
        } else {
            format!(
                "every row reads the same {} ({} mm): a calibration needs readings that change with the pose",
                measurement.def().file_columns()[c],
                first[c]
            )
        };
        return Err(Error::data(&data.source, msg));
    }
    let (mut model, search) = crate::calib::pipeline::placement::place(opts, &split.train, [&data.stations().labels, &data.mounts().labels])?;
    // Stage "weighting": a tracker's per-row standard deviations weight the fit (and the screen).
    // (A learned corrector learns plain residuals: its methods fit with equal weights.)
    let weighting = if opts.floor.row_std && !needs.equal_weights {
        crate::calib::fit::weighting::training_weights(&model, data, &split.train_idx, &split.train, opts.rank_tol).map(|(w, info)| {
            split.train.w = Some(w);
            info
        })
    } else {
        None
    };
    // Two instruments (faces beside sockets, points beside them): each on its own noise.
    if split.train.w.is_none() && !needs.equal_weights {
        if let Some((w, _)) = crate::calib::fit::weighting::instrument_weights(&model, &split.train, opts.rank_tol) {
            split.train.w = Some(w);
        }
    }
    // The effects asked for are in the model before the screen: a warm-up's drift or a backlash
    // band, screened against the geometry alone, would look like reading steps and outliers.
    effects_stage(&mut model, &mut split, data, opts, row_inputs)?;
    let (screen, rows_changed) = outlier_stage(&model, &mut split, data, opts)?;
    if rows_changed && matches!(opts.model, ModelSpec::Nominal { .. }) {
        // The instrument placed again on the kept rows is a new model: the effects go back in.
        model = crate::calib::pipeline::placement::place_sensor(opts, &split.train, [&data.stations().labels, &data.mounts().labels])?;
        effects_stage(&mut model, &mut split, data, opts, row_inputs)?;
    }
    let test_rows_in_steps = samples(data, &split.test_idx).y.iter().zip(&split.test.y).filter(|(a, b)| a != b).count();
    let id = identify(&ReadingFit { model: &model, data: &split.train }, &model.nominal, opts.rank_tol);
    Ok(Prepared { split, model, screen, test_rows_in_steps, id, weighting, search })
}

/// The parameters held at their nominal values: those the data cannot identify, and those
/// `free` does not fit.
fn held_fixed(model: &CalibModel, id: &Identifiability, free: FreeParams) -> Vec<bool> {
    let zero_offsets = model.chain.zero_offset_params();
    let held = |k: usize| match free {
        FreeParams::All => false,
        FreeParams::Placement => !model.setup_range().contains(&k),
        FreeParams::Controller => !model.setup_range().contains(&k) && !zero_offsets.contains(&k),
    };
    id.fixed_mask.iter().enumerate().map(|(k, f)| *f || held(k)).collect()
}

/// Stage "set-up" of a calibration with `opts`: the data with their stations resolved
/// ([`setup::resolve`](super::setup::resolve)), the change points read from a first fit of
/// every row.
pub fn resolve_stations(data: &Dataset, opts: &CalibOptions) -> Result<(Option<Dataset>, super::setup::Found)> {
    super::split::check_arm(data, opts)?;
    super::setup::resolve(data, opts, &|d: &Dataset| first_fit(d, opts))
}

/// The generic arm's search of a first fit runs on at most this many rows, spread evenly over
/// the file (the fit itself then takes every row): its arm is a start, not the result.
pub const FIRST_FIT_SEARCH_ROWS: usize = 2000;
/// ... and on at least this many of each set-up's rows (all of a smaller one).
pub const FIRST_FIT_SEARCH_MIN_ROWS: usize = 30;

/// The model fitted to every row with the set-ups `data` names (no screen), the effects asked
/// for included (a warm-up's drift left in the residuals would look like a slow train of
/// moves): what the change-point search reads the residuals of. Under the generic arm its
/// search starts from [`FIRST_FIT_SEARCH_ROWS`] rows at most.
fn first_fit(data: &Dataset, opts: &CalibOptions) -> Result<(CalibModel, Vec<f64>, Samples)> {
    let mut all = samples(data, &(0..data.rows.len()).collect::<Vec<_>>());
    let labels = [&data.stations().labels[..], &data.mounts().labels[..]];
    let mut model = match opts.model {
        ModelSpec::Generic if all.len() > FIRST_FIT_SEARCH_ROWS => {
            // Every k-th row of each set-up (station and mount), and at least its first few.
            let every = all.len().div_ceil(FIRST_FIT_SEARCH_ROWS);
            let mut seen = std::collections::HashMap::new();
            let spread: Vec<usize> = (0..all.len())
                .filter(|&i| {
                    let rank = seen.entry((all.inputs[i].station, all.inputs[i].mount)).or_insert(0usize);
                    *rank += 1;
                    (*rank - 1) % every == 0 || *rank <= FIRST_FIT_SEARCH_MIN_ROWS
                })
                .collect();
            crate::calib::pipeline::placement::place_sensor(opts, &all.subset(&spread), labels)?
        }
        _ => crate::calib::pipeline::placement::place_sensor(opts, &all, labels)?,
    };
    if !opts.effects.is_empty() {
        all.inputs = add_effects(&mut model, data, opts)?.1;
    }
    let fit = ReadingFit { model: &model, data: &all };
    let id = identify(&fit, &model.nominal, opts.rank_tol);
    let x = LevenbergMarquardt::budget(100).minimize(&fit, &model.nominal, &id.fixed_mask, &mut NoObserver).x;
    Ok((model, x, all))
}

/// Runs a calibration with a given solver. `truth` enables the parameter-error report.
pub fn calibrate_with(data: &Dataset, truth: Option<&TruthFile>, opts: &CalibOptions, solver: &dyn Solver) -> Result<CalibResult> {
    let t0 = Instant::now();
    // Stage "set-up": the instrument's stations (declared, declared blocks, change points).
    let (labelled, found) = resolve_stations(data, opts)?;
    let data = labelled.as_ref().unwrap_or(data);
    let Prepared { mut split, model, screen, test_rows_in_steps: test_in_steps, id, weighting, search } = prepare(data, opts, SolverNeeds::of(solver))?;
    sees_the_blocks(&model, solver)?;
    let mut warnings = setup_warnings(&model, data, screen.is_some(), opts);
    let x0 = model.nominal.clone();
    let fixed = held_fixed(&model, &id, opts.free);
    let (noise_model, as_read) = noise_model_stage(&model, &x0, &fixed, &mut split, data, opts);
    let fit = ReadingFit { model: &model, data: &split.train };
    check_design(data, &split, &fixed, &mut warnings)?;
    let repeatability = reading_repeatability(data);

    let noise = if solver.needs_noise() { estimate_noise(&fit, &x0, &fixed, repeatability.as_ref()) } else { f64::NAN };
    let prior_std = opts.tolerances.prior_std(&model);
    let mut history = History::default();
    let problem = Problem { fit: &fit, x0: &x0, fixed: &fixed, prior_std: &prior_std, noise_mm: noise, seed: opts.seed };
    let Solution { report, corrector } = solver.solve(&problem, &mut history)?;
    let x = report.x.clone();
    if x.iter().any(|v| !v.is_finite()) {
        return Err(Error::Calibration(format!("{} diverged (non-finite parameters)", solver.name())));
    }
    if !report.converged() {
        warnings.push(format!(
            "{} stopped without converging ({}, after {} iterations); the parameters may be far from the optimum \
             (see `converged` / `stop_reason` in the result file; a larger --effort gives the stochastic methods more budget)",
            solver.name(),
            report.reason,
            report.iterations
        ));
    }

    // Stage "uncertainty": standard uncertainties from the Jacobian at the solution (all methods alike).
    // (Of the rows as read, whitened: the corrected readings would understate them.)
    let cov = grouped_covariance(&ReadingFit { model: &model, data: as_read.as_ref().unwrap_or(&split.train) }, &x, &fixed);
    let noise_estimate_mm = if noise.is_finite() { noise } else { residual_sigma(&fit, &x, &fixed) };
    let test_fit = ReadingFit { model: &model, data: &split.test };
    let correct = corrector.as_ref().map(|c| c.as_correct());
    // The metrics judge the training rows in mm, unweighted, as the test rows.
    let plain = match &as_read {
        Some(read) => Some(read.unweighted()),
        None => split.train.w.is_some().then(|| split.train.unweighted()),
    };
    let plain_fit = ReadingFit { model: &model, data: plain.as_ref().unwrap_or(&split.train) };
    let mut metrics = metrics_stage(&plain_fit, &test_fit, &x0, &x, correct);
    warnings.extend(metric_warnings(solver.name(), &metrics, noise));
    let test_residuals_mm = residuals_with(&test_fit, &x, correct);
    let test_outliers = test_outlier_stage(&plain_fit, &split.test, &test_residuals_mm, &split.test_idx, &x, correct, opts.screen.outlier_k);
    test_inlier_metrics(&mut metrics, &split, &test_residuals_mm, &test_outliers);
    let all_rows = samples(data, &(0..data.rows.len()).collect::<Vec<_>>());
    let noise_floor = floor_stage(&model, &x, data, &all_rows, &opts.floor, repeatability.as_ref());
    warnings.extend(leak_warning(data, &split, &test_residuals_mm, &test_outliers, noise_floor.total_mm));
    let truth_x = truth_stage(&model, &opts.model, truth, data, &split, &x0, &fixed);
    let (parameters, truth_comparison) = parameter_reports(&model, &x0, &x, &fixed, cov.as_ref(), truth_x.as_deref(), truth);
    let artifact = artifact_report(&model, &x, &split.train, &parameters, &opts.tolerances);
    let history_disp = history.x.iter().map(|xs| xs.iter().enumerate().map(|(k, v)| model.display(k, *v)).collect()).collect();
    Ok(CalibResult {
        schema_version: super::result::RESULT_SCHEMA_VERSION,
        provenance: Provenance {
            twincal_version: env!("CARGO_PKG_VERSION").into(),
            data: data.source.clone(),
            data_sha256: None,
            method: solver.name().into(),
            model_name: model.name.clone(),
            seed: opts.seed,
            n_train: split.train.len(),
            n_test: split.test.len(),
            test_rows: split.test_idx.clone(),
            wall_time_s: t0.elapsed().as_secs_f64(),
        },
        parameters,
        solve: Solve {
            iterations: report.iterations,
            evaluations: report.evaluations,
            converged: report.converged(),
            stop_reason: report.reason.clone(),
            loss: opts.loss,
            noise_estimate_mm,
            weighting,
            noise_model,
            identifiability: serde_json::to_value(&id).unwrap_or_default(),
            search,
        },
        screen: ScreenReport::of(screen, opts.screen.outlier_k, test_in_steps, test_outliers),
        evaluation: Evaluation { metrics, truth_comparison, repeatability, noise_floor: Some(noise_floor) },
        warnings,
        setup: super::setup::setup_report(&model, &x, data, opts.stations, &found),
        artifact,
        x,
        corrector,
        legacy_rbf: None,
        torque_model: split.torque_model.clone(),
        history: history_disp,
        test_residuals_mm,
        model,
    })
}

/// [`super::artifact::report`] of a result's `parameters` (held, and loose against the
/// tolerances).
fn artifact_report(
    model: &CalibModel,
    x: &[f64],
    train: &Samples,
    parameters: &[ParamReport],
    tolerances: &crate::calib::model::tolerance::Tolerances,
) -> Option<super::artifact::ArtifactReport> {
    let fixed: Vec<String> = parameters.iter().filter(|p| p.fixed).map(|p| p.name.clone()).collect();
    let params: Vec<(String, Option<f64>, String)> =
        parameters.iter().map(|p| (p.name.clone(), p.std_uncertainty.filter(|_| !p.fixed), p.unit.clone())).collect();
    super::artifact::report(model, x, train, &fixed, &super::artifact::loose(model, &params, tolerances))
}

/// Refuses a solver that reads the rows one by one (and never a spacing) for a model with
/// residual blocks of its own (a ball in sockets, a probe on faces).
fn sees_the_blocks(model: &CalibModel, solver: &dyn Solver) -> Result<()> {
    if !model.spacings.is_empty() && solver.name() != Method::LM.name() {
        return Err(Error::Invalid(format!(
            "an artifact's rows (a ball in sockets, a probe on faces) are calibrated by least squares over the rows and the stated spacings (--method lm); {} reads the rows one by one and never sees a spacing",
            solver.name()
        )));
    }
    Ok(())
}

/// A pose probe turning less than this over a mount's rows, degrees, leaves its origin on the
/// flange ill-determined (a turn of δ rad sees the origin with a lever of δ).
pub const MIN_PROBE_TURN_DEG: f64 = 1.0;

/// The smallest, over a pose probe's mounts, of the largest turn of its readings from the
/// mount's first one (degrees), with that mount's label; `None` for another instrument.
fn probe_turn(model: &CalibModel, data: &Dataset) -> Option<(f64, Option<String>)> {
    if model.measurement != crate::measurement::Measurement::Pose {
        return None;
    }
    let mut first: Vec<(Option<&str>, nalgebra::Matrix3<f64>, f64)> = Vec::new();
    for r in &data.rows {
        let m = crate::measurement::Euler::XYZ.matrix([r.reading_mm[3], r.reading_mm[4], r.reading_mm[5]].map(f64::to_radians));
        match first.iter_mut().find(|(label, ..)| *label == r.mount.as_deref()) {
            Some((_, m0, turn)) => *turn = turn.max(nalgebra::Rotation3::from_matrix_unchecked(m * m0.transpose()).angle().to_degrees()),
            None => first.push((r.mount.as_deref(), m, 0.0)),
        }
    }
    first.into_iter().map(|(l, _, t)| (t, l.map(str::to_string))).min_by(|a, b| a.0.total_cmp(&b.0))
}

/// Warnings about the pipeline's setup: a thermal block run as a warm-up, no outlier screen, a
/// probe that hardly turns.
pub(super) fn setup_warnings(model: &CalibModel, data: &Dataset, screened: bool, opts: &CalibOptions) -> Vec<String> {
    let mut warnings: Vec<String> = crate::calib::effects::inputs::payload_warning(data, &opts.loads.joints).into_iter().collect();
    if model.effects.iter().any(|b| matches!(b.thermal, Some(crate::calib::effects::ThermalDrive::WarmUp))) && data.rows.iter().all(|r| r.temp_c.is_some()) {
        warnings.push(format!(
            "the temp column spans less than {} K, so it drives no thermal drift: the thermal block runs on t as a warm-up",
            crate::calib::effects::MIN_TEMP_SPREAD_K
        ));
    }
    if let Some((turn, mount)) = probe_turn(model, data).filter(|(t, _)| *t < MIN_PROBE_TURN_DEG) {
        let at = mount.map_or(String::new(), |m| format!(" on mount {m}"));
        warnings.push(format!(
            "the probe{at} turns by at most {turn:.3}° over these rows: where its orientation hardly changes, its origin on the flange cannot be told \
             from the tracker's position, so the directions the rows do not see are held at the flange's origin (see the fixed tool.* parameters)"
        ));
    }
    if !screened && opts.screen.outlier_k > 0.0 {
        warnings.push(format!(
            "no outlier screen: fewer than {SCREEN_ROWS_PER_PARAM} training rows (reading values) per identifiable parameter, too few for a robust scale of the residuals"
        ));
    }
    warnings
}

/// Stage "noise model": the joint angles' logging error shared by a block's rows taken out of
/// the training readings of `split`; returns the noise model and the rows as read, whitened by
/// it (kept for the metrics and the uncertainties).
pub(super) fn noise_model_stage(
    model: &CalibModel,
    x0: &[f64],
    fixed: &[bool],
    split: &mut SplitData,
    data: &Dataset,
    opts: &CalibOptions,
) -> (Option<crate::calib::fit::gls::NoiseModel>, Option<Samples>) {
    let logging = match opts.floor.noise_model {
        crate::calib::fit::noise_model::NoiseChoice::Auto => {
            crate::calib::fit::noise_model::remove_logging_error(model, x0, fixed, &split.train, &split.train_idx, split.logging(data))
        }
        crate::calib::fit::noise_model::NoiseChoice::Off => None,
    };
    // With the noise model: the rows as read, whitened by it.
    match logging {
        Some((n, w, corrected)) => {
            let read = std::mem::replace(&mut split.train, corrected);
            (Some(n), Some(Samples { gls: Some(w), ..read }))
        }
        None => (None, None),
    }
}

/// Refuses a design with no more distinct training configurations (in reading values) than
/// identifiable parameters; warns below three times as many.
pub(super) fn check_design(data: &Dataset, split: &SplitData, fixed: &[bool], warnings: &mut Vec<String>) -> Result<()> {
    let n_free = fixed.iter().filter(|f| !**f).count();
    // Counted in reading values: a configuration a tracker reads gives three.
    let dim = split.train.dim.max(1);
    let distinct = distinct_configurations(data, &split.train_idx);
    if distinct * dim <= n_free {
        let values = if dim > 1 { format!(" ({} reading values)", distinct * dim) } else { String::new() };
        return Err(Error::Calibration(format!(
            "{distinct} distinct training configurations{values} for {n_free} identifiable parameters: an exact fit says nothing; \
             measure more poses (at least {} recommended)",
            (3 * n_free).div_ceil(dim)
        )));
    }
    if split.train.y.len() < 3 * n_free {
        let values = if dim > 1 { format!(" ({} reading values)", split.train.y.len()) } else { String::new() };
        warnings.push(format!(
            "only {} training rows{values} for {n_free} identifiable parameters (3x as many recommended): uncertainties are large",
            split.train.len()
        ));
    }
    Ok(())
}

/// What the metrics say against the result: worse than the nominal model on the training rows,
/// or on the test rows while better on the training rows; fitted far inside the reading noise
/// `noise` (mm) and missing the test rows.
pub(super) fn metric_warnings(name: &str, metrics: &Metrics, noise: f64) -> Vec<String> {
    let mut warnings = Vec::new();
    // Differences of a nanometre or less are numerical (a noise-free dataset), not worse.
    let worse = |before: f64, after: f64| after > before && after - before > crate::stats::NUMERICAL_MM;
    if worse(metrics.train_before.rmse, metrics.train_after.rmse) {
        warnings.push(format!(
            "{} ended worse than the nominal model it started from (training RMSE {:.4} -> {:.4} mm): the result is not a calibration; \
             try --method lm, or a larger --effort",
            name, metrics.train_before.rmse, metrics.train_after.rmse
        ));
    } else if let (Some(before), Some(after)) = (&metrics.test_before, &metrics.test_after) {
        // Beyond 5 %: a model already calibrated (its own URDF export) moves within noise.
        if after.rmse > 1.05 * before.rmse && worse(before.rmse, after.rmse) {
            warnings.push(format!(
                "the calibrated model predicts the test rows worse than the nominal model (test RMSE {:.4} -> {:.4} mm) while it fits the training \
                 rows better: the training poses do not cover the test rows (a joint held still or a narrow range) or the model follows their noise",
                before.rmse, after.rmse
            ));
        }
    }
    // A model that fits its training rows far inside the reading noise and then misses the test
    // rows has learned the rows, not the arm (an unpenalised network, as pso-ekf-awnn-v5's).
    if let (true, Some(test)) = (noise.is_finite() && noise > 0.0, &metrics.test_after) {
        if metrics.train_after.rmse < 0.5 * noise && test.rmse > 2.0 * metrics.train_after.rmse.max(noise) {
            warnings.push(format!(
                "{} fits the training rows far inside the reading noise (training RMSE {:.4} mm, noise {noise:.4} mm) and misses the test rows \
                 ({:.4} mm): it has more freedom than the data support and follows their noise",
                name, metrics.train_after.rmse, test.rmse
            ));
        }
    }
    warnings
}

/// The test rows' error statistics without the test outliers, and trimmed of the worst 1 %.
pub(super) fn test_inlier_metrics(metrics: &mut Metrics, split: &SplitData, test_residuals_mm: &[f64], test_outliers: &[Outlier]) {
    if !split.test.is_empty() {
        let out: Vec<usize> = test_outliers.iter().map(|o| o.row - 1).collect();
        let d = split.test.dim;
        let inliers: Vec<f64> =
            (0..split.test.len()).filter(|i| !out.contains(&split.test_idx[*i])).flat_map(|i| test_residuals_mm[i * d..(i + 1) * d].iter().copied()).collect();
        // Every test row beyond the rule: there are no inliers to describe.
        metrics.test_after_inliers = (!inliers.is_empty()).then(|| ErrorStats::of(&inliers));
        metrics.test_after_trimmed = Some(trimmed_stats(test_residuals_mm, 0.01));
    }
}

/// A model fitted outside the pipeline: the start `x0`, the fit `x`, the identifiability
/// analysis that fixed what it held, and the torque model of its effect blocks.
pub struct FittedModel {
    /// The fitted model.
    pub model: CalibModel,
    /// The start of the fit (internal units).
    pub x0: Vec<f64>,
    /// The fitted parameter vector (internal units).
    pub x: Vec<f64>,
    /// The identifiability analysis that decided which parameters were held.
    pub id: Identifiability,
    /// How the effect blocks get their joint torques on new rows.
    pub torque_model: Option<crate::calib::effects::inputs::TorqueModel>,
}

/// A calibration result for a model already fitted on every row of `data` (`x` from `x0`, the
/// parameters `fixed` held): what `diagnose --result` writes, so that the file is exactly the
/// model its report evaluated. No test rows; `torque_model` gives the effect blocks their joint
/// torques on new rows.
pub fn result_of_fit(
    data: &Dataset,
    rows: &Samples,
    fitted: FittedModel,
    seed: u64,
    angle_step_deg: Option<f64>,
    instrument_accuracy_mm: Option<f64>,
) -> Result<CalibResult> {
    let FittedModel { model, x0, x, id, torque_model } = fitted;
    let (x0, id) = (&x0[..], &id);
    let t0 = Instant::now();
    let fixed = &id.fixed_mask;
    let fit = ReadingFit { model: &model, data: rows };
    let cov = covariance(&fit, &x, fixed);
    let (parameters, _) = parameter_reports(&model, x0, &x, fixed, cov.as_ref(), None, None);
    let empty = Samples::new(Vec::new(), Vec::new());
    // The metrics in mm, unweighted (the covariance is the weighted fit's).
    let plain = rows.unweighted();
    let metrics = metrics_stage(&ReadingFit { model: &model, data: &plain }, &ReadingFit { model: &model, data: &empty }, x0, &x, None);
    data.require_readings()?;
    let repeatability = reading_repeatability(data);
    let noise_floor =
        floor_stage(&model, &x, data, rows, &FloorOptions { angle_step_deg, instrument_accuracy_mm, ..Default::default() }, repeatability.as_ref());
    let artifact = artifact_report(&model, &x, rows, &parameters, &Default::default());
    Ok(CalibResult {
        schema_version: super::result::RESULT_SCHEMA_VERSION,
        provenance: Provenance {
            twincal_version: env!("CARGO_PKG_VERSION").into(),
            data: data.source.clone(),
            data_sha256: None,
            method: Method::LM.name().into(),
            model_name: model.name.clone(),
            seed,
            n_train: rows.len(),
            n_test: 0,
            test_rows: Vec::new(),
            wall_time_s: t0.elapsed().as_secs_f64(),
        },
        parameters,
        solve: Solve {
            iterations: 0,
            evaluations: 0,
            converged: true,
            stop_reason: "the diagnosis's final model, fitted on every kept row".into(),
            loss: Loss::L2,
            noise_estimate_mm: residual_sigma(&fit, &x, fixed),
            weighting: None,
            noise_model: None,
            identifiability: serde_json::to_value(id).unwrap_or_default(),
            search: None,
        },
        screen: ScreenReport::default(),
        evaluation: Evaluation { metrics, truth_comparison: None, repeatability, noise_floor: Some(noise_floor) },
        warnings: Vec::new(),
        setup: super::setup::setup_report(&model, &x, data, super::options::StationSource::Declared, &[]),
        artifact,
        x,
        corrector: None,
        legacy_rbf: None,
        torque_model,
        history: Vec::new(),
        test_residuals_mm: Vec::new(),
        model,
    })
}

/// Every parameter in display units with its uncertainty and, with a truth, its error and z.
pub(super) fn parameter_reports(
    model: &CalibModel,
    x0: &[f64],
    x: &[f64],
    fixed: &[bool],
    cov: Option<&DMatrix<f64>>,
    truth_x: Option<&[f64]>,
    truth: Option<&TruthFile>,
) -> (Vec<ParamReport>, Option<TruthComparison>) {
    let mut parameters = Vec::with_capacity(model.n_params());
    let (mut within, mut max_z) = (0, 0.0f64);
    for k in 0..model.n_params() {
        let d = model.kinds[k].display();
        let sd = cov.map(|c| c[(k, k)].max(0.0).sqrt() * d).filter(|_| !fixed[k]);
        let truth_v = truth_x.map(|t| t[k] * d);
        let error = truth_v.map(|t| x[k] * d - t);
        let z = match (error, sd) {
            (Some(e), Some(s)) if s > 0.0 => Some(e / s),
            _ => None,
        };
        if let Some(z) = z {
            max_z = max_z.max(z.abs());
            if z.abs() <= 3.0 {
                within += 1;
            }
        }
        parameters.push(ParamReport {
            name: model.names[k].clone(),
            unit: model.kinds[k].unit().into(),
            nominal: x0[k] * d,
            value: x[k] * d,
            std_uncertainty: sd,
            fixed: fixed[k],
            truth: truth_v,
            error,
            z,
        });
    }
    let comparison = truth.filter(|_| truth_x.is_some()).map(|t| TruthComparison {
        within_3_sigma: within,
        identifiable: fixed.iter().filter(|f| !**f).count(),
        max_abs_z: max_z,
        method: "mapped from the true frame errors, then fitted to the noise-free lengths from there".into(),
        noise_floor_mm: t.noise_std_mm,
    });
    (parameters, comparison)
}
