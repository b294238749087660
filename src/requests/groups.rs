//! The argument groups requests share: how a dataset's readings are read ([`Reading`]), where
//! the instrument stood ([`SetUp`]), the model fitted ([`ModelChoice`]), what loads the joints ([`Loads`]), the data's floor
//! ([`Floor`]) and the robust screen ([`Robust`]); and the `KIND[:JOINT]` lists of effects.
//! The field docs are the command line's `--help`.

use crate::calib::effects::inputs::JointLoads;
use crate::calib::fit::noise_model::NoiseChoice;
use crate::calib::fit::robust::Loss;
use crate::calib::pipeline::{FloorOptions, LoadOptions, ModelSpec, Parametrisation, ScreenOptions, StationSource};
use crate::dataset::{AngleUnit, ReadOptions};
use crate::error::{Error, Result};
use crate::measurement::{Euler, Measurement};
use crate::robot::statics::Payload;
use crate::robot::Robot;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// How a dataset is read: the joint angles' unit and the reading columns (`--angles`,
/// `--measurement`, `--euler`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct Reading {
    /// Unit of the joint angles in the data.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = AngleUnit::Auto))]
    pub angles: AngleUnit,
    /// The instrument whose columns to read when the header holds more than one's (point: only
    /// x, y, z of a file that also has a pose's rx, ry, rz); default: what the header holds
    /// (L: length; x, y, z: point; x, y, z, rx, ry, rz: pose).
    #[cfg_attr(feature = "clap", arg(long, value_enum, ignore_case = true))]
    pub measurement: Option<Measurement>,
    /// The Euler convention of a pose's rx, ry, rz (degrees): capitals for rotations about the
    /// moving axes (intrinsic; XYZ is R = Rx(rx)·Ry(ry)·Rz(rz)), lower case for the fixed axes
    /// (extrinsic; xyz is R = Rz(rz)·Ry(ry)·Rx(rx)); ZYX, ZYZ, ... likewise.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = Euler::default()))]
    pub euler: Euler,
}

impl Reading {
    /// How a dataset is read with these options (any source: a file, or columns in memory).
    /// `require_length`: the `L` column must be there when the header holds no other
    /// instrument's.
    pub fn load_options(&self, require_length: bool) -> ReadOptions {
        ReadOptions { angles: self.angles, require_length, measurement: self.measurement, euler: self.euler }
    }
}

/// Where the instrument stood (`--stations`): for the commands that fit the instrument's
/// placements (calibrate, diagnose) and nowhere else.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct SetUp {
    /// Where the instrument stood: auto (the station column where the file has one, then, for a
    /// tracker, the change points a first fit finds: a re-stationed, re-registered or bumped
    /// tracker), declared (the station column only), blocks (each declared block a station) or
    /// one (one placement for every row). Each station is fitted a placement of its own.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = StationSource::Auto))]
    pub stations: StationSource,
}

/// Which model a calibration fits (`--model`, `--params`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct ModelChoice {
    /// irb120 (embedded URDF), a .urdf path, a UR kinematics .yaml (the factory calibration the
    /// UR driver extracts, as the nominal), or generic (no nominal: the arm's axes found from
    /// the data; 6 or 7 joints, also written generic6r / generic7r).
    #[cfg_attr(feature = "clap", arg(long, default_value = "irb120"))]
    pub model: String,
    /// Parametrisation of a nominal model: hayati (D-H, β on parallel axes; the default), dh (papers' 24)
    /// or frame. Not for the generic arm.
    #[cfg_attr(feature = "clap", arg(long, value_enum, ignore_case = true))]
    pub params: Option<Parametrisation>,
}

impl Default for ModelChoice {
    fn default() -> Self {
        ModelChoice { model: "irb120".into(), params: None }
    }
}

impl ModelChoice {
    /// The model these options name; `--params` is refused for the generic arm, which has no
    /// nominal model to parametrise.
    pub fn spec(&self) -> Result<ModelSpec> {
        if ModelSpec::is_generic_name(&self.model) {
            if let Some(p) = &self.params {
                return Err(Error::Invalid(format!(
                    "--params {} applies to nominal models (irb120 or a .urdf); {} has no nominal model to parametrise",
                    p.name(),
                    self.model
                )));
            }
        }
        if let Some(path) = self.input().filter(|p| p.extension().is_some_and(|e| e == "yaml" || e == "yml")) {
            let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
            let robot = crate::export::ur_yaml::robot(&text, &path.display().to_string())?;
            return Ok(ModelSpec::nominal(robot, self.params.unwrap_or_default()));
        }
        ModelSpec::parse(&self.model, self.params.unwrap_or_default())
    }

