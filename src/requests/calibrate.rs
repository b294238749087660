//! A calibration as a user asks for it: `twincal calibrate`'s options but `--data` and the
//! files it writes, Python's `twincal.calibrate` keyword arguments.

use super::groups::{parse_effects, Loads, ModelChoice, Reading, Robust};
use crate::calib::model::SensorGuess;
use crate::calib::run::{CalibOptions, Method, DEFAULT_RANK_TOL};
use crate::dataset::LoadOptions;
use crate::error::{Error, Result};
use crate::report::verdict::Limit;
use serde::{Deserialize, Serialize};

/// Range of `--effort` (a multiple of the methods' default budgets): below a hundredth of it a
/// stochastic method has next to no iterations, and its "result" is its start.
pub const MIN_EFFORT: f64 = 0.01;
/// See [`MIN_EFFORT`].
pub const MAX_EFFORT: f64 = 10.0;

/// `--effort`, checked: between [`MIN_EFFORT`] and [`MAX_EFFORT`] (`calibrate`, `compare`).
pub fn check_effort(effort: f64) -> Result<()> {
    if !(MIN_EFFORT..=MAX_EFFORT).contains(&effort) {
        return Err(Error::Invalid(format!("--effort must be in [{MIN_EFFORT}, {MAX_EFFORT}], got {effort}")));
    }
    Ok(())
}

/// The options of a calibration (the field docs are `twincal calibrate --help`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct CalibrateRequest {
    /// How the data are read.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub reading: Reading,
    /// The calibration method (any case).
    #[cfg_attr(feature = "clap", arg(long, default_value = "lm", ignore_case = true, value_parser = super::method_values()))]
    pub method: String,
    /// The model fitted.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub model: ModelChoice,
    /// Hold out this fraction instead of the dataset's split column (0 trains on every row).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub test_fraction: Option<f64>,
    /// How --test-fraction draws its rows: blocks (whole sweeps, pauses, declared blocks:
    /// test rows share no error with training rows) or rows (stratified by the reading).
    #[cfg_attr(feature = "clap", arg(long, default_value = "blocks"))]
    pub split_by: String,
    /// The joint angles' logging error: auto (where training rows share sweeps and the angles
    /// are logged at a step, estimated per sweep and joint, at most half a step, and taken out
    /// of the readings before the fit) or off (rows taken as independent).
    #[cfg_attr(feature = "clap", arg(long, default_value = "auto"))]
    pub noise_model: String,
    /// Seed of the hold-out split and of the stochastic methods.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, default_value_t = 0))]
    pub seed: u64,
    /// Sensor geometry guess, mm: exit x,y,z, length offset, tool x,y,z (default: estimated).
    #[cfg_attr(
        feature = "clap",
        arg(long, allow_negative_numbers = true, value_delimiter = ',', allow_hyphen_values = true, value_name = "EX,EY,EZ,OFFSET,TX,TY,TZ")
    )]
    pub sensor_guess: Option<Vec<f64>>,
    /// Relative singular-value threshold for identifiability (combinations the data see below
    /// this fraction of the strongest are fixed).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DEFAULT_RANK_TOL, allow_negative_numbers = true))]
    pub rank_tol: f64,
    /// Budget of the stochastic methods and of the generic model's global search (1 = default).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 1.0, allow_negative_numbers = true))]
    pub effort: f64,
    /// Accuracy limit for the verdict in --out: RMSE of the test rows after calibration, mm.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub max_test_rmse_mm: Option<f64>,
    /// Accuracy limit for the verdict in --out: largest |residual| of the test rows, mm.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub max_test_max_mm: Option<f64>,
    /// Non-geometric effects to fit with the geometry: compliance, backlash, thermal,
    /// eccentricity, nonlinearity, each optionally on one joint (backlash:2).
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ','))]
    pub effects: Vec<String>,
    /// Fit a temperature-driven thermal block without the sensor's lag (the `temp` column taken
    /// as the structure's temperature), even where the rows have a time column.
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_sensor_lag: bool,
    /// What loads the joints.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub loads: Loads,
    /// The robust screen and the data's floor.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub robust: Robust,
    /// Fit the instrument's placement only, the arm held at its nominal model: with
    /// --scenario-out, the nominal twin of a set-up whose instrument was not surveyed.
    #[cfg_attr(feature = "clap", arg(long))]
    pub placement_only: bool,
}

impl Default for CalibrateRequest {
    fn default() -> Self {
        CalibrateRequest {
            reading: Reading::default(),
            method: "lm".into(),
            model: ModelChoice::default(),
            test_fraction: None,
            split_by: "blocks".into(),
            noise_model: "auto".into(),
            seed: 0,
            sensor_guess: None,
            rank_tol: DEFAULT_RANK_TOL,
            effort: 1.0,
            max_test_rmse_mm: None,
            max_test_max_mm: None,
            effects: Vec::new(),
            no_sensor_lag: false,
            loads: Loads::default(),
            robust: Robust::default(),
            placement_only: false,
        }
    }
}

