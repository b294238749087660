//! `twincal calibrate`: data → model → identifiability → method → calibrated model and report.

use super::identify::{analyse, Identifiability};
use super::metrics::ErrorStats;
use super::model::{CalibModel, SensorGuess};
use super::optim::{Bounds, De, DeVariant, Ekf, History, LeastSquares, LevenbergMarquardt, ParticleFilter, Pso, Report};
use super::problem::{FreeCost, LengthFit, Samples};
use super::rbf::RbfNetwork;
pub use super::truth::TruthFile;
use crate::dataset::{Dataset, Split};
use crate::error::{Error, Result};
use crate::robot::Robot;
use nalgebra::{DMatrix, DVector};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;
use rayon::prelude::*;
use std::time::Instant;

/// Calibration methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    Lm,
    Ekf,
    Pf,
    Pso,
    Rbf,
}

impl Method {
    pub fn parse(s: &str) -> Result<Method> {
        Ok(match s.trim().to_ascii_lowercase().as_str() {
            "lm" => Method::Lm,
            "ekf" => Method::Ekf,
            "pf" => Method::Pf,
            "pso" => Method::Pso,
            "rbf" => Method::Rbf,
            other => return Err(Error::Invalid(format!("unknown method '{other}' (expected lm, ekf, pf, pso or rbf)"))),
        })
    }
    pub fn name(self) -> &'static str {
        match self {
            Method::Lm => "lm",
            Method::Ekf => "ekf",
            Method::Pf => "pf",
            Method::Pso => "pso",
            Method::Rbf => "rbf",
        }
    }
}

/// Which kinematic model to calibrate.
#[derive(Clone, Debug)]
pub enum ModelSpec {
    /// A robot with a nominal URDF (the embedded IRB 120 or a file) in a parametrisation:
    /// `dh`, `hayati` or `frame`.
    Nominal { robot: Robot, parametrisation: String },
    /// A 6R arm with no published nominal.
    Generic6r,
}

impl ModelSpec {
    pub fn parse(model: &str, parametrisation: &str) -> Result<ModelSpec> {
        let p = parametrisation.to_ascii_lowercase();
        if !matches!(p.as_str(), "dh" | "hayati" | "frame") {
            return Err(Error::Invalid(format!("unknown parametrisation '{parametrisation}' (expected dh, hayati or frame)")));
        }
        match model {
            "irb120" => Ok(ModelSpec::Nominal { robot: Robot::irb120(), parametrisation: p }),
            "generic6r" => Ok(ModelSpec::Generic6r),
            path if path.ends_with(".urdf") => {
                let robot = Robot::from_urdf_file(Path::new(path))?;
                if robot.dof() != 6 {
                    return Err(Error::Invalid(format!("{path}: {} revolute joints; calibration data hold six joint angles (q1..q6)", robot.dof())));
                }
                Ok(ModelSpec::Nominal { robot, parametrisation: p })
            }
            other => Err(Error::Invalid(format!("unknown model '{other}' (expected irb120, generic6r or a .urdf path)"))),
        }
    }
}

#[derive(Clone, Debug)]
pub struct CalibOptions {
    pub model: ModelSpec,
    pub method: Method,
    /// Hold out this fraction (stratified over L) instead of the dataset's split column.
    pub test_fraction: Option<f64>,
    pub seed: u64,
    /// Relative singular-value tolerance of the identifiability analysis.
    pub rank_tol: f64,
    /// Sensor geometry guess; estimated from the data when absent.
    pub sensor_guess: Option<SensorGuess>,
    /// Effort scale for the stochastic methods (1 = default budget).
    pub effort: f64,
}

impl CalibOptions {
    pub fn new(model: ModelSpec, method: Method) -> Self {
        CalibOptions { model, method, test_fraction: None, seed: 0, rank_tol: 1e-7, sensor_guess: None, effort: 1.0 }
    }
}

