//! Denavit–Hartenberg tables, standard and modified, built from the calibrated joint axes.
//!
//! Both are exact for any arm of revolute joints: the frames sit on the common normals of
//! consecutive axes (through the previous normal's foot when two axes are parallel, where the
//! normal is not unique), a base transform takes the robot's base frame to the first D-H frame
//! and a tool transform the last D-H frame to the flange. Joint zero offsets are the θ offsets.
//!
//! - standard (`dh`): `T = base · Π_i Rz(θ_i + q_i) · Tz(d_i) · Tx(a_i) · Rx(α_i) · tool`; frame
//!   i − 1's z is joint i's axis.
//! - modified (`mdh`, Craig): `T = base · Π_i Rx(α_{i−1}) · Tx(a_{i−1}) · Rz(θ_i + q_i) · Tz(d_i) · tool`;
//!   frame i's z is joint i's axis.
//!
//! Nearly parallel axes (a UR's joints 2 to 4, calibrated) put the common normal far away: the
//! table stays exact but its `d` values grow as the distance over the angle, which a warning
//! names (a frame table or the URDF states the same arm without it).

use super::{ExportFormat, JointTable, Pose6, ReadBack};
use crate::calib::model::CalibModel;
use crate::error::{Error, Result};
use crate::robot::kinematics::{ChainBuilder, Frame};
use crate::robot::Robot;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::fmt::Write;

/// A `d` (mm) beyond which the table warns of nearly parallel axes.
pub const LARGE_D_MM: f64 = 10_000.0;

/// One row of a D-H table: θ offset, d, a, α (standard: joint i's; modified: α_{i−1}, a_{i−1},
/// θ_i, d_i).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DhRow {
    /// The joint angle's offset, degrees.
    pub theta_deg: f64,
    /// Offset along the z axis, mm.
    pub d_mm: f64,
    /// Length of the common normal, mm.
    pub a_mm: f64,
    /// Twist about the common normal, degrees.
    pub alpha_deg: f64,
}

/// A D-H table with its base and tool transforms.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DhFile {
    /// `standard` or `modified`.
    pub convention: String,
    /// How a row composes.
    pub formula: String,
    /// The robot's base frame to the first D-H frame.
    pub base: Pose6,
    /// One row per joint, base to flange.
    pub joints: Vec<DhRow>,
    /// The last D-H frame to the flange.
    pub tool: Pose6,
    /// The tool point in the flange frame, mm.
    pub tcp_mm: [f64; 3],
    /// What the file does not carry of the calibrated model.
    #[serde(default)]
    pub not_carried: Vec<String>,
}

/// Standard or modified D-H.
pub struct Dh {
    modified: bool,
}

impl Dh {
    /// Standard D-H.
    pub const STANDARD: Dh = Dh { modified: false };
    /// Modified (Craig) D-H.
    pub const MODIFIED: Dh = Dh { modified: true };

    fn convention(&self) -> &'static str {
        if self.modified {
            "modified"
        } else {
            "standard"
        }
    }
    fn formula(&self) -> &'static str {
        if self.modified {
            "T = base * prod_i Rx(alpha_i) Tx(a_i) Rz(theta_i + q_i) Tz(d_i) * tool (row i holds alpha and a of the normal before joint i: Craig's alpha_{i-1}, a_{i-1})"
        } else {
            "T = base * prod_i Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i) * tool"
        }
    }
}

/// The signed angle from `a` to `b` about `axis` (all unit, `a` and `b` perpendicular to it).
fn angle_about(a: &Vector3<f64>, b: &Vector3<f64>, axis: &Vector3<f64>) -> f64 {
    axis.dot(&a.cross(b)).atan2(a.dot(b))
}

