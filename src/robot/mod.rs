//! Robot description: a serial arm of revolute joints loaded from a URDF, with its inertial data,
//! and the kinematic chain with per-joint geometric error parameters built from it.
//!
//! Nothing here is specific to one robot: any URDF whose joints from the root link to the flange
//! form a single serial chain of revolute joints (fixed joints may sit between them) loads the same way.

pub mod choice;
pub mod kinematics;
pub mod statics;

pub use choice::RobotChoice;

use crate::error::{Error, Result};
use kinematics::{Chain, ChainBuilder, Frame};
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::path::Path;

/// The IRB 120 description shipped with twincal (used when no URDF path is given).
pub const IRB120_URDF: &str = include_str!("../../urdf/irb120.urdf");

/// Mass, centre of mass and inertia tensor about the COM, in the link frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Inertial {
    /// Mass, kg.
    pub mass: f64,
    /// Centre of mass in the link frame, m.
    pub com: Vector3<f64>,
    /// Inertia tensor about the centre of mass, in the link frame's axes, kg·m².
    pub inertia: Matrix3<f64>,
}

impl Inertial {
    /// A massless body: zero mass, centre of mass and inertia.
    pub fn zero() -> Self {
        Inertial { mass: 0.0, com: Vector3::zeros(), inertia: Matrix3::zeros() }
    }
    /// Combines two bodies given in the same frame (parallel-axis theorem).
    pub fn combine(&self, other: &Inertial) -> Inertial {
        let m = self.mass + other.mass;
        if m <= 0.0 {
            return Inertial::zero();
        }
        let com = (self.com * self.mass + other.com * other.mass) / m;
        let shift = |i: &Inertial| {
            let d = i.com - com;
            i.inertia + (Matrix3::identity() * d.dot(&d) - d * d.transpose()) * i.mass
        };
        Inertial { mass: m, com, inertia: shift(self) + shift(other) }
    }
    /// Expresses this body in a parent frame where the body's frame is `f`.
    pub fn transformed(&self, f: &Frame) -> Inertial {
        Inertial { mass: self.mass, com: f.point(&self.com), inertia: f.rot * self.inertia * f.rot.transpose() }
    }
}

/// One revolute joint of the serial chain.
#[derive(Clone, Debug)]
pub struct JointSpec {
    /// Joint name in the URDF.
    pub name: String,
    /// Child link of this joint.
    pub link: String,
    /// Origin of the joint in the parent link frame (fixed joints in between folded in).
    pub origin_xyz: Vector3<f64>,
    /// URDF roll-pitch-yaw of the origin (R = Rz(yaw)·Ry(pitch)·Rx(roll)).
    pub origin_rpy: Vector3<f64>,
    /// Unit rotation axis in the joint frame.
    pub axis: Vector3<f64>,
    /// Lower joint limit, rad (−π for a continuous joint).
    pub lower: f64,
    /// Upper joint limit, rad (π for a continuous joint).
    pub upper: f64,
    /// The URDF's velocity limit, rad/s; 0 when the URDF gives none (see [`Self::speed_limit`]).
    pub max_velocity: f64,
    /// A `continuous` joint (no stops; its limits are one turn, [-π, π]).
    pub continuous: bool,
}

/// Speed limit (rad/s) taken for a joint whose URDF gives none (`velocity` 0 or no `<limit>`,
/// as continuous joints often have): a typical industrial joint, about 57°/s.
pub const DEFAULT_JOINT_SPEED_RAD_S: f64 = 1.0;

impl JointSpec {
    /// Whether the URDF gives the joint a speed limit.
    pub fn has_speed_limit(&self) -> bool {
        self.max_velocity > 0.0
    }
    /// The joint's speed limit, rad/s: the URDF's, else [`DEFAULT_JOINT_SPEED_RAD_S`].
    pub fn speed_limit(&self) -> f64 {
        if self.has_speed_limit() {
            self.max_velocity
        } else {
            DEFAULT_JOINT_SPEED_RAD_S
        }
    }
}

