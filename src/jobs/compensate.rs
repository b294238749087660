//! `twincal compensate`: the joint commands that make the calibrated arm reach a program's
//! targets ([`crate::compensate`]), written as a CSV whole or not at all.

use crate::calib::run::CalibResult;
use crate::compensate::{commands_csv, nominal_x, read_targets, Compensated, Compensator, Status};
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A compensation as `twincal compensate` runs it; Python's `twincal.compensate` arguments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct CompensateJob {
    /// A result.json written by `calibrate` (or diagnosed.json by `diagnose`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub model: PathBuf,
    /// The program's targets, CSV: columns x, y, z (mm, the robot's base frame), with rx, ry, rz
    /// (degrees, the tool's orientation, `--euler`) for poses, or q1..qN (degrees, joint targets
    /// taught on the nominal model).
    #[cfg_attr(feature = "clap", arg(long))]
    pub targets: PathBuf,
    /// The payload the program runs with, kg (default: the one the calibration stated); it
    /// loads the joints of a model with compliance.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    #[serde(default)]
    pub payload_kg: Option<f64>,
    /// Its centre of mass in the flange frame, mm (x,y,z).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y,Z"))]
    #[serde(default)]
    pub payload_com_mm: Option<Vec<f64>>,
    /// Model residual at which a target counts as reached, mm.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0.001))]
    #[serde(default = "default_tol")]
    pub tol_mm: f64,
    /// Orientation residual at which a pose target counts as reached, degrees.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0.001))]
    #[serde(default = "default_tol")]
    pub tol_deg: f64,
    /// The Euler convention of the targets' (and the commands') rx, ry, rz: capitals for
    /// rotations about the moving axes (intrinsic; XYZ is R = Rx(rx)·Ry(ry)·Rz(rz)), lower case
    /// for the fixed axes (extrinsic; xyz is R = Rz(rz)·Ry(ry)·Rx(rx)).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = crate::measurement::Euler::default()))]
    #[serde(default)]
    pub euler: crate::measurement::Euler,
    /// The commands: per target its point, the compensated joint angles, the status, the
    /// predicted residual and uncompensated error, the filtered Cartesian target and the nominal
    /// command.
    #[cfg_attr(feature = "clap", arg(long, default_value = "commands.csv"))]
    #[serde(default = "default_out")]
    pub out: PathBuf,
}

fn default_tol() -> f64 {
    0.001
}
fn default_out() -> PathBuf {
    PathBuf::from("commands.csv")
}

/// What a compensation did.
#[derive(Clone, Debug, Serialize)]
pub struct CompensateSummary {
    /// Per target, in file order.
    pub targets: Vec<Compensated>,
    /// Targets per status.
    pub reachable: usize,
    /// Targets not reached (limit, singular, unreachable, invalid).
    pub not_reached: usize,
    /// The payload the commands were computed for (mass kg, centre of mass mm), when the model
    /// has load-driven effects.
    pub payload: Option<(f64, [f64; 3])>,
    /// What the user should know (a payload that changes nothing, targets not reached).
    pub warnings: Vec<String>,
}

impl CompensateJob {
    /// Reads the model and the targets, compensates, writes the commands.
    pub fn run(&self) -> Result<CompensateSummary> {
        check_outputs(&[("--model", self.model.clone()), ("--targets", self.targets.clone())], &[("--out", self.out.as_path())])?;
        let r = CalibResult::load(&self.model)?;
        let euler = self.euler;
        let targets = read_targets(&self.targets, r.model.chain.n_joints, euler)?;
        // Taught joint targets lie inside the arm's limits (a radian file read as degrees does not).
        let limits = r.model.joint_limits();
        for (i, t) in targets.iter().enumerate() {
            if let crate::compensate::Target::Joints(q) = t {
                if let Some((j, v)) = q.iter().enumerate().find(|(j, v)| !(limits[*j].0 - 1e-9..=limits[*j].1 + 1e-9).contains(*v)) {
                    return Err(Error::data(
                        self.targets.display(),
                        format!(
                            "target {}: q{} = {} deg is outside the joint's limits [{:.1}, {:.1}] deg",
                            i + 1,
                            j + 1,
                            crate::error::shown(v.to_degrees()),
                            limits[j].0.to_degrees(),
                            limits[j].1.to_degrees()
                        ),
                    ));
                }
            }
        }
        let mut warnings = Vec::new();
        let loads = crate::requests::Loads { payload_kg: self.payload_kg, payload_com_mm: self.payload_com_mm.clone(), ..Default::default() }.resolve()?.joints;
        let mut torque = r.torque_model.clone();
        match (&mut torque, &loads.payload) {
            (Some(tm), Some(p)) => tm.payload = Some((p.mass_kg, p.com_mm.map(crate::units::to_m))),
            (None, Some(_)) => warnings.push("the model has no load-driven effect (no compliance block): --payload-kg changes nothing".into()),
            _ => {}
        }
        let x_nom = nominal_x(&r);
        let payload = torque.as_ref().map(|t| t.payload.map_or((0.0, [0.0; 3]), |(m, c)| (m, c.map(crate::units::to_mm))));
        let c = Compensator::new(&r, &x_nom, torque, self.tol_mm, self.tol_deg)?;
        let solved = c.compensate(&targets);
        let reachable = solved.iter().filter(|s| s.status == Status::Reachable).count();
        if reachable < solved.len() {
            warnings.push(format!("{} of {} targets not reached (see the status column)", solved.len() - reachable, solved.len()));
        }
        if solved.is_empty() {
            return Err(Error::Invalid("no targets".into()));
        }
        let mut outputs = OutputSet::new();
        outputs.write(&self.out, commands_csv(&solved, euler).as_bytes())?;
        outputs.commit()?;
        Ok(CompensateSummary { reachable, not_reached: solved.len() - reachable, targets: solved, payload, warnings })
    }
}