    /// `--model` as an input file, when it names one (a .urdf, or a UR kinematics .yaml).
    pub fn input(&self) -> Option<PathBuf> {
        [".urdf", ".yaml", ".yml"].iter().any(|e| self.model.ends_with(e)).then(|| PathBuf::from(&self.model))
    }

    /// A URDF path made absolute against the current working directory, so that the request
    /// names the same file after the working directory changes (Python: a `chdir` between
    /// `calibrate` and `save` must not let an output land on the model it read).
    pub fn resolve_paths(&mut self) {
        if let Some(p) = self.input() {
            if let Ok(abs) = std::path::absolute(&p) {
                self.model = abs.to_string_lossy().into_owned();
            }
        }
    }
}

/// What loads the joints, for the torque-driven effects (`--robot`, `--payload-kg`,
/// `--payload-com-mm`, `--cable-tension-n`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct Loads {
    /// URDF whose inertial data give the static joint torques (default: the model's own robot;
    /// needed for compliance with generic6r).
    #[cfg_attr(feature = "clap", arg(long))]
    pub robot: Option<PathBuf>,
    /// Payload on the flange, kg.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub payload_kg: Option<f64>,
    /// Payload centre of mass in the flange frame, mm (x,y,z).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y,Z"))]
    pub payload_com_mm: Option<Vec<f64>>,
    /// Draw-wire cable tension from the sensor's data sheet, N (0: ignored).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0.0, allow_negative_numbers = true))]
    pub cable_tension_n: f64,
    /// The force pressing the ball into its socket, or the probe onto a face, along the flange's z
    /// axis, N (artifact data; 0: ignored). A hand pushes 10–30 N; a spring or magnet states its own.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0.0, allow_negative_numbers = true))]
    pub preload_n: f64,
}

impl Loads {
    /// What loads the joints and the inertial robot (`--robot`, read from its URDF), validated.
    pub fn resolve(&self) -> Result<LoadOptions> {
        let mut o = JointLoads::default();
        if !(self.cable_tension_n.is_finite() && (0.0..=1000.0).contains(&self.cable_tension_n)) {
            return Err(Error::Invalid(format!("--cable-tension-n must be in [0, 1000] N, got {}", self.cable_tension_n)));
        }
        o.cable_tension_n = self.cable_tension_n;
        if !(self.preload_n.is_finite() && (0.0..=crate::calib::effects::inputs::MAX_PRELOAD_N).contains(&self.preload_n)) {
            return Err(Error::Invalid(format!("--preload-n must be in [0, {}] N, got {}", crate::calib::effects::inputs::MAX_PRELOAD_N, self.preload_n)));
        }
        o.preload_n = self.preload_n;
        match (self.payload_kg, &self.payload_com_mm) {
            (None, None) => {}
            (Some(m), com) => {
                if !(m.is_finite() && (0.0..=1000.0).contains(&m)) {
                    return Err(Error::Invalid(format!("--payload-kg must be in [0, 1000] kg, got {m}")));
                }
                let com = com.clone().unwrap_or_else(|| vec![0.0; 3]);
                if com.len() != 3 || com.iter().any(|v| !v.is_finite() || v.abs() > 5000.0) {
                    return Err(Error::Invalid("--payload-com-mm needs 3 finite values in mm (x,y,z in the flange frame, each within ±5000)".into()));
                }
                o.payload = Some(Payload { mass_kg: m, com_mm: [com[0], com[1], com[2]] });
            }
            // The centre of mass of the rows' own payloads (a `payload_kg` column): a payload of
            // no mass of its own that states where theirs sits.
            (None, Some(com)) => {
                if com.len() != 3 || com.iter().any(|v| !v.is_finite() || v.abs() > 5000.0) {
                    return Err(Error::Invalid("--payload-com-mm needs 3 finite values in mm (x,y,z in the flange frame, each within ±5000)".into()));
                }
                o.payload = Some(Payload { mass_kg: 0.0, com_mm: [com[0], com[1], com[2]] });
            }
        }
        let inertial = match &self.robot {
            Some(p) => Some(Robot::from_urdf_file(p)?),
            None => None,
        };
        Ok(LoadOptions { joints: o, inertial })
    }
}

