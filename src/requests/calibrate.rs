//! A calibration as a user asks for it: `twincal calibrate`'s options but `--data` and the
//! files it writes, Python's `twincal.calibrate` keyword arguments.

use super::groups::{Artifact, Loads, ModelChoice, Reading, Robust, SetUp};
use crate::calib::effects::EffectChoice;
use crate::calib::model::DrawWireGuess;
use crate::calib::pipeline::{CalibOptions, FreeParams, Method, SplitBy, SplitOptions, DEFAULT_EFFORT, DEFAULT_RANK_TOL};
use crate::dataset::ReadOptions;
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

/// `--test-fraction`, checked by every command that takes it (calibrate, diagnose, compare,
/// replay): in [0, 1), the share of rows (blocks) held out; 0 holds none out, whatever the
/// data's split column says.
pub fn check_test_fraction(f: Option<f64>) -> Result<()> {
    match f {
        Some(f) if !(0.0..1.0).contains(&f) => Err(Error::Invalid(format!("--test-fraction must be in [0, 1) (0: no row held out), got {f}"))),
        _ => Ok(()),
    }
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
    /// Where the instrument stood.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub setup: SetUp,
    /// The calibration method (any case).
    #[cfg_attr(feature = "clap", arg(long, value_enum, ignore_case = true, default_value_t = Method::default()))]
    pub method: Method,
    /// The model fitted.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub model: ModelChoice,
    /// Hold out this fraction instead of the dataset's split column (0 trains on every row).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub test_fraction: Option<f64>,
    /// How --test-fraction draws its rows: blocks (whole sweeps, pauses, declared blocks:
    /// test rows share no error with training rows), rows (stratified by the reading) or time
    /// (the last rows: what varies with time judged on later rows).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = SplitBy::default()))]
    pub split_by: SplitBy,
    /// Seed of the hold-out split and of the stochastic methods.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, default_value_t = 0))]
    pub seed: u64,
    /// The draw-wire's placement guess, mm: cable exit x,y,z, length offset, tool x,y,z (default:
    /// estimated; `--sensor-guess` is its former name).
    #[cfg_attr(
        feature = "clap",
        arg(
            long,
            alias = "sensor-guess",
            allow_negative_numbers = true,
            value_delimiter = ',',
            allow_hyphen_values = true,
            value_name = "EX,EY,EZ,OFFSET,TX,TY,TZ"
        )
    )]
    #[serde(alias = "sensor_guess")]
    pub draw_wire_guess: Option<Vec<f64>>,
    /// Relative singular-value threshold for identifiability (combinations the data see below
    /// this fraction of the strongest are fixed).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DEFAULT_RANK_TOL, allow_negative_numbers = true))]
    pub rank_tol: f64,
    /// Budget of the stochastic methods and of the generic model's global search (1 = default).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DEFAULT_EFFORT, allow_negative_numbers = true))]
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
    pub effects: Vec<EffectChoice>,
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
    /// Fit only what a controller that takes no new kinematic model can be given: the joints'
    /// zero offsets, the base frame (the instrument's placement) and the tool point, the rest of
    /// the arm held at its nominal model; its held-out accuracy is what such a controller keeps.
    #[cfg_attr(feature = "clap", arg(long, conflicts_with = "placement_only"))]
    pub controller_subset: bool,
    /// The artifact a ball was seated in (a probe touched).
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub artifact: Artifact,
}

impl Default for CalibrateRequest {
    fn default() -> Self {
        CalibrateRequest {
            reading: Reading::default(),
            setup: SetUp::default(),
            method: Method::default(),
            model: ModelChoice::default(),
            test_fraction: None,
            split_by: SplitBy::default(),
            seed: 0,
            draw_wire_guess: None,
            rank_tol: DEFAULT_RANK_TOL,
            effort: DEFAULT_EFFORT,
            max_test_rmse_mm: None,
            max_test_max_mm: None,
            effects: Vec::new(),
            no_sensor_lag: false,
            loads: Loads::default(),
            robust: Robust::default(),
            placement_only: false,
            controller_subset: false,
            artifact: Artifact::default(),
        }
    }
}

