//! `twincal calibrate` as a pipeline of named stages:
//!
//! ```text
//! rows ─ split ─► sensor placement ─► identifiability ─► noise estimate ─► solve ─► uncertainty
//!                 (placement.rs)       (identify.rs)                        (method.rs)
//!      ─► metrics ─► truth comparison (equivalent.rs) ─► CalibResult
//! ```
//!
//! Each stage is a function of its own below or in the module named; the method is a
//! [`Solver`] value that carries its own settings.

pub mod equivalent;
pub mod export;
pub mod generic;
mod options;
pub mod placement;

use crate::calib::correctors::rbf::RbfNetwork;
use crate::calib::correctors::{Correct, Corrector, EffectCorrection};
use crate::calib::effects::EffectBlock;
use crate::calib::effects::RowInputs;
pub use crate::calib::methods::{Method, Solver};
use crate::calib::methods::{Problem, Solution};
use crate::calib::model::CalibModel;
use crate::calib::problem::identify::Identifiability;
pub use crate::calib::problem::identify::{identify, still_joints, STILL_SPAN_DEG};
use crate::calib::problem::robust::{Loss, Outlier, OutlierRun, ReadingStep, ScreenRule};
use crate::calib::problem::{ReadingFit, Samples};
pub use crate::dataset::truth::TruthFile;
use crate::dataset::{Dataset, Split};
use crate::error::{Error, Result};
use crate::optim::{covariance, History, LeastSquares, LevenbergMarquardt, NoObserver};
use crate::robot::Robot;
use crate::stats::metrics::ErrorStats;
use nalgebra::DMatrix;
pub use options::{CalibOptions, ModelSpec, SplitBy, DEFAULT_OUTLIER_K, DEFAULT_RANK_TOL};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

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
    /// Every test row.
    pub test_after: Option<ErrorStats>,
    /// The test rows that are not outliers by the training rows' rule (median ± k robust
    /// standard deviations of the training residuals after calibration).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_after_inliers: Option<ErrorStats>,
    /// The test rows without the worst 1 % (largest |residual|, rounded up): how measured data
    /// are compared with their repeatability floor, which a few bad readings would swamp.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_after_trimmed: Option<ErrorStats>,
    /// For a reading of several values (a tracker's point): the test rows' position error
    /// |Δp| (one distance per row, mm; `mae` is the mean absolute position error papers quote)
    /// before and after calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_position_before: Option<ErrorStats>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_position_after: Option<ErrorStats>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TruthComparison {
    /// Identifiable parameters within 3 standard uncertainties of the truth.
    pub within_3_sigma: usize,
    pub identifiable: usize,
    pub max_abs_z: f64,
    /// How the truth-equivalent values were obtained.
    pub method: String,
    /// Sensor noise floor (std of an averaged reading), mm.
    pub noise_floor_mm: f64,
}

/// The calibrated model: everything `predict` needs, and the report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CalibResult {
    /// See [`crate::io::SCHEMA_VERSION`].
    #[serde(default = "crate::io::schema_version")]
    pub schema_version: u32,
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
    /// Standard deviation of one reading estimated from the data, mm (the residual spread of
    /// the fit, or the repeatability of repeated configurations where there are enough).
    #[serde(default)]
    pub noise_estimate_mm: f64,
    /// SHA-256 of the data file calibrated on (written by `calibrate`): `ik` checks that a twin
    /// it validates against was generated with these very data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_sha256: Option<String>,
    /// Things a user should know before trusting the result (did not converge, few rows, ...).
    #[serde(default)]
    pub warnings: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_comparison: Option<TruthComparison>,
    /// Repeated configurations in the data and the spread of L over them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repeatability: Option<crate::stats::metrics::Repeatability>,
    /// The data's own floor: repeatability and logging resolutions, each named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_floor: Option<crate::calib::problem::floor::NoiseFloor>,
    /// The robust screen of the training rows: threshold (robust standard deviations, 0 = off),
    /// the robust scale of the kept rows' residuals (mm), the rows kept out and their runs.
    #[serde(default)]
    pub outlier_k: f64,
    #[serde(default)]
    pub robust_scale_mm: f64,
    #[serde(default)]
    pub outliers: Vec<Outlier>,
    #[serde(default)]
    pub outlier_runs: Vec<OutlierRun>,
    /// Stretches whose readings were one constant offset off: corrected by it and kept. The
    /// offsets belong to this acquisition (`predict` on new data does not apply them).
    #[serde(default)]
    pub reading_steps: Vec<ReadingStep>,
    /// Test rows corrected by a reading step's offset (estimated from training rows): those
    /// whose nearest training row in acquisition order is in the step.
    #[serde(default)]
    pub test_rows_in_steps: usize,
    /// Test rows beyond the same threshold around the calibrated model's training residuals.
    #[serde(default)]
    pub test_outliers: Vec<Outlier>,
    /// The least-squares loss.
    #[serde(default)]
    pub loss: Loss,
    /// The model itself (chain and parameter vector, internal units m / rad).
    pub model: CalibModel,
    pub x: Vec<f64>,
    /// The learned corrector of what the geometry and effects leave, if the method fits one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corrector: Option<Corrector>,
    /// Result files written before correctors were one interface stored the RBF network here.
    #[serde(default, rename = "rbf", skip_serializing)]
    legacy_rbf: Option<RbfNetwork>,
    /// How the effect blocks get their joint torques on new rows (with effects only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_model: Option<crate::calib::effects::inputs::TorqueModel>,
    /// Parameter values per iteration (display units), for convergence plots.
    #[serde(skip)]
    pub history: Vec<Vec<f64>>,
    /// Measured minus predicted reading of each test row (mm, in `test_rows` order), exactly as
    /// the metrics saw them: with the rows' inputs (time, temperature, flanks, torques) and
    /// reading steps. Not stored in the file.
    #[serde(skip)]
    pub test_residuals_mm: Vec<f64>,
    /// Data rows (0-based) of the test rows.
    #[serde(skip)]
    pub test_rows: Vec<usize>,
    /// How the fit weighted the training rows by their own standard deviations (absent: equal
    /// weights).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weighting: Option<crate::calib::problem::weighting::Weighting>,
    /// The joint angles' logging error as the fit's noise model (absent: the training rows were
    /// taken as independent): see [`crate::calib::problem::noise_model::remove_logging_error`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_model: Option<crate::calib::problem::gls::NoiseModel>,
}

