//! The argument groups requests share: how a dataset's readings are read ([`Reading`]), the
//! model fitted ([`ModelChoice`]), what loads the joints ([`Loads`]), the data's floor
//! ([`Floor`]) and the robust screen ([`Robust`]); and the `KIND[:JOINT]` lists of effects.
//! The field docs are the command line's `--help`.

use crate::calib::effects::EffectKind;
use crate::calib::problem::robust::Loss;
use crate::calib::run::ModelSpec;
use crate::calib::run::StationSource;
use crate::dataset::{AngleUnit, LoadOptions};
use crate::error::{Error, Result};
use crate::measurement::{Euler, Measurement};
use crate::robot::statics::Payload;
use crate::robot::Robot;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// How a dataset is read: the joint angles' unit and the reading columns (`--angles`,
/// `--measurement`, `--euler`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct Reading {
    /// Unit of the joint angles in the data.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = AngleUnit::Auto))]
    pub angles: AngleUnit,
    /// The instrument whose columns to read when the header holds more than one's (point: only
    /// x, y, z of a file that also has a pose's rx, ry, rz); default: what the header holds
    /// (L: length; x, y, z: point; x, y, z, rx, ry, rz: pose).
    #[cfg_attr(feature = "clap", arg(long, ignore_case = true, value_parser = clap::builder::PossibleValuesParser::new(Measurement::ALL.map(Measurement::name))))]
    pub measurement: Option<String>,
    /// The Euler convention of a pose's rx, ry, rz (degrees): capitals for rotations about the
    /// moving axes (intrinsic; XYZ is R = Rx(rx)·Ry(ry)·Rz(rz)), lower case for the fixed axes
    /// (extrinsic; xyz is R = Rz(rz)·Ry(ry)·Rx(rx)); ZYX, ZYZ, ... likewise.
    #[cfg_attr(feature = "clap", arg(long, default_value = "XYZ"))]
    pub euler: String,
    /// Where the instrument stood: auto (the station column where the file has one, then, for a
    /// tracker, the change points a first fit finds: a re-stationed, re-registered or bumped
    /// tracker), declared (the station column only), blocks (each declared block a station) or
    /// one (one placement for every row). Each station is fitted a placement of its own.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = StationSource::Auto))]
    pub stations: StationSource,
}

impl Default for Reading {
    fn default() -> Self {
        Reading { angles: AngleUnit::Auto, measurement: None, euler: "XYZ".into(), stations: StationSource::Auto }
    }
}

impl Reading {
    /// The instrument asked for and the Euler convention, or an error naming the option.
    pub fn resolve(&self) -> Result<(Option<Measurement>, Euler)> {
        let measurement = match &self.measurement {
            None => None,
            Some(name) => Some(Measurement::ALL.into_iter().find(|m| m.name().eq_ignore_ascii_case(name.trim())).ok_or_else(|| {
                Error::Invalid(format!("--measurement '{name}' is not one of {}", Measurement::ALL.iter().map(|m| m.name()).collect::<Vec<_>>().join(", ")))
            })?),
        };
        let euler = Euler::parse(&self.euler).map_err(|e| Error::Invalid(format!("--euler: {e}")))?;
        Ok((measurement, euler))
    }

    /// How a dataset is read with these options (any source: a file, or columns in memory).
    /// `require_length`: the `L` column must be there when the header holds no other
    /// instrument's.
    pub fn load_options(&self, require_length: bool) -> Result<LoadOptions> {
        let (measurement, euler) = self.resolve()?;
        Ok(LoadOptions { angles: self.angles, require_length, measurement, euler })
    }
}

/// Which model a calibration fits (`--model`, `--params`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct ModelChoice {
    /// irb120 (embedded URDF), a .urdf path, or generic (no nominal: the arm's axes found from
    /// the data; 6 or 7 joints, also written generic6r / generic7r).
    #[cfg_attr(feature = "clap", arg(long, default_value = "irb120"))]
    pub model: String,
    /// Parametrisation of a nominal model: hayati (D-H, β on parallel axes; the default), dh (papers' 24)
    /// or frame. Not for the generic arm.
    #[cfg_attr(feature = "clap", arg(long))]
    pub params: Option<String>,
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
                    "--params {p} applies to nominal models (irb120 or a .urdf); {} has no nominal model to parametrise",
                    self.model
                )));
            }
        }
        ModelSpec::parse(&self.model, self.params.as_deref().unwrap_or(crate::calib::run::Parametrisation::Hayati.name()))
    }

    /// `--model` as an input file, when it names one (a .urdf).
    pub fn input(&self) -> Option<PathBuf> {
        self.model.ends_with(".urdf").then(|| PathBuf::from(&self.model))
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
    /// needed for joint_compliance with generic6r).
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
}