/// The frames both conventions are built of, at zero joint angles: the first D-H frame, and per
/// pair of consecutive axes (i, i + 1) the common normal: its foot on axis i, its foot on axis
/// i + 1 and its unit direction.
struct Normals {
    base: Frame,
    dirs: Vec<Vector3<f64>>,
    feet: Vec<(Vector3<f64>, Vector3<f64>, Vector3<f64>)>,
}

fn normals(t: &JointTable) -> Normals {
    let n = t.n_joints();
    let lines: Vec<(Vector3<f64>, Vector3<f64>)> = (0..n).map(|j| t.axis_line(j)).collect();
    // The first frame: on axis 1 at the foot of the base origin, x the base's x (else y) made
    // perpendicular to the axis.
    let base = crate::robot::kinematics::dh_base_frame(&lines[0].0, &lines[0].1);
    let (mut anchor, mut x_prev) = (base.pos, base.rot.column(0).into_owned());
    let mut feet = Vec::new();
    for i in 0..n.saturating_sub(1) {
        let ((c, z), (c2, z2)) = (lines[i], lines[i + 1]);
        let cross = z.cross(&z2);
        let (p, r) = if cross.norm() > 1e-12 {
            // Closest points of two skew (or intersecting) lines.
            crate::robot::kinematics::closest_points(&c, &z, &c2, &z2)
        } else {
            // Parallel: the normal through the previous foot on axis i.
            (anchor, c2 + z2 * (anchor - c2).dot(&z2))
        };
        let gap = r - p;
        let x = if gap.norm() > 1e-12 {
            gap.normalize()
        } else if cross.norm() > 1e-12 {
            cross.normalize()
        } else {
            x_prev
        };
        feet.push((p, r, x));
        anchor = r;
        x_prev = x;
    }
    let dirs = lines.iter().map(|l| l.1).collect();
    Normals { base, dirs, feet }
}

impl Normals {
    /// The last D-H frame at zero joint angles (both conventions): on the last axis at the last
    /// normal's foot, x along that normal.
    fn last(&self) -> Frame {
        let z = *self.dirs.last().expect("an arm has a joint");
        let (o, x) = match self.feet.last() {
            Some((_, r, x)) => (*r, *x),
            None => (self.base.pos, self.base.rot.column(0).into()),
        };
        Frame { rot: Matrix3::from_columns(&[x, z.cross(&x), z]), pos: o }
    }
    /// The previous normal's direction and its foot on axis `i` (the first frame's for i = 0).
    fn before(&self, i: usize) -> (Vector3<f64>, Vector3<f64>) {
        match i {
            0 => (self.base.rot.column(0).into(), self.base.pos),
            _ => (self.feet[i - 1].2, self.feet[i - 1].1),
        }
    }
    fn standard(&self) -> Vec<DhRow> {
        let n = self.dirs.len();
        (0..n)
            .map(|i| match self.feet.get(i) {
                Some((p, r, x)) => {
                    let (x_prev, o_prev) = self.before(i);
                    let z = self.dirs[i];
                    DhRow {
                        theta_deg: angle_about(&x_prev, x, &z).to_degrees(),
                        d_mm: crate::units::to_mm(z.dot(&(p - o_prev))),
                        a_mm: crate::units::to_mm((r - p).dot(x)),
                        alpha_deg: angle_about(&z, &self.dirs[i + 1], x).to_degrees(),
                    }
                }
                None => DhRow { theta_deg: 0.0, d_mm: 0.0, a_mm: 0.0, alpha_deg: 0.0 },
            })
            .collect()
    }
}

/// The modified (Craig) rows of a standard table whose last row is zero (as [`Normals`] builds
/// it): the same frames regrouped, `Tx(a)·Rx(α)` of the normal before joint i moved into row i
/// (they commute), so row i holds the standard α and a of row i − 1 (none for the first) with
/// the standard θ and d of row i, and the tool transform is the same.
fn modified_of(standard: &[DhRow]) -> Vec<DhRow> {
    standard
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (alpha_deg, a_mm) = i.checked_sub(1).map_or((0.0, 0.0), |k| (standard[k].alpha_deg, standard[k].a_mm));
            DhRow { theta_deg: r.theta_deg, d_mm: r.d_mm, a_mm, alpha_deg }
        })
        .collect()
}