impl CalibResult {
    /// Predicted length (mm) at joint angles in degrees.
    pub fn predict_mm(&self, q_deg: &[f64]) -> f64 {
        let q: Vec<f64> = q_deg.iter().map(|d| d.to_radians()).collect();
        let mut w = self.model.work();
        let inp = RowInputs::default();
        self.model.predict_with(&self.x, &q, &inp, &mut w) * 1e3 + self.correction_mm(&q, &inp)
    }

    /// The dataset columns the model reads besides the joint angles, each with what reads it:
    /// `temp` or `t` for a thermal block (by how it was driven) or a corrector with that input.
    /// Torques and backlash flanks come from the angles and the acquisition order.
    /// The learned wavelet network (the first, when there is one per reading value: they share
    /// their inputs).
    fn wavelet_network(&self) -> Option<&crate::calib::correctors::awnn::Awnn> {
        match &self.corrector {
            Some(crate::calib::correctors::Corrector::Awnn(n)) => Some(n),
            Some(crate::calib::correctors::Corrector::Values(v)) => v.values.iter().find_map(|c| match c {
                crate::calib::correctors::Corrector::Awnn(n) => Some(n),
                _ => None,
            }),
            _ => None,
        }
    }

    /// Whether the model reads a row's backlash approach flanks (a backlash block, or a network
    /// with flank inputs) or its joint torques as network inputs: `ik` solves without them.
    pub fn reads_flanks(&self) -> bool {
        self.model.effects.iter().any(|b| b.kind == crate::calib::effects::EffectKind::Backlash)
            || self.wavelet_network().is_some_and(|n| {
                n.extra.iter().any(|f| matches!(f, crate::calib::correctors::awnn::Feature::Side(_) | crate::calib::correctors::awnn::Feature::Torque(_)))
            })
    }

    pub fn columns_read(&self) -> Vec<(&'static str, String)> {
        use crate::calib::effects::{EffectKind, ThermalDrive};
        let mut out = Vec::new();
        for b in self.model.effects.iter().filter(|b| b.kind == EffectKind::ThermalDrift) {
            let col = if matches!(b.thermal, Some(ThermalDrive::Temperature { .. })) { "temp" } else { "t" };
            out.push((col, format!("its {} block", b.label())));
        }
        if let Some(n) = self.wavelet_network() {
            for f in &n.extra {
                match f {
                    crate::calib::correctors::awnn::Feature::Temperature => out.push(("temp", "its network's temperature input".into())),
                    crate::calib::correctors::awnn::Feature::Time => out.push(("t", "its network's time input".into())),
                    _ => {}
                }
            }
        }
        out
    }

    /// An error naming the first column the model reads ([`Self::columns_read`]) that `data`
    /// lacks on some row: without it the prediction would silently be the reference state's.
    pub fn require_columns(&self, data: &Dataset) -> Result<()> {
        for (col, why) in self.columns_read() {
            let has = |r: &crate::dataset::Row| if col == "temp" { r.temp_c.is_some() } else { r.t_s.is_some() };
            if !data.rows.iter().all(has) {
                return Err(Error::data(
                    &data.source,
                    format!("the model reads a {col} column ({why}), which these data lack; give it, or predict with a model calibrated without it"),
                ));
            }
        }
        Ok(())
    }

    /// Predicted readings (mm, [`Measurement::dim`](crate::measurement::Measurement::dim) values
    /// per row, row after row) of every row of a dataset (rows in acquisition order: backlash
    /// flanks follow the order), every effect and corrector included.
    pub fn predict_rows(&self, data: &Dataset) -> Vec<f64> {
        let inputs = crate::calib::effects::inputs::row_inputs(data, self.torque_model.as_ref());
        let mut w = self.model.work();
        let mut y = vec![0.0; self.model.measurement.dim()];
        let mut corr = vec![0.0; y.len()];
        let mut out = Vec::with_capacity(data.rows.len() * y.len());
        for (r, inp) in data.rows.iter().zip(&inputs) {
            let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
            self.model.readings_with(&self.x, &q, inp, &mut w, &mut y);
            if y.len() == 1 {
                out.push(y[0] * 1e3 + self.correction_mm(&q, inp));
            } else {
                if let Some(c) = &self.corrector {
                    c.as_correct().corrections_mm(&q, inp, &mut corr);
                }
                out.extend(y.iter().zip(&corr).map(|(v, c)| v * 1e3 + c));
            }
        }
        out
    }

    /// An error naming the data unless their readings (if any) are the model's measurement.
    pub fn require_measurement(&self, data: &Dataset) -> Result<()> {
        let m = self.model.measurement;
        match data.measurement() {
            Some(d) if d != m => Err(Error::data(
                &data.source,
                format!(
                    "the rows hold a {} ({}), the model predicts a {} ({})",
                    d.def().describe(),
                    d.def().columns().join(", "),
                    m.def().describe(),
                    m.def().columns().join(", ")
                ),
            )),
            _ => Ok(()),
        }
    }

    /// The learned corrector's length correction (mm; 0 without one).
    pub fn correction_mm(&self, q: &[f64], inp: &RowInputs) -> f64 {
        self.corrector.as_ref().map(|c| c.as_correct().correction_mm(q, inp)).unwrap_or(0.0)
    }