/// A parameter in the report (display units: mm, degrees).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ParamReport {
    pub name: String,
    pub unit: String,
    pub nominal: f64,
    pub value: f64,
    pub std_uncertainty: Option<f64>,
    pub fixed: bool,
    /// With a truth file: the value this model should reach on noise-free data.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<f64>,
    /// error / std_uncertainty.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Metrics {
    pub train_before: ErrorStats,
    pub test_before: Option<ErrorStats>,
    pub train_after: ErrorStats,
    pub test_after: Option<ErrorStats>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TruthComparison {
    /// Identifiable parameters within 3 standard uncertainties of the truth.
    pub within_3_sigma: usize,
    pub identifiable: usize,
    pub max_abs_z: f64,
    /// Sensor noise floor (std of an averaged reading), mm.
    pub noise_floor_mm: f64,
}

/// The calibrated model: everything `predict` needs, and the report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CalibResult {
    pub twincal_version: String,
    pub data: String,
    pub method: Method,
    pub model_name: String,
    pub seed: u64,
    pub n_train: usize,
    pub n_test: usize,
    pub parameters: Vec<ParamReport>,
    pub identifiability: serde_json::Value,
    pub metrics: Metrics,
    pub iterations: usize,
    pub evaluations: usize,
    pub converged: bool,
    pub stop_reason: String,
    pub wall_time_s: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_comparison: Option<TruthComparison>,
    /// Repeated configurations in the data and the spread of L over them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repeatability: Option<super::metrics::Repeatability>,
    /// The model itself (chain and parameter vector, internal units m / rad).
    pub model: CalibModel,
    pub x: Vec<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rbf: Option<RbfNetwork>,
    /// Parameter values per iteration (display units), for convergence plots.
    #[serde(skip)]
    pub history: Vec<Vec<f64>>,
}

impl CalibResult {
    /// Predicted length (mm) at joint angles in degrees.
    pub fn predict_mm(&self, q_deg: &[f64; 6]) -> f64 {
        let q: Vec<f64> = q_deg.iter().map(|d| d.to_radians()).collect();
        let mut w = self.model.work();
        let base = self.model.predict(&self.x, &q, &mut w) * 1e3;
        base + self.rbf.as_ref().map(|n| n.predict(&q)).unwrap_or(0.0)
    }

    pub fn load(path: &Path) -> Result<CalibResult> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let r: CalibResult =
            serde_json::from_str(&text).map_err(|e| Error::data(path.display(), format!("not a twincal calibration result: {e}")))?;
        let chain = &r.model.chain;
        let consistent = chain.n_joints == 6
            && r.x.len() == r.model.n_params()
            && r.model.kinds.len() == r.model.n_params()
            && r.model.n_params() == chain.n_params() + super::model::SENSOR_PARAMS.len()
            && chain.frame_end.last().is_some_and(|e| *e == chain.ops.len())
            && chain.ops.iter().all(|o| o.joint.is_none_or(|j| j < 6) && o.param.is_none_or(|k| k < chain.n_params()));
        if !consistent || r.x.iter().any(|v| !v.is_finite()) {
            return Err(Error::data(path.display(), "the calibrated model is inconsistent (edited or truncated result file?)"));
        }
        Ok(r)
    }
}

/// Train / test row indices: the dataset's split column, or a stratified hold-out of
/// `test_fraction` (rows sorted by L, one random pick per stratum).
pub fn split_rows(data: &Dataset, test_fraction: Option<f64>, seed: u64) -> Result<(Vec<usize>, Vec<usize>)> {
    let n = data.rows.len();
    match test_fraction {
        Some(f) => {
            if !(0.0..1.0).contains(&f) {
                return Err(Error::Invalid(format!("--test-fraction must be in [0, 1), got {f}")));
            }
            let n_test = (f * n as f64).round() as usize;
            let lengths = data.lengths_mm()?;
            let split = crate::generate::stratified_split(&lengths, n_test, seed);
            Ok(((0..n).filter(|i| split[*i] == Split::Train).collect(), (0..n).filter(|i| split[*i] == Split::Test).collect()))
        }
        None => Ok((data.train_indices(), data.test_indices())),
    }
}

/// The rows `idx` of a dataset as calibration samples (radians, metres).
pub fn samples(data: &Dataset, idx: &[usize]) -> Samples {
    Samples {
        q: idx.iter().map(|&i| data.rows[i].q_deg.iter().map(|d| d.to_radians()).collect()).collect(),
        l: idx.iter().map(|&i| data.rows[i].l_mm.unwrap_or(f64::NAN) * 1e-3).collect(),
    }
}

