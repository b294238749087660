//! What a calibration gives (`result.json`): the parameters with their uncertainties, the
//! metrics, the truth comparison, the model and what its readers need; its loader's checks.

use crate::calib::correctors::rbf::RbfNetwork;
use crate::calib::correctors::{Correct, Corrector, EffectCorrection};
use crate::calib::effects::EffectBlock;
use crate::calib::effects::RowInputs;
use crate::calib::fit::robust::{Loss, Outlier, OutlierRun, ReadingStep};
use crate::calib::model::CalibModel;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::stats::metrics::ErrorStats;
use serde::{Deserialize, Serialize};
use std::path::Path;

pub use super::setup::{SetupPart, SetupReport, StationOrigin};

/// A parameter in the report (display units: mm, degrees).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ParamReport {
    /// Parameter name (`joint_2.dtheta`, an instrument placement or an effect parameter).
    pub name: String,
    /// Display unit of `nominal`, `value`, `std_uncertainty`, `truth` and `error`.
    pub unit: String,
    /// Start value of the fit (display units).
    pub nominal: f64,
    /// Calibrated value (display units).
    pub value: f64,
    /// Standard uncertainty of `value` (display units); absent for a fixed parameter or without a
    /// covariance.
    pub std_uncertainty: Option<f64>,
    /// Held at its start value, not fitted (not identifiable from the data, or held by the
    /// options).
    pub fixed: bool,
    /// With a truth file: the value this model should reach on noise-free data.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<f64>,
    /// With a truth file: `value` minus `truth` (display units).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<f64>,
    /// error / std_uncertainty.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
}

/// Reading errors of the model before (at its start values) and after calibration, on the training
/// and the test rows.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Metrics {
    /// Training rows, model at its start values.
    pub train_before: ErrorStats,
    /// Test rows, model at its start values (absent without test rows).
    pub test_before: Option<ErrorStats>,
    /// Training rows, calibrated model (with its corrector).
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
    /// The same after calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_position_after: Option<ErrorStats>,
}

/// How the calibrated parameters compare with the truth-equivalent values (with a truth file).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TruthComparison {
    /// Identifiable parameters within 3 standard uncertainties of the truth.
    pub within_3_sigma: usize,
    /// Identifiable (not fixed) parameters.
    pub identifiable: usize,
    /// Largest |z| = |error| / standard uncertainty over the parameters.
    pub max_abs_z: f64,
    /// How the truth-equivalent values were obtained.
    pub method: String,
    /// Sensor noise floor (std of an averaged reading), mm.
    pub noise_floor_mm: f64,
}

/// Where a result comes from: the software, the data and how they were split, the method and
/// its seed, the time it took.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Provenance {
    /// Version of twincal that wrote the result.
    pub twincal_version: String,
    /// Where the calibrated data came from (the dataset's source).
    pub data: String,
    /// SHA-256 of the data file calibrated on (written by `calibrate`): `ik` checks that a twin
    /// it validates against was generated with these very data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_sha256: Option<String>,
    /// The calibration method's name: a registered method's ([`crate::calib::methods::Method`]), or a solver's of the
    /// user's own.
    pub method: String,
    /// Name of the calibrated model.
    pub model_name: String,
    /// Seed of the run (the split and a stochastic method).
    pub seed: u64,
    /// Training rows.
    pub n_train: usize,
    /// Test rows.
    pub n_test: usize,
    /// The rows held out as the test set (0-based here; 1-based row numbers in the file, as an
    /// outlier's `row`): what the report, the recording and a user's own script need to tell
    /// training rows from test rows without redoing the split. Absent in files written before
    /// it was stored, and for a calibration without test rows.
    #[serde(default, skip_serializing_if = "Vec::is_empty", with = "one_based")]
    pub test_rows: Vec<usize>,
    /// Wall time of the calibration, s.
    pub wall_time_s: f64,
}