/// A serial revolute arm.
#[derive(Clone, Debug)]
pub struct Robot {
    /// Robot name in the URDF.
    pub name: String,
    /// Name of the root link, whose frame is the base frame.
    pub base_link: String,
    /// The revolute joints from base to flange, in chain order.
    pub joints: Vec<JointSpec>,
    /// Inertials of the moving links, `links[j]` is the child of joint `j` (fixed children merged).
    pub links: Vec<Inertial>,
    /// Name of the flange frame and its pose in the last link's frame.
    pub flange_name: String,
    /// Pose of the flange frame in the last moving link's frame (fixed joints folded in).
    pub flange: Frame,
    /// The URDF text the robot was read from (so a twin's truth file can carry its robot).
    pub urdf: String,
}

/// Number of geometric error parameters per joint: origin offset (x, y, z), origin rotation
/// (about x, y, z of the origin frame) and joint zero offset.
pub const PARAMS_PER_JOINT: usize = 7;
/// Name suffixes of a joint's geometric error parameters, in their order: origin offset (dx, dy,
/// dz), origin rotation (rx, ry, rz) and joint zero offset (dtheta).
pub const PARAM_SUFFIXES: [&str; PARAMS_PER_JOINT] = ["dx", "dy", "dz", "rx", "ry", "rz", "dtheta"];
/// What each of a joint's geometric error parameters measures, in [`PARAM_SUFFIXES`]' order.
pub const PARAM_KINDS: [GeoKind; PARAMS_PER_JOINT] =
    [GeoKind::Length, GeoKind::Length, GeoKind::Length, GeoKind::Angle, GeoKind::Angle, GeoKind::Angle, GeoKind::Angle];

/// What a geometric error parameter measures: the one place its unit is decided. Inside the
/// code a length is in m and an angle in rad; files (truth.json, result.json) write mm and
/// degrees.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeoKind {
    /// A length: m in the code, mm in files.
    Length,
    /// An angle: rad in the code, degrees in files.
    Angle,
}

impl GeoKind {
    /// The kind of the parameter named `<joint>.<suffix>`; None for another name.
    pub fn of_name(name: &str) -> Option<GeoKind> {
        let suffix = name.rsplit_once('.')?.1;
        PARAM_SUFFIXES.iter().position(|s| *s == suffix).map(|k| PARAM_KINDS[k])
    }
    /// A value in the code's unit (m, rad) in the file's (mm, degrees).
    pub fn to_file(self, v: f64) -> f64 {
        match self {
            GeoKind::Length => crate::units::to_mm(v),
            GeoKind::Angle => v.to_degrees(),
        }
    }
    /// A value in the file's unit (mm, degrees) in the code's (m, rad).
    pub fn from_file(self, v: f64) -> f64 {
        match self {
            GeoKind::Length => crate::units::to_m(v),
            GeoKind::Angle => v.to_radians(),
        }
    }
    /// The file's unit.
    pub fn file_unit(self) -> &'static str {
        match self {
            GeoKind::Length => "mm",
            GeoKind::Angle => "deg",
        }
    }
}

fn frame_from_xyz_rpy(xyz: &[f64; 3], rpy: &[f64; 3]) -> Frame {
    Frame { rot: *Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]).matrix(), pos: Vector3::new(xyz[0], xyz[1], xyz[2]) }
}

