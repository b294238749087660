//! The kinematics parameters file of the ROS UR driver and `ur_description`
//! (`kinematics: shoulder, upper_arm, forearm, wrist_1, wrist_2, wrist_3`, each `x, y, z` in m
//! and `roll, pitch, yaw` in rad, then `hash`).
//!
//! `ur_description` builds the arm from it as `base_link_inertia · Π_j origin_j · Rz(q_j)`, every
//! joint turning about its own z, and puts `tool0` on `wrist_3_link` (its `flange` and `tool0`
//! fixed joints compose to the identity); `base_link_inertia` is the frame of UR's D-H table,
//! the base frame of twincal's UR models. Each link frame here sits on its joint's axis, as near
//! the calibrated model's own link frame as that allows, the last one on the flange, so the
//! file is exact for any six-joint arm whose flange lies on joint 6's axis. A
//! flange off that axis (a tilt or an offset the calibration found) cannot be carried by a
//! joint origin: the file then puts `wrist_3_link` on the axis and states what is left as the
//! tool's offset to set in the controller (a comment, and a warning).
//!
//! `hash` is the driver's check that the file belongs to the connected robot's factory
//! calibration; twincal writes its own (`twincal_` and 16 hex digits of the values), so the
//! driver warns that it differs, as it must for a recalibrated arm.

use super::{ExportFormat, JointTable, ReadBack};
use crate::calib::model::CalibModel;
use crate::error::{Error, Result};
use crate::robot::kinematics::{rpy, ChainBuilder, Frame};
use crate::robot::Robot;
use nalgebra::{Matrix3, Vector3};
use std::fmt::Write;

/// The file's link names, base to flange.
pub const LINKS: [&str; 6] = ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"];
/// A flange within this of joint 6's axis (m, and rad of tilt) counts as on it.
pub const ON_AXIS: f64 = 1e-12;

/// The UR kinematics YAML format.
pub struct UrYaml;

/// The frame on axis `(c, z)` closest to `f`: its origin projected onto the axis, its x made
/// perpendicular to the axis (`f` itself when its z is the axis and its origin on it).
fn on_axis(f: &Frame, c: &Vector3<f64>, z: &Vector3<f64>) -> Frame {
    if (f.rot.column(2) - z).norm() < ON_AXIS && (f.pos - c).cross(z).norm() < ON_AXIS {
        return *f;
    }
    let x: Vector3<f64> =
        [f.rot.column(0), f.rot.column(1)].iter().map(|v| v - z * v.dot(z)).find(|v| v.norm() > 1e-6).unwrap_or_else(|| z.cross(&Vector3::x())).normalize();
    Frame { rot: Matrix3::from_columns(&[x, z.cross(&x), *z]), pos: c + z * (f.pos - c).dot(z) }
}

/// The link frames at zero joint angles, each on its joint's axis and as near the model's own
/// link frame as that allows (the model's own where its joint turns about its z), the last on
/// the flange; and the tool's offset from `wrist_3_link` (identity when the flange is on joint
/// 6's axis).
fn link_frames(t: &JointTable) -> (Vec<Frame>, Frame) {
    let n = t.n_joints();
    let mut links: Vec<Frame> = (0..n - 1)
        .map(|j| {
            let (c, z) = t.axis_line(j);
            on_axis(&t.frames[j], &c, &z)
        })
        .collect();
    let (c, z) = t.axis_line(n - 1);
    let last = on_axis(&t.flange, &c, &z);
    links.push(last);
    (links, t.flange.relative_to(&last))
}

fn hash(text: &str) -> String {
    format!("twincal_{}", &crate::dataset::truth::sha256_hex(text.as_bytes())[..16])
}

impl ExportFormat for UrYaml {
    fn name(&self) -> &'static str {
        "ur-yaml"
    }
    fn describe(&self) -> &'static str {
        "the kinematics parameters YAML of the ROS UR driver and ur_description (six joints)"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["yaml", "yml"]
    }
    fn write(&self, table: &JointTable, _model: &CalibModel, _x: &[f64], _nominal: Option<&Robot>, _ext: &str, warnings: &mut Vec<String>) -> Result<String> {
        if table.n_joints() != 6 {
            return Err(Error::Invalid(format!("a UR kinematics file holds six joints; this arm has {}", table.n_joints())));
        }
        let (links, offset) = link_frames(table);
        let tcp = offset.point(&table.tcp);
        let (moved, turned) = (offset.pos.norm() > ON_AXIS, (offset.rot - Matrix3::identity()).norm() > ON_AXIS);
        if moved || turned {
            let [r, p, y] = rpy(&offset.rot).map(f64::to_degrees);
            let o = crate::units::to_mm(offset.pos);
            // Only what is off is named.
            let off = [
                moved.then(|| format!("off joint 6's axis by ({:.4}, {:.4}, {:.4}) mm", o.x, o.y, o.z)),
                turned.then(|| format!("turned from joint 6's frame by rpy ({r:.4}, {p:.4}, {y:.4})°")),
            ];
            warnings.push(format!(
                "the calibrated flange is {}, which a UR joint origin cannot hold: set the tool (TCP) relative to tool0 to the tool point below, ({:.4}, {:.4}, {:.4}) mm",
                off.into_iter().flatten().collect::<Vec<_>>().join(" and "),
                crate::units::to_mm(tcp.x),
                crate::units::to_mm(tcp.y),
                crate::units::to_mm(tcp.z)
            ));
        }
        let mut body = String::from("kinematics:\n");
        let mut parent = Frame::identity();
        for (name, link) in LINKS.iter().zip(&links) {
            let o = link.relative_to(&parent);
            let [r, p, y] = rpy(&o.rot);
            let _ = write!(
                body,
                "  {name}:\n    x: {:?}\n    y: {:?}\n    z: {:?}\n    roll: {r:?}\n    pitch: {p:?}\n    yaw: {y:?}\n",
                o.pos.x, o.pos.y, o.pos.z
            );
            parent = *link;
        }
        let mut out = String::new();
        let _ = writeln!(
            out,
            "# UR kinematics parameters written by twincal {} (m, rad; ur_description's convention, every joint about its own z)",
            env!("CARGO_PKG_VERSION")
        );
        let _ = writeln!(out, "# tcp_m (the tool point in tool0): {:?} {:?} {:?}", tcp.x, tcp.y, tcp.z);
        for w in warnings.iter() {
            let _ = writeln!(out, "# not carried: {w}");
        }
        let h = hash(&body);
        Ok(format!("{out}{body}  hash: {h}\n"))
    }
    fn read(&self, text: &str, _ext: &str) -> Result<ReadBack> {
        let values = parse(text)?;
        let mut b = ChainBuilder::new();
        for (name, v) in LINKS.iter().zip(&values) {
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                return Err(Error::Invalid(format!("UR kinematics: {name} holds {x}, not a finite number")));
            }
            b.origin([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
            b.joint(Vector3::z(), 0.0, None);
        }
        let tcp: Vec<f64> = text
            .lines()
            .find_map(|l| l.strip_prefix("# tcp_m (the tool point in tool0):"))
            .map(|s| s.split_whitespace().filter_map(|v| v.parse().ok()).collect())
            .unwrap_or_default();
        let tcp = match tcp[..] {
            [x, y, z] => Vector3::new(x, y, z),
            _ => Vector3::zeros(),
        };
        Ok(ReadBack::of_chain(b.finish(), tcp))
    }
}