/// Exit point and length offset by linear multilateration from known tool points (m):
/// (L − c)² = |p − e|² is linear in (e, c, |e|² − c²).
pub fn multilaterate(points: &[nalgebra::Vector3<f64>], lengths: &[f64]) -> Option<([f64; 3], f64)> {
    let m = points.len();
    if m < 6 {
        return None;
    }
    let a = DMatrix::from_fn(m, 5, |i, k| match k {
        0..=2 => -2.0 * points[i][k],
        3 => 2.0 * lengths[i],
        _ => 1.0,
    });
    let b = DVector::from_fn(m, |i, _| lengths[i] * lengths[i] - points[i].norm_squared());
    let sol = a.svd(true, true).solve(&b, 1e-12).ok()?;
    Some(([sol[0], sol[1], sol[2]], sol[3]))
}

fn build_model(spec: &ModelSpec, guess: &SensorGuess) -> CalibModel {
    match spec {
        ModelSpec::Nominal { robot, parametrisation } => match parametrisation.as_str() {
            "frame" => CalibModel::frame(robot, guess),
            "dh" => CalibModel::dh(robot, guess, false),
            _ => CalibModel::dh(robot, guess, true),
        },
        ModelSpec::Generic6r => CalibModel::generic(6, guess),
    }
}

fn stats(fit: &LengthFit, x: &[f64], rbf: Option<&RbfNetwork>) -> ErrorStats {
    let mut r = fit.residuals_mm(x);
    if let Some(net) = rbf {
        for (i, ri) in r.iter_mut().enumerate() {
            *ri -= net.predict(&fit.data.q[i]);
        }
    }
    ErrorStats::of(&r)
}

/// Initial parameter vector: nominal geometry and a sensor guess (given or multilaterated), or
/// for the generic model a global search from broad bounds.
fn initial(spec: &ModelSpec, opts: &CalibOptions, train: &Samples) -> Result<CalibModel> {
    let zero_guess = SensorGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
    if let Some(g) = &opts.sensor_guess {
        return Ok(build_model(spec, g));
    }
    match spec {
        ModelSpec::Nominal { .. } => {
            let m = build_model(spec, &zero_guess);
            let mut w = m.work();
            let pts: Vec<_> = train.q.iter().map(|q| m.tool_point(&m.nominal, q, &mut w)).collect();
            let (e, c) = multilaterate(&pts, &train.l)
                .ok_or_else(|| Error::Calibration("cannot locate the cable exit point: need at least 6 well-spread poses".into()))?;
            // Then align the sensor alone (exit point, offset, tool point) to the nominal robot,
            // so that every method starts from "nominal kinematics, best-fitting sensor".
            let mut model = build_model(spec, &SensorGuess { exit_m: e, offset_m: c, tool_m: [0.0; 3] });
            let nc = model.n_chain();
            let fixed: Vec<bool> = (0..model.n_params()).map(|k| k < nc).collect();
            let fit = LengthFit { model: &model, data: train };
            let lm = LevenbergMarquardt { max_iter: 200, ..Default::default() };
            let x = lm.minimize(&fit, &model.nominal, &fixed, &mut super::optim::NoObserver).x;
            if x.iter().all(|v| v.is_finite()) {
                model.nominal = x;
            }
            Ok(model)
        }
        ModelSpec::Generic6r => Ok(build_model(spec, &zero_guess)),
    }
}

/// Broad bounds for the generic 6R search: D-H angles over the full circle, lengths within ±1.5 m,
/// exit point within ±3 m, offset within ±2 m, tool point within ±0.3 m.
fn generic_bounds(model: &CalibModel) -> Bounds {
    let pi = std::f64::consts::PI;
    let (lo, hi): (Vec<f64>, Vec<f64>) = model
        .names
        .iter()
        .map(|n| {
            if n.ends_with(".theta") || n.ends_with(".alpha") {
                (-pi, pi)
            } else if n.starts_with("exit.") {
                (-3.0, 3.0)
            } else if n == "length_offset" {
                (-2.0, 2.0)
            } else if n.starts_with("tool.") {
                (-0.3, 0.3)
            } else {
                (-1.5, 1.5)
            }
        })
        .unzip();
    Bounds::new(lo, hi)
}