    /// Every non-geometric part of the calibrated model as a [`Correct`]: the physical effect
    /// blocks (when the model has any), then the learned corrector.
    pub fn correctors(&self) -> Vec<Box<dyn Correct + '_>> {
        let mut out: Vec<Box<dyn Correct + '_>> = Vec::new();
        if !self.model.effects.is_empty() {
            out.push(Box::new(EffectCorrection::new(&self.model, &self.x)));
        }
        if let Some(c) = &self.corrector {
            out.push(Box::new(c.as_correct()));
        }
        out
    }

    pub fn load(path: &Path) -> Result<CalibResult> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let value: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| Error::model(path.display(), format!("not a twincal calibration result: {e}")))?;
        // What the model computes with holds no number a calibration could not have produced.
        for key in ["model", "x", "corrector", "torque_model", "rbf"] {
            if let Some((at, n)) = value.get(key).and_then(|v| beyond_magnitude(v, MAX_MODEL_MAGNITUDE)) {
                return Err(Error::model(
                    path.display(),
                    format!("{key}{at} = {n} is beyond what a calibration writes (|value| <= {MAX_MODEL_MAGNITUDE:e}); edited result file?"),
                ));
            }
        }
        // A learned corrector's outputs (weights, biases, spline coefficients, its output range,
        // in mm) stay far below a correction of 100 m; its input statistics may not (a time
        // input's mean over days of acquisition is 1e5 s and more).
        for key in ["corrector", "rbf"] {
            if let Some((at, n)) = value.get(key).and_then(corrector_output_beyond) {
                return Err(Error::model(
                    path.display(),
                    format!("{key}{at} = {n} is beyond what a calibration writes (a correction within {MAX_CORRECTOR_MAGNITUDE:e} mm); edited result file?"),
                ));
            }
        }
        let mut r: CalibResult = serde_json::from_value(value).map_err(|e| Error::model(path.display(), format!("not a twincal calibration result: {e}")))?;
        crate::io::check_schema(r.schema_version, "a calibration result").map_err(|e| Error::model(path.display(), e))?;
        if let Some(net) = r.legacy_rbf.take() {
            r.corrector.get_or_insert(Corrector::Rbf(net));
        }
        if let Some(c) = &r.corrector {
            c.validate(r.model.chain.n_joints).map_err(|e| Error::model(path.display(), e))?;
            let (want, has) = (r.model.measurement.dim(), c.as_correct().dim());
            if want != has {
                return Err(Error::model(
                    path.display(),
                    format!(
                        "the corrector corrects {has} value(s) per row, the model's {} reads {want} (edited result file?)",
                        r.model.measurement.def().describe()
                    ),
                ));
            }
        }
        let chain = &r.model.chain;
        chain.validate().map_err(|e| Error::model(path.display(), e))?;
        let temps = crate::dataset::MIN_TEMP_C..=crate::dataset::MAX_TEMP_C;
        if let Some(t) = r.model.effects.iter().find_map(|b| match b.thermal {
            Some(crate::calib::effects::ThermalDrive::Temperature { ref_c }) if !temps.contains(&ref_c) => Some(ref_c),
            _ => None,
        }) {
            return Err(Error::model(
                path.display(),
                format!(
                    "the thermal block's reference temperature {} °C is outside [{}, {}] °C (edited result file?)",
                    crate::error::shown(t),
                    temps.start(),
                    temps.end()
                ),
            ));
        }
        if let Some(t) = &r.torque_model {
            t.validate(chain.n_joints).map_err(|e| Error::model(path.display(), e))?;
        }
        let consistent = r.x.len() == r.model.n_params()
            && r.model.nominal.len() == r.model.n_params()
            && r.model.effects.iter().all(|e| e.joint.is_none_or(|j| j < chain.n_joints))
            && (r.model.limits.is_empty() || r.model.limits.len() == chain.n_joints)
            && r.model.limits.iter().all(|(lo, hi)| lo.is_finite() && hi.is_finite() && lo < hi)
            && r.model.kinds.len() == r.model.n_params()
            && r.model.n_params() == chain.n_params() + r.model.measurement.n_placement() + r.model.effects.iter().map(EffectBlock::n_params).sum::<usize>()
            && chain.frame_end.last().is_some_and(|e| *e == chain.ops.len())
            && chain.ops.iter().all(|o| o.joint.is_none_or(|j| j < chain.n_joints) && o.param.is_none_or(|k| k < chain.n_params()));
        if !consistent || r.x.iter().any(|v| !v.is_finite()) {
            return Err(Error::model(path.display(), "the calibrated model is inconsistent (edited or truncated result file?)"));
        }
        let place = r.model.placement(&r.x);
        let names = r.model.measurement.placement_names();
        if let Some((name, v)) = names.iter().zip(place.own.iter().chain(place.tool.iter())).find(|(_, v)| v.abs() > MAX_PLACEMENT) {
            return Err(Error::model(
                path.display(),
                format!("the instrument's placement {name} = {} is beyond {MAX_PLACEMENT} (m or rad; edited result file?)", crate::error::shown(*v)),
            ));
        }
        Ok(r)
    }
}

/// The rows a calibration trains and tests on: the dataset's split column, or with a test
/// fraction `f` a held-out share drawn by `by` from `seed`.
pub fn split_rows(data: &Dataset, test_fraction: Option<f64>, seed: u64, by: SplitBy) -> Result<(Vec<usize>, Vec<usize>)> {
    let n = data.rows.len();
    match test_fraction {
        Some(f) => {
            if !(0.0..1.0).contains(&f) {
                return Err(Error::Invalid(format!("--test-fraction must be in [0, 1), got {f}")));
            }
            let n_test = (f * n as f64).round() as usize;
            // Rows that share a sweep (or a pause, a declared block) share its errors: the test
            // rows are then whole blocks, never rows of a block whose other rows train.
            let (blocks, _) = crate::dataset::blocks::detect(data, None);
            if by == SplitBy::Blocks && blocks.any_shared() && n_test > 0 {
                let test = block_split(&blocks, n_test, seed);
                return Ok(((0..n).filter(|i| !test[*i]).collect(), (0..n).filter(|i| test[*i]).collect()));
            }
            // Strata by the reading: the cable length, or a point's distance from the
            // instrument's origin.
            let lengths = reading_measurement(data)?.file_lengths();
            let key: Vec<f64> = data
                .rows
                .iter()
                .map(|r| if r.reading_mm.len() == 1 { r.reading_mm[0] } else { r.reading_mm.iter().take(lengths).map(|v| v * v).sum::<f64>().sqrt() })
                .collect();
            let split = crate::dataset::split::stratified_split(&key, n_test, seed);
            Ok(((0..n).filter(|i| split[*i] == Split::Train).collect(), (0..n).filter(|i| split[*i] == Split::Test).collect()))
        }
        None => Ok((data.train_indices(), data.test_indices())),
    }
}

