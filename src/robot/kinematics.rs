//! The one forward-kinematics implementation of twincal.
//!
//! A serial arm is a chain of elementary operations: translations and rotations along unit axes.
//! The value of every operation is
//!
//! ```text
//! value = base · (thermal scale, translations only) + q[joint] (if any) + p[param] (if any)
//! ```
//!
//! so one evaluator serves every parametrisation (per-joint frame errors from a URDF, D-H,
//! Hayati, a generic 6R model): each model only builds its chain. Derivatives of any point fixed in
//! any link frame with respect to joint angles, parameters and the thermal scale come from the same
//! sweep, analytically:
//!
//! * translation along the world direction `w` of its axis: `∂p/∂v = w`,
//! * rotation about the world axis `w` through the frame origin `o`: `∂p/∂v = w × (p − o)`.
//!
//! Following Pinocchio, the immutable [`Chain`] holds the model and a reusable [`FkWork`]
//! holds the per-call frames so that hot loops allocate nothing.

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use serde::{Deserialize, Serialize};

/// Kind of an elementary operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum OpKind {
    /// A translation along the axis (value in m).
    Trans,
    /// A rotation about the axis (value in rad).
    Rot,
}

/// One elementary operation of a chain.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Op {
    /// Translation or rotation.
    pub kind: OpKind,
    /// Unit axis in the frame before the operation.
    pub axis: Vector3<f64>,
    /// Nominal value (m or rad).
    pub base: f64,
    /// Joint whose angle adds to the value.
    pub joint: Option<usize>,
    /// Parameter whose value adds to the value.
    pub param: Option<usize>,
    /// Factor of the parameter (1, or −1 where an operation undoes another one with the same
    /// parameter, as in a product of exponentials).
    #[serde(default = "unit", skip_serializing_if = "is_unit")]
    pub coef: f64,
    /// Whether `base` scales with the thermal factor (link lengths).
    pub thermal: bool,
}

fn unit() -> f64 {
    1.0
}

fn is_unit(v: &f64) -> bool {
    *v == 1.0
}

/// A rigid frame: rotation and origin in the base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Orientation: the frame's axes as columns, in base coordinates.
    pub rot: Matrix3<f64>,
    /// Origin in the base frame, m.
    pub pos: Vector3<f64>,
}

impl Frame {
    /// The base frame itself.
    pub fn identity() -> Self {
        Frame { rot: Matrix3::identity(), pos: Vector3::zeros() }
    }
    /// Maps a point given in this frame to the base frame.
    pub fn point(&self, local: &Vector3<f64>) -> Vector3<f64> {
        self.rot * local + self.pos
    }
    /// This frame expressed in `parent` (parent⁻¹ · self).
    pub fn relative_to(&self, parent: &Frame) -> Frame {
        let rt = parent.rot.transpose();
        Frame { rot: rt * self.rot, pos: rt * (self.pos - parent.pos) }
    }
    /// `child` (given in this frame) expressed in the base frame (self · child).
    pub fn compose(&self, child: &Frame) -> Frame {
        Frame { rot: self.rot * child.rot, pos: self.rot * child.pos + self.pos }
    }
}

/// The closest points of two lines given by a point and a unit direction, on the first and on
/// the second (their common normal's feet). The lines must not be parallel (|z1 × z2| > 0).
pub fn closest_points(c1: &Vector3<f64>, z1: &Vector3<f64>, c2: &Vector3<f64>, z2: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let w = c1 - c2;
    let (b, d, e) = (z1.dot(z2), z1.dot(&w), z2.dot(&w));
    let den = 1.0 - b * b;
    (c1 + z1 * ((b * e - d) / den), c2 + z2 * ((e - b * d) / den))
}

/// D-H frame 0 of an arm whose first joint axis is the line through `c` along the unit `z`: its
/// origin on the axis at the foot of the base origin, its x the base's x (the base's y where x
/// lies along the axis) made perpendicular to the axis.
pub fn dh_base_frame(c: &Vector3<f64>, z: &Vector3<f64>) -> Frame {
    let o = c - z * c.dot(z);
    let x = [Vector3::x(), Vector3::y()].iter().map(|v| v - z * v.dot(z)).find(|v| v.norm() > 1e-6).unwrap_or_else(Vector3::x).normalize();
    Frame { rot: Matrix3::from_columns(&[x, z.cross(&x), *z]), pos: o }
}

