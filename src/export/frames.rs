//! The generic per-joint frame table (CSV or JSON): each joint's origin in its parent link's
//! frame at zero joint angles and the axis it turns about, then the flange in the last link's
//! frame and the tool point on the flange. It is the URDF's kinematics as a table, the form most
//! controllers' "frame per axis" inputs take.
//!
//! CSV: `#` lines say the convention; one row per joint (`name, parent, x_mm, y_mm, z_mm,
//! roll_deg, pitch_deg, yaw_deg, axis_x, axis_y, axis_z`), then `flange` (no axis) and `tcp`
//! (x, y, z only). JSON: the same as `joints`, `flange` and `tcp_mm`, with the units, the
//! convention and what the file does not carry.

use super::{ExportFormat, JointTable, Pose6, ReadBack};
use crate::calib::model::CalibModel;
use crate::error::{Error, Result};
use crate::robot::kinematics::{ChainBuilder, Frame};
use crate::robot::Robot;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::fmt::Write;

/// The convention, as both files state it.
pub const CONVENTION: &str = "link j's frame = link (j-1)'s frame * origin_j * Rot(axis_j, q_j), link 0 the robot's base frame; origin = Trans(x, y, z) * Rz(yaw) * Ry(pitch) * Rx(roll) (URDF's); the flange = link n's frame * flange; the tool point in the flange frame";

/// One joint of the table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointRow {
    /// The joint's name.
    pub name: String,
    /// Its origin in the parent link's frame.
    #[serde(flatten)]
    pub origin: Pose6,
    /// The axis it turns about, in its own frame (unit vector).
    pub axis: [f64; 3],
}

/// The JSON file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameFile {
    /// What the file is.
    pub format: String,
    /// How the values compose.
    pub convention: String,
    /// The joints, base to flange.
    pub joints: Vec<JointRow>,
    /// The flange in the last link's frame.
    pub flange: Pose6,
    /// The tool point in the flange frame, mm.
    pub tcp_mm: [f64; 3],
    /// What the file does not carry of the calibrated model.
    #[serde(default)]
    pub not_carried: Vec<String>,
}

/// The name `format` holds in a frame table's JSON.
pub const FORMAT_NAME: &str = "twincal frame table";

impl FrameFile {
    /// The table of `t`.
    pub fn of(t: &JointTable, warnings: &[String]) -> FrameFile {
        let mut parent = Frame::identity();
        let joints = (0..t.n_joints())
            .map(|j| {
                let row = JointRow { name: format!("joint_{}", j + 1), origin: Pose6::of(&t.frames[j].relative_to(&parent)), axis: t.axes[j].into() };
                parent = t.frames[j];
                row
            })
            .collect();
        FrameFile {
            format: FORMAT_NAME.into(),
            convention: CONVENTION.into(),
            joints,
            flange: Pose6::of(&t.flange.relative_to(&parent)),
            tcp_mm: crate::units::to_mm(t.tcp).into(),
            not_carried: warnings.to_vec(),
        }
    }