/// How the solver ran: its iterations and stop, the loss, the noise model and weights it fitted
/// with, and the identifiability analysis that chose the free parameters.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Solve {
    /// Iterations the solver ran.
    pub iterations: usize,
    /// Model evaluations the solver made.
    pub evaluations: usize,
    /// Whether the solver stopped on a convergence criterion (not a budget, a non-finite value or
    /// no descent).
    pub converged: bool,
    /// Why the solver stopped.
    pub stop_reason: String,
    /// The least-squares loss.
    #[serde(default)]
    pub loss: Loss,
    /// Standard deviation of one reading estimated from the data, mm (the residual spread of
    /// the fit, or the repeatability of repeated configurations where there are enough).
    #[serde(default)]
    pub noise_estimate_mm: f64,
    /// How the fit weighted the training rows by their own standard deviations (absent: equal
    /// weights).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weighting: Option<crate::calib::fit::weighting::Weighting>,
    /// The joint angles' logging error as the fit's noise model (absent: the training rows were
    /// taken as independent): see [`crate::calib::fit::noise_model::remove_logging_error`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_model: Option<crate::calib::fit::gls::NoiseModel>,
    /// The identifiability analysis of the training rows at the nominal parameters (rank, condition
    /// numbers, fixed parameters).
    pub identifiability: serde_json::Value,
    /// The generic model's global search: starts, finalists, how many reached the best basin
    /// (absent for a nominal arm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub search: Option<super::generic::SearchReport>,
}

/// The robust screen of the training rows: its threshold and scale, the rows kept out and
/// their runs, the reading steps corrected, and the test rows beyond the same rule.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ScreenReport {
    /// Threshold of the screen, robust standard deviations (0 = off).
    #[serde(default)]
    pub outlier_k: f64,
    /// Robust scale of the kept training rows' residuals, mm (0 without the screen).
    #[serde(default)]
    pub robust_scale_mm: f64,
    /// Training rows kept out of the fit as outliers.
    #[serde(default)]
    pub outliers: Vec<Outlier>,
    /// Runs of consecutive outlier rows.
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
}

impl ScreenReport {
    /// What a calibration's screen (`None`: it did not run) at threshold `outlier_k` kept out
    /// and corrected, with the test rows it judged.
    pub fn of(screen: Option<crate::calib::fit::robust::Screen>, outlier_k: f64, test_rows_in_steps: usize, test_outliers: Vec<Outlier>) -> Self {
        let Some(s) = screen else { return ScreenReport { outlier_k, test_rows_in_steps, test_outliers, ..ScreenReport::default() } };
        ScreenReport {
            outlier_k,
            robust_scale_mm: s.scale_mm,
            outliers: s.outliers,
            outlier_runs: s.runs,
            reading_steps: s.steps,
            test_rows_in_steps,
            test_outliers,
        }
    }
}

/// How good the result is: reading errors before and after on training and test rows, the
/// truth comparison (with a truth file), and the data's own floor.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Evaluation {
    /// Reading errors before and after calibration.
    pub metrics: Metrics,
    /// With a truth file: the parameters against their truth-equivalent values.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth_comparison: Option<TruthComparison>,
    /// Repeated configurations in the data and the spread of the readings over them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repeatability: Option<crate::stats::metrics::Repeatability>,
    /// The data's own floor: repeatability and logging resolutions, each named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_floor: Option<crate::calib::fit::floor::NoiseFloor>,
}

/// The version of result.json's layout this build writes: 2 nests the result by what it is
/// (`provenance`, the model, `solve`, `screen`, `evaluation`); files of version 1 (flat) are
/// still read.
pub const RESULT_SCHEMA_VERSION: u32 = 2;

fn result_schema_version() -> u32 {
    RESULT_SCHEMA_VERSION
}