/// Test rows of whole blocks: the blocks in a seeded random order, taken while the test rows
/// stay nearer to `n_test` than without the block (at least one block, never all of them).
pub fn block_split(blocks: &crate::dataset::blocks::Blocks, n_test: usize, seed: u64) -> Vec<bool> {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let mut sizes = vec![0usize; blocks.len()];
    for &b in &blocks.of_row {
        sizes[b] += 1;
    }
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    let seed = crate::seed::stream_seed(seed, crate::seed::Stream::Split, 1);
    order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
    let mut chosen = vec![false; blocks.len()];
    let mut rows = 0;
    for (taken, &b) in order.iter().enumerate() {
        if taken + 1 == order.len() || (rows > 0 && (rows + sizes[b]).abs_diff(n_test) > rows.abs_diff(n_test)) {
            break;
        }
        chosen[b] = true;
        rows += sizes[b];
        if rows >= n_test {
            break;
        }
    }
    blocks.of_row.iter().map(|&b| chosen[b]).collect()
}

/// The rows `idx` of a dataset as calibration samples (radians, metres), with their time and
/// temperature; torques and backlash sides are added by [`crate::calib::effects::inputs`] where needed. A row
/// without a reading reads NaN.
pub fn samples(data: &Dataset, idx: &[usize]) -> Samples {
    let rows = idx.iter().map(|&i| &data.rows[i]);
    let m = data.measurement();
    let dim = m.map_or(1, |m| m.dim());
    let reading = |r: &crate::dataset::Row| -> Vec<f64> {
        match r.values_mm() {
            Some(v) if v.len() == dim => v.iter().map(|v| v * 1e-3).collect(),
            _ => vec![f64::NAN; dim],
        }
    };
    Samples {
        q: rows.clone().map(|r| r.q_deg.iter().map(|d| d.to_radians()).collect()).collect(),
        y: rows.clone().flat_map(reading).collect(),
        dim,
        inputs: rows.map(|r| crate::calib::effects::RowInputs { t_s: r.t_s, temp_c: r.temp_c, ..Default::default() }).collect(),
        w: None,
        gls: None,
    }
}

/// How far outside a joint's limits (degrees) a row may be before it is refused: encoders read
/// a little past a soft limit, nothing reads far past a hard stop.
pub const JOINT_LIMIT_SLACK_DEG: f64 = 2.0;

/// Smallest spread of the measured lengths a calibration accepts, mm (a micrometre: less is one
/// reading repeated, not a measurement of the arm).
pub const MIN_LENGTH_SPREAD_MM: f64 = 1e-3;

/// Largest magnitude of any number in a result file's model (parameters in m and rad, network
/// weights in mm, masses, forces): beyond it the file was edited, not written by a calibration.
pub const MAX_MODEL_MAGNITUDE: f64 = 1e9;
/// Largest |number| among a stored learned corrector's outputs (weights, biases, coefficients,
/// its output range; mm), see [`CalibResult::load`].
pub const MAX_CORRECTOR_MAGNITUDE: f64 = 1e5;
/// The keys of a stored corrector whose numbers are outputs in mm.
const CORRECTOR_OUTPUT_KEYS: [&str; 5] = ["weights", "bias", "coef", "w", "output_range"];

/// The first output number of a stored corrector (under [`CORRECTOR_OUTPUT_KEYS`], at any depth:
/// a per-value corrector nests them) beyond [`MAX_CORRECTOR_MAGNITUDE`], with its JSON path.
fn corrector_output_beyond(v: &serde_json::Value) -> Option<(String, serde_json::Number)> {
    use serde_json::Value;
    match v {
        Value::Array(items) => items.iter().enumerate().find_map(|(i, x)| corrector_output_beyond(x).map(|(p, n)| (format!("[{i}]{p}"), n))),
        Value::Object(map) => map.iter().find_map(|(k, x)| {
            let found = if CORRECTOR_OUTPUT_KEYS.contains(&k.as_str()) { beyond_magnitude(x, MAX_CORRECTOR_MAGNITUDE) } else { corrector_output_beyond(x) };
            found.map(|(p, n)| (format!(".{k}{p}"), n))
        }),
        _ => None,
    }
}
/// Largest |value| of an instrument placement parameter in a result file (m or rad): an exit
/// point, a tracker or a reflector 100 m away is an edit, not a calibration.
pub const MAX_PLACEMENT: f64 = 100.0;

/// The first number in `v` beyond [`MAX_MODEL_MAGNITUDE`]: its JSON path below `v` and the number.
fn beyond_magnitude(v: &serde_json::Value, limit: f64) -> Option<(String, serde_json::Number)> {
    use serde_json::Value;
    match v {
        Value::Number(n) => n.as_f64().is_none_or(|x| x.abs() > limit).then(|| (String::new(), n.clone())),
        Value::Array(items) => items.iter().enumerate().find_map(|(i, x)| beyond_magnitude(x, limit).map(|(p, n)| (format!("[{i}]{p}"), n))),
        Value::Object(map) => map.iter().find_map(|(k, x)| beyond_magnitude(x, limit).map(|(p, n)| (format!(".{k}{p}"), n))),
        _ => None,
    }
}

/// Stage "split": training and test samples, with the checks that make a calibration meaningful.
pub struct SplitData {
    /// The static-torque model of the effects (set by the effects stage where there is one).
    pub torque_model: Option<crate::calib::effects::inputs::TorqueModel>,
    pub train_idx: Vec<usize>,
    pub test_idx: Vec<usize>,
    pub train: Samples,
    pub test: Samples,
}