impl DhFile {
    /// The chain and tool point the table states, or the first value that is not a number.
    pub fn read_back(&self, modified: bool) -> Result<ReadBack> {
        if self.joints.is_empty() {
            return Err(Error::Invalid("the D-H table has no joints".into()));
        }
        self.base.check("the base transform")?;
        self.tool.check("the tool transform")?;
        let mut b = ChainBuilder::new();
        self.base.build(&mut b);
        for (i, r) in self.joints.iter().enumerate() {
            if let Some(v) = [r.theta_deg, r.d_mm, r.a_mm, r.alpha_deg].iter().find(|v| !v.is_finite()) {
                return Err(Error::Invalid(format!("D-H row {} holds {v}: every value must be a finite number", i + 1)));
            }
            let (d, a, alpha) = (crate::units::to_m(r.d_mm), crate::units::to_m(r.a_mm), r.alpha_deg.to_radians());
            if modified {
                b.rot(Vector3::x(), alpha, None);
                b.trans(Vector3::x(), a, None, false);
                b.joint(Vector3::z(), r.theta_deg.to_radians(), None);
                b.trans(Vector3::z(), d, None, false);
            } else {
                b.joint(Vector3::z(), r.theta_deg.to_radians(), None);
                b.trans(Vector3::z(), d, None, false);
                b.trans(Vector3::x(), a, None, false);
                b.rot(Vector3::x(), alpha, None);
            }
        }
        self.tool.build(&mut b);
        if let Some(v) = self.tcp_mm.iter().find(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!("the tool point holds {v}: every value must be a finite number")));
        }
        Ok(ReadBack::of_chain(b.finish(), crate::units::to_m(Vector3::from(self.tcp_mm))))
    }

    fn csv(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "# twincal D-H table ({} convention) written by twincal {}: {}", self.convention, env!("CARGO_PKG_VERSION"), self.formula);
        let pose = |p: &Pose6| {
            format!(
                "x_mm={:?} y_mm={:?} z_mm={:?} roll_deg={:?} pitch_deg={:?} yaw_deg={:?}",
                p.xyz_mm[0], p.xyz_mm[1], p.xyz_mm[2], p.rpy_deg[0], p.rpy_deg[1], p.rpy_deg[2]
            )
        };
        let _ = writeln!(out, "# base: {} (Trans(x, y, z) * Rz(yaw) * Ry(pitch) * Rx(roll))", pose(&self.base));
        let _ = writeln!(out, "# tool: {}", pose(&self.tool));
        let _ = writeln!(out, "# tcp_mm: {:?} {:?} {:?}", self.tcp_mm[0], self.tcp_mm[1], self.tcp_mm[2]);
        for w in &self.not_carried {
            let _ = writeln!(out, "# not carried: {w}");
        }
        let _ = writeln!(out, "joint,theta_deg,d_mm,a_mm,alpha_deg");
        for (i, r) in self.joints.iter().enumerate() {
            let _ = writeln!(out, "{},{:?},{:?},{:?},{:?}", i + 1, r.theta_deg, r.d_mm, r.a_mm, r.alpha_deg);
        }
        out
    }

    fn parse_csv(text: &str, modified: bool) -> Result<DhFile> {
        let comment = |key: &str| text.lines().find_map(|l| l.strip_prefix("# ").and_then(|l| l.strip_prefix(key))).map(str::trim);
        let field = |s: &str, name: &str| -> Result<f64> {
            s.split_whitespace()
                .find_map(|kv| kv.strip_prefix(name).and_then(|v| v.strip_prefix('=')))
                .and_then(|v| v.parse::<f64>().ok())
                .ok_or_else(|| Error::Invalid(format!("D-H table: no number '{name}=' in '{s}'")))
        };
        let pose = |key: &str| -> Result<Pose6> {
            let s = comment(key).ok_or_else(|| Error::Invalid(format!("D-H table: no '# {key}' line")))?;
            Ok(Pose6 {
                xyz_mm: [field(s, "x_mm")?, field(s, "y_mm")?, field(s, "z_mm")?],
                rpy_deg: [field(s, "roll_deg")?, field(s, "pitch_deg")?, field(s, "yaw_deg")?],
            })
        };
        let tcp: Vec<f64> = comment("tcp_mm:").unwrap_or("").split_whitespace().filter_map(|v| v.parse().ok()).collect();
        let [tx, ty, tz] = tcp[..] else { return Err(Error::Invalid("D-H table: no '# tcp_mm: x y z' line".into())) };
        let mut r = csv::ReaderBuilder::new().comment(Some(b'#')).from_reader(text.as_bytes());
        let mut joints = Vec::new();
        for rec in r.deserialize::<(usize, f64, f64, f64, f64)>() {
            let (_, theta_deg, d_mm, a_mm, alpha_deg) = rec.map_err(|e| Error::Invalid(format!("D-H table: {e}")))?;
            joints.push(DhRow { theta_deg, d_mm, a_mm, alpha_deg });
        }
        let d = if modified { Dh::MODIFIED } else { Dh::STANDARD };
        Ok(DhFile {
            convention: d.convention().into(),
            formula: d.formula().into(),
            base: pose("base:")?,
            joints,
            tool: pose("tool:")?,
            tcp_mm: [tx, ty, tz],
            not_carried: Vec::new(),
        })
    }
}