/// A UR's kinematics file (the factory calibration the UR driver's `ur_calibration` extracts,
/// or one `export --format ur-yaml` wrote) as a robot: six revolute joints about their own z at
/// the file's origins, the flange (`tool0`) on `wrist_3`, the base UR's D-H base frame. The file
/// holds no limits, masses or speeds: joints of ±360° at 180°/s, no inertials (a calibration's
/// torques then come from `--robot`, the arm's URDF).
pub fn robot(text: &str, source: &str) -> Result<Robot> {
    let values = parse(text).map_err(|e| Error::Invalid(format!("{source}: {e}")))?;
    let mut urdf = String::from("<?xml version=\"1.0\"?>\n<robot name=\"ur_kinematics\">\n  <link name=\"base\"/>\n");
    let mut parent = String::from("base");
    for (name, v) in LINKS.iter().zip(&values) {
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(Error::Invalid(format!("{source}: {name} holds {x}, not a finite number")));
        }
        let _ = write!(
            urdf,
            "  <link name=\"{name}_link\"/>\n  <joint name=\"{name}_joint\" type=\"revolute\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{name}_link\"/>\n    \
             <origin xyz=\"{:?} {:?} {:?}\" rpy=\"{:?} {:?} {:?}\"/>\n    <axis xyz=\"0 0 1\"/>\n    \
             <limit lower=\"{:?}\" upper=\"{:?}\" effort=\"0\" velocity=\"{:?}\"/>\n  </joint>\n",
            v[0],
            v[1],
            v[2],
            v[3],
            v[4],
            v[5],
            -std::f64::consts::TAU,
            std::f64::consts::TAU,
            std::f64::consts::PI
        );
        parent = format!("{name}_link");
    }
    urdf.push_str("  <link name=\"flange\"/>\n  <joint name=\"wrist_3-flange\" type=\"fixed\">\n    <parent link=\"wrist_3_link\"/>\n    <child link=\"flange\"/>\n    <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n  </joint>\n</robot>\n");
    Robot::from_urdf_str(&urdf, source)
}

/// The six links' `x, y, z, roll, pitch, yaw` of a UR kinematics file, or what is wrong with it.
/// The file is read as the driver's files are laid out: `kinematics:`, a line per link name,
/// then its six `key: value` lines; other keys are refused by name.
fn parse(text: &str) -> Result<Vec<[f64; 6]>> {
    const KEYS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];
    let mut values = vec![[f64::NAN; 6]; 6];
    let mut link: Option<usize> = None;
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim_end();
        if line.trim().is_empty() || line.trim() == "kinematics:" {
            continue;
        }
        let bad = |why: String| Error::Invalid(format!("UR kinematics, line {}: {why}", n + 1));
        let (key, value) = line.trim().split_once(':').ok_or_else(|| bad(format!("'{}' is not 'key: value'", line.trim())))?;
        let (key, value) = (key.trim(), value.trim());
        if let Some(k) = LINKS.iter().position(|l| *l == key) {
            link = Some(k);
            continue;
        }
        if key == "hash" {
            continue;
        }
        let k = KEYS
            .iter()
            .position(|c| *c == key)
            .ok_or_else(|| bad(format!("unknown key '{key}' (expected one of {} or {})", LINKS.join(", "), KEYS.join(", "))))?;
        let l = link.ok_or_else(|| bad(format!("'{key}' before any link name")))?;
        values[l][k] = value.parse::<f64>().map_err(|_| bad(format!("{}.{key} = '{value}' is not a number", LINKS[l])))?;
    }
    for (l, v) in values.iter().enumerate() {
        if let Some(k) = v.iter().position(|x| x.is_nan()) {
            return Err(Error::Invalid(format!("UR kinematics: {}.{} is missing", LINKS[l], KEYS[k])));
        }
    }
    Ok(values)
}
