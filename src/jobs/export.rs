//! `twincal export`: a calibrated model written for a controller or a driver ([`crate::export`]),
//! checked by reading it back before it is written.

use crate::calib::run::{CalibResult, OTHER_ARM_MM};
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use crate::robot::Robot;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// An export as `twincal export` runs it; Python's `twincal.export` keyword arguments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct ExportJob {
    /// A result.json written by `calibrate` (or diagnosed.json by `diagnose`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub model: PathBuf,
    /// The file to write; its extension picks the format when --format is not given (.urdf,
    /// .yaml for the UR driver; .csv and .json need --format: frames, dh or mdh).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// urdf, frames (a per-joint frame table), dh (standard D-H), mdh (modified D-H, Craig) or
    /// ur-yaml (the ROS UR driver's kinematics parameters).
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub format: Option<String>,
    /// The nominal robot the model was calibrated on (irb120 or a URDF path), for what only it
    /// has: the URDF's inertials, joint limits and continuous joints.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub robot: Option<String>,
}

/// What an export wrote.
#[derive(Clone, Debug, Serialize)]
pub struct ExportSummary {
    /// The format's name.
    pub format: String,
    /// The file written.
    pub out: PathBuf,
    /// What the file does not carry of the calibrated model.
    pub warnings: Vec<String>,
    /// The largest difference between the file's tool point, read back, and the model's, over
    /// 64 configurations spread over ±180° per joint, m.
    pub round_trip_m: f64,
}

impl ExportJob {
    /// Writes the file (whole, or not at all), or says why not.
    pub fn run(&self) -> Result<ExportSummary> {
        let format = match &self.format {
            Some(f) => crate::export::format(f)?,
            None => crate::export::format_of_path(&self.out)?,
        };
        let mut inputs: Vec<(&str, PathBuf)> = vec![("--model", self.model.clone())];
        inputs.extend(self.robot.as_deref().and_then(super::files::named_robot_input));
        check_outputs(&inputs, &[("--out", self.out.as_path())])?;
        let result = CalibResult::load(&self.model)?;
        let nominal = self.robot.as_deref().map(super::files::named_robot).transpose()?;
        if let Some(r) = &nominal {
            if r.dof() != result.model.chain.n_joints {
                return Err(Error::Invalid(format!("--robot '{}' has {} joints, the model {}", r.name, r.dof(), result.model.chain.n_joints)));
            }
            let gap = nominal_gap_mm(&result, r);
            if gap > OTHER_ARM_MM {
                return Err(Error::Invalid(format!(
                    "--robot '{}' is not the arm the model was calibrated on: its flange is {gap:.1} mm from the model's nominal flange at the same joint angles",
                    r.name
                )));
            }
        }
        let ext = crate::export::extension(&self.out);
        let exported = crate::export::export(&result, format, &ext, nominal.as_ref())?;
        let back = format.read(&exported.text, &ext)?;
        let round_trip_m = crate::export::round_trip_error(&back, &result.model, &result.x, 64);
        let mut outputs = OutputSet::new();
        outputs.write(&self.out, exported.text.as_bytes())?;
        outputs.commit()?;
        Ok(ExportSummary { format: format.name().into(), out: self.out.clone(), warnings: exported.warnings, round_trip_m })
    }
}

/// The largest distance (mm) between `robot`'s flange and the nominal flange of `r`'s model
/// (its chain at the nominal values) over 32 seeded configurations inside the robot's limits.
/// A model without a nominal arm (`generic6r`) gives 0: there is nothing to compare.
pub(crate) fn nominal_gap_mm(r: &CalibResult, robot: &Robot) -> f64 {
    use rand::{Rng, SeedableRng};
    if r.provenance.model_name.starts_with("generic") {
        return 0.0;
    }
    let x = crate::compensate::nominal_x(r);
    let chain = robot.error_chain();
    let zero = vec![0.0; chain.n_params()];
    let (mut wm, mut wr) = (r.model.work(), crate::robot::kinematics::FkWork::new(&chain));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    (0..32)
        .map(|_| {
            let q: Vec<f64> = robot.limits().iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect();
            chain.forward(&q, &zero, 1.0, &mut wr);
            let theirs = chain.frame(&wr, chain.flange()).pos;
            crate::units::to_mm((r.model.flange_frame(&x, &q, &mut wm).pos - theirs).norm())
        })
        .fold(0.0, f64::max)
}