/// The data's floor and the rows' weights (`--angle-resolution-deg`,
/// `--instrument-accuracy-mm`, `--ignore-row-std`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct Floor {
    /// Logging step of the joint angles in degrees, for the noise floor (default: read from the
    /// data's decimals).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub angle_resolution_deg: Option<f64>,
    /// The instrument's stated accuracy, mm (standard uncertainty of one coordinate or of the
    /// cable length), for the noise floor.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub instrument_accuracy_mm: Option<f64>,
    /// Fit with equal weights even where the data give per-row standard deviations (a
    /// tracker's sx, sy, sz; by default they weight the fits as 1/(floor² + s²)).
    #[cfg_attr(feature = "clap", arg(long))]
    pub ignore_row_std: bool,
    /// The joint angles' logging error: auto (where rows share sweeps and the angles are
    /// logged at a step, the fits model the error it puts on every row of a sweep; estimated
    /// per sweep and joint, at most half a step) or off (rows taken as independent).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = NoiseChoice::default()))]
    pub noise_model: NoiseChoice,
}

impl Floor {
    /// The floor's options, validated.
    pub fn resolve(&self) -> Result<FloorOptions> {
        if let Some(r) = self.angle_resolution_deg {
            if !(r.is_finite() && r > 0.0 && r <= 10.0) {
                return Err(Error::Invalid(format!("--angle-resolution-deg must be in (0, 10] degrees, got {r}")));
            }
        }
        Ok(FloorOptions {
            angle_step_deg: self.angle_resolution_deg,
            instrument_accuracy_mm: instrument_accuracy(self.instrument_accuracy_mm)?,
            row_std: !self.ignore_row_std,
            noise_model: self.noise_model,
        })
    }
}

/// `--instrument-accuracy-mm`, checked: a standard uncertainty in (0, 100] mm.
fn instrument_accuracy(v: Option<f64>) -> Result<Option<f64>> {
    match v {
        Some(a) if !(a.is_finite() && a > 0.0 && a <= 100.0) => {
            Err(Error::Invalid(format!("--instrument-accuracy-mm must be in (0, 100] mm (a standard uncertainty of one coordinate), got {a}")))
        }
        _ => Ok(v),
    }
}

/// The robust screen and the loss (`--outliers`, `--no-reading-steps`, `--loss`), with the
/// data's floor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct Robust {
    /// Training rows more than this many robust standard deviations (1.4826 MAD) off the fit
    /// are outliers: kept out and listed in the result (0: keep every row).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = crate::calib::pipeline::DEFAULT_OUTLIER_K, allow_negative_numbers = true))]
    pub outliers: f64,
    /// Keep out the rows of a run of outliers even when they all sit one constant offset off
    /// (by default such a reading step is corrected and its rows kept).
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_reading_steps: bool,
    /// Least-squares loss of `--method lm`: l2, huber or cauchy (by IRLS, robust scale from the data).
    #[cfg_attr(feature = "clap", arg(long, value_enum, ignore_case = true, default_value_t = Loss::default()))]
    pub loss: Loss,
    /// The data's floor and the rows' weights.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub floor: Floor,
}

impl Default for Robust {
    fn default() -> Self {
        let screen = ScreenOptions::default();
        Robust { outliers: screen.outlier_k, no_reading_steps: !screen.reading_steps, loss: Loss::default(), floor: Floor::default() }
    }
}

impl Robust {
    /// The screen's options, validated.
    pub fn resolve(&self) -> Result<ScreenOptions> {
        if !(self.outliers.is_finite() && (self.outliers == 0.0 || (2.0..=100.0).contains(&self.outliers))) {
            return Err(Error::Invalid(format!("--outliers must be 0 (off) or in [2, 100] robust standard deviations, got {}", self.outliers)));
        }
        Ok(ScreenOptions { outlier_k: self.outliers, reading_steps: !self.no_reading_steps })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generic6r_takes_no_parametrisation() {
        let spec = |model: &str, params: Option<Parametrisation>| ModelChoice { model: model.into(), params }.spec();
        let e = spec("generic6r", Some(Parametrisation::Dh)).unwrap_err().to_string();
        assert!(e.contains("--params dh"), "{e}");
        assert!(spec("generic6r", None).is_ok());
        assert!(spec("irb120", Some(Parametrisation::Frame)).is_ok());
    }
}

/// The artifact a ball was seated in (`calibrate`, `diagnose`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct Artifact {
    /// Known distance between sockets of the artifact a ball was seated in (the step between two
    /// parallel faces a probe touched), mm: 50 for an artifact of two sockets, A:B=50 between
    /// sockets (faces) A and B (repeat or comma-separate for more), A:B=50±0.02 (or +-) with its
    /// standard uncertainty as made (without one: held to 0.001 mm); it holds on every placement
    /// of the artifact.
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ',', value_name = "[A:B=]MM[±SD]"))]
    pub spacing_mm: Vec<crate::calib::model::KnownSpacing>,
}