/// A spread per parameter: `sensor` (m) for the draw-wire geometry, `length` (m) and `angle`
/// (rad) for the robot's parameters.
fn prior_std(model: &CalibModel, sensor: f64, length: f64, angle: f64) -> Vec<f64> {
    let nc = model.n_chain();
    (0..model.n_params())
        .map(|k| {
            if k >= nc {
                sensor
            } else if model.kinds[k] == super::model::Kind::Length {
                length
            } else {
                angle
            }
        })
        .collect()
}

/// Sensor parameters first: they are the unknowns of every set-up, while the robot's own
/// parameters have nominal values; where the two repeat each other the robot's are fixed.
fn priority(model: &CalibModel) -> Vec<usize> {
    let nc = model.n_chain();
    (nc..model.n_params()).chain(0..nc).collect()
}

/// Identifiability of `model` on `fit`'s poses at `x`.
pub fn identify(fit: &LengthFit, x: &[f64], tol: f64) -> Identifiability {
    analyse(&jacobian(fit, x), &fit.model.names, &vec![false; fit.model.n_params()], tol, &priority(fit.model))
}

/// Covariance of the free parameters, σ²·(JᵀJ)⁻¹ with σ² = 2·cost / (m − n_free), computed on
/// unit-norm columns so that millimetres and radians do not spoil the conditioning.
pub fn covariance(fit: &LengthFit, x: &[f64], fixed: &[bool]) -> Option<DMatrix<f64>> {
    let n = fit.model.n_params();
    let free: Vec<usize> = (0..n).filter(|k| !fixed[*k]).collect();
    let m = fit.data.len();
    if m <= free.len() {
        return None;
    }
    let j = jacobian(fit, x);
    let norms: Vec<f64> = free.iter().map(|&k| j.column(k).norm().max(1e-300)).collect();
    let js = DMatrix::from_fn(m, free.len(), |r, c| j[(r, free[c])] / norms[c]);
    let sigma2 = 2.0 * LeastSquares::cost(fit, x) / (m - free.len()) as f64;
    let jtj = js.transpose() * &js;
    let inv = jtj.clone().cholesky().map(|c| c.inverse()).or_else(|| jtj.pseudo_inverse(1e-14).ok())?;
    let mut cov = DMatrix::zeros(n, n);
    for (a, &ka) in free.iter().enumerate() {
        for (b, &kb) in free.iter().enumerate() {
            cov[(ka, kb)] = sigma2 * inv[(a, b)] / (norms[a] * norms[b]);
        }
    }
    Some(cov)
}

fn jacobian(fit: &LengthFit, x: &[f64]) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(fit.data.len(), fit.model.n_params());
    LeastSquares::jacobian(fit, x, &mut j);
    j
}