/// The calibrated model (everything `predict` needs: `model`, `x`, `corrector`,
/// `torque_model`, and `parameters`, its report in display units), where it came from, how it
/// was solved and screened, how good it is, and what a user must know (`warnings`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CalibResult {
    /// The layout of the file ([`RESULT_SCHEMA_VERSION`]).
    #[serde(default = "result_schema_version")]
    pub schema_version: u32,
    /// Where the result comes from.
    pub provenance: Provenance,
    /// The model itself (chain, instrument placement and effect blocks; internal units m / rad).
    pub model: CalibModel,
    /// The calibrated parameter vector (internal units m / rad, in the model's order).
    pub x: Vec<f64>,
    /// The learned corrector of what the geometry and effects leave, if the method fits one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corrector: Option<Corrector>,
    /// Result files written before correctors were one interface stored the RBF network here.
    #[serde(default, rename = "rbf", skip_serializing)]
    pub(super) legacy_rbf: Option<RbfNetwork>,
    /// How the effect blocks get their joint torques on new rows (with effects only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_model: Option<crate::calib::effects::inputs::TorqueModel>,
    /// Every parameter of the model with its value and uncertainty (display units).
    pub parameters: Vec<ParamReport>,
    /// How the solver ran.
    pub solve: Solve,
    /// The robust screen of the training rows.
    pub screen: ScreenReport,
    /// How good the result is.
    pub evaluation: Evaluation,
    /// Things a user should know before trusting the result (did not converge, few rows, ...).
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The instrument's stations, where it stood at more than one ([`super::setup`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<SetupReport>,
    /// A ball seated in an artifact's sockets: each socket, each spacing, and what such rows
    /// cannot determine ([`super::artifact`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub artifact: Option<super::artifact::ArtifactReport>,
    /// Parameter values per iteration (display units), for convergence plots.
    #[serde(skip)]
    pub history: Vec<Vec<f64>>,
    /// Measured minus predicted reading of each test row (mm, in `provenance.test_rows` order),
    /// exactly as the metrics saw them: with the rows' inputs (time, temperature, flanks,
    /// torques) and reading steps. Not stored in the file.
    #[serde(skip)]
    pub test_residuals_mm: Vec<f64>,
}

/// A version-1 result file (flat: every group's keys side by side at the top): each group takes
/// its own keys, as its struct names them, and the rest (the model, the warnings) stays on top.
#[derive(Deserialize)]
struct FlatLayout {
    #[serde(flatten)]
    provenance: Provenance,
    #[serde(flatten)]
    solve: Solve,
    #[serde(flatten)]
    screen: ScreenReport,
    #[serde(flatten)]
    evaluation: Evaluation,
    #[serde(flatten)]
    rest: serde_json::Map<String, serde_json::Value>,
}

/// A value twincal leaves out when it writes a result: `null`, `[]`, `{}`.
fn empty(v: &serde_json::Value) -> bool {
    v.is_null() || v.as_array().is_some_and(Vec::is_empty) || v.as_object().is_some_and(serde_json::Map::is_empty)
}

/// The first key (as `group.key`) of `given`'s top level or of its groups (objects one level down)
/// that `known` — the same result as twincal writes it — lacks. A key twincal leaves out when
/// empty may be given empty ([`empty`]); `rbf` is an old file's corrector.
fn unknown_keys(given: &serde_json::Value, known: &serde_json::Value) -> Option<String> {
    let (Some(g), Some(k)) = (given.as_object(), known.as_object()) else { return None };
    for (key, v) in g {
        if empty(v) || (key == "rbf") {
            continue;
        }
        match k.get(key) {
            None => return Some(key.clone()),
            Some(kv) => {
                if let (Some(go), Some(ko)) = (v.as_object(), kv.as_object()) {
                    if let Some(sub) = go.iter().find(|(sk, sv)| !empty(sv) && !ko.contains_key(*sk)) {
                        return Some(format!("{key}.{}", sub.0));
                    }
                }
            }
        }
    }
    None
}

/// A version-1 result file's JSON (flat: no `provenance`) in the nested layout; other JSON as it is.
fn nested(value: serde_json::Value) -> std::result::Result<serde_json::Value, serde_json::Error> {
    let Some(map) = value.as_object() else { return Ok(value) };
    if map.contains_key("provenance") || map.get("schema_version").and_then(serde_json::Value::as_u64).is_some_and(|v| v >= 2) {
        return Ok(value);
    }
    let flat: FlatLayout = serde_json::from_value(value)?;
    let mut map = flat.rest;
    map.insert("provenance".into(), serde_json::to_value(flat.provenance)?);
    map.insert("solve".into(), serde_json::to_value(flat.solve)?);
    map.insert("screen".into(), serde_json::to_value(flat.screen)?);
    map.insert("evaluation".into(), serde_json::to_value(flat.evaluation)?);
    Ok(serde_json::Value::Object(map))
}

