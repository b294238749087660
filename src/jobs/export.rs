//! `twincal export`: a calibrated model written for a controller or a driver ([`crate::export`]),
//! checked by reading it back before it is written.

use crate::calib::pipeline::{CalibResult, OTHER_ARM_MM};
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
    pub robot: Option<crate::robot::RobotChoice>,
    /// Another kinematics file of the same format (the maker's calibration: a UR's
    /// calibration.yaml) to compare with, joint by joint: how far each joint's frame, placed in
    /// its parent's, lies from the file's.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub against: Option<PathBuf>,
}

/// How far one joint's frame lies from another file's, each placed in its parent joint's frame
/// at zero joint angles.
#[derive(Clone, Debug, Serialize)]
pub struct JointGap {
    /// The joint (1-based).
    pub joint: usize,
    /// Distance between the two frames' origins, mm.
    pub position_mm: f64,
    /// Angle between the two frames' orientations, degrees.
    pub rotation_deg: f64,
}

/// Joint by joint, how far the frames of `a` lie from those of `b` (the same number of joints),
/// each in its parent's frame at zero joint angles; then the flange's.
fn joint_gaps(a: &crate::export::ReadBack, b: &crate::export::ReadBack) -> Vec<JointGap> {
    use crate::robot::kinematics::FkWork;
    let local = |r: &crate::export::ReadBack| {
        let mut fk = FkWork::new(&r.chain);
        r.chain.forward(&vec![0.0; r.chain.n_joints], &r.params, 1.0, &mut fk);
        (1..r.chain.n_frames()).map(|f| r.chain.frame(&fk, f).relative_to(&r.chain.frame(&fk, f - 1))).collect::<Vec<_>>()
    };
    local(a)
        .iter()
        .zip(local(b))
        .enumerate()
        .map(|(j, (fa, fb))| JointGap {
            joint: j + 1,
            position_mm: crate::units::to_mm((fa.pos - fb.pos).norm()),
            rotation_deg: crate::ik::solver::turn(&fa.rot, &fb.rot).norm().to_degrees(),
        })
        .collect()
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
    /// With `--against`: joint by joint (then the flange), how far the written file's frames lie
    /// from the other file's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub against: Option<Vec<JointGap>>,
}

impl ExportJob {
    /// Writes the file (whole, or not at all), or says why not.
    pub fn run(&self) -> Result<ExportSummary> {
        let format = match &self.format {
            Some(f) => crate::export::format(f)?,
            None => crate::export::format_of_path(&self.out)?,
        };
        let mut inputs: Vec<(&str, PathBuf)> = vec![("--model", self.model.clone())];
        inputs.extend(self.robot.as_ref().and_then(super::files::named_robot_input));
        inputs.extend(self.against.iter().map(|p| ("--against", p.clone())));
        check_outputs(&inputs, &[("--out", self.out.as_path())])?;
        let result = CalibResult::load(&self.model)?;
        let nominal = self.robot.as_ref().map(crate::robot::RobotChoice::load).transpose()?;
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
        let against = match &self.against {
            None => None,
            Some(p) => {
                let text = std::fs::read_to_string(p).map_err(|e| Error::io(p, e))?;
                let other =
                    format.read(&text, &crate::export::extension(p)).map_err(|e| Error::data(p.display(), format!("not a {} file: {e}", format.name())))?;
                if other.chain.n_joints != back.chain.n_joints || other.chain.n_frames() != back.chain.n_frames() {
                    return Err(Error::data(p.display(), format!("states {} joints, the model {}", other.chain.n_joints, back.chain.n_joints)));
                }
                Some(joint_gaps(&back, &other))
            }
        };
        let mut outputs = OutputSet::new();
        outputs.write(&self.out, exported.text.as_bytes())?;
        outputs.commit()?;
        Ok(ExportSummary { format: format.name().into(), out: self.out.clone(), warnings: exported.warnings, round_trip_m, against })
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