/// Number of distinct joint configurations among `rows` (angles compared to 1e-6 degrees).
fn distinct_configurations(data: &Dataset, rows: &[usize]) -> usize {
    let mut keys: Vec<Vec<i64>> = rows.iter().map(|&i| data.rows[i].q_deg.iter().map(|v| (v * 1e6).round() as i64).collect()).collect();
    keys.sort_unstable();
    keys.dedup();
    keys.len()
}

pub fn split_stage(data: &Dataset, opts: &CalibOptions) -> Result<SplitData> {
    if let Some(robot) = opts.model.robot() {
        data.require_joints(robot.dof(), &format!("the robot '{}'", robot.name))?;
        check_joint_limits(data, robot)?;
    }
    if let Some(robot) = opts.inertial.as_ref() {
        data.require_joints(robot.dof(), &format!("the inertial robot '{}' (--robot)", robot.name))?;
    }
    let (train_idx, test_idx) = split_rows(data, opts.test_fraction, opts.seed, opts.split_by)?;
    if train_idx.len() < 8 {
        return Err(Error::Calibration(format!("only {} training rows; at least 8 are needed", train_idx.len())));
    }
    let distinct = distinct_configurations(data, &train_idx);
    if distinct < 8 {
        return Err(Error::Calibration(format!(
            "the {} training rows hold only {distinct} distinct joint configurations; a calibration needs many different poses",
            train_idx.len()
        )));
    }
    let train = samples(data, &train_idx);
    let test = samples(data, &test_idx);
    Ok(SplitData { torque_model: None, train_idx, test_idx, train, test })
}

/// Refuses rows whose joint angles lie beyond the robot's limits (more than the slack).
fn check_joint_limits(data: &Dataset, robot: &Robot) -> Result<()> {
    match outside_limits(data, &robot.limits()).next() {
        Some((i, j, q)) => {
            let spec = &robot.joints[j];
            let (lo, hi) = (spec.lower.to_degrees(), spec.upper.to_degrees());
            Err(Error::data(&data.source, format!("row {}: q{} = {q} deg is outside {}'s limits [{lo:.2}, {hi:.2}] deg", i + 1, j + 1, spec.name)))
        }
        None => Ok(()),
    }
}

/// Every joint angle of `data` beyond `limits` (rad, per joint) by more than
/// [`JOINT_LIMIT_SLACK_DEG`], as (row, joint, angle in degrees), rows in order.
pub fn outside_limits<'a>(data: &'a Dataset, limits: &'a [(f64, f64)]) -> impl Iterator<Item = (usize, usize, f64)> + 'a {
    data.rows.iter().enumerate().flat_map(move |(i, r)| {
        r.q_deg.iter().zip(limits).enumerate().filter_map(move |(j, (q, (lo, hi)))| {
            (*q < lo.to_degrees() - JOINT_LIMIT_SLACK_DEG || *q > hi.to_degrees() + JOINT_LIMIT_SLACK_DEG).then_some((i, j, *q))
        })
    })
}

