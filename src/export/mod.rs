//! A calibrated model written for controllers and drivers, and read back to check it.
//!
//! | format | files | what |
//! |---|---|---|
//! | `urdf` ([`urdf`]) | `.urdf` | one revolute joint per chain joint, the calibrated frames as origins, inertials moved over from the nominal robot |
//! | `frames` ([`frames`]) | `.csv`, `.json` | a generic per-joint frame table: each joint's origin in its parent link (x, y, z mm; roll, pitch, yaw degrees, URDF's convention) and its axis, then the flange and the tool point |
//! | `dh`, `mdh` ([`dh`]) | `.csv`, `.json` | a standard (Denavit–Hartenberg) or modified (Craig) D-H table with the base and tool transforms it needs to be exact |
//! | `ur-yaml` ([`ur_yaml`]) | `.yaml` | the kinematics parameters file the ROS UR driver and `ur_description` load (per joint x, y, z, roll, pitch, yaw) |
//!
//! Every format is exact: its forward kinematics, read back from the file by [`ExportFormat::read`]
//! into the crate's one [`Chain`], gives the calibrated model's tool point to rounding (the tests
//! hold it to 1e-9 m on 1 000 random configurations of a UR5, a UR10 and an IRB 120). What a
//! format cannot carry (the model's non-geometric effect blocks, a learned corrector, a UR
//! flange that is off joint 6's axis) is named in [`Exported::warnings`], never dropped
//! silently. Adding a format means one module implementing [`ExportFormat`] and its line in
//! [`FORMATS`].

pub mod dh;
pub mod frames;
pub mod ur_yaml;
pub mod urdf;

#[cfg(test)]
mod tests;

use crate::calib::model::CalibModel;
use crate::calib::pipeline::CalibResult;
use crate::error::{Error, Result};
use crate::robot::kinematics::{Chain, FkWork, Frame};
use crate::robot::Robot;
use nalgebra::Vector3;

/// The calibrated kinematics every format writes: the model's chain at zero joint angles.
#[derive(Clone, Debug)]
pub struct JointTable {
    /// Each joint's frame at zero joint angles (the frame right after its rotation, joint zero
    /// offsets folded in), base frame.
    pub frames: Vec<Frame>,
    /// Each joint's axis in its own frame (a unit vector; the positive sense of its angle).
    pub axes: Vec<Vector3<f64>>,
    /// The flange at zero joint angles, base frame.
    pub flange: Frame,
    /// The tool point (the instrument's target: the cable's hook, the reflector, the probe's
    /// origin) in the flange frame, m.
    pub tcp: Vector3<f64>,
}

/// Link frames of a calibrated chain at zero joint angles: the frame right after each joint
/// rotation, each joint's axis in it, and the flange.
pub(crate) fn joint_frames(model: &CalibModel, x: &[f64]) -> (Vec<Frame>, Vec<Vector3<f64>>, Frame) {
    let chain = &model.chain;
    let mut ws = FkWork::new(chain);
    chain.forward(&vec![0.0; chain.n_joints], &x[..model.n_chain()], 1.0, &mut ws);
    let mut frames = Vec::new();
    let mut axes = Vec::new();
    for j in 0..chain.n_joints {
        let k = chain.joint_op(j).expect("every joint has an op");
        frames.push(ws.pre[k + 1]);
        axes.push(chain.ops[k].axis);
    }
    (frames, axes, chain.frame(&ws, chain.flange()))
}

impl JointTable {
    /// The table of calibrated model `model` at parameters `x`.
    pub fn of(model: &CalibModel, x: &[f64]) -> JointTable {
        let (frames, axes, flange) = joint_frames(model, x);
        JointTable { frames, axes, flange, tcp: model.placement(x).tool }
    }
    /// Number of joints.
    pub fn n_joints(&self) -> usize {
        self.frames.len()
    }
    /// Joint `j`'s axis as a line in the base frame at zero angles: a point on it and its unit
    /// direction.
    pub fn axis_line(&self, j: usize) -> (Vector3<f64>, Vector3<f64>) {
        (self.frames[j].pos, (self.frames[j].rot * self.axes[j]).normalize())
    }
}