impl CalibrateRequest {
    /// Every option checked and resolved into the calibration's options and the verdict's
    /// limits (reads no data; reads --robot's URDF).
    pub fn options(&self) -> Result<(CalibOptions, [Limit; 2])> {
        let a = self;
        if !(a.rank_tol > 0.0 && a.rank_tol < 1.0) {
            return Err(Error::Invalid(format!("--rank-tol must be in (0, 1), got {}", a.rank_tol)));
        }
        check_effort(a.effort)?;
        check_test_fraction(a.test_fraction)?;
        let limits = [Limit { flag: "--max-test-rmse-mm", value: a.max_test_rmse_mm }, Limit { flag: "--max-test-max-mm", value: a.max_test_max_mm }];
        for l in &limits {
            l.validate()?;
        }
        let model = a.model.spec()?;
        let loads = a.loads.resolve()?;
        if let Some(path) = &a.loads.robot {
            crate::calib::pipeline::check_inertial(&model, loads.inertial.as_ref(), &path.display().to_string())?;
        }
        let opts = CalibOptions {
            split: SplitOptions { test_fraction: a.test_fraction, by: a.split_by },
            seed: a.seed,
            rank_tol: a.rank_tol,
            effort: a.effort,
            draw_wire_guess: draw_wire_guess(a.draw_wire_guess.as_deref())?,
            effects: a.effects.iter().map(|c| c.pair()).collect(),
            sensor_lag: !a.no_sensor_lag,
            loads,
            screen: a.robust.resolve()?,
            loss: a.robust.loss,
            floor: a.robust.floor.resolve()?,
            free: match (a.placement_only, a.controller_subset) {
                (true, true) => return Err(Error::Invalid("--placement-only and --controller-subset each choose what is fitted: give one of them".into())),
                (true, false) => FreeParams::Placement,
                (false, true) => FreeParams::Controller,
                (false, false) => FreeParams::All,
            },
            stations: a.setup.stations,
            spacings: a.artifact.spacing_mm.clone(),
            ..CalibOptions::new(model, a.method)
        };
        if opts.free != FreeParams::All {
            // The subset alone is fitted: nothing else may be asked to be.
            let flag = if a.placement_only { "--placement-only" } else { "--controller-subset" };
            if !opts.effects.is_empty() {
                return Err(Error::Invalid(format!(
                    "{flag} fits the instrument's placement{} alone, with the rest of the robot as it is: --effects cannot be fitted with it (drop one of them)",
                    if a.placement_only { "" } else { ", the joints' zero offsets and the tool" }
                )));
            }
            if matches!(opts.model, crate::calib::pipeline::ModelSpec::Generic) {
                return Err(Error::Invalid(format!(
                    "{flag} needs the robot's own geometry (a URDF or irb120): the generic arm has none to keep, its geometry is what it searches for"
                )));
            }
        }
        Ok((opts, limits))
    }

    /// How the data are read (`--angles`, `--measurement`, `--euler`); a calibration needs a
    /// reading.
    pub fn load_options(&self) -> ReadOptions {
        self.reading.load_options(true)
    }
}

/// `--draw-wire-guess`: seven values in mm, as the model's guess in metres.
fn draw_wire_guess(g: Option<&[f64]>) -> Result<Option<DrawWireGuess>> {
    let Some(g) = g else { return Ok(None) };
    if g.len() != 7 {
        return Err(Error::Invalid(format!("--draw-wire-guess needs 7 values in mm (exit x,y,z, length offset, tool x,y,z), got {}", g.len())));
    }
    if g.iter().any(|v| !v.is_finite()) {
        return Err(Error::Invalid("--draw-wire-guess values must be finite numbers (mm)".into()));
    }
    let m = crate::units::to_m::<f64>;
    Ok(Some(DrawWireGuess { exit_m: [m(g[0]), m(g[1]), m(g[2])], offset_m: m(g[3]), tool_m: [m(g[4]), m(g[5]), m(g[6])] }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placement_only_refuses_what_it_would_not_fit() {
        let r = CalibrateRequest { placement_only: true, effects: vec!["compliance:2".parse().unwrap()], ..CalibrateRequest::default() };
        let e = r.options().err().unwrap().to_string();
        assert!(e.contains("--placement-only") && e.contains("--effects"), "{e}");
        let mut r = CalibrateRequest { placement_only: true, ..CalibrateRequest::default() };
        r.model.model = "generic6r".into();
        let e = r.options().err().unwrap().to_string();
        assert!(e.contains("--placement-only") && e.contains("generic arm"), "{e}");
        assert!(CalibrateRequest { placement_only: true, ..CalibrateRequest::default() }.options().is_ok());
    }
}