impl CalibResult {
    /// Predicted length (mm) at joint angles in degrees (a draw-wire's model; a tracker's
    /// readings: [`crate::jobs::predicted_readings`]). Example: the whole job (the twin's data, this call, the others) runs as a doctest in [`crate::prelude`].
    pub fn predict_mm(&self, q_deg: &[f64]) -> f64 {
        let q: Vec<f64> = q_deg.iter().map(|d| d.to_radians()).collect();
        let mut w = self.model.work();
        let inp = RowInputs::default();
        crate::units::to_mm(self.model.length(&self.x, &q, &inp, &mut w)) + self.correction_mm(&q, &inp)
    }

    /// The learned wavelet network (the first, when there is one per reading value: they share
    /// their inputs).
    pub(super) fn wavelet_network(&self) -> Option<&crate::calib::correctors::awnn::Awnn> {
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

    /// The dataset columns the model reads besides the joint angles, each with what reads it:
    /// `temp` or `t` for a thermal block (by how it was driven) or a corrector with that input.
    /// Torques and backlash flanks come from the angles and the acquisition order.
    pub fn columns_read(&self) -> Vec<(&'static str, String)> {
        use crate::calib::effects::{EffectKind, ThermalDrive};
        let mut out = Vec::new();
        for b in self.model.effects.iter().filter(|b| b.kind == EffectKind::Thermal) {
            let col = if matches!(b.thermal, Some(ThermalDrive::Temperature { .. })) { "temp" } else { "t" };
            out.push((col, format!("its {} block", b.label())));
            if b.fits_sensor_lag() {
                out.push(("t", format!("its {} block's sensor lag (the temperature's rate)", b.label())));
            }
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
        let inputs = self.row_inputs(data);
        let mut w = self.model.work();
        let mut y = vec![0.0; self.model.measurement.dim()];
        let mut corr = vec![0.0; y.len()];
        let mut out = Vec::with_capacity(data.rows.len() * y.len());
        for (r, inp) in data.rows.iter().zip(&inputs) {
            let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
            self.model.readings(&self.x, &q, inp, &mut w, &mut y);
            if y.len() == 1 {
                out.push(crate::units::to_mm(y[0]) + self.correction_mm(&q, inp));
            } else {
                if let Some(c) = &self.corrector {
                    c.as_correct().corrections_mm(&q, inp, &mut corr);
                }
                out.extend(y.iter().zip(&corr).map(|(v, c)| crate::units::to_mm(v) + c));
            }
        }
        out
    }

    /// RMSE per value (mm) of the model's readings of `data`'s rows against the readings they
    /// hold ([`Self::predict_rows`]; NaN where a row reads nothing).
    pub fn rmse_on(&self, data: &Dataset) -> f64 {
        let m = self.model.measurement;
        let measured: Vec<f64> = data.rows.iter().flat_map(|r| m.values_of_file(&r.reading_mm)).collect();
        let e: Vec<f64> = self.predict_rows(data).iter().zip(&measured).map(|(p, y)| y - p).collect();
        crate::stats::rms(&e)
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

    /// Reads a result file and checks it: JSON of a calibration result of a supported schema, no
    /// number beyond what a calibration writes, and a model, corrector and torque model consistent
    /// with each other. Errors name the file.
    pub fn load(path: &Path) -> Result<CalibResult> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        // A byte-order mark (an editor's UTF-8 save) is no part of the JSON, as in data files.
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| Error::model(path.display(), format!("not a twincal calibration result: {e}")))?;
        Self::from_value(value, &path.display().to_string())
    }

    /// Checks, before it is written, that [`Self::load`] will read this result back: no command
    /// writes a file its own loader refuses (a placement kilometres away, a non-finite value);
    /// the error says what would be refused, and nothing is written.
    pub fn check_writable(&self) -> Result<()> {
        let value = serde_json::to_value(self).map_err(|e| Error::Calibration(format!("cannot serialise the result: {e}")))?;
        Self::from_value(value, "the result")
            .map(|_| ())
            .map_err(|e| Error::Calibration(format!("the calibration gave a result twincal could not read back, so nothing was written: {e}")))
    }

    /// [`Self::load`] of a parsed file (`origin` names it in errors).
    fn from_value(value: serde_json::Value, origin: &str) -> Result<CalibResult> {
        // What the model computes with holds no number a calibration could not have produced.
        for key in ["model", "x", "corrector", "torque_model", "rbf"] {
            if let Some((at, n)) = value.get(key).and_then(|v| beyond_magnitude(v, MAX_MODEL_MAGNITUDE)) {
                return Err(Error::model(
                    origin,
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
                    origin,
                    format!("{key}{at} = {n} is beyond what a calibration writes (a correction within {MAX_CORRECTOR_MAGNITUDE:e} mm); edited result file?"),
                ));
            }
        }
        if let Some(v) = value.get("schema_version").and_then(serde_json::Value::as_u64).filter(|v| *v > u64::from(RESULT_SCHEMA_VERSION)) {
            return Err(Error::model(
                origin,
                format!("a calibration result of schema_version {v}, written by a newer twincal; this one reads up to {RESULT_SCHEMA_VERSION}: update twincal"),
            ));
        }
        let flat = !value.get("provenance").is_some_and(serde_json::Value::is_object);
        let given = (!flat).then(|| value.clone());
        let not_a_result = |e: &dyn std::fmt::Display| Error::model(origin, format!("not a twincal calibration result: {e}"));
        let value = nested(value).map_err(|e| not_a_result(&e))?;
        // The wrong-typed value named by its JSON path (`provenance.schema_version: invalid type ...`).
        let mut r: CalibResult = serde_path_to_error::deserialize(value).map_err(|e| {
            let at = e.path().to_string();
            if at == "." {
                not_a_result(e.inner())
            } else {
                not_a_result(&format!("{at}: {}", e.inner()))
            }
        })?;
        // A key twincal does not write is a typo or someone else's file: named, not ignored (the
        // top level and its groups; a version-1 flat file is read as it is).
        if let Some(given) = given {
            let known = serde_json::to_value(&r).map_err(|e| Error::model(origin, format!("cannot check the file's keys: {e}")))?;
            if let Some(k) = unknown_keys(&given, &known) {
                return Err(Error::model(origin, format!("unknown key '{k}' (a typo, or not a twincal result file?)")));
            }
        }
        // Read in the current layout, whatever the file's.
        r.schema_version = RESULT_SCHEMA_VERSION;
        if let Some(net) = r.legacy_rbf.take() {
            r.corrector.get_or_insert(Corrector::Rbf(net));
        }
        if let Some(c) = &r.corrector {
            c.validate(r.model.chain.n_joints).map_err(|e| Error::model(origin, e))?;
            let (want, has) = (r.model.measurement.dim(), c.as_correct().dim());
            if want != has {
                return Err(Error::model(
                    origin,
                    format!(
                        "the corrector corrects {has} value(s) per row, the model's {} reads {want} (edited result file?)",
                        r.model.measurement.def().describe()
                    ),
                ));
            }
        }
        check_model(&r).map_err(|e| Error::model(origin, e))?;
        Ok(r)
    }
}

/// The checks of a result file's model after it parsed: chain, thermal reference, torque model,
/// the consistency of its parts and sizes, the parameter report, the instrument's placement;
/// what is wrong, for [`CalibResult::load`] to name with the file.
/// The parameter report of a result read from a file: each value the model's `x` in display
/// units (the report is derived, and an edit there would change nothing a command computes),
/// finite nominal values and uncertainties that are not negative.
fn check_parameter_report(r: &CalibResult) -> std::result::Result<(), String> {
    for (k, p) in r.parameters.iter().enumerate() {
        let want = r.x[k] * r.model.kinds[k].display();
        let bad = |what: String| Err(format!("parameters[{k}] ({}): {what} (edited result file?)", p.name));
        if (p.value - want).abs() > 1e-9 * want.abs().max(1.0) {
            return bad(format!("value {} is not the model's {} (x)", crate::error::shown(p.value), crate::error::shown(want)));
        }
        if !p.nominal.is_finite() || p.nominal.abs() > MAX_MODEL_MAGNITUDE {
            return bad(format!("nominal {} is beyond what a calibration writes", crate::error::shown(p.nominal)));
        }
        if let Some(s) = p.std_uncertainty.filter(|s| !(s.is_finite() && *s >= 0.0)) {
            return bad(format!("std_uncertainty {} must be a finite number >= 0", crate::error::shown(s)));
        }
    }
    Ok(())
}

/// Longest method name a result file may hold.
pub const MAX_METHOD_NAME: usize = 64;

fn check_model(r: &CalibResult) -> std::result::Result<(), String> {
    let chain = &r.model.chain;
    chain.validate()?;
    let mut seen = std::collections::BTreeSet::new();
    let m = &r.provenance.method;
    if m.is_empty() || m.len() > MAX_METHOD_NAME || !m.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) {
        return Err(format!(
            "provenance.method {m:?} is not a method's name (letters, digits, '-', '_', '.'; at most {MAX_METHOD_NAME}) (edited result file?)"
        ));
    }
    if let Some(row) = r.provenance.test_rows.iter().find(|i| !seen.insert(**i)) {
        return Err(format!("provenance.test_rows names row {} twice: a calibration holds a row out once (edited result file?)", row + 1));
    }
    let temps = crate::dataset::MIN_TEMP_C..=crate::dataset::MAX_TEMP_C;
    if let Some(t) = r.model.effects.iter().find_map(|b| match b.thermal {
        Some(crate::calib::effects::ThermalDrive::Temperature { ref_c, .. }) if !temps.contains(&ref_c) => Some(ref_c),
        _ => None,
    }) {
        return Err(format!(
            "the thermal block's reference temperature {} °C is outside [{}, {}] °C (edited result file?)",
            crate::error::shown(t),
            temps.start(),
            temps.end()
        ));
    }
    if let Some(t) = &r.torque_model {
        t.validate(chain.n_joints)?;
    } else if let Some(b) = r.model.effects.iter().find(|b| b.kind.def().reads_torques()) {
        // Without it the block would read zero torque on every row: a silent error.
        return Err(format!("the model's {} block reads joint torques, but the file has no torque_model to compute them (edited result file?)", b.kind.name()));
    }
    let consistent = r.x.len() == r.model.n_params()
        && r.model.nominal.len() == r.model.n_params()
        && r.model.effects.iter().all(|e| e.joint.is_none_or(|j| j < chain.n_joints))
        && (r.model.limits.is_empty() || r.model.limits.len() == chain.n_joints)
        && r.model.limits.iter().all(|(lo, hi)| lo.is_finite() && hi.is_finite() && lo < hi)
        && r.model.kinds.len() == r.model.n_params()
        && r.model.n_params() == r.model.first_effect() + r.model.effects.iter().map(EffectBlock::n_params).sum::<usize>()
        && [&r.model.stations, &r.model.mounts].iter().all(|l| l.iter().enumerate().all(|(i, s)| !s.is_empty() && !l[..i].contains(s)))
        && chain.frame_end.last().is_some_and(|e| *e == chain.ops.len())
        && chain.ops.iter().all(|o| o.joint.is_none_or(|j| j < chain.n_joints) && o.param.is_none_or(|k| k < chain.n_params()));
    let reported = r.parameters.len() == r.model.n_params() && r.parameters.iter().zip(&r.model.names).all(|(p, n)| &p.name == n);
    if consistent && !reported {
        return Err(format!(
            "the parameter report lists {} parameters, the model has {} (or names them otherwise): edited or truncated result file?",
            r.parameters.len(),
            r.model.n_params()
        ));
    }
    if !consistent || r.x.iter().any(|v| !v.is_finite()) {
        return Err("the calibrated model is inconsistent (edited or truncated result file?)".into());
    }
    // A chain's deviation beyond the instrument's farthest placement is no calibration's (an
    // angle may wander by whole turns: the bound is 100 rad, as the chain's own offsets').
    if let Some(k) = (0..r.model.n_chain()).find(|&k| r.x[k].abs() > MAX_PLACEMENT || r.model.nominal[k].abs() > MAX_PLACEMENT) {
        return Err(format!(
            "the chain's {} = {} (x) / {} (nominal) is beyond what a calibration writes ({MAX_PLACEMENT} m or rad; edited result file?)",
            r.model.names[k],
            crate::error::shown(r.x[k]),
            crate::error::shown(r.model.nominal[k])
        ));
    }
    let place = r.model.placement(&r.x);
    let names = r.model.measurement.placement_names();
    if let Some((name, v)) = names.iter().zip(place.own.iter().chain(place.tool.iter())).find(|(_, v)| v.abs() > MAX_PLACEMENT) {
        return Err(format!("the instrument's placement {name} = {} is beyond {MAX_PLACEMENT} (m or rad; edited result file?)", crate::error::shown(*v)));
    }
    if let Some(k) = r.model.setup_range().find(|k| r.x[*k].abs() > MAX_PLACEMENT) {
        return Err(format!(
            "the instrument's placement {} = {} is beyond {MAX_PLACEMENT} (m or rad; edited result file?)",
            r.model.names[k],
            crate::error::shown(r.x[k])
        ));
    }
    check_parameter_report(r)
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
pub(super) const CORRECTOR_OUTPUT_KEYS: [&str; 5] = ["weights", "bias", "coef", "w", "output_range"];

/// The first output number of a stored corrector (under [`CORRECTOR_OUTPUT_KEYS`], at any depth:
/// a per-value corrector nests them) beyond [`MAX_CORRECTOR_MAGNITUDE`], with its JSON path.
pub(super) fn corrector_output_beyond(v: &serde_json::Value) -> Option<(String, serde_json::Number)> {
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
pub(super) fn beyond_magnitude(v: &serde_json::Value, limit: f64) -> Option<(String, serde_json::Number)> {
    use serde_json::Value;
    match v {
        Value::Number(n) => n.as_f64().is_none_or(|x| x.abs() > limit).then(|| (String::new(), n.clone())),
        Value::Array(items) => items.iter().enumerate().find_map(|(i, x)| beyond_magnitude(x, limit).map(|(p, n)| (format!("[{i}]{p}"), n))),
        Value::Object(map) => map.iter().find_map(|(k, x)| beyond_magnitude(x, limit).map(|(p, n)| (format!(".{k}{p}"), n))),
        _ => None,
    }
}

/// Row indices stored as 1-based row numbers (the file's convention for rows).
mod one_based {
    use serde::{de::Error as _, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(rows: &[usize], s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_seq(rows.iter().map(|i| i + 1))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Vec<usize>, D::Error> {
        Vec::<usize>::deserialize(d)?
            .into_iter()
            .map(|r| r.checked_sub(1).ok_or_else(|| D::Error::custom("test_rows holds 1-based row numbers; 0 is not one")))
            .collect()
    }
}

#[cfg(test)]
mod one_based_tests {
    #[derive(serde::Serialize, serde::Deserialize)]
    struct Rows {
        #[serde(with = "super::one_based")]
        r: Vec<usize>,
    }

    #[test]
    fn test_rows_are_row_numbers_in_files() {
        assert_eq!(serde_json::to_string(&Rows { r: vec![0, 7] }).unwrap(), r#"{"r":[1,8]}"#);
        assert_eq!(serde_json::from_str::<Rows>(r#"{"r":[1,8]}"#).unwrap().r, vec![0, 7]);
        let e = serde_json::from_str::<Rows>(r#"{"r":[0]}"#).err().unwrap().to_string();
        assert!(e.contains("1-based row numbers"), "{e}");
    }
}