/// A file read back: the chain it describes (no parameters) and the tool point on its flange.
#[derive(Clone, Debug)]
pub struct ReadBack {
    /// The kinematic chain the file states, from the robot's base frame to the flange.
    pub chain: Chain,
    /// Its parameters' values (zeros for a chain whose operations hold the file's values).
    pub params: Vec<f64>,
    /// The tool point in the flange frame, m.
    pub tcp: Vector3<f64>,
}

impl ReadBack {
    /// The tool point at joint angles `q` (rad), base frame, m.
    pub fn tool_point(&self, q: &[f64]) -> Vector3<f64> {
        self.chain.point(q, &self.params, 1.0, self.chain.flange(), &self.tcp)
    }
}

impl ReadBack {
    /// The read-back of a chain whose operations hold every value (no parameters).
    pub fn of_chain(chain: Chain, tcp: Vector3<f64>) -> ReadBack {
        ReadBack { params: vec![0.0; chain.n_params()], chain, tcp }
    }
}

/// A rigid transform as the files state it: a translation in mm and URDF roll, pitch, yaw in
/// degrees (R = Rz(yaw)·Ry(pitch)·Rx(roll)).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose6 {
    /// x, y, z, mm.
    pub xyz_mm: [f64; 3],
    /// Roll, pitch, yaw, degrees.
    pub rpy_deg: [f64; 3],
}

impl Pose6 {
    /// The file's statement of frame `f`.
    pub fn of(f: &Frame) -> Pose6 {
        Pose6 { xyz_mm: crate::units::to_mm(f.pos).into(), rpy_deg: crate::robot::kinematics::rpy(&f.rot).map(f64::to_degrees) }
    }
    /// Appends the transform to a chain being built.
    pub fn build(&self, b: &mut crate::robot::kinematics::ChainBuilder) {
        b.origin(self.xyz_mm.map(crate::units::to_m), self.rpy_deg.map(f64::to_radians));
    }
    /// An error naming `what` unless every value is finite.
    pub fn check(&self, what: &str) -> Result<()> {
        match self.xyz_mm.iter().chain(&self.rpy_deg).find(|v| !v.is_finite()) {
            Some(v) => Err(Error::Invalid(format!("{what} holds {v}: every value must be a finite number"))),
            None => Ok(()),
        }
    }
}

/// One export format.
pub trait ExportFormat: Sync {
    /// The name `--format` takes.
    fn name(&self) -> &'static str;
    /// What it is, for `--help` and messages.
    fn describe(&self) -> &'static str;
    /// The file extensions it writes, the first the default (a format with several writes by
    /// the one the output's name ends with).
    fn extensions(&self) -> &'static [&'static str];
    /// The file's text for `table` (`nominal`: the robot the model was built on, for what only
    /// it has, such as inertials and limits), and what it does not carry, in `warnings`; or why
    /// this format cannot hold the model (a UR file for an arm that has not six joints).
    fn write(&self, table: &JointTable, model: &CalibModel, x: &[f64], nominal: Option<&Robot>, ext: &str, warnings: &mut Vec<String>) -> Result<String>;
    /// The kinematics a file of this format states (the check of an export, or a file from
    /// elsewhere), or what is wrong with it.
    fn read(&self, text: &str, ext: &str) -> Result<ReadBack>;
}

/// Every export format, in `--help` order.
pub const FORMATS: &[&dyn ExportFormat] = &[&urdf::Urdf, &frames::Frames, &dh::Dh::STANDARD, &dh::Dh::MODIFIED, &ur_yaml::UrYaml];

/// The format called `name` (any case), or an error listing them.
pub fn format(name: &str) -> Result<&'static dyn ExportFormat> {
    FORMATS.iter().copied().find(|f| f.name().eq_ignore_ascii_case(name.trim())).ok_or_else(|| {
        Error::Invalid(format!("unknown export format '{name}' (expected one of {})", FORMATS.iter().map(|f| f.name()).collect::<Vec<_>>().join(", ")))
    })
}