/// Runs a calibration. `truth` enables the parameter-error report.
pub fn calibrate(data: &Dataset, truth: Option<&TruthFile>, opts: &CalibOptions) -> Result<CalibResult> {
    let t0 = Instant::now();
    data.require_length()?;
    let (train_idx, test_idx) = split_rows(data, opts.test_fraction, opts.seed)?;
    if train_idx.len() < 8 {
        return Err(Error::Calibration(format!("only {} training rows; at least 8 are needed", train_idx.len())));
    }
    let train = samples(data, &train_idx);
    let test = samples(data, &test_idx);
    let mut model = initial(&opts.model, opts, &train)?;
    // Narrow-range data leave the generic model badly conditioned: LM then needs many small steps.
    let max_iter = if matches!(opts.model, ModelSpec::Generic6r) { 5000 } else { 500 };
    let lm = LevenbergMarquardt { max_iter, ..Default::default() };
    let mut history = History::default();

    // The generic model first needs a structure: global search, then local refinement.
    if matches!(opts.model, ModelSpec::Generic6r) && opts.sensor_guess.is_none() {
        model.nominal = generic_search(&model, &train, opts)?;
    }
    let x0 = model.nominal.clone();
    let fit = LengthFit { model: &model, data: &train };
    let id = identify(&fit, &x0, opts.rank_tol);
    let fixed = id.fixed_mask.clone();
    let free: Vec<usize> = (0..model.n_params()).filter(|k| !fixed[*k]).collect();

    let mut rbf = None;
    let report: Report = match opts.method {
        Method::Lm | Method::Rbf => {
            let r = lm.minimize(&fit, &x0, &fixed, &mut history);
            if opts.method == Method::Rbf {
                let res = fit.residuals_mm(&r.x);
                let (net, _) = RbfNetwork::fit_cv(&train.q, &res, &[5, 10, 20, 40], &[1e-6, 1e-4, 1e-2], opts.seed)
                    .map_err(|e| Error::Calibration(format!("RBF network: {e}")))?;
                rbf = Some(net);
            }
            r
        }
        Method::Ekf => {
            // Prior: 20 mm on the sensor, 1 mm on lengths, 0.1° on angles; R from a noise guess of 0.05 mm.
            let p0: Vec<f64> = prior_std(&model, 0.02, 1e-3, 0.1f64.to_radians()).iter().map(|s| s * s).collect();
            let ekf = Ekf { epochs: (20.0 * opts.effort).ceil() as usize, q: 0.0, r: 0.05f64.powi(2), p0, tol: 1e-10 };
            let mut order: Vec<usize> = (0..train.len()).collect();
            order.shuffle(&mut ChaCha8Rng::seed_from_u64(opts.seed));
            ekf.run(&fit, &x0, &fixed, &order, &mut history)
        }
        Method::Pf => {
            // Prior around the aligned start: 1 mm on the sensor, 0.5 mm and 0.05° on the robot.
            let std = prior_std(&model, 1e-3, 5e-4, 0.05f64.to_radians());
            // Measurement variance tempered to the starting misfit, so the weights do not collapse
            // onto a handful of particles in the first batches.
            let r0 = 2.0 * LeastSquares::cost(&fit, &x0) / train.len() as f64;
            let pf = ParticleFilter {
                particles: (4000.0 * opts.effort) as usize,
                epochs: 4,
                batch: 10,
                r: r0.max(0.05f64.powi(2)),
                roughening: 0.1,
                seed: opts.seed,
            };
            let mut order: Vec<usize> = (0..train.len()).collect();
            order.shuffle(&mut ChaCha8Rng::seed_from_u64(opts.seed));
            pf.run(&fit, &x0, &std, &fixed, &order, &mut history)
        }
        Method::Pso => {
            let prior = prior_std(&model, 0.05, 3e-3, 0.3f64.to_radians());
            let half: Vec<f64> = free.iter().map(|&k| prior[k]).collect();
            let centre: Vec<f64> = free.iter().map(|&k| x0[k]).collect();
            let bounds = Bounds::around(&centre, &half);
            let cost = FreeCost { fit: LengthFit { model: &model, data: &train }, base: x0.clone(), free: free.clone() };
            let pso = Pso { particles: 60, iterations: (1500.0 * opts.effort) as usize, seed: opts.seed, patience: 200, ..Default::default() };
            let mut r = pso.minimize(&cost, &bounds, Some(&centre), &mut history);
            r.x = cost.expand(&r.x);
            // The swarm works on the free parameters only; record full vectors like the others.
            history.x = history.x.iter().map(|xf| cost.expand(xf)).collect();
            r
        }
    };
    let x = report.x.clone();
    if x.iter().any(|v| !v.is_finite()) {
        return Err(Error::Calibration(format!("{} diverged (non-finite parameters)", opts.method.name())));
    }

    // Standard uncertainties from the Jacobian at the solution (all methods alike).
    let cov = covariance(&fit, &x, &fixed);
    let test_fit = LengthFit { model: &model, data: &test };
    let metrics = Metrics {
        train_before: stats(&fit, &x0, None),
        test_before: (!test.is_empty()).then(|| stats(&test_fit, &x0, None)),
        train_after: stats(&fit, &x, rbf.as_ref()),
        test_after: (!test.is_empty()).then(|| stats(&test_fit, &x, rbf.as_ref())),
    };

    // Truth: the parameters this model reaches on noise-free lengths of the same poses.
    let truth_x = match truth {
        Some(t) if t.poses.len() == data.rows.len() => {
            let clean = Samples { q: train.q.clone(), l: train_idx.iter().map(|&i| t.poses[i].length_true_mm * 1e-3).collect() };
            let cfit = LengthFit { model: &model, data: &clean };
            Some(lm.minimize(&cfit, &x, &fixed, &mut super::optim::NoObserver).x)
        }
        _ => None,
    };
    let mut parameters = Vec::with_capacity(model.n_params());
    let mut within = 0;
    let mut max_z: f64 = 0.0;
    for k in 0..model.n_params() {
        let d = model.kinds[k].display();
        let sd = cov.as_ref().map(|c| c[(k, k)].max(0.0).sqrt() * d).filter(|_| !fixed[k]);
        let truth_v = truth_x.as_ref().map(|t| t[k] * d);
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
    let truth_comparison = truth.filter(|_| truth_x.is_some()).map(|t| TruthComparison {
        within_3_sigma: within,
        identifiable: free.len(),
        max_abs_z: max_z,
        noise_floor_mm: t.noise_std_mm,
    });
    let q_deg: Vec<[f64; 6]> = data.rows.iter().map(|r| r.q_deg).collect();
    let l = data.lengths_mm()?;
    let repeatability = super::metrics::repeatability(&q_deg, &l, 1e-6).filter(|r| r.groups > 0);
    let history_disp = history.x.iter().map(|xs| xs.iter().enumerate().map(|(k, v)| model.display(k, *v)).collect()).collect();
    Ok(CalibResult {
        twincal_version: env!("CARGO_PKG_VERSION").into(),
        data: data.source.clone(),
        method: opts.method,
        model_name: model.name.clone(),
        seed: opts.seed,
        n_train: train.len(),
        n_test: test.len(),
        parameters,
        identifiability: serde_json::to_value(&id).unwrap_or_default(),
        metrics,
        iterations: report.iterations,
        evaluations: report.evaluations,
        converged: report.converged,
        stop_reason: report.reason.clone(),
        wall_time_s: t0.elapsed().as_secs_f64(),
        truth_comparison,
        repeatability,
        x,
        rbf,
        history: history_disp,
        model,
    })
}

/// Global search for the generic model: L-SHADE over broad bounds, several restarts, each
/// polished by LM; the best training fit wins.
fn generic_search(model: &CalibModel, train: &Samples, opts: &CalibOptions) -> Result<Vec<f64>> {
    let bounds = generic_bounds(model);
    let all: Vec<usize> = (0..model.n_params()).collect();
    // The global search sees an evenly spread subset (every k-th row, at most 400); LM then
    // polishes each candidate on every training row.
    let step = train.len().div_ceil(400).max(1);
    let subset = Samples { q: train.q.iter().step_by(step).cloned().collect(), l: train.l.iter().step_by(step).copied().collect() };
    let fit = LengthFit { model, data: train };
    let lm = LevenbergMarquardt { max_iter: 300, ..Default::default() };
    let restarts = (4.0 * opts.effort).ceil() as u64;
    // Restarts are independent (own seeds) and run in parallel; the result does not depend on
    // the number of threads.
    let candidates: Vec<(f64, Vec<f64>)> = (0..restarts)
        .into_par_iter()
        .map(|r| {
            let cost = FreeCost { fit: LengthFit { model, data: &subset }, base: model.nominal.clone(), free: all.clone() };
            let de = De {
                variant: DeVariant::LShade { memory: 6, p: 0.11, min_pop: 6 },
                pop: 120,
                generations: 100_000,
                max_evals: Some((60_000.0 * opts.effort.min(1.0)) as usize),
                seed: opts.seed.wrapping_mul(31).wrapping_add(r),
                tol: 1e-12,
                patience: 300,
            };
            let g = de.minimize(&cost, &bounds, None, &mut super::optim::NoObserver);
            let id = identify(&fit, &g.x, opts.rank_tol);
            let polished = lm.minimize(&fit, &g.x, &id.fixed_mask, &mut super::optim::NoObserver);
            (LeastSquares::cost(&fit, &polished.x), polished.x)
        })
        .collect();
    let best = candidates.into_iter().filter(|c| c.0.is_finite()).min_by(|a, b| a.0.total_cmp(&b.0));
    best.map(|b| b.1).ok_or_else(|| Error::Calibration("global search found nothing".into()))
}