/// URDF roll, pitch, yaw of rotation `m` (m = Rz(yaw)·Ry(pitch)·Rx(roll)), exact to rounding
/// also at and near gimbal lock (pitch ±90°, where the yaw is taken as 0). nalgebra's
/// `euler_angles` loses the orientation there (0.05 rad for a pitch 1.5e-8 rad off the lock).
pub fn rpy(m: &nalgebra::Matrix3<f64>) -> [f64; 3] {
    // The yaw first (0 at lock), then pitch and roll from Rz(−yaw)·m = Ry(pitch)·Rx(roll), whose
    // first column is (cos p, 0, −sin p) and second row (0, cos r, −sin r) whatever the yaw's
    // rounding: the three angles then compose back to m.
    let y = if m[(0, 0)].hypot(m[(1, 0)]) > 1e-12 { m[(1, 0)].atan2(m[(0, 0)]) } else { 0.0 };
    let n = Rotation3::from_axis_angle(&Vector3::z_axis(), -y).into_inner() * m;
    [(-n[(1, 2)]).atan2(n[(1, 1)]), (-n[(2, 0)]).atan2(n[(0, 0)]), y]
}

/// Rotation matrix about a unit axis.
///
/// Inlined (the coordinate axes of every chain are a few instructions besides the sine and
/// cosine: built in registers, the matrix is not stored and read back); other axes go through
/// `general_rotation`.
#[inline]
pub fn axis_rotation(axis: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    if axis.x == 1.0 && axis.y == 0.0 && axis.z == 0.0 {
        let (s, c) = angle.sin_cos();
        return Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c);
    }
    if axis.y == 1.0 && axis.x == 0.0 && axis.z == 0.0 {
        let (s, c) = angle.sin_cos();
        return Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c);
    }
    if axis.z == 1.0 && axis.x == 0.0 && axis.y == 0.0 {
        let (s, c) = angle.sin_cos();
        return Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    }
    general_rotation(axis, angle)
}

/// Rotation matrix about any unit axis (the rare case of [`axis_rotation`]).
#[inline(never)]
fn general_rotation(axis: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Unit::new_normalize(*axis), angle).matrix()
}

/// A serial chain: elementary operations, the frame boundaries and the parameter names.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Chain {
    /// The elementary operations, base to flange.
    pub ops: Vec<Op>,
    /// `frame_end[f]` = number of operations that produce frame `f`.
    /// Frame 0 is the base, frame `j + 1` the child link of joint `j`, the last one the flange.
    pub frame_end: Vec<usize>,
    /// Number of joints (the length of `q`).
    pub n_joints: usize,
    /// Name of each parameter (`joint_2.a`, `joint_3.theta`, ...), in the order of `p`.
    pub param_names: Vec<String>,
}

/// Reusable scratch space for [`Chain`] evaluations.
#[derive(Clone, Debug)]
pub struct FkWork {
    /// Frame before each operation, then the final frame (len = ops + 1).
    pub pre: Vec<Frame>,
    /// Value of each operation in the last evaluation.
    pub values: Vec<f64>,
    /// The last rotation matrix of each operation and the bits of the (value, axis) it was made
    /// of (`None` before the first): an operation without a joint has the same value on every
    /// row, so its sine and cosine are computed once per parameter vector, not once per row.
    rot_key: Vec<Option<[u64; 4]>>,
    rot: Vec<Matrix3<f64>>,
}

impl FkWork {
    /// A workspace sized for `chain`.
    pub fn new(chain: &Chain) -> Self {
        let n = chain.ops.len();
        FkWork { pre: vec![Frame::identity(); n + 1], values: vec![0.0; n], rot_key: vec![None; n], rot: vec![Matrix3::identity(); n] }
    }
}

/// Derivatives of one point with respect to everything the chain depends on.
#[derive(Clone, Debug)]
pub struct PointJacobian {
    /// The point in the base frame, m.
    pub point: Vector3<f64>,
    /// ∂p/∂q_j, one column per joint.
    pub dq: Vec<Vector3<f64>>,
    /// ∂p/∂p_k, one column per parameter.
    pub dparam: Vec<Vector3<f64>>,
    /// ∂p/∂s (thermal scale factor).
    pub dscale: Vector3<f64>,
}