/// Stage "effects": adds the requested effect blocks to the model and gives every sample the
/// per-row inputs they need (computed over the whole file in acquisition order, then split);
/// with `inputs` the rows get their inputs (and the result its torque model) even without
/// effect blocks, for a solver that reads them ([`Solver::needs_row_inputs`]).
pub fn effects_stage(model: &mut CalibModel, split: &mut SplitData, data: &Dataset, opts: &CalibOptions, inputs: bool) -> Result<()> {
    if opts.effects.is_empty() && !inputs {
        return Ok(());
    }
    let x = &model.nominal;
    let placement = model.placement(x);
    let robot = opts.inertial_robot();
    let torque = robot.map(|r| crate::calib::effects::inputs::TorqueModel::new(r, &opts.loads, placement.exit(), placement.tool));
    let all = crate::calib::effects::inputs::row_inputs(data, torque.as_ref());
    split.torque_model = torque;
    split.train.inputs = split.train_idx.iter().map(|&i| all[i].clone()).collect();
    split.test.inputs = split.test_idx.iter().map(|&i| all[i].clone()).collect();
    let span = crate::calib::effects::inputs::time_span(data);
    for &(kind, joint) in &opts.effects {
        let joints: Vec<Option<usize>> = match (kind.per_joint(), joint) {
            (true, None) => (0..data.n_joints()).map(Some).collect(),
            (_, j) => vec![j],
        };
        for j in joints {
            model.add_effect(crate::calib::effects::inputs::block_for(data, kind, j, robot.is_some())?, span);
        }
    }
    Ok(())
}

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
fn residuals_with(fit: &ReadingFit, x: &[f64], corrector: Option<&dyn Correct>) -> Vec<f64> {
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

fn stats(fit: &ReadingFit, x: &[f64], corrector: Option<&dyn Correct>) -> ErrorStats {
    ErrorStats::of(&residuals_with(fit, x, corrector))
}

/// The outlier screen needs this many training rows per identifiable parameter.
pub const SCREEN_ROWS_PER_PARAM: usize = 3;

/// Stage "outliers": the training rows far off a robust fit ([`crate::calib::problem::robust::screen`], the
/// identifiable parameters refitted with the Cauchy loss at each pass) are taken out of the split;
/// readings in a reading step are corrected by its offset, in training and test rows alike; a
/// nominal model's sensor is then placed again on the rows kept (a new model: the second value
/// says so). `None` when the screen is off. The screen's scale is never taken below the
/// angle-resolution part of the training rows' floor: where a sweep's rows share the angles'
/// rounding their residuals' robust scale can fall far below the rounding itself, and the
/// screen would flag good rows (as `diagnose` does, see docs/diagnose.md).
pub fn outlier_stage(
    model: &mut CalibModel,
    split: &mut SplitData,
    data: &Dataset,
    opts: &CalibOptions,
) -> Result<(Option<crate::calib::problem::robust::Screen>, bool)> {
    if opts.outlier_k <= 0.0 {
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
        let m: &CalibModel = model;
        let refit = |d: &Samples, x: &[f64]| crate::calib::problem::robust::screen_fit(m, d, x, opts.rank_tol);
        let rule = screen_rule(m, data, &split.train, opts.outlier_k, opts.reading_steps, opts.angle_step_deg);
        crate::calib::problem::robust::screen(m, &m.nominal, &split.train, &split.train_idx, rule, &refit)
    };
    if !screen.steps.is_empty() {
        split.test = crate::calib::problem::robust::apply_steps_nearest(&split.test, &split.test_idx, &split.train_idx, &screen.steps);
    }
    let mut placed_again = false;
    if !screen.outliers.is_empty() || !screen.steps.is_empty() {
        split.train_idx = screen.keep.iter().map(|&i| split.train_idx[i]).collect();
        split.train = screen.corrected.subset(&screen.keep);
        if matches!(opts.model, ModelSpec::Nominal { .. }) {
            *model = crate::calib::run::placement::place_sensor(opts, &split.train)?;
            placed_again = true;
        }
    }
    Ok((Some(screen), placed_again))
}

/// Test rows beyond `k` robust standard deviations of the calibrated model's training
/// residuals (around their median); none when `k` is 0. A row of several values (a point) is
/// out when any of them is, and is reported by its farthest value.
fn test_outlier_stage(fit: &ReadingFit, test_r: &[f64], test_idx: &[usize], x: &[f64], corrector: Option<&dyn Correct>, k: f64) -> Vec<Outlier> {
    if k <= 0.0 || test_r.is_empty() {
        return Vec::new();
    }
    let r = residuals_with(fit, x, corrector);
    let d = fit.data.dim.max(1);
    // Each value against its group's scale (a pose's axes have their own), reported by the
    // value farthest out.
    let groups = fit.model.measurement.def().value_groups();
    let group = |k: usize| groups.get(k).copied().unwrap_or(0);
    let stats = crate::calib::problem::robust::group_scales(&r, d, groups, &(0..r.len() / d).collect::<Vec<_>>());
    let n_groups = stats.len();
    test_r
        .chunks(d)
        .zip(test_idx)
        .filter_map(|(vs, &i)| {
            let (med, scale) = stats[0];
            if n_groups == 1 {
                let v = crate::calib::problem::robust::farthest_from(vs, med);
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
/// (computed from the truth, see [`crate::calib::run::equivalent`]), with z = error / standard uncertainty.
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
        .map(|&i| t.poses[i].q_cmd_deg.as_ref().filter(|q| q.len() == robot.dof()).map(|q| q.iter().map(|d| d.to_radians()).collect()))
        .collect();
    let clean = Samples { y: y?.concat(), q: commanded.unwrap_or_else(|| split.train.q.clone()), ..split.train.clone() };
    crate::calib::run::equivalent::truth_equivalent(model, robot, t, &clean, x0, fixed)
}

/// Runs a calibration with the method named in `opts` at its default settings.
pub fn calibrate(data: &Dataset, truth: Option<&TruthFile>, opts: &CalibOptions) -> Result<CalibResult> {
    let solver = match (opts.method, opts.loss) {
        (_, Loss::L2) => opts.method.solver(opts.effort),
        (Method::Lm, loss) => Box::new(crate::calib::methods::LmSolver { loss, ..Default::default() }),
        (m, loss) => return Err(Error::Invalid(format!("--loss {} applies to --method lm, not {}", loss.name(), m.name()))),
    };
    calibrate_with(data, truth, opts, solver.as_ref())
}

/// The stages before a fit, as one value that a calibration, a diagnosis and the benchmarks
/// share instead of re-deriving them: the split, the model with its instrument placed (and the
/// requested effect blocks), the robust screen, the rows' inputs with their torque model (in
/// `split`) and the identifiability at the start. Built by [`prepare`].
pub struct Prepared {
    pub split: SplitData,
    pub model: CalibModel,
    /// The robust screen of the training rows (`None` when off or with too few rows).
    pub screen: Option<crate::calib::problem::robust::Screen>,
    /// Test rows whose reading a reading step corrected.
    pub test_rows_in_steps: usize,
    /// Which parameters the training poses determine, at the model's nominal.
    pub id: Identifiability,
    /// How the training rows are weighted (per-row standard deviations), `None` for equal weights.
    pub weighting: Option<crate::calib::problem::weighting::Weighting>,
}

/// What the rows of `data` read: every row must have a reading (a cable length `L`, or a
/// tracker's `x, y, z`), as [`Dataset::require_length`] words it for the draw-wire.
pub fn reading_measurement(data: &Dataset) -> Result<crate::measurement::Measurement> {
    match data.measurement() {
        Some(m) if m != crate::measurement::Measurement::Length => {
            data.require_readings()?;
            Ok(m)
        }
        _ => {
            data.require_length()?;
            Ok(crate::measurement::Measurement::Length)
        }
    }
}

/// The repeatability of the readings over repeated configurations: for several values per row
/// (a point), pooled over the values (each coordinate's within-group variance, averaged).
pub fn reading_repeatability(data: &Dataset) -> Option<crate::stats::metrics::Repeatability> {
    let q_deg: Vec<&[f64]> = data.rows.iter().map(|r| r.q_deg.as_slice()).collect();
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
    Some(crate::stats::metrics::Repeatability { pooled_std, max_spread, ..first }).filter(|r| r.groups > 0)
}

/// The outlier screens' rule (`k` robust standard deviations, reading steps if `steps`) for
/// `model` at its nominal parameters on `rows` of `data`: its scale never below the
/// angle-resolution part of their floor, what the angles' logging alone puts on a reading.
pub fn screen_rule(model: &CalibModel, data: &Dataset, rows: &Samples, k: f64, steps: bool, angle_step_deg: Option<f64>) -> ScreenRule {
    let floor = floor_stage(model, &model.nominal, data, rows, angle_step_deg, None, None);
    let min_scale_mm = floor.sources.iter().find(|s| s.source == "angle_resolution").map_or(0.0, |s| s.rms_mm);
    ScreenRule { k, steps, min_scale_mm }
}

/// No model predicts unseen rows better than the data's floor: a held-out RMSE (of the test rows
/// that are not outliers) below it by more than its sampling error over the test rows' blocks
/// means the test rows shared errors with training rows (rows of one sweep on both sides of a
/// random split share its rounding). The warning, if so; none for a pose's angles, which the
/// floor does not hold.
fn leak_warning(data: &Dataset, split: &SplitData, test_r: &[f64], test_outliers: &[Outlier], floor_mm: f64, angle_step_deg: Option<f64>) -> Option<String> {
    let d = split.test.dim.max(1);
    if split.test.is_empty() || !(floor_mm > 0.0) || data.measurement().is_some_and(|m| m.file_lengths() != d) {
        return None;
    }
    let mut kept: Vec<usize> = (0..split.test.len()).filter(|&i| !test_outliers.iter().any(|o| o.row == split.test_idx[i] + 1)).collect();
    kept.sort_by_key(|&i| split.test_idx[i]);
    let r: Vec<f64> = kept.iter().flat_map(|&i| test_r[i * d..(i + 1) * d].iter().copied()).collect();
    let rows: Vec<usize> = kept.iter().map(|&i| split.test_idx[i]).collect();
    let groups = crate::dataset::blocks::detect(data, angle_step_deg).0.ids_of(&rows);
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
/// the repeatability given, the joint angles' logging step (`angle_step_deg`, else read from the
/// data's decimals) and the readings' logging step. See [`crate::calib::problem::floor`].
pub fn floor_stage(
    model: &CalibModel,
    x: &[f64],
    data: &Dataset,
    rows: &Samples,
    angle_step_deg: Option<f64>,
    instrument_accuracy_mm: Option<f64>,
    repeat: Option<&crate::stats::metrics::Repeatability>,
) -> crate::calib::problem::floor::NoiseFloor {
    use crate::calib::problem::floor::{logging_step, Step};
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
    let instrument = crate::calib::problem::floor::Instrument { row_std_mm, accuracy_mm: instrument_accuracy_mm };
    crate::calib::problem::floor::noise_floor(model, x, rows, angle_step, reading_step, repeat, instrument)
}

/// Stages "split", "placement", "outliers", "effects" and "identifiability" of a calibration
/// with `opts`; `row_inputs` gives every row its inputs (and the split its torque model) even
/// without effect blocks ([`Solver::needs_row_inputs`]).
pub fn prepare(data: &Dataset, opts: &CalibOptions, row_inputs: bool) -> Result<Prepared> {
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
    let mut model = crate::calib::run::placement::place_sensor(opts, &split.train)?;
    // Stage "weighting": a tracker's per-row standard deviations weight the fit (and the screen).
    // (A learned corrector learns plain residuals: its methods fit with equal weights.)
    let weighting = if opts.row_std && !opts.method.learns_corrector() {
        crate::calib::problem::weighting::training_weights(&model, data, &split.train_idx, &split.train, opts.rank_tol).map(|(w, info)| {
            split.train.w = Some(w);
            info
        })
    } else {
        None
    };
    // The effects asked for are in the model before the screen: a warm-up's drift or a backlash
    // band, screened against the geometry alone, would look like reading steps and outliers.
    effects_stage(&mut model, &mut split, data, opts, row_inputs)?;
    let (screen, placed_again) = outlier_stage(&mut model, &mut split, data, opts)?;
    if placed_again {
        // The sensor placed again on the kept rows is a new model: the effects go back in.
        effects_stage(&mut model, &mut split, data, opts, row_inputs)?;
    }
    let test_rows_in_steps = samples(data, &split.test_idx).y.iter().zip(&split.test.y).filter(|(a, b)| a != b).count();
    let id = identify(&ReadingFit { model: &model, data: &split.train }, &model.nominal, opts.rank_tol);
    Ok(Prepared { split, model, screen, test_rows_in_steps, id, weighting })
}

/// Runs a calibration with a given solver. `truth` enables the parameter-error report.
pub fn calibrate_with(data: &Dataset, truth: Option<&TruthFile>, opts: &CalibOptions, solver: &dyn Solver) -> Result<CalibResult> {
    let t0 = Instant::now();
    let mut warnings = Vec::new();
    let Prepared { split, model, screen, test_rows_in_steps: test_in_steps, id, weighting } = prepare(data, opts, solver.needs_row_inputs())?;
    if model.effects.iter().any(|b| matches!(b.thermal, Some(crate::calib::effects::ThermalDrive::WarmUp))) && data.rows.iter().all(|r| r.temp_c.is_some()) {
        warnings.push(format!(
            "the temp column spans less than {} K, so it drives no thermal drift: the thermal block runs on t as a warm-up",
            crate::calib::effects::MIN_TEMP_SPREAD_K
        ));
    }
    if screen.is_none() && opts.outlier_k > 0.0 {
        warnings.push(format!(
            "no outlier screen: fewer than {SCREEN_ROWS_PER_PARAM} training rows (reading values) per identifiable parameter, too few for a robust scale of the residuals"
        ));
    }
    let x0 = model.nominal.clone();
    let mut fixed = id.fixed_mask.clone();
    if opts.placement_only {
        let free = model.placement_range();
        fixed.iter_mut().enumerate().filter(|(k, _)| !free.contains(k)).for_each(|(_, f)| *f = true);
    }
    // Stage "noise model": the joint angles' logging error shared by a block's rows taken out of
    // the training readings (the rows as read kept for the metrics and the uncertainties).
    let mut split = split;
    let logging = match opts.noise_model {
        crate::calib::problem::noise_model::NoiseChoice::Auto => {
            crate::calib::problem::noise_model::remove_logging_error(&model, &x0, &fixed, &split.train, &split.train_idx, data, opts.angle_step_deg)
        }
        crate::calib::problem::noise_model::NoiseChoice::Off => None,
    };
    // With the noise model: the rows as read, whitened by it.
    let (noise_model, as_read) = match logging {
        Some((n, w, corrected)) => {
            let read = std::mem::replace(&mut split.train, corrected);
            (Some(n), Some(Samples { gls: Some(w), ..read }))
        }
        None => (None, None),
    };
    let fit = ReadingFit { model: &model, data: &split.train };
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
    if metrics.train_after.rmse > metrics.train_before.rmse {
        warnings.push(format!(
            "{} ended worse than the nominal model it started from (training RMSE {:.4} -> {:.4} mm): the result is not a calibration; \
             try --method lm, or a larger --effort",
            solver.name(),
            metrics.train_before.rmse,
            metrics.train_after.rmse
        ));
    } else if let (Some(before), Some(after)) = (&metrics.test_before, &metrics.test_after) {
        // Beyond 5 %: a model already calibrated (its own URDF export) moves within noise.
        if after.rmse > 1.05 * before.rmse {
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
                solver.name(),
                metrics.train_after.rmse,
                test.rmse
            ));
        }
    }
    let test_residuals_mm = residuals_with(&test_fit, &x, correct);
    let test_outliers = test_outlier_stage(&plain_fit, &test_residuals_mm, &split.test_idx, &x, correct, opts.outlier_k);
    if !split.test.is_empty() {
        let out: Vec<usize> = test_outliers.iter().map(|o| o.row - 1).collect();
        let d = split.test.dim;
        let inliers: Vec<f64> =
            (0..split.test.len()).filter(|i| !out.contains(&split.test_idx[*i])).flat_map(|i| test_residuals_mm[i * d..(i + 1) * d].iter().copied()).collect();
        // Every test row beyond the rule: there are no inliers to describe.
        metrics.test_after_inliers = (!inliers.is_empty()).then(|| ErrorStats::of(&inliers));
        metrics.test_after_trimmed = Some(trimmed_stats(&test_residuals_mm, 0.01));
    }
    let all_rows = samples(data, &(0..data.rows.len()).collect::<Vec<_>>());
    let noise_floor = floor_stage(&model, &x, data, &all_rows, opts.angle_step_deg, opts.instrument_accuracy_mm, repeatability.as_ref());
    warnings.extend(leak_warning(data, &split, &test_residuals_mm, &test_outliers, noise_floor.total_mm, opts.angle_step_deg));
    let truth_x = truth_stage(&model, &opts.model, truth, data, &split, &x0, &fixed);
    let (parameters, truth_comparison) = parameter_reports(&model, &x0, &x, &fixed, cov.as_ref(), truth_x.as_deref(), truth);
    let history_disp = history.x.iter().map(|xs| xs.iter().enumerate().map(|(k, v)| model.display(k, *v)).collect()).collect();
    Ok(CalibResult {
        schema_version: crate::io::SCHEMA_VERSION,
        twincal_version: env!("CARGO_PKG_VERSION").into(),
        data: data.source.clone(),
        method: Method::parse(solver.name())?,
        model_name: model.name.clone(),
        seed: opts.seed,
        n_train: split.train.len(),
        n_test: split.test.len(),
        parameters,
        identifiability: serde_json::to_value(&id).unwrap_or_default(),
        metrics,
        iterations: report.iterations,
        evaluations: report.evaluations,
        converged: report.converged(),
        stop_reason: report.reason.clone(),
        wall_time_s: t0.elapsed().as_secs_f64(),
        noise_estimate_mm,
        data_sha256: None,
        warnings,
        truth_comparison,
        repeatability,
        noise_floor: Some(noise_floor),
        outlier_k: opts.outlier_k,
        robust_scale_mm: screen.as_ref().map_or(0.0, |s| s.scale_mm),
        outliers: screen.as_ref().map(|s| s.outliers.clone()).unwrap_or_default(),
        outlier_runs: screen.as_ref().map(|s| s.runs.clone()).unwrap_or_default(),
        test_rows_in_steps: test_in_steps,
        reading_steps: screen.map(|s| s.steps).unwrap_or_default(),
        test_outliers,
        loss: opts.loss,
        x,
        corrector,
        legacy_rbf: None,
        torque_model: split.torque_model.clone(),
        history: history_disp,
        test_residuals_mm,
        test_rows: split.test_idx.clone(),
        weighting,
        noise_model,
        model,
    })
}

/// A model fitted outside the pipeline: the start `x0`, the fit `x`, the identifiability
/// analysis that fixed what it held, and the torque model of its effect blocks.
pub struct FittedModel {
    pub model: CalibModel,
    pub x0: Vec<f64>,
    pub x: Vec<f64>,
    pub id: Identifiability,
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
    let noise_floor = floor_stage(&model, &x, data, rows, angle_step_deg, instrument_accuracy_mm, repeatability.as_ref());
    Ok(CalibResult {
        schema_version: crate::io::SCHEMA_VERSION,
        twincal_version: env!("CARGO_PKG_VERSION").into(),
        data: data.source.clone(),
        method: Method::Lm,
        model_name: model.name.clone(),
        seed,
        n_train: rows.len(),
        n_test: 0,
        parameters,
        identifiability: serde_json::to_value(id).unwrap_or_default(),
        metrics,
        iterations: 0,
        evaluations: 0,
        converged: true,
        stop_reason: "the diagnosis's final model, fitted on every kept row".into(),
        wall_time_s: t0.elapsed().as_secs_f64(),
        noise_estimate_mm: residual_sigma(&fit, &x, fixed),
        data_sha256: None,
        warnings: Vec::new(),
        truth_comparison: None,
        repeatability,
        noise_floor: Some(noise_floor),
        outlier_k: 0.0,
        robust_scale_mm: 0.0,
        outliers: Vec::new(),
        outlier_runs: Vec::new(),
        reading_steps: Vec::new(),
        test_rows_in_steps: 0,
        test_outliers: Vec::new(),
        loss: Loss::L2,
        x,
        corrector: None,
        legacy_rbf: None,
        torque_model,
        history: Vec::new(),
        test_residuals_mm: Vec::new(),
        test_rows: Vec::new(),
        weighting: None,
        noise_model: None,
        model,
    })
}

/// Every parameter in display units with its uncertainty and, with a truth, its error and z.
fn parameter_reports(
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