/// Refuses a link whose inertial data are not finite, whose mass is negative or whose principal
/// moments (ixx, iyy, izz) are negative.
fn check_inertial(link: &urdf_rs::Link) -> std::result::Result<(), String> {
    let i = &link.inertial;
    let name = &link.name;
    let m = i.mass.value;
    if !(m.is_finite() && m >= 0.0) {
        return Err(format!("link '{name}' has mass {m}; it must be finite and >= 0"));
    }
    let t = &i.inertia;
    // (name, value, is a principal moment)
    let terms = [("ixx", t.ixx, true), ("iyy", t.iyy, true), ("izz", t.izz, true), ("ixy", t.ixy, false), ("ixz", t.ixz, false), ("iyz", t.iyz, false)];
    for (k, v, principal) in terms {
        if !v.is_finite() || (principal && v < 0.0) {
            return Err(format!(
                "link '{name}' has inertia {k} = {v}; inertia terms must be finite and ixx, iyy, \
                 izz >= 0"
            ));
        }
    }
    if i.origin.xyz.0.iter().chain(&i.origin.rpy.0).any(|v| !v.is_finite()) {
        return Err(format!("link '{name}' has a non-finite inertial origin"));
    }
    Ok(())
}

fn inertial_of(link: &urdf_rs::Link) -> Inertial {
    let i = &link.inertial;
    let f = frame_from_xyz_rpy(&i.origin.xyz.0, &i.origin.rpy.0);
    let t = &i.inertia;
    let local = Matrix3::new(t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz);
    Inertial { mass: i.mass.value, com: f.pos, inertia: f.rot * local * f.rot.transpose() }
}

/// Farthest (m) a joint may sit from its parent link's frame: the longest link of an industrial
/// arm is a few metres; beyond this a URDF is in other units or broken.
pub const MAX_JOINT_OFFSET_M: f64 = 20.0;

/// The URDF's one root link, after checking the links' inertials and that the joints form a
/// tree with finite origins (within [`MAX_JOINT_OFFSET_M`]) and axes.
fn tree_root(urdf: &urdf_rs::Robot) -> std::result::Result<String, String> {
    for link in &urdf.links {
        check_inertial(link)?;
    }
    let mut parents: std::collections::HashMap<&str, &str> = std::collections::HashMap::new();
    for j in &urdf.joints {
        if let Some(other) = parents.insert(j.child.link.as_str(), j.name.as_str()) {
            return Err(format!("link '{}' is the child of two joints ('{other}' and '{}'): not a tree", j.child.link, j.name));
        }
        let o = &j.origin;
        if o.xyz.0.iter().chain(&o.rpy.0).chain(&j.axis.xyz.0).any(|v| !v.is_finite()) {
            return Err(format!("joint '{}' has a non-finite origin or axis", j.name));
        }
        let d = Vector3::from(o.xyz.0).norm();
        if d > MAX_JOINT_OFFSET_M {
            return Err(format!(
                "joint '{}' sits {} m from its parent link's frame, beyond the {MAX_JOINT_OFFSET_M} m any arm's link spans (lengths in mm where URDF takes metres?)",
                j.name,
                crate::error::shown(d)
            ));
        }
    }
    let children: std::collections::HashSet<&str> = urdf.joints.iter().map(|j| j.child.link.as_str()).collect();
    let roots: Vec<&urdf_rs::Link> = urdf.links.iter().filter(|l| !children.contains(l.name.as_str())).collect();
    if roots.len() != 1 {
        return Err(format!("expected exactly one root link, found {}", roots.len()));
    }
    Ok(roots[0].name.clone())
}

/// The joint the serial walk follows out of link `current`: its one moving child joint, else its
/// one fixed child, else (several fixed children, frames like tool0) one named like a flange or
/// the first; None at the end of the chain.
fn next_joint<'a>(urdf: &'a urdf_rs::Robot, current: &str) -> std::result::Result<Option<&'a urdf_rs::Joint>, String> {
    let outgoing: Vec<&urdf_rs::Joint> = urdf.joints.iter().filter(|j| j.parent.link == current).collect();
    let moving: Vec<&&urdf_rs::Joint> = outgoing.iter().filter(|j| j.joint_type != urdf_rs::JointType::Fixed).collect();
    Ok(if moving.len() > 1 {
        return Err(format!("link '{current}' has {} moving child joints: not a serial arm", moving.len()));
    } else if let Some(j) = moving.first() {
        Some(**j)
    } else if outgoing.len() == 1 {
        Some(outgoing[0])
    } else if outgoing.is_empty() {
        None
    } else {
        outgoing.iter().find(|j| j.child.link.contains("flange")).copied().or(outgoing.first().copied())
    })
}