impl PointJacobian {
    /// Zeroed derivatives sized for `chain`.
    pub fn new(chain: &Chain) -> Self {
        PointJacobian {
            point: Vector3::zeros(),
            dq: vec![Vector3::zeros(); chain.n_joints],
            dparam: vec![Vector3::zeros(); chain.n_params()],
            dscale: Vector3::zeros(),
        }
    }
}

impl Chain {
    /// The parameters that are joint zero offsets (each added to a joint's own rotation), in
    /// joint order: what a controller's joint calibration table holds.
    pub fn zero_offset_params(&self) -> Vec<usize> {
        self.ops.iter().filter(|o| o.joint.is_some()).filter_map(|o| o.param).collect()
    }
    /// Number of parameters (the length of `p`).
    pub fn n_params(&self) -> usize {
        self.param_names.len()
    }
    /// Index of the flange frame.
    pub fn flange(&self) -> usize {
        self.frame_end.len() - 1
    }
    /// Number of frames: the base, one per joint, the flange.
    pub fn n_frames(&self) -> usize {
        self.frame_end.len()
    }

    /// Evaluates all frames for joint angles `q` (rad), parameters `p` and thermal scale `scale`.
    pub fn forward(&self, q: &[f64], p: &[f64], scale: f64, ws: &mut FkWork) {
        debug_assert_eq!(q.len(), self.n_joints);
        debug_assert_eq!(p.len(), self.n_params());
        if ws.pre.len() != self.ops.len() + 1 || ws.rot.len() != self.ops.len() || ws.rot_key.len() != self.ops.len() {
            *ws = FkWork::new(self);
        }
        let mut f = Frame::identity();
        for (k, op) in self.ops.iter().enumerate() {
            ws.pre[k] = f;
            let mut v = if op.thermal { op.base * scale } else { op.base };
            if let Some(j) = op.joint {
                v += q[j];
            }
            if let Some(i) = op.param {
                v += op.coef * p[i];
            }
            ws.values[k] = v;
            match op.kind {
                OpKind::Trans => f.pos += f.rot * (op.axis * v),
                OpKind::Rot if op.joint.is_some() => f.rot *= axis_rotation(&op.axis, v),
                // The other rotations do not change from row to row: the same (value, axis) bits
                // are the same matrix.
                OpKind::Rot => {
                    let a = &op.axis;
                    let same = match &ws.rot_key[k] {
                        Some(key) => key[0] == v.to_bits() && key[1] == a.x.to_bits() && key[2] == a.y.to_bits() && key[3] == a.z.to_bits(),
                        None => false,
                    };
                    if !same {
                        ws.rot_key[k] = Some([v.to_bits(), a.x.to_bits(), a.y.to_bits(), a.z.to_bits()]);
                        ws.rot[k] = axis_rotation(a, v);
                    }
                    f.rot *= &ws.rot[k];
                }
            }
        }
        ws.pre[self.ops.len()] = f;
    }

    /// Frame `f` from the last [`Chain::forward`].
    pub fn frame(&self, ws: &FkWork, f: usize) -> Frame {
        ws.pre[self.frame_end[f]]
    }

    /// Position and derivatives of a point fixed in frame `f` (local coordinates in m),
    /// using the frames of the last [`Chain::forward`].
    pub fn point_jacobian(&self, ws: &FkWork, f: usize, local: &Vector3<f64>, out: &mut PointJacobian) {
        let end = self.frame_end[f];
        let p = ws.pre[end].point(local);
        out.point = p;
        out.dq.iter_mut().for_each(|v| *v = Vector3::zeros());
        out.dparam.iter_mut().for_each(|v| *v = Vector3::zeros());
        out.dscale = Vector3::zeros();
        for (k, op) in self.ops[..end].iter().enumerate() {
            let fr = &ws.pre[k];
            let w = fr.rot * op.axis;
            let d = match op.kind {
                OpKind::Trans => w,
                OpKind::Rot => w.cross(&(p - fr.pos)),
            };
            if let Some(j) = op.joint {
                out.dq[j] += d;
            }
            if let Some(i) = op.param {
                out.dparam[i] += d * op.coef;
            }
            if op.thermal && op.kind == OpKind::Trans {
                out.dscale += d * op.base;
            }
        }
    }

