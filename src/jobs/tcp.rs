//! `twincal tcp` and `twincal user-frame`: the tool's own routines on files — the N-point TCP of
//! configurations holding the tool's tip at a fixed point, and the 3-point user frame touched
//! with the tool — on the nominal arm or a calibration's ([`crate::tcp`]).

use crate::dataset::{AngleUnit, Dataset, ReadOptions};
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use crate::robot::kinematics::Frame;
use crate::tcp::{TcpFit, UserFrame};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The arm the routines read the flange of: a calibration (`--model`) or a nominal robot.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct ArmChoice {
    /// A calibration result (result.json): its arm, geometry and joint offsets (the rows carry
    /// no load, so load-driven effects read none).
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub model: Option<PathBuf>,
    /// Without --model: the nominal robot, irb120 or a URDF path.
    #[cfg_attr(feature = "clap", arg(long, default_value_t))]
    #[serde(default)]
    pub robot: crate::robot::RobotChoice,
}

impl ArmChoice {
    /// The files it reads, by option.
    fn inputs(&self) -> Vec<(&'static str, PathBuf)> {
        match &self.model {
            Some(m) => vec![("--model", m.clone())],
            None => super::files::named_robot_input(&self.robot).into_iter().collect(),
        }
    }
    /// The flange frames of `data`'s rows on the arm.
    fn flanges(&self, data: &Dataset) -> Result<Vec<Frame>> {
        let (model, x) = match &self.model {
            Some(m) => {
                let r = crate::calib::pipeline::CalibResult::load(m)?;
                (r.model, r.x)
            }
            None => {
                let robot = self.robot.load()?;
                let guess = crate::calib::model::DrawWireGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
                let m = crate::calib::model::CalibModel::dh(&robot, &guess, true);
                let x = m.nominal.clone();
                (m, x)
            }
        };
        data.require_joints(model.chain.n_joints, &format!("the arm ({})", model.name))?;
        let mut w = model.work();
        Ok(data.rows.iter().map(|r| model.flange_frame(&x, &r.q_deg.iter().map(|d| d.to_radians()).collect::<Vec<_>>(), &mut w)).collect())
    }
}

/// Reads joint angles (`q1..qN`, optionally a `socket` column naming each row's fixed point).
fn read_joints(path: &Path, angles: AngleUnit) -> Result<Dataset> {
    let data = Dataset::load_with(path, &ReadOptions { angles, require_length: false, ..Default::default() })?;
    if let Some(m) = data.rows.first().and_then(|r| Measurement::of_file_dim(r.reading_mm.len())) {
        return Err(Error::data(&data.source, format!("the routine reads joint angles only; this file holds a {} too", m.def().describe())));
    }
    Ok(data)
}

use crate::measurement::Measurement;

/// Refuses an `--out` over a file the routine reads (`inputs`, and the arm's).
fn check(mut inputs: Vec<(&'static str, PathBuf)>, arm: &ArmChoice, out: &Option<PathBuf>) -> Result<()> {
    inputs.extend(arm.inputs());
    let outs: Vec<(&str, &Path)> = out.iter().map(|p| ("--out", p.as_path())).collect();
    check_outputs(&inputs, &outs)
}

/// Writes `value` as JSON to `out`, whole or not at all (nothing without `--out`).
fn write<T: Serialize>(out: &Option<PathBuf>, value: &T) -> Result<()> {
    if let Some(p) = out {
        let mut set = OutputSet::new();
        set.write_json(p, value)?;
        set.commit()?;
    }
    Ok(())
}

/// `twincal tcp`: the N-point TCP; Python's `twincal.tcp` arguments.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct TcpJob {
    /// The configurations: joint angles q1..qN, one row each with the tool's tip at the fixed
    /// point (a `socket` column names the point where there are several).
    #[cfg_attr(feature = "clap", arg(long))]
    pub data: PathBuf,
    /// Unit of the joint angles.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = AngleUnit::Auto))]
    #[serde(default)]
    pub angles: AngleUnit,
    /// The arm.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub arm: ArmChoice,
    /// Write the tool point and its accuracy as JSON here.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub out: Option<PathBuf>,
    /// The tool's orientation too (the 6-point routine, ABB's "TCP and Z, X"): the file's last
    /// two rows are the elongators, the tool moved without turning from the last configuration
    /// at the fixed point until that point lies on the tool's +z axis, then on its +x axis.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub orientation: bool,
}