/// The format whose extensions include `path`'s, for an output named without `--format`.
pub fn format_of_path(path: &std::path::Path) -> Result<&'static dyn ExportFormat> {
    let ext = extension(path);
    let candidates: Vec<&dyn ExportFormat> = FORMATS.iter().copied().filter(|f| f.extensions().contains(&ext.as_str())).collect();
    match candidates.as_slice() {
        [one] => Ok(*one),
        [] => Err(Error::Invalid(format!("cannot tell the export format from '{}': give --format", path.display()))),
        many => {
            Err(Error::Invalid(format!("'{}' could be any of {}: give --format", path.display(), many.iter().map(|f| f.name()).collect::<Vec<_>>().join(", "))))
        }
    }
}

/// The lower-case extension of `path` ("" without one).
pub fn extension(path: &std::path::Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// A written export: the file's text and what the format did not carry.
#[derive(Clone, Debug)]
pub struct Exported {
    /// The file's text.
    pub text: String,
    /// What the file does not carry of the calibrated model, one sentence each.
    pub warnings: Vec<String>,
}

/// Writes `result`'s calibrated model as `format` (a file ending in `ext`), checks it by reading
/// it back (its tool point equal to the model's on configurations spread over ±π, to 1e-9 m),
/// and names what it does not carry.
pub fn export(result: &CalibResult, format: &dyn ExportFormat, ext: &str, nominal: Option<&Robot>) -> Result<Exported> {
    if !format.extensions().contains(&ext) {
        return Err(Error::Invalid(format!("a {} file ends in .{}, not '.{ext}'", format.name(), format.extensions().join(" or ."))));
    }
    let table = JointTable::of(&result.model, &result.x);
    let mut warnings = not_carried(result);
    let text = format.write(&table, &result.model, &result.x, nominal, ext, &mut warnings)?;
    let worst = round_trip_error(&format.read(&text, ext)?, &result.model, &result.x, 64);
    if !(worst <= ROUND_TRIP_TOL_M) {
        return Err(Error::Invalid(format!(
            "the {} export does not reproduce the model (off by {worst:e} m): not written{}",
            format.name(),
            if format.name().ends_with("dh") { " (a D-H table of nearly parallel axes is ill-conditioned: write a frame table or a URDF)" } else { "" }
        )));
    }
    Ok(Exported { text, warnings })
}

/// Largest difference between an export read back and the model's tool point, m.
pub const ROUND_TRIP_TOL_M: f64 = 1e-9;

/// The largest distance (m) between `back`'s tool point and the model's kinematic one (its
/// chain at the calibrated parameters, without the effect blocks no kinematic file holds) over
/// `n` joint configurations spread over ±π (a fixed low-discrepancy sequence).
pub fn round_trip_error(back: &ReadBack, model: &CalibModel, x: &[f64], n: usize) -> f64 {
    let dof = model.chain.n_joints;
    if back.chain.n_joints != dof {
        return f64::INFINITY;
    }
    let (c, tcp) = (&model.chain, model.placement(x).tool);
    (0..n)
        .map(|i| {
            // A Weyl sequence: the fractional parts of i·√p over the first primes.
            let q: Vec<f64> = (0..dof).map(|j| std::f64::consts::PI * (2.0 * ((i + 1) as f64 * PRIMES[j % PRIMES.len()].sqrt()).fract() - 1.0)).collect();
            (back.tool_point(&q) - c.point(&q, &x[..model.n_chain()], 1.0, c.flange(), &tcp)).norm()
        })
        .fold(0.0, f64::max)
}

const PRIMES: [f64; 8] = [2.0, 3.0, 5.0, 7.0, 11.0, 13.0, 17.0, 19.0];

/// What a kinematic export does not carry of `result`: its effect blocks and its corrector.
pub fn not_carried(result: &CalibResult) -> Vec<String> {
    let mut out: Vec<String> =
        result.model.effects.iter().map(|b| format!("{} is not carried (a kinematic file has no place for a non-geometric effect)", b.label())).collect();
    if let Some(c) = &result.corrector {
        out.push(format!("the learned {} corrector is not carried (a kinematic file has no place for it)", c.name()));
    }
    out
}