impl CalibrateRequest {
    /// Every option checked and resolved into the calibration's options and the verdict's
    /// limits (reads no data; reads --robot's URDF).
    pub fn options(&self) -> Result<(CalibOptions, [Limit; 2])> {
        let a = self;
        let method = Method::parse(&a.method)?;
        if !(a.rank_tol > 0.0 && a.rank_tol < 1.0) {
            return Err(Error::Invalid(format!("--rank-tol must be in (0, 1), got {}", a.rank_tol)));
        }
        check_effort(a.effort)?;
        if let Some(f) = a.test_fraction {
            if !(0.0..1.0).contains(&f) {
                return Err(Error::Invalid(format!("--test-fraction must be in [0, 1), got {f}")));
            }
        }
        let limits = [Limit { flag: "--max-test-rmse-mm", value: a.max_test_rmse_mm }, Limit { flag: "--max-test-max-mm", value: a.max_test_max_mm }];
        for l in &limits {
            l.validate()?;
        }
        let mut opts = CalibOptions::new(a.model.spec()?, method);
        opts.test_fraction = a.test_fraction;
        opts.split_by = a.split_by.parse()?;
        opts.noise_model = a.noise_model.parse()?;
        opts.seed = a.seed;
        opts.rank_tol = a.rank_tol;
        opts.effort = a.effort;
        opts.sensor_guess = sensor_guess(a.sensor_guess.as_deref())?;
        opts.effects = parse_effects("--effects", &a.effects)?;
        opts.sensor_lag = !a.no_sensor_lag;
        (opts.loads, opts.inertial) = a.loads.resolve()?;
        if let Some(path) = &a.loads.robot {
            crate::calib::run::check_inertial(&opts.model, opts.inertial.as_ref(), &path.display().to_string())?;
        }
        (opts.outlier_k, opts.loss) = a.robust.resolve()?;
        (opts.angle_step_deg, opts.instrument_accuracy_mm) = a.robust.floor.resolve()?;
        opts.row_std = !a.robust.floor.ignore_row_std;
        opts.reading_steps = !a.robust.no_reading_steps;
        opts.placement_only = a.placement_only;
        opts.stations = a.reading.stations;
        if a.placement_only {
            // The instrument's placement alone is fitted: nothing else may be asked to be.
            if !opts.effects.is_empty() {
                return Err(Error::Invalid(
                    "--placement-only fits the instrument's placement alone, with the robot as it is: --effects cannot be fitted with it (drop one of them)"
                        .into(),
                ));
            }
            if matches!(opts.model, crate::calib::run::ModelSpec::Generic) {
                return Err(Error::Invalid(
                    "--placement-only needs the robot's own geometry (a URDF or irb120): the generic arm has none to keep, its geometry is what it searches for".into(),
                ));
            }
        }
        Ok((opts, limits))
    }

    /// How the data are read (`--angles`, `--measurement`, `--euler`); a calibration needs a
    /// reading.
    pub fn load_options(&self) -> Result<LoadOptions> {
        self.reading.load_options(true)
    }
}

/// `--sensor-guess`: seven values in mm, as the model's guess in metres.
fn sensor_guess(g: Option<&[f64]>) -> Result<Option<SensorGuess>> {
    let Some(g) = g else { return Ok(None) };
    if g.len() != 7 {
        return Err(Error::Invalid(format!("--sensor-guess needs 7 values in mm (exit x,y,z, length offset, tool x,y,z), got {}", g.len())));
    }
    if g.iter().any(|v| !v.is_finite()) {
        return Err(Error::Invalid("--sensor-guess values must be finite numbers (mm)".into()));
    }
    let m = crate::units::to_m::<f64>;
    Ok(Some(SensorGuess { exit_m: [m(g[0]), m(g[1]), m(g[2])], offset_m: m(g[3]), tool_m: [m(g[4]), m(g[5]), m(g[6])] }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placement_only_refuses_what_it_would_not_fit() {
        let r = CalibrateRequest { placement_only: true, effects: vec!["compliance:2".into()], ..CalibrateRequest::default() };
        let e = r.options().err().unwrap().to_string();
        assert!(e.contains("--placement-only") && e.contains("--effects"), "{e}");
        let mut r = CalibrateRequest { placement_only: true, ..CalibrateRequest::default() };
        r.model.model = "generic6r".into();
        let e = r.options().err().unwrap().to_string();
        assert!(e.contains("--placement-only") && e.contains("generic arm"), "{e}");
        assert!(CalibrateRequest { placement_only: true, ..CalibrateRequest::default() }.options().is_ok());
    }
}