/// A revolute (or continuous) joint of the chain, at origin `full` from the previous moving
/// joint's child frame (the fixed joints between folded in), after checking its axis and limits.
fn joint_spec(j: &urdf_rs::Joint, full: &Frame) -> std::result::Result<JointSpec, String> {
    let axis = Vector3::from(j.axis.xyz.0);
    if axis.norm() < 1e-9 {
        return Err(format!("joint '{}' has a zero axis", j.name));
    }
    let (roll, pitch, yaw) = Rotation3::from_matrix_unchecked(full.rot).euler_angles();
    let (lower, upper) =
        if j.joint_type == urdf_rs::JointType::Continuous { (-std::f64::consts::PI, std::f64::consts::PI) } else { (j.limit.lower, j.limit.upper) };
    if lower == 0.0 && upper == 0.0 {
        return Err(format!(
            "revolute joint '{}' has no range (<limit lower=... upper=...> absent or both 0); give its limits, or make it type=\"continuous\"",
            j.name
        ));
    }
    if !(lower.is_finite() && upper.is_finite() && lower < upper) {
        return Err(format!("joint '{}' has invalid limits [{lower}, {upper}]", j.name));
    }
    let v = j.limit.velocity;
    if !(v.is_finite() && v >= 0.0) {
        return Err(format!("joint '{}' has velocity limit {v}; it must be finite and >= 0", j.name));
    }
    Ok(JointSpec {
        name: j.name.clone(),
        link: j.child.link.clone(),
        origin_xyz: full.pos,
        origin_rpy: Vector3::new(roll, pitch, yaw),
        axis: axis.normalize(),
        lower,
        upper,
        max_velocity: j.limit.velocity,
        continuous: j.joint_type == urdf_rs::JointType::Continuous,
    })
}

impl Robot {
    /// The controller's own frames as its URDF states them (the ROS-Industrial convention): the
    /// controller's base frame (link `base`) in the chain's base frame, and its flange frame
    /// (link `tool0`, the frame a program's tool data are written in) in the chain's flange
    /// frame, each reached from the chain through fixed joints; the identity where the URDF has
    /// no such link.
    pub fn controller_frames(&self) -> (Frame, Frame) {
        let Ok(urdf) = urdf_rs::read_from_string(&self.urdf) else { return (Frame::identity(), Frame::identity()) };
        // A link's pose in the nearest ancestor that a moving joint moves (or the root), through
        // the fixed joints between, and that ancestor's name.
        let up = |name: &str| -> Option<(Frame, String)> {
            let mut f = Frame::identity();
            let mut at = name.to_string();
            loop {
                let Some(j) = urdf.joints.iter().find(|j| j.child.link == at) else { return Some((f, at)) };
                if j.joint_type != urdf_rs::JointType::Fixed {
                    return Some((f, at));
                }
                f = frame_from_xyz_rpy(&j.origin.xyz.0, &j.origin.rpy.0).compose(&f);
                at = j.parent.link.clone();
            }
        };
        let exists = |n: &str| urdf.links.iter().any(|l| l.name == n);
        let base = match (exists("base"), up("base"), up(&self.base_link)) {
            (true, Some((b, root)), Some((own, own_root))) if root == own_root => b.relative_to(&own),
            _ => Frame::identity(),
        };
        let tool0 = match (exists("tool0"), up("tool0"), up(&self.flange_name)) {
            (true, Some((t, at)), Some((fl, fl_at))) if at == fl_at => t.relative_to(&fl),
            _ => Frame::identity(),
        };
        (base, tool0)
    }