impl ExportFormat for Dh {
    fn name(&self) -> &'static str {
        if self.modified {
            "mdh"
        } else {
            "dh"
        }
    }
    fn describe(&self) -> &'static str {
        if self.modified {
            "a modified (Craig) D-H table with its base and tool transforms (CSV or JSON)"
        } else {
            "a standard D-H table with its base and tool transforms (CSV or JSON)"
        }
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["csv", "json"]
    }
    fn write(&self, table: &JointTable, _model: &CalibModel, _x: &[f64], _nominal: Option<&Robot>, ext: &str, warnings: &mut Vec<String>) -> Result<String> {
        let nm = normals(table);
        let standard = nm.standard();
        let joints = if self.modified { modified_of(&standard) } else { standard };
        if let Some((i, r)) = joints.iter().enumerate().find(|(_, r)| r.d_mm.abs() > LARGE_D_MM) {
            warnings.push(format!(
                "D-H row {} has d = {:.0} mm: consecutive joint axes there are nearly parallel, so their common normal lies far away (the table is exact, but a frame table or the URDF states this arm without it)",
                i + 1,
                r.d_mm
            ));
        }
        let f = DhFile {
            convention: self.convention().into(),
            formula: self.formula().into(),
            base: Pose6::of(&nm.base),
            joints,
            tool: Pose6::of(&table.flange.relative_to(&nm.last())),
            tcp_mm: crate::units::to_mm(table.tcp).into(),
            not_carried: warnings.clone(),
        };
        Ok(if ext == "json" { serde_json::to_string_pretty(&f).map_err(|e| Error::Invalid(e.to_string()))? + "\n" } else { f.csv() })
    }
    fn read(&self, text: &str, ext: &str) -> Result<ReadBack> {
        let f = if ext == "json" {
            serde_json::from_str(text).map_err(|e| Error::Invalid(format!("D-H table: {e}")))?
        } else {
            DhFile::parse_csv(text, self.modified)?
        };
        if f.convention != self.convention() {
            return Err(Error::Invalid(format!("a {} D-H table read as {}", f.convention, self.convention())));
        }
        f.read_back(self.modified)
    }
}