    /// The chain and tool point the table states, or the first value that is not a number.
    pub fn read_back(&self) -> Result<ReadBack> {
        let mut b = ChainBuilder::new();
        for (j, row) in self.joints.iter().enumerate() {
            row.origin.check(&format!("joint {} ('{}')", j + 1, row.name))?;
            let axis = Vector3::from(row.axis);
            if !(axis.iter().all(|v| v.is_finite()) && (axis.norm() - 1.0).abs() < 1e-6) {
                return Err(Error::Invalid(format!("joint {} ('{}'): its axis {:?} is not a unit vector", j + 1, row.name, row.axis)));
            }
            row.origin.build(&mut b);
            b.joint(axis, 0.0, None);
        }
        self.flange.check("the flange")?;
        self.flange.build(&mut b);
        if let Some(v) = self.tcp_mm.iter().find(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!("the tool point holds {v}: every value must be a finite number")));
        }
        if self.joints.is_empty() {
            return Err(Error::Invalid("the frame table has no joints".into()));
        }
        Ok(ReadBack::of_chain(b.finish(), crate::units::to_m(Vector3::from(self.tcp_mm))))
    }

    /// The CSV text.
    pub fn csv(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "# {FORMAT_NAME} written by twincal {}: {CONVENTION}", env!("CARGO_PKG_VERSION"));
        let _ = writeln!(out, "# units: mm, degrees; axis: a unit vector in the joint's own frame");
        for w in &self.not_carried {
            let _ = writeln!(out, "# not carried: {w}");
        }
        let _ = writeln!(out, "frame,parent,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg,axis_x,axis_y,axis_z");
        let mut parent = "base".to_string();
        let row = |o: &Pose6| o.xyz_mm.iter().chain(&o.rpy_deg).map(|v| format!("{v:?}")).collect::<Vec<_>>().join(",");
        for j in &self.joints {
            let _ = writeln!(out, "{},{parent},{},{}", j.name, row(&j.origin), j.axis.map(|v| format!("{v:?}")).join(","));
            parent = j.name.clone();
        }
        let _ = writeln!(out, "flange,{parent},{},,,", row(&self.flange));
        let _ = writeln!(out, "tcp,flange,{},,,,,,", self.tcp_mm.map(|v| format!("{v:?}")).join(","));
        out
    }

    /// The table of a CSV text, or what is wrong with it (naming the line).
    pub fn parse_csv(text: &str) -> Result<FrameFile> {
        let mut r = csv::ReaderBuilder::new().comment(Some(b'#')).flexible(false).from_reader(text.as_bytes());
        let bad = |line: u64, why: String| Error::Invalid(format!("frame table, line {line}: {why}"));
        let mut joints = Vec::new();
        let (mut flange, mut tcp) = (None, None);
        for rec in r.records() {
            let rec = rec.map_err(|e| Error::Invalid(format!("frame table: {e}")))?;
            let line = rec.position().map_or(0, |p| p.line());
            let num = |k: usize| -> Result<f64> {
                let cell = rec.get(k).unwrap_or("").trim();
                cell.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| bad(line, format!("column {} holds '{cell}', not a finite number", k + 1)))
            };
            let pose = || -> Result<Pose6> { Ok(Pose6 { xyz_mm: [num(2)?, num(3)?, num(4)?], rpy_deg: [num(5)?, num(6)?, num(7)?] }) };
            match rec.get(0).unwrap_or("") {
                "flange" => flange = Some(pose()?),
                "tcp" => tcp = Some([num(2)?, num(3)?, num(4)?]),
                name => joints.push(JointRow { name: name.to_string(), origin: pose()?, axis: [num(8)?, num(9)?, num(10)?] }),
            }
        }
        Ok(FrameFile {
            format: FORMAT_NAME.into(),
            convention: CONVENTION.into(),
            joints,
            flange: flange.ok_or_else(|| Error::Invalid("frame table: no 'flange' row".into()))?,
            tcp_mm: tcp.ok_or_else(|| Error::Invalid("frame table: no 'tcp' row".into()))?,
            not_carried: Vec::new(),
        })
    }
}

/// The frame table format.
pub struct Frames;

impl ExportFormat for Frames {
    fn name(&self) -> &'static str {
        "frames"
    }
    fn describe(&self) -> &'static str {
        "a per-joint frame table (origin x, y, z, roll, pitch, yaw and axis of each joint; CSV or JSON)"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["csv", "json"]
    }
    fn write(&self, table: &JointTable, _model: &CalibModel, _x: &[f64], _nominal: Option<&Robot>, ext: &str, warnings: &mut Vec<String>) -> Result<String> {
        let f = FrameFile::of(table, warnings);
        Ok(if ext == "json" { serde_json::to_string_pretty(&f).map_err(|e| Error::Invalid(e.to_string()))? + "\n" } else { f.csv() })
    }
    fn read(&self, text: &str, ext: &str) -> Result<ReadBack> {
        let f = if ext == "json" {
            let f: FrameFile = serde_json::from_str(text).map_err(|e| Error::Invalid(format!("frame table: {e}")))?;
            if f.format != FORMAT_NAME {
                return Err(Error::Invalid(format!("frame table: format '{}' is not '{FORMAT_NAME}'", f.format)));
            }
            f
        } else {
            FrameFile::parse_csv(text)?
        };
        f.read_back()
    }
}
