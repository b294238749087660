//! `twincal controller-data`: what a controller that takes no new kinematic model can be given
//! of a calibration ([`crate::controller::ControllerData`]), as RAPID, KRL or URScript data.

use crate::calib::pipeline::CalibResult;
use crate::controller::{ControllerData, Language};
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A controller data file as `twincal controller-data` writes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct ControllerDataJob {
    /// A result.json of `calibrate --controller-subset`.
    #[cfg_attr(feature = "clap", arg(long))]
    pub model: PathBuf,
    /// rapid (a module of tooldata, wobjdata and the joint offsets), krl (a data list of FRAMEs
    /// for TOOL_DATA and BASE_DATA, and the offsets) or urscript (set_tcp and the instrument's
    /// frame).
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    pub format: Language,
    /// The tool's mass, kg, where the calibration states no payload (RAPID's tooldata needs one).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    #[serde(default)]
    pub tool_mass_kg: Option<f64>,
    /// A full calibration of the same rows (`calibrate` with the same --data, --seed and
    /// --test-fraction, without --controller-subset): its held-out RMSE is reported beside the
    /// subset's and the nominal model's.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub full: Option<PathBuf>,
    /// The arm's URDF (or irb120), whose links `base` and `tool0` are the controller's base and
    /// flange frames: the tool is written in tool0, the instrument's frame in the base frame
    /// (default: the model's flange and base frames are the controller's).
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub robot: Option<crate::robot::RobotChoice>,
    /// The file to write (.mod, .dat or .script); its stem names the module or data list.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
}

/// A subset's accuracy on its calibration's held-out rows, beside the nominal model's and a full
/// calibration's of the same rows (RMSE per value, mm).
#[derive(Clone, Debug, Serialize)]
pub struct HeldOut {
    /// Held-out rows.
    pub rows: usize,
    /// The nominal model's RMSE on them.
    pub nominal_rmse_mm: f64,
    /// The controller subset's.
    pub subset_rmse_mm: f64,
    /// The full calibration's, where `--full` names one.
    pub full_rmse_mm: Option<f64>,
}

impl HeldOut {
    /// The held-out figures of `subset` (and `full`, which must be a calibration of the same data
    /// file with the same held-out rows); `None` for a calibration without held-out rows.
    fn of(subset: &CalibResult, full: Option<&CalibResult>) -> Result<Option<HeldOut>> {
        let m = &subset.evaluation.metrics;
        let (Some(before), Some(after)) = (&m.test_before, &m.test_after) else { return Ok(None) };
        let full_rmse_mm = match full {
            None => None,
            Some(f) => {
                let (a, b) = (&subset.provenance, &f.provenance);
                if a.data_sha256 != b.data_sha256 || a.test_rows != b.test_rows || a.test_rows.is_empty() {
                    return Err(Error::Invalid(format!(
                        "--full was not calibrated on the same rows as --model (data {} / {}, {} / {} held-out rows, the same ones: {}): calibrate both with the same --data, --seed and --test-fraction",
                        a.data,
                        b.data,
                        a.test_rows.len(),
                        b.test_rows.len(),
                        a.test_rows == b.test_rows
                    )));
                }
                // A subset beside itself (or beside another subset) is no comparison.
                if crate::controller::ControllerData::of(f).is_ok() {
                    return Err(Error::Invalid(
                        "--full names a calibration of the controller subset, not a full one: give `calibrate`'s result without --controller-subset on the same rows".into(),
                    ));
                }
                Some(f.evaluation.metrics.test_after.as_ref().map_or(f64::NAN, |t| t.rmse))
            }
        };
        Ok(Some(HeldOut { rows: subset.provenance.n_test, nominal_rmse_mm: before.rmse, subset_rmse_mm: after.rmse, full_rmse_mm }))
    }

    /// In words, for the data file's header.
    fn words(&self) -> String {
        let full = self.full_rmse_mm.map_or(String::new(), |f| format!(", the full calibration {f:.4} mm"));
        format!(
            "On the calibration's {} held-out rows (RMSE): nominal {:.4} mm, this subset {:.4} mm{full}.",
            self.rows, self.nominal_rmse_mm, self.subset_rmse_mm
        )
    }
}

/// What `controller-data` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct ControllerDataSummary {
    /// The file written.
    pub out: PathBuf,
    /// The joint zero offsets, degrees.
    pub joint_offsets_deg: Vec<(String, f64)>,
    /// The tool point in the flange frame (tool0 with `--robot`), mm.
    pub tool_mm: [f64; 3],
    /// What the subset leaves on the held-out rows, beside the nominal and the full model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOut>,
}

impl ControllerDataJob {
    /// Reads the calibration and writes the file, whole or not at all.
    pub fn run(&self) -> Result<ControllerDataSummary> {
        let mut inputs = vec![("--model", self.model.clone())];
        inputs.extend(self.full.iter().map(|f| ("--full", f.clone())));
        inputs.extend(self.robot.as_ref().and_then(crate::jobs::files::named_robot_input));
        check_outputs(&inputs, &[("--out", self.out.as_path())])?;
        if let Some(m) = self.tool_mass_kg.filter(|m| !(m.is_finite() && *m > 0.0 && *m <= crate::dataset::MAX_PAYLOAD_KG)) {
            return Err(Error::Invalid(format!("--tool-mass-kg must be in (0, {}] kg, got {m}", crate::dataset::MAX_PAYLOAD_KG)));
        }
        let want = self.format.data_extension();
        let name = self.out.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        if self.out.extension().and_then(|e| e.to_str()) != Some(want) {
            return Err(Error::Invalid(format!("--out {}: a {} data file is a .{want}", self.out.display(), self.format.name())));
        }
        let r = CalibResult::load(&self.model)?;
        let full = self.full.as_deref().map(CalibResult::load).transpose()?;
        let held_out = HeldOut::of(&r, full.as_ref())?;
        let mut data = ControllerData::of(&r)?;
        if let Some(robot) = self.robot.as_ref().map(crate::robot::RobotChoice::load).transpose()? {
            let (base, tool0) = robot.controller_frames();
            data = data.in_controller_frames(&base, &tool0);
        }
        data.accuracy = held_out.as_ref().map(HeldOut::words);
        let file = data.write(self.format, name, self.tool_mass_kg, &self.model.display().to_string())?;
        let mut outputs = OutputSet::new();
        outputs.write(&self.out, file.text.as_bytes())?;
        outputs.commit()?;
        Ok(ControllerDataSummary { out: self.out.clone(), joint_offsets_deg: data.joint_offsets_deg, tool_mm: data.tool_mm.into(), held_out })
    }
}