    /// The IRB 120 shipped with twincal.
    pub fn irb120() -> Robot {
        Robot::from_urdf_str(IRB120_URDF, "urdf/irb120.urdf (embedded)").expect("embedded URDF is valid")
    }

    /// Whether this is the embedded IRB 120 (read from [`IRB120_URDF`]).
    pub fn is_embedded(&self) -> bool {
        self.urdf == IRB120_URDF
    }

    /// Reads a URDF file and parses it as [`Self::from_urdf_str`] does; errors if the file cannot
    /// be read or does not describe a serial revolute arm.
    pub fn from_urdf_file(path: &Path) -> Result<Robot> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Robot::from_urdf_str(&text, &path.display().to_string())
    }

    /// Parses a URDF and extracts the serial chain of revolute joints from the root link.
    pub fn from_urdf_str(text: &str, origin: &str) -> Result<Robot> {
        let err = |msg: String| Error::Urdf { path: origin.to_string(), msg };
        let urdf = urdf_rs::read_from_string(text).map_err(|e| err(format!("cannot parse: {e}")))?;
        let base = tree_root(&urdf).map_err(err)?;
        let link_by_name = |n: &str| urdf.links.iter().find(|l| l.name == n);

        let mut joints = Vec::new();
        let mut links: Vec<Inertial> = Vec::new();
        let mut current = base.clone();
        // Fixed transform accumulated since the last revolute joint's child frame.
        let mut pending = Frame::identity();
        let mut pending_names: Vec<String> = Vec::new();
        let mut flange_name = base.clone();
        let mut flange = Frame::identity();
        // Links already walked through: a cycle of joints must end the walk, not loop forever.
        let mut visited: std::collections::HashSet<String> = std::collections::HashSet::new();
        loop {
            if !visited.insert(current.clone()) {
                return Err(err(format!("the joints form a cycle through link '{current}'")));
            }
            let Some(j) = next_joint(&urdf, &current).map_err(err)? else { break };
            let origin = frame_from_xyz_rpy(&j.origin.xyz.0, &j.origin.rpy.0);
            let child_inertial = link_by_name(&j.child.link).map(inertial_of).unwrap_or(Inertial::zero());
            match &j.joint_type {
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                    if let Some(m) = &j.mimic {
                        return Err(err(format!(
                            "joint '{}' mimics joint '{}': mimic joints are not supported (each joint of the chain is its own angle, read from its own column)",
                            j.name, m.joint
                        )));
                    }
                    joints.push(joint_spec(j, &pending.compose(&origin)).map_err(err)?);
                    links.push(child_inertial);
                    pending = Frame::identity();
                    pending_names.clear();
                    flange_name = j.child.link.clone();
                    flange = Frame::identity();
                }
                urdf_rs::JointType::Fixed => {
                    pending = pending.compose(&origin);
                    pending_names.push(j.child.link.clone());
                    // Mass on a fixed child belongs to the last moving link.
                    if child_inertial.mass > 0.0 {
                        if let Some(last) = links.last_mut() {
                            *last = last.combine(&child_inertial.transformed(&pending));
                        }
                    }
                    if j.child.link.contains("flange") || flange_name == base || joints.is_empty() {
                        flange_name = j.child.link.clone();
                        flange = pending;
                    }
                }
                other => {
                    return Err(err(format!("joint '{}' has type {other:?}; only revolute, continuous and fixed are supported", j.name)));
                }
            }
            current = j.child.link.clone();
        }
        if joints.is_empty() {
            return Err(err("no revolute joints found".into()));
        }
        Ok(Robot { name: urdf.name, base_link: base, joints, links, flange_name, flange, urdf: text.to_owned() })
    }

    /// Number of revolute joints (degrees of freedom).
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Names of the geometric error parameters: `<joint>.<dx|dy|dz|rx|ry|rz|dtheta>`.
    pub fn param_names(&self) -> Vec<String> {
        self.joints.iter().flat_map(|j| PARAM_SUFFIXES.iter().map(move |s| format!("{}.{s}", j.name))).collect()
    }

    /// What each of [`Self::param_names`] measures.
    pub fn param_kinds(&self) -> Vec<GeoKind> {
        self.joints.iter().flat_map(|_| PARAM_KINDS).collect()
    }

    /// The kinematic chain with per-joint frame errors: for joint `j`, the origin translation
    /// (thermally scaled) plus (dx, dy, dz), the nominal origin rotation, error rotations about the
    /// origin frame's x, y, z, then the joint rotation plus its zero offset.
    pub fn error_chain(&self) -> Chain {
        let mut b = ChainBuilder::new();
        let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
        for j in &self.joints {
            let idx: Vec<usize> = PARAM_SUFFIXES.iter().map(|s| b.param(format!("{}.{s}", j.name))).collect();
            b.trans(x, j.origin_xyz.x, Some(idx[0]), true);
            b.trans(y, j.origin_xyz.y, Some(idx[1]), true);
            b.trans(z, j.origin_xyz.z, Some(idx[2]), true);
            b.rot(z, j.origin_rpy.z, None);
            b.rot(y, j.origin_rpy.y, None);
            b.rot(x, j.origin_rpy.x, None);
            b.rot(x, 0.0, Some(idx[3]));
            b.rot(y, 0.0, Some(idx[4]));
            b.rot(z, 0.0, Some(idx[5]));
            b.joint(j.axis, 0.0, Some(idx[6]));
        }
        let (roll, pitch, yaw) = Rotation3::from_matrix_unchecked(self.flange.rot).euler_angles();
        b.trans(x, self.flange.pos.x, None, true);
        b.trans(y, self.flange.pos.y, None, true);
        b.trans(z, self.flange.pos.z, None, true);
        b.rot(z, yaw, None);
        b.rot(y, pitch, None);
        b.rot(x, roll, None);
        b.finish()
    }

    /// Joint limits in radians.
    pub fn limits(&self) -> Vec<(f64, f64)> {
        self.joints.iter().map(|j| (j.lower, j.upper)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn irb120_loads_with_six_joints_and_known_flange() {
        let r = Robot::irb120();
        assert_eq!(r.dof(), 6);
        assert_eq!(r.flange_name, "flange");
        let c = r.error_chain();
        let p = vec![0.0; c.n_params()];
        let f = c.point(&[0.0; 6], &p, 1.0, c.flange(), &Vector3::zeros());
        assert!((f - Vector3::new(0.374, 0.0, 0.630)).norm() < 1e-12, "{f}");
        assert!((r.links[1].mass - 3.909).abs() < 1e-12);
    }

    #[test]
    fn rejects_branching_and_prismatic() {
        let bad = r#"<robot name="x"><link name="a"/><link name="b"/>
            <joint name="j" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
            <limit lower="0" upper="1" effort="0" velocity="1"/></joint></robot>"#;
        let e = Robot::from_urdf_str(bad, "bad.urdf").unwrap_err().to_string();
        assert!(e.contains("prismatic") || e.contains("Prismatic"), "{e}");
    }

    fn revolute(name: &str, parent: &str, child: &str) -> String {
        format!(
            r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>
            <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
            <limit lower="-1" upper="1" effort="0" velocity="1"/></joint>"#
        )
    }

    fn link(name: &str, mass: &str, ixx: &str) -> String {
        format!(
            r#"<link name="{name}"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="{mass}"/>
            <inertia ixx="{ixx}" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>"#
        )
    }

    #[test]
    fn a_cycle_of_joints_is_an_error_not_an_endless_loop() {
        // base -> a -> b -> c -> a: the cycle a, b, c does not pass through the root.
        let text = format!(
            r#"<robot name="loop">{}{}{}{}{}{}{}{}</robot>"#,
            link("base", "1", "0.01"),
            link("a", "1", "0.01"),
            link("b", "1", "0.01"),
            link("c", "1", "0.01"),
            revolute("j1", "base", "a"),
            revolute("j2", "a", "b"),
            revolute("j3", "b", "c"),
            revolute("j4", "c", "a"),
        );
        let e = Robot::from_urdf_str(&text, "loop.urdf").unwrap_err().to_string();
        assert!(e.contains("loop.urdf") && e.contains("link 'a'") && e.contains("not a tree"), "{e}");
        // A cycle of fixed joints only, reached from the root, is caught by the walk itself.
        let fixed = |n: &str, p: &str, c: &str| format!(r#"<joint name="{n}" type="fixed"><parent link="{p}"/><child link="{c}"/></joint>"#);
        let text = format!(
            r#"<robot name="loop2">{}{}{}{}{}{}</robot>"#,
            link("base", "1", "0.01"),
            link("a", "1", "0.01"),
            link("b", "1", "0.01"),
            revolute("j1", "base", "a"),
            fixed("f1", "a", "b"),
            fixed("f2", "b", "a"),
        );
        let e = Robot::from_urdf_str(&text, "loop2.urdf").unwrap_err().to_string();
        assert!(e.contains("not a tree") || e.contains("cycle"), "{e}");
    }

    #[test]
    fn non_physical_mass_or_inertia_is_refused_naming_the_link() {
        for (mass, ixx, what) in
            [("NaN", "0.01", "mass"), ("-2", "0.01", "mass"), ("inf", "0.01", "mass"), ("1", "NaN", "ixx"), ("1", "-0.5", "ixx"), ("1", "inf", "ixx")]
        {
            let text = format!(r#"<robot name="r">{}{}{}</robot>"#, link("base", "1", "0.01"), link("arm", mass, ixx), revolute("j1", "base", "arm"),);
            let e = Robot::from_urdf_str(&text, "m.urdf").unwrap_err().to_string();
            assert!(e.contains("m.urdf") && e.contains("link 'arm'") && e.contains(what), "{mass} {ixx}: {e}");
        }
        // The same robot with sane values loads.
        let ok = format!(r#"<robot name="r">{}{}{}</robot>"#, link("base", "1", "0.01"), link("arm", "1", "0.01"), revolute("j1", "base", "arm"),);
        assert_eq!(Robot::from_urdf_str(&ok, "ok.urdf").expect("loads").dof(), 1);
    }

    #[test]
    fn a_link_in_millimetres_and_a_mimic_joint_are_named() {
        // 1 000 km: a URDF written in mm (or broken) is refused, naming the joint and the units.
        let far = format!(r#"<robot name="r">{}{}{}</robot>"#, link("base", "1", "0.01"), link("arm", "1", "0.01"), revolute("j1", "base", "arm"))
            .replace(r#"xyz="0 0 0.1""#, r#"xyz="0 0 1000000""#);
        let e = Robot::from_urdf_str(&far, "far.urdf").unwrap_err().to_string();
        assert!(e.contains("far.urdf") && e.contains("joint 'j1' sits 1000000 m") && e.contains("mm where URDF takes metres"), "{e}");
        let mimic = format!(
            r#"<robot name="r">{}{}{}{}{}</robot>"#,
            link("base", "1", "0.01"),
            link("a", "1", "0.01"),
            link("b", "1", "0.01"),
            revolute("j1", "base", "a"),
            revolute("j2", "a", "b")
        )
        .replace(
            r#"<limit lower="-1" upper="1" effort="0" velocity="1"/></joint>"#,
            r#"<limit lower="-1" upper="1" effort="0" velocity="1"/><mimic joint="j1"/></joint>"#,
        );
        let e = Robot::from_urdf_str(&mimic, "mimic.urdf").unwrap_err().to_string();
        assert!(e.contains("joint 'j1' mimics joint 'j1'") || e.contains("mimics joint 'j1'"), "{e}");
        assert!(e.contains("mimic joints are not supported"), "{e}");
    }
}