    /// Angular Jacobian of frame `f` with respect to the joint angles, from the last
    /// [`Chain::forward`]: column `j` into `out[j]` is the base-frame axis of joint `j`'s
    /// rotations before `f` (a small change `δq` turns the frame by the rotation vector
    /// `Σ out[j]·δq_j`); translations turn nothing.
    pub fn angular_jacobian(&self, ws: &FkWork, f: usize, out: &mut [Vector3<f64>]) {
        out.iter_mut().for_each(|v| *v = Vector3::zeros());
        for (k, op) in self.ops[..self.frame_end[f]].iter().enumerate() {
            if let (OpKind::Rot, Some(j)) = (op.kind, op.joint) {
                out[j] += ws.pre[k].rot * op.axis;
            }
        }
    }

    /// Convenience: position of a point fixed in frame `f` (allocates a workspace).
    pub fn point(&self, q: &[f64], p: &[f64], scale: f64, f: usize, local: &Vector3<f64>) -> Vector3<f64> {
        let mut ws = FkWork::new(self);
        self.forward(q, p, scale, &mut ws);
        self.frame(&ws, f).point(local)
    }

    /// Checks a chain read from a file (a hand-edited or truncated one must give an error, not a
    /// panic): frames in order and ending at the last operation, joint and parameter indices in
    /// range, finite axes and offsets.
    pub fn validate(&self) -> Result<(), String> {
        let frames_ok = self.frame_end.len() >= 2 && self.frame_end.windows(2).all(|w| w[0] <= w[1]) && self.frame_end.last() == Some(&self.ops.len());
        let ops_ok = self.ops.iter().all(|o| {
            o.joint.is_none_or(|j| j < self.n_joints)
                && o.param.is_none_or(|k| k < self.n_params())
                && o.axis.iter().all(|v| v.is_finite())
                && o.base.is_finite()
                && o.coef.is_finite()
        });
        let joints_ok = (0..self.n_joints).all(|j| self.ops.iter().any(|o| o.joint == Some(j)));
        if !(frames_ok && ops_ok && joints_ok) {
            return Err("the kinematic chain is inconsistent (frames, joint or parameter indices, or non-finite values)".into());
        }
        // An axis is a unit vector; an offset is a link length (m) or an angle (rad).
        if let Some(i) = self.ops.iter().position(|o| (o.axis.norm() - 1.0).abs() > 1e-6) {
            return Err(format!("chain operation {i}: its axis {:?} is not a unit vector (edited result file?)", self.ops[i].axis.as_slice()));
        }
        if let Some(i) = self.ops.iter().position(|o| o.base.abs() > MAX_OP_OFFSET || o.coef.abs() > MAX_OP_OFFSET) {
            return Err(format!(
                "chain operation {i}: offset {} / coefficient {} beyond {MAX_OP_OFFSET} (m or rad; edited result file?)",
                crate::error::shown(self.ops[i].base),
                crate::error::shown(self.ops[i].coef)
            ));
        }
        Ok(())
    }

    /// Index of the operation that rotates joint `j`.
    pub fn joint_op(&self, j: usize) -> Option<usize> {
        self.ops.iter().position(|o| o.joint == Some(j))
    }
}

/// Largest |offset| of a chain operation a result file may hold (a 100 m link, 100 rad).
pub const MAX_OP_OFFSET: f64 = 100.0;

/// Helper to build chains operation by operation.
#[derive(Default)]
pub struct ChainBuilder {
    ops: Vec<Op>,
    frame_end: Vec<usize>,
    n_joints: usize,
    param_names: Vec<String>,
}

