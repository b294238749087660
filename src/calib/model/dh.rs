//! The D-H description of a serial arm: derived from its URDF at zero angles (standard, or in
//! Hayati's form for nearly parallel axes), and the chain of its deviation parameters.

use super::Kind;
use crate::robot::kinematics::{Chain, ChainBuilder, FkWork, Frame};
use crate::robot::Robot;
use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// One standard D-H row (Craig's distal convention: Rz(θ)·Tz(d)·Tx(a)·Rx(α)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DhRow {
    /// Joint angle offset θ, rad.
    pub theta: f64,
    /// Offset d along the previous z axis, m.
    pub d: f64,
    /// Length a along the new x axis, m.
    pub a: f64,
    /// Twist α about the new x axis, rad.
    pub alpha: f64,
    /// This joint's axis is parallel to the next one (Hayati's β replaces Δd).
    pub parallel: bool,
    /// Hayati's nominal tilt β about the new y axis, rad, of a row whose next axis is nearly
    /// but not exactly parallel (a calibrated arm's): 0 otherwise.
    pub beta: f64,
}

/// Consecutive axes closer to parallel than this (rad) take Hayati's form in a `hayati` table
/// (a β tilt instead of a far common normal: 0.4 m of offset at 1e-4 rad would put it 4 km away).
pub const NEARLY_PARALLEL_RAD: f64 = 0.05;

/// A D-H description of a serial arm: fixed base transform, rows, fixed flange transform.
#[derive(Clone, Debug, PartialEq)]
pub struct DhTable {
    /// Fixed transform from the base frame to D-H frame 0.
    pub base: Frame,
    /// One row per joint.
    pub rows: Vec<DhRow>,
    /// Fixed transform from the last D-H frame to the flange.
    pub tool: Frame,
}

fn signed_angle(from: &Vector3<f64>, to: &Vector3<f64>, about: &Vector3<f64>) -> f64 {
    from.cross(to).dot(about).atan2(from.dot(to))
}

impl DhTable {
    /// Derives the D-H table of a robot from its joint axes at zero angles.
    pub fn from_robot(robot: &Robot) -> DhTable {
        Self::from_robot_within(robot, 1e-9)
    }

    /// [`Self::from_robot`] in Hayati's form: consecutive axes within [`NEARLY_PARALLEL_RAD`]
    /// of parallel are parallel rows with a nominal β (exact: the row's origin where the next
    /// axis pierces the plane normal to the previous one, α and β the tilt between them).
    pub fn from_robot_hayati(robot: &Robot) -> DhTable {
        Self::from_robot_within(robot, NEARLY_PARALLEL_RAD)
    }

