//! `twincal program`: a pose list (`plan`'s poses.csv, or any list `generate --poses` reads)
//! written as a measurement program the controller runs as it is ([`crate::controller`]).

use crate::controller::{Language, Tour, DEFAULT_HOLD_S, DEFAULT_SPEED_FRACTION};
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A measurement program as `twincal program` writes it; Python's `twincal.program` arguments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct ProgramJob {
    /// The pose list: a header `q1..qN` (degrees) and optionally `payload_kg`, one pose per row
    /// in the order to measure them.
    #[cfg_attr(feature = "clap", arg(long))]
    pub poses: PathBuf,
    /// The language: rapid (NAME.mod), krl (NAME.src and NAME.dat) or urscript (NAME.script).
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    pub format: Language,
    /// The robot whose joint limits the poses must lie within: irb120 or a URDF path.
    #[cfg_attr(feature = "clap", arg(long, default_value_t))]
    #[serde(default)]
    pub robot: crate::robot::RobotChoice,
    /// The program's name (a letter, then letters, digits and '_').
    #[cfg_attr(feature = "clap", arg(long, default_value = "twincal_tour"))]
    #[serde(default = "default_name")]
    pub name: String,
    /// Seconds the arm holds still at each pose before the program waits for the measurement.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DEFAULT_HOLD_S, allow_negative_numbers = true))]
    #[serde(default = "default_hold_s")]
    pub hold_s: f64,
    /// Joint speed of the moves, a fraction of each joint's maximum.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DEFAULT_SPEED_FRACTION, allow_negative_numbers = true))]
    #[serde(default = "default_speed")]
    pub speed_fraction: f64,
    /// Folder to write the program's files in.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
}

fn default_name() -> String {
    "twincal_tour".into()
}
fn default_hold_s() -> f64 {
    DEFAULT_HOLD_S
}
fn default_speed() -> f64 {
    DEFAULT_SPEED_FRACTION
}

/// What `program` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct ProgramSummary {
    /// The language.
    pub format: Language,
    /// The files written.
    pub files: Vec<PathBuf>,
    /// Poses in the program.
    pub poses: usize,
}

impl ProgramJob {
    /// Reads the pose list and writes the program, whole or not at all.
    pub fn run(&self) -> Result<ProgramSummary> {
        if self.out.exists() && !self.out.is_dir() {
            return Err(Error::Invalid(format!("--out {} is a file; program writes a folder", self.out.display())));
        }
        let robot = self.robot.load()?;
        let files: Vec<PathBuf> = self.format.file_names(&self.name).iter().map(|n| self.out.join(n)).collect();
        let mut inputs = vec![("--poses", self.poses.clone())];
        inputs.extend(super::files::named_robot_input(&self.robot));
        let outs: Vec<(&str, &std::path::Path)> = files.iter().map(|p| ("--out", p.as_path())).collect();
        check_outputs(&inputs, &outs)?;
        let list = crate::sim::pose_list::read_pose_list(&self.poses, &robot)?;
        let tour = Tour {
            name: self.name.clone(),
            q: list.q,
            payload_kg: list.payload_kg,
            hold_s: self.hold_s,
            speed_fraction: self.speed_fraction,
            about: vec![format!("Poses of {} for {}.", self.poses.display(), robot.name)],
        };
        let program = self.format.measurement_program(&tour)?;
        let mut outputs = OutputSet::new();
        for (f, path) in program.iter().zip(&files) {
            outputs.write(path, f.text.as_bytes())?;
        }
        outputs.commit()?;
        Ok(ProgramSummary { format: self.format, files, poses: tour.q.len() })
    }
}