impl TcpJob {
    /// Reads the configurations, fits the tool and writes `--out`, whole or not at all.
    pub fn run(&self) -> Result<TcpFit> {
        check(vec![("--data", self.data.clone())], &self.arm, &self.out)?;
        let data = read_joints(&self.data, self.angles)?;
        let mut flanges = self.arm.flanges(&data)?;
        let elongators = if self.orientation {
            if flanges.len() < crate::tcp::MIN_TCP_ROWS + 2 {
                return Err(Error::Calibration(format!(
                    "--orientation reads the last two rows as the z and x elongators: {} rows leave fewer than {} at the fixed point",
                    flanges.len(),
                    crate::tcp::MIN_TCP_ROWS
                )));
            }
            Some(flanges.split_off(flanges.len() - 2))
        } else {
            None
        };
        let points = crate::dataset::Stations::of_labels(data.rows[..flanges.len()].iter().map(|r| r.socket()));
        let mut fit = crate::tcp::tcp(&flanges, &points.of_row, &points.labels)?;
        if let Some(e) = elongators {
            let tool = crate::units::to_m(Vector3::from(fit.tool_mm));
            let sd = fit.tool_sd_mm.iter().map(|v| v * v).sum::<f64>().sqrt();
            fit.orientation = Some(crate::tcp::tool_orientation(flanges.last().expect("rows at the fixed point"), &e[0], &e[1], &tool, sd)?);
        }
        write(&self.out, &fit)?;
        Ok(fit)
    }
}

/// `twincal user-frame`: the 3-point user frame; Python's `twincal.user_frame` arguments.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct UserFrameJob {
    /// The three configurations, in order: the tip at the frame's origin, at a point on its +x
    /// axis, at a point on its xy plane (+y side); joint angles q1..qN.
    #[cfg_attr(feature = "clap", arg(long))]
    pub data: PathBuf,
    /// Unit of the joint angles.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = AngleUnit::Auto))]
    #[serde(default)]
    pub angles: AngleUnit,
    /// The tool's tip on the flange: `tcp`'s result file (tcp.json), whose uncertainty the frame
    /// is judged with.
    #[cfg_attr(feature = "clap", arg(long))]
    pub tcp: PathBuf,
    /// The arm.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub arm: ArmChoice,
    /// Write the frame as JSON here.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub out: Option<PathBuf>,
}

impl UserFrameJob {
    /// Reads the three configurations and the tool, and writes `--out`, whole or not at all.
    pub fn run(&self) -> Result<UserFrame> {
        check(vec![("--data", self.data.clone()), ("--tcp", self.tcp.clone())], &self.arm, &self.out)?;
        let text = std::fs::read_to_string(&self.tcp).map_err(|e| Error::io(&self.tcp, e))?;
        let tool: TcpFit = serde_json::from_str(&text).map_err(|e| Error::data(self.tcp.display(), format!("not a tcp result file: {e}")))?;
        if tool.tool_mm.iter().chain(&tool.tool_sd_mm).any(|v| !v.is_finite()) {
            return Err(Error::data(self.tcp.display(), "the tool point holds a number that is not finite"));
        }
        let data = read_joints(&self.data, self.angles)?;
        if data.rows.len() != 3 {
            return Err(Error::data(
                &data.source,
                format!("{} rows: the user frame is touched at three points (origin, +x, xy plane), one row each", data.rows.len()),
            ));
        }
        let flanges = self.arm.flanges(&data)?;
        let t = crate::units::to_m(Vector3::from(tool.tool_mm));
        let tips: Vec<Vector3<f64>> = flanges.iter().map(|f| f.point(&t)).collect();
        let sd = tool.tool_sd_mm.iter().map(|s| s * s).sum::<f64>().sqrt().max(tool.rms_mm);
        let frame = crate::tcp::user_frame(&tips[0], &tips[1], &tips[2], sd)?;
        write(&self.out, &frame)?;
        Ok(frame)
    }
}