impl ChainBuilder {
    /// An empty chain: the base frame only.
    pub fn new() -> Self {
        ChainBuilder { frame_end: vec![0], ..Default::default() }
    }
    /// Adds a parameter and returns its index.
    pub fn param(&mut self, name: impl Into<String>) -> usize {
        self.param_names.push(name.into());
        self.param_names.len() - 1
    }
    /// Appends an operation (its axis normalised) with factor 1 on its parameter.
    pub fn op(&mut self, kind: OpKind, axis: Vector3<f64>, base: f64, joint: Option<usize>, param: Option<usize>, thermal: bool) {
        let axis = if axis.norm() > 0.0 { axis.normalize() } else { axis };
        self.ops.push(Op { kind, axis, base, joint, param, coef: 1.0, thermal });
    }
    /// Translation by `base + coef·p[param]` (`coef` −1: the inverse of a translation by the
    /// same parameter).
    pub fn trans_coef(&mut self, axis: Vector3<f64>, base: f64, param: usize, coef: f64, thermal: bool) {
        self.op(OpKind::Trans, axis, base, None, Some(param), thermal);
        self.ops.last_mut().expect("just pushed").coef = coef;
    }
    /// Rotation by `base + coef·p[param]`.
    pub fn rot_coef(&mut self, axis: Vector3<f64>, base: f64, param: usize, coef: f64) {
        self.op(OpKind::Rot, axis, base, None, Some(param), false);
        self.ops.last_mut().expect("just pushed").coef = coef;
    }
    /// Translation along an axis; `thermal` scales the base value.
    pub fn trans(&mut self, axis: Vector3<f64>, base: f64, param: Option<usize>, thermal: bool) {
        if base == 0.0 && param.is_none() {
            return;
        }
        self.op(OpKind::Trans, axis, base, None, param, thermal);
    }
    /// Rotation about an axis by `base` (rad) plus the parameter; a zero rotation without a
    /// parameter is left out.
    pub fn rot(&mut self, axis: Vector3<f64>, base: f64, param: Option<usize>) {
        if base == 0.0 && param.is_none() {
            return;
        }
        self.op(OpKind::Rot, axis, base, None, param, false);
    }
    /// A fixed transform as a URDF origin states it: the translation `xyz` (m), then the rotation
    /// `rpy` (rad; R = Rz(yaw)·Ry(pitch)·Rx(roll)).
    pub fn origin(&mut self, xyz: [f64; 3], rpy: [f64; 3]) {
        for (k, v) in xyz.into_iter().enumerate() {
            self.trans(Vector3::ith(k, 1.0), v, None, false);
        }
        for k in [2, 1, 0] {
            self.rot(Vector3::ith(k, 1.0), rpy[k], None);
        }
    }
    /// A fixed transform `f` (its rotation as URDF roll, pitch, yaw: [`rpy`]).
    pub fn fixed(&mut self, f: &Frame) {
        self.origin(f.pos.into(), rpy(&f.rot));
    }
    /// The joint rotation; closes the frame of the joint's child link.
    pub fn joint(&mut self, axis: Vector3<f64>, offset: f64, param: Option<usize>) -> usize {
        let j = self.n_joints;
        self.op(OpKind::Rot, axis, offset, Some(j), param, false);
        self.n_joints += 1;
        self.frame_end.push(self.ops.len());
        j
    }
    /// Closes the flange frame after any fixed operations that follow the last joint.
    pub fn finish(mut self) -> Chain {
        self.frame_end.push(self.ops.len());
        Chain { ops: self.ops, frame_end: self.frame_end, n_joints: self.n_joints, param_names: self.param_names }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_chain() -> Chain {
        let mut b = ChainBuilder::new();
        let x = Vector3::x();
        let y = Vector3::y();
        let z = Vector3::z();
        for j in 0..3 {
            let px = b.param(format!("j{j}.dx"));
            let pz = b.param(format!("j{j}.dz"));
            let rx = b.param(format!("j{j}.rx"));
            let ry = b.param(format!("j{j}.ry"));
            let th = b.param(format!("j{j}.dth"));
            b.trans(x, 0.1 * j as f64, Some(px), true);
            b.trans(z, 0.3, Some(pz), true);
            b.rot(x, 0.0, Some(rx));
            b.rot(y, 0.2, Some(ry));
            b.joint(if j == 1 { y } else { Vector3::new(0.3, 0.5, 0.8) }, 0.1, Some(th));
        }
        b.trans(x, 0.07, None, true);
        b.finish()
    }

    /// A workspace that kept the rotations of the last call (and of another chain) gives the
    /// frames of a fresh one, bit for bit.
    #[test]
    fn reused_workspace_gives_the_frames_of_a_fresh_one() {
        let c = test_chain();
        // The same number of operations, other axes (one of them not a coordinate axis).
        let mut other = test_chain();
        other.ops[2].axis = Vector3::new(0.6, 0.0, 0.8);
        other.ops[3].axis = Vector3::z();
        let mut ws = FkWork::new(&c);
        for k in 0..40 {
            let chain = if k % 7 == 3 { &other } else { &c };
            let q: Vec<f64> = (0..3).map(|j| ((k * 3 + j) as f64 * 0.71).sin()).collect();
            // The parameters change every fourth call, as between the trial points of a fit.
            let p: Vec<f64> = (0..c.n_params()).map(|i| 0.01 * ((i + k / 4) as f64 * 1.7).sin()).collect();
            let s = if k % 5 == 0 { 1.0002 } else { 1.0 };
            chain.forward(&q, &p, s, &mut ws);
            let mut fresh = FkWork::new(chain);
            chain.forward(&q, &p, s, &mut fresh);
            for (a, b) in ws.pre.iter().zip(&fresh.pre) {
                assert!(a.rot.iter().chain(a.pos.iter()).zip(b.rot.iter().chain(b.pos.iter())).all(|(u, v)| u.to_bits() == v.to_bits()), "call {k}");
            }
        }
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let c = test_chain();
        let q = [0.3, -0.7, 1.1];
        let p: Vec<f64> = (0..c.n_params()).map(|i| 0.01 * ((i as f64) * 1.7).sin()).collect();
        let s = 1.0003;
        let local = Vector3::new(0.01, -0.02, 0.05);
        let mut ws = FkWork::new(&c);
        let mut jac = PointJacobian::new(&c);
        for f in 0..c.n_frames() {
            c.forward(&q, &p, s, &mut ws);
            c.point_jacobian(&ws, f, &local, &mut jac);
            let h = 1e-6;
            for j in 0..3 {
                let mut qp = q;
                qp[j] += h;
                let mut qm = q;
                qm[j] -= h;
                let fd = (c.point(&qp, &p, s, f, &local) - c.point(&qm, &p, s, f, &local)) / (2.0 * h);
                assert!((fd - jac.dq[j]).norm() < 1e-8, "frame {f} joint {j}: {fd} vs {}", jac.dq[j]);
            }
            for i in 0..c.n_params() {
                let mut pp = p.clone();
                pp[i] += h;
                let mut pm = p.clone();
                pm[i] -= h;
                let fd = (c.point(&q, &pp, s, f, &local) - c.point(&q, &pm, s, f, &local)) / (2.0 * h);
                assert!((fd - jac.dparam[i]).norm() < 1e-8, "frame {f} param {}", c.param_names[i]);
            }
            let fd = (c.point(&q, &p, s + h, f, &local) - c.point(&q, &p, s - h, f, &local)) / (2.0 * h);
            assert!((fd - jac.dscale).norm() < 1e-8);
        }
    }

    /// The angular Jacobian turns each frame as a central difference of its rotation does.
    #[test]
    fn angular_jacobian_matches_finite_differences() {
        let c = test_chain();
        let q = [0.3, -0.7, 1.1];
        let p: Vec<f64> = (0..c.n_params()).map(|i| 0.01 * ((i as f64) * 1.3).cos()).collect();
        let mut ws = FkWork::new(&c);
        let mut w = vec![Vector3::zeros(); 3];
        let rot = |q: &[f64; 3], f: usize| {
            let mut ws = FkWork::new(&c);
            c.forward(q, &p, 1.0, &mut ws);
            c.frame(&ws, f).rot
        };
        for f in 0..c.n_frames() {
            c.forward(&q, &p, 1.0, &mut ws);
            c.angular_jacobian(&ws, f, &mut w);
            let h = 1e-6;
            for j in 0..3 {
                let (mut qp, mut qm) = (q, q);
                qp[j] += h;
                qm[j] -= h;
                // R(q + h) R(q − h)ᵀ turns by 2h times the column: its antisymmetric part's vector
                // (sin of the angle times the axis; exact where an arc cosine is not).
                let m = rot(&qp, f) * rot(&qm, f).transpose();
                let d = Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) / (4.0 * h);
                assert!((d - w[j]).norm() < 1e-8, "frame {f} joint {j}: {d} vs {}", w[j]);
            }
        }
    }
}