impl Loads {
    /// The load options and the inertial robot (`--robot`, read from its URDF), validated.
    pub fn resolve(&self) -> Result<(crate::calib::effects::inputs::LoadOptions, Option<Robot>)> {
        let mut o = crate::calib::effects::inputs::LoadOptions::default();
        if !(self.cable_tension_n.is_finite() && (0.0..=1000.0).contains(&self.cable_tension_n)) {
            return Err(Error::Invalid(format!("--cable-tension-n must be in [0, 1000] N, got {}", self.cable_tension_n)));
        }
        o.cable_tension_n = self.cable_tension_n;
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
        let robot = match &self.robot {
            Some(p) => Some(Robot::from_urdf_file(p)?),
            None => None,
        };
        Ok((o, robot))
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
}

impl Floor {
    /// (the angles' logging step in degrees, the instrument's accuracy in mm), validated.
    pub fn resolve(&self) -> Result<(Option<f64>, Option<f64>)> {
        if let Some(r) = self.angle_resolution_deg {
            if !(r.is_finite() && r > 0.0 && r <= 10.0) {
                return Err(Error::Invalid(format!("--angle-resolution-deg must be in (0, 10] degrees, got {r}")));
            }
        }
        Ok((self.angle_resolution_deg, instrument_accuracy(self.instrument_accuracy_mm)?))
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
    #[cfg_attr(feature = "clap", arg(long, default_value_t = crate::calib::run::DEFAULT_OUTLIER_K, allow_negative_numbers = true))]
    pub outliers: f64,
    /// Keep out the rows of a run of outliers even when they all sit one constant offset off
    /// (by default such a reading step is corrected and its rows kept).
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_reading_steps: bool,
    /// Least-squares loss of `--method lm`: l2, huber or cauchy (by IRLS, robust scale from the data).
    #[cfg_attr(feature = "clap", arg(long, default_value = "l2"))]
    pub loss: String,
    /// The data's floor and the rows' weights.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub floor: Floor,
}

impl Default for Robust {
    fn default() -> Self {
        Robust { outliers: crate::calib::run::DEFAULT_OUTLIER_K, no_reading_steps: false, loss: "l2".into(), floor: Floor::default() }
    }
}

impl Robust {
    /// (outlier threshold, loss), validated.
    pub fn resolve(&self) -> Result<(f64, Loss)> {
        if !(self.outliers.is_finite() && (self.outliers == 0.0 || (2.0..=100.0).contains(&self.outliers))) {
            return Err(Error::Invalid(format!("--outliers must be 0 (off) or in [2, 100] robust standard deviations, got {}", self.outliers)));
        }
        Ok((self.outliers, Loss::parse(&self.loss)?))
    }
}

/// The `KIND[:JOINT]` items of an option (`--effects`, `--candidates`; `option` names it in
/// errors): a kind, optionally with its joint, 1..N (checked against the data later).
pub fn parse_effects(option: &str, list: &[String]) -> Result<Vec<(EffectKind, Option<usize>)>> {
    // `--effects ,` (or an empty string) names nothing: an option given must name an effect.
    if !list.is_empty() && list.iter().all(|s| s.trim().is_empty()) {
        return Err(Error::Invalid(format!("{option} '{}' names no effect: give KIND[:JOINT] items separated by commas", list.join(","))));
    }
    list.iter().filter(|s| !s.trim().is_empty()).map(|item| parse_effect(option, item)).collect()
}

fn parse_effect(option: &str, item: &str) -> Result<(EffectKind, Option<usize>)> {
    let kind = |k: &str| EffectKind::parse(k).map_err(|e| Error::Invalid(format!("{option} {item}: {e}")));
    let (kind, joint) = match item.split_once(':') {
        Some((k, j)) => {
            let max = crate::dataset::MAX_JOINTS;
            let bad = || Error::Invalid(format!("{option} {item}: the joint after ':' must be a joint number, 1..N"));
            let j: usize = j.trim().parse().map_err(|_| bad())?;
            if !(1..=max).contains(&j) {
                return Err(bad());
            }
            (kind(k)?, Some(j - 1))
        }
        None => (kind(item)?, None),
    };
    let allowed = kind.joint_options(crate::dataset::MAX_JOINTS).contains(&joint) || (joint.is_none() && kind.per_joint());
    if !allowed {
        return Err(Error::Invalid(format!("{option} {item}: {} is not a per-joint effect", kind.name())));
    }
    Ok((kind, joint))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generic6r_takes_no_parametrisation() {
        let spec = |model: &str, params: Option<&str>| ModelChoice { model: model.into(), params: params.map(String::from) }.spec();
        let e = spec("generic6r", Some("dh")).unwrap_err().to_string();
        assert!(e.contains("--params dh"), "{e}");
        assert!(spec("generic6r", None).is_ok());
        assert!(spec("irb120", Some("frame")).is_ok());
    }
}