    fn from_robot_within(robot: &Robot, parallel_rad: f64) -> DhTable {
        let chain = robot.error_chain();
        let n = chain.n_joints;
        let mut ws = FkWork::new(&chain);
        chain.forward(&vec![0.0; n], &vec![0.0; chain.n_params()], 1.0, &mut ws);
        let lines: Vec<(Vector3<f64>, Vector3<f64>)> = (0..n)
            .map(|j| {
                let k = chain.joint_op(j).expect("joint op");
                let f = ws.pre[k];
                (f.pos, (f.rot * chain.ops[k].axis).normalize())
            })
            .collect();
        let flange = chain.frame(&ws, chain.flange());
        // Frame 0 on joint 1's axis, at the foot of the base origin; x0 from world x.
        let mut frames = vec![crate::robot::kinematics::dh_base_frame(&lines[0].0, &lines[0].1)];
        let mut rows = Vec::with_capacity(n);
        for i in 1..=n {
            let prev = frames[i - 1];
            let (zp, op) = (prev.rot.column(2).into_owned(), prev.pos);
            let (pi, zi) = if i < n { lines[i] } else { (flange.pos, zp) };
            let cross = zp.cross(&zi);
            let parallel = cross.norm() < 1e-9 || (i < n && cross.norm() < parallel_rad.sin() && zp.dot(&zi) > 0.0);
            if parallel && i < n && cross.norm() >= 1e-9 {
                // Nearly parallel: the origin where axis i pierces the plane through the previous
                // origin normal to the previous axis (d = 0), x towards it, then α and β tilt z
                // onto axis i.
                let q = pi + zi * ((op - pi).dot(&zp) / zi.dot(&zp));
                let gap = q - op;
                let xi = if gap.norm() > 1e-9 { gap.normalize() } else { prev.rot.column(0).into_owned() };
                let f = Matrix3::from_columns(&[xi, zp.cross(&xi), zp]);
                let local = f.transpose() * zi;
                let beta = local.x.clamp(-1.0, 1.0).asin();
                let alpha = (-local.y).atan2(local.z);
                let theta = signed_angle(&prev.rot.column(0).into_owned(), &xi, &zp);
                rows.push(DhRow { theta, d: 0.0, a: gap.dot(&xi), alpha, parallel: true, beta });
                let rot =
                    f * Rotation3::from_axis_angle(&Vector3::x_axis(), alpha).into_inner() * Rotation3::from_axis_angle(&Vector3::y_axis(), beta).into_inner();
                frames.push(Frame { rot, pos: q });
                continue;
            }
            let (foot_prev, foot_i, xi) = if !parallel {
                // Closest points of the two lines.
                let (fp, fi) = crate::robot::kinematics::closest_points(&op, &zp, &pi, &zi);
                let gap = fi - fp;
                let x = if gap.norm() > 1e-9 { gap.normalize() } else { cross.normalize() };
                (fp, fi, x)
            } else {
                // Parallel axes: the common normal through the previous origin (d = 0), or for the
                // flange the foot of the flange origin on the last axis.
                let fi = if i < n { pi + zi * (op - pi).dot(&zi) } else { op + zp * (flange.pos - op).dot(&zp) };
                let fp = if i < n { op } else { fi };
                let gap = fi - fp;
                let x = if gap.norm() > 1e-9 { gap.normalize() } else { prev.rot.column(0).into_owned() };
                (fp, fi, x)
            };
            let xp = prev.rot.column(0).into_owned();
            let theta = signed_angle(&xp, &xi, &zp);
            let d = (foot_prev - op).dot(&zp);
            let a = (foot_i - foot_prev).dot(&xi);
            let alpha = signed_angle(&zp, &zi, &xi);
            rows.push(DhRow { theta, d, a, alpha, parallel: parallel && i < n, beta: 0.0 });
            frames.push(Frame { rot: Matrix3::from_columns(&[xi, zi.cross(&xi), zi]), pos: foot_i });
        }
        let tool = flange.relative_to(&frames[n]);
        DhTable { base: frames[0], rows, tool }
    }

    /// The chain of this table with deviation parameters (`absolute = false`: values are nominal +
    /// parameter) or absolute parameters (`absolute = true` is expressed by nominal zeros).
    pub fn chain(&self, hayati: bool, with_fixed: bool) -> (Chain, Vec<Kind>) {
        let mut b = ChainBuilder::new();
        let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
        let mut kinds = Vec::new();
        let fixed = |b: &mut ChainBuilder, f: &Frame| {
            b.trans(x, f.pos.x, None, true);
            b.trans(y, f.pos.y, None, true);
            b.trans(z, f.pos.z, None, true);
            let (r, p, yw) = Rotation3::from_matrix_unchecked(f.rot).euler_angles();
            b.rot(z, yw, None);
            b.rot(y, p, None);
            b.rot(x, r, None);
        };
        if with_fixed {
            fixed(&mut b, &self.base);
        }
        for (i, row) in self.rows.iter().enumerate() {
            let j = i + 1;
            let th = b.param(format!("joint_{j}.theta"));
            kinds.push(Kind::Angle);
            b.joint(z, row.theta, Some(th));
            let beta = hayati && row.parallel;
            if beta {
                b.trans(z, row.d, None, true);
            } else {
                let d = b.param(format!("joint_{j}.d"));
                kinds.push(Kind::Length);
                b.trans(z, row.d, Some(d), true);
            }
            let a = b.param(format!("joint_{j}.a"));
            kinds.push(Kind::Length);
            b.trans(x, row.a, Some(a), true);
            let al = b.param(format!("joint_{j}.alpha"));
            kinds.push(Kind::Angle);
            b.rot(x, row.alpha, Some(al));
            if beta {
                let be = b.param(format!("joint_{j}.beta"));
                kinds.push(Kind::Angle);
                b.rot(y, row.beta, Some(be));
            }
        }
        // The joint ops close link frames right after the joint rotation; D-H puts the link's
        // geometry after it, which is the same serial product.
        if with_fixed {
            fixed(&mut b, &self.tool);
        }
        (b.finish(), kinds)
    }
}
