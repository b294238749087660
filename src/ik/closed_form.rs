//! Closed-form inverse kinematics of a six-joint arm: every solution of a flange pose, for the two
//! structures most six-axis arms have.
//!
//! # The model
//!
//! A [`Chain`] evaluated at a parameter vector `p` (thermal scale 1) is a product of
//! exponentials: with joint `k`'s axis the line through `c_k` along the unit `z_k` at q = 0 (in
//! the base frame) and `E_k(θ)` the rotation by θ about that line,
//!
//! ```text
//! T(q) = E_1(q_1) · E_2(q_2) · … · E_6(q_6) · T(0)
//! ```
//!
//! whatever the chain's own parametrisation, joint offsets, axis directions and sign conventions
//! (they are all in the lines and in `T(0)`). Everything below is derived from the chain's frames
//! at q = 0 only, so any URDF or calibrated model of one of the two shapes is solved, not a table
//! of particular robots. Joints are numbered 1..6 in these docs, 0..5 in the code.
//!
//! # Structures ([`ClosedFormKind`])
//!
//! * **Spherical wrist** (the ortho-parallel industrial arms: ABB IRB 120, KUKA KR 6, …): axes 4,
//!   5, 6 meet in one point W (the wrist centre), axis 2 ∥ axis 3, axis 1 ⟂ axis 2. `E_4…E_6` leave
//!   W in place, so W's position depends on q1..q3 only:
//!   - q1: the rotations about the parallel axes 2 and 3 keep a point's height along them, so
//!     `E_1(−q1)·W` must have W's height at q = 0 (the arm plane's lateral offset included):
//!     `a cos q1 + b sin q1 = d`, two solutions (front, back);
//!   - q3: the distance from axis 2 to `E_1(−q1)·W` is a function of q3 alone,
//!     `A + B cos q3 + C sin q3 = ρ²`, two solutions (elbow up, down);
//!   - q2: the planar angle about axis 2 between the wrist centre after q3 and its target;
//!   - q4, q5, q6: the wrist rotation `R_4 R_5 R_6 = (R_1 R_2 R_3)ᵀ R R(0)ᵀ`: axis 6's direction
//!     after q4, q5 lies on two cones (about axis 4 and about axis 5), two solutions (q5 and −q5
//!     for an orthogonal wrist), then q6 from the rest.
//! * **UR family** (UR3, UR5, UR10, …): axes 2, 3, 4 parallel, axis 1 ⟂ 2, axis 5 ⟂ 4, axis 6 ⟂
//!   5, and axes 5 and 6 meeting in a point P (as in every UR arm: D-H a5 = 0):
//!   - q1: P depends on q1..q4 only and the parallel axes keep its height: as above, two;
//!   - q5: axis 6's direction has a height along the parallel axes that depends on q1 and q5
//!     only: two per q1;
//!   - q6: from the same direction equation in the frame of axis 6;
//!   - q2, q3: a point of axis 4 (where q5, q6 and the pose put it) reached by the planar 2R of
//!     axes 2 and 3, two elbows; q4: the rest of the rotation about the parallel axes.
//!
//! Up to 8 solutions each. Every one is finished by Gauss-Newton steps on the 6-D pose error with
//! the chain's own forward kinematics, so it reproduces the pose to [`ACCEPT_M`] and
//! [`ACCEPT_RAD`] on the chain even where the structure holds only to [`STRUCTURE_TOL_M`] and
//! [`STRUCTURE_TOL_RAD`]; a candidate that does not is not returned.
//!
//! # Singular cases (one representative solution, never NaN)
//!
//! * shoulder (the wrist centre, or P, on axis 1): q1 is free; q1 = 0 is returned;
//! * wrist (q5 = 0 for a spherical wrist, axes 4 and 6 aligned): q4 is free; q4 = 0 and q6 takes
//!   the whole turn;
//! * UR's q6 undetermined (axis 6 parallel to axes 2, 3, 4): q6 = 0 and q4 takes the turn;
//! * elbow stretched or folded (the two q3 coincide), and any solutions that coincide: returned
//!   once ([`DUPLICATE_RAD`]).
//!
//! # Poses off the chain's poses
//!
//! Nothing above assumes the pose is one the chain takes at some configuration: a pose read on
//! another model (a target taught on the true arm, read on the nominal one) is solved exactly
//! wherever the chain reaches it. Near a singularity a small change of the pose can change the
//! solutions a lot: within a few degrees of a stretched elbow the reach margin is a small
//! fraction of a millimetre (a pose past it has no solution at all: the chain does not reach
//! it), and near the wrist singularity (q5 ≈ 0) q4 and q6 trade, near the shoulder singularity
//! q1 and q4, by far more than the pose moved.

use crate::robot::kinematics::{axis_rotation, closest_points, Chain, FkWork, Frame, OpKind};
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use std::cell::RefCell;
use std::f64::consts::{PI, TAU};

/// Tolerance on the structure, rad: axes whose directions differ by less are parallel, axes whose
/// directions are within it of a right angle are perpendicular.
pub const STRUCTURE_TOL_RAD: f64 = 1e-9;
/// Tolerance on the structure, m: axes closer than this meet.
pub const STRUCTURE_TOL_M: f64 = 1e-9;
/// Smallest sine of the angle between two wrist axes that must meet (axes 4 and 5, 5 and 6): a
/// wrist with nearly parallel consecutive axes has no well-defined centre.
pub const MIN_CROSSING_SINE: f64 = 1e-3;
/// A projection shorter than this (m for points, unitless for directions) is taken as zero: the
/// angle it would give is undetermined (a singular case) and the documented convention is used.
pub const DEGENERATE: f64 = 1e-12;
/// Relative slack on `|d| ≤ √(a² + b²)` in `a cos x + b sin x = d`: a target past the boundary by
/// less (rounding at a stretched elbow, a tangent shoulder) is solved at the boundary.
pub const REACH_SLACK: f64 = 1e-9;
/// Largest number of Gauss-Newton steps that finish a closed-form solution.
pub const NEWTON_STEPS: usize = 6;
/// Position error (m) below which the Gauss-Newton steps stop.
pub const NEWTON_GOAL_M: f64 = 1e-13;
/// Orientation error (rad) below which the Gauss-Newton steps stop.
pub const NEWTON_GOAL_RAD: f64 = 1e-13;
/// Damping of the Gauss-Newton steps (m or rad): a singular Jacobian gives a bounded step.
pub const NEWTON_DAMPING: f64 = 1e-9;
/// A solution is returned only if it reproduces the flange position to this, m.
pub const ACCEPT_M: f64 = 1e-12;
/// A solution is returned only if it reproduces the flange orientation to this, rad.
pub const ACCEPT_RAD: f64 = 1e-12;
/// Two solutions whose every wrapped joint angle differs by less than this (rad) are one.
pub const DUPLICATE_RAD: f64 = 1e-9;
/// Slack (rad) on the joint limits in [`within_limits`]: an angle beyond a limit by less (the
/// rounding of a solution at its limit) is clamped onto it.
pub const LIMIT_SLACK_RAD: f64 = 1e-12;

/// Which closed form a chain has (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClosedFormKind {
    /// Axes 4, 5, 6 meet in the wrist centre, axis 2 ∥ axis 3, axis 1 ⟂ axis 2.
    SphericalWrist,
    /// Axes 2, 3, 4 parallel, axis 1 ⟂ 2, axis 5 ⟂ 4, axis 6 ⟂ 5, axes 5 and 6 meeting.
    Ur,
}

/// Closed-form inverse kinematics of one six-joint chain at one parameter vector: every flange
/// pose's solutions (up to 8), prepared once by [`ClosedForm::of`].
#[derive(Clone, Debug)]
pub struct ClosedForm {
    /// The chain, evaluated at `p` with thermal scale 1.
    chain: Chain,
    /// The parameter vector the chain is evaluated at.
    p: Vec<f64>,
    /// The structure detected.
    kind: ClosedFormKind,
    /// Index of each joint's rotation in the chain's operations.
    joint_op: [usize; 6],
    /// A point of each joint's axis at q = 0 (the joint's origin), base frame, m.
    c: [Vector3<f64>; 6],
    /// Each joint's unit axis at q = 0, base frame.
    z: [Vector3<f64>; 6],
    /// A unit vector perpendicular to each joint's axis (to read an angle about it).
    perp: [Vector3<f64>; 6],
    /// The flange at q = 0.
    home: Frame,
    /// The point the first three (spherical wrist) or four (UR) joints place, at q = 0: the wrist
    /// centre, or where axes 5 and 6 meet; base frame, m.
    centre: Vector3<f64>,
    /// [`Self::centre`] in the flange frame (it moves with the flange), m.
    centre_local: Vector3<f64>,
    /// The point the planar 2R of axes 2 and 3 reaches, at q = 0: the wrist centre, or a point
    /// of axis 4 (UR); base frame, m.
    elbow_point: Vector3<f64>,
}

thread_local! {
    /// The forward-kinematics workspace of [`ClosedForm::solve`] (allocated once per thread).
    static WORK: RefCell<Option<FkWork>> = const { RefCell::new(None) };
}

/// Wraps an angle into (−π, π], rad.
pub fn wrap(x: f64) -> f64 {
    let y = x.rem_euclid(TAU);
    if y > PI {
        y - TAU
    } else {
        y
    }
}

/// Rotation by `angle` (rad) about the unit axis `z`.
fn rot(z: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    axis_rotation(z, angle)
}

/// The component of `v` perpendicular to the unit `z`.
fn perpendicular(z: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    v - z * z.dot(v)
}

/// The angle (rad) of the rotation about the unit `z` that turns `a` onto `b` (their components
/// perpendicular to `z`); 0 where either component is shorter than [`DEGENERATE`] (undetermined).
fn angle_about(z: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let (a, b) = (perpendicular(z, a), perpendicular(z, b));
    if a.norm() < DEGENERATE || b.norm() < DEGENERATE {
        return 0.0;
    }
    z.dot(&a.cross(&b)).atan2(a.dot(&b))
}

/// The solutions x of `a cos x + b sin x = d`, at most two (the count second). Where
/// `√(a² + b²) < degenerate` any x solves it if `|d|` is as small (x = 0 is returned), none
/// otherwise; past the boundary by less than [`REACH_SLACK`] the boundary's one solution.
fn trig(a: f64, b: f64, d: f64, degenerate: f64) -> ([f64; 2], usize) {
    let r = a.hypot(b);
    if !(r.is_finite() && d.is_finite()) {
        return ([0.0; 2], 0);
    }
    if r < degenerate {
        return if d.abs() < degenerate { ([0.0; 2], 1) } else { ([0.0; 2], 0) };
    }
    let ratio = d / r;
    if ratio.abs() > 1.0 + REACH_SLACK {
        return ([0.0; 2], 0);
    }
    let (phi, delta) = (b.atan2(a), ratio.clamp(-1.0, 1.0).acos());
    if delta == 0.0 {
        ([phi, phi], 1)
    } else {
        ([phi + delta, phi - delta], 2)
    }
}

/// The joints' axes of a chain at q = 0.
struct Lines {
    /// A point of each axis (the joint's origin), base frame, m.
    c: [Vector3<f64>; 6],
    /// Each axis's unit direction, base frame.
    z: [Vector3<f64>; 6],
    /// Index of each joint's rotation in the chain's operations.
    joint_op: [usize; 6],
    /// The flange at q = 0.
    home: Frame,
}

/// The joints' axes at q = 0, if each of the six joints is one rotation of the chain.
fn joint_lines(chain: &Chain, p: &[f64]) -> Option<Lines> {
    if chain.n_joints != 6 || p.len() != chain.n_params() || chain.validate().is_err() {
        return None;
    }
    let mut ws = FkWork::new(chain);
    chain.forward(&[0.0; 6], p, 1.0, &mut ws);
    let (mut c, mut z, mut ops) = ([Vector3::zeros(); 6], [Vector3::zeros(); 6], [0; 6]);
    for j in 0..6 {
        let mut of_joint = chain.ops.iter().enumerate().filter(|(_, o)| o.joint == Some(j));
        let (k, op) = of_joint.next()?;
        if of_joint.next().is_some() || op.kind != OpKind::Rot {
            return None;
        }
        let fr = &ws.pre[k];
        (c[j], z[j], ops[j]) = (fr.pos, (fr.rot * op.axis).normalize(), k);
    }
    let home = chain.frame(&ws, chain.flange());
    let finite = c.iter().chain(&z).chain([&home.pos]).all(|v| v.iter().all(|x| x.is_finite()));
    finite.then_some(Lines { c, z, joint_op: ops, home })
}

/// Whether the unit directions `a` and `b` are parallel (or antiparallel) within the tolerance.
fn parallel(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
    a.cross(b).norm() <= STRUCTURE_TOL_RAD
}

/// Whether the unit directions `a` and `b` are perpendicular within the tolerance.
fn orthogonal(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
    a.dot(b).abs() <= STRUCTURE_TOL_RAD
}

/// Where the lines `(c1, z1)` and `(c2, z2)` meet (the middle of their common normal), if they
/// cross at more than [`MIN_CROSSING_SINE`] and pass within [`STRUCTURE_TOL_M`] of each other.
fn meeting(c1: &Vector3<f64>, z1: &Vector3<f64>, c2: &Vector3<f64>, z2: &Vector3<f64>) -> Option<Vector3<f64>> {
    if z1.cross(z2).norm() < MIN_CROSSING_SINE {
        return None;
    }
    let (a, b) = closest_points(c1, z1, c2, z2);
    ((a - b).norm() <= STRUCTURE_TOL_M).then_some((a + b) / 2.0)
}

/// A unit vector perpendicular to the unit `z`.
fn any_perpendicular(z: &Vector3<f64>) -> Vector3<f64> {
    let other = if z.x.abs() < 0.5 { Vector3::x() } else { Vector3::y() };
    perpendicular(z, &other).normalize()
}

impl ClosedForm {
    /// Prepares the closed form of `chain` evaluated at the parameter vector `p` (thermal scale
    /// 1): `None` unless the chain has six joints, each one rotation, and at q = 0 one of the two
    /// structures of [`ClosedFormKind`] within [`STRUCTURE_TOL_RAD`] and [`STRUCTURE_TOL_M`]
    /// (the spherical wrist is tried first), with links that make the planar 2R of axes 2 and 3
    /// non-degenerate (both its links longer than [`STRUCTURE_TOL_M`]).
    pub fn of(chain: &Chain, p: &[f64]) -> Option<ClosedForm> {
        let Lines { c, z, joint_op, home } = joint_lines(chain, p)?;
        let (kind, centre, elbow_point) = spherical_wrist(&c, &z).or_else(|| ur(&c, &z))?;
        // The planar 2R of axes 2 and 3: both links must have a length.
        let e = perpendicular(&z[1], &(c[2] - c[1]));
        let r = perpendicular(&z[1], &(elbow_point - c[2]));
        if e.norm() <= STRUCTURE_TOL_M || r.norm() <= STRUCTURE_TOL_M {
            return None;
        }
        let perp = z.map(|v| any_perpendicular(&v));
        let centre_local = home.rot.transpose() * (centre - home.pos);
        Some(ClosedForm { chain: chain.clone(), p: p.to_vec(), kind, joint_op, c, z, perp, home, centre, centre_local, elbow_point })
    }

    /// The structure this chain has.
    pub fn kind(&self) -> ClosedFormKind {
        self.kind
    }

    /// Every solution (up to 8) of the flange pose `flange` (the chain's flange frame in its base
    /// frame, m), pushed onto `out` (nothing is cleared): joint angles in rad, each wrapped into
    /// (−π, π], each reproducing the pose on the chain to [`ACCEPT_M`] and [`ACCEPT_RAD`], none
    /// twice. An unreachable (or non-finite) pose pushes nothing; the singular cases push one
    /// representative (module docs). Joint limits are not applied (see [`within_limits`]). Uses a
    /// per-thread workspace: nothing is allocated after a thread's first call besides `out`'s
    /// growth.
    pub fn solve(&self, flange: &Frame, out: &mut Vec<[f64; 6]>) {
        WORK.with(|cell| {
            let mut slot = cell.borrow_mut();
            let ws = slot.get_or_insert_with(|| FkWork::new(&self.chain));
            self.solve_with(flange, ws, out);
        })
    }

    /// [`Self::solve`] with the caller's forward-kinematics workspace (made by
    /// [`FkWork::new`] for this chain; resized if it is another chain's).
    pub fn solve_with(&self, flange: &Frame, ws: &mut FkWork, out: &mut Vec<[f64; 6]>) {
        if !flange.rot.iter().chain(flange.pos.iter()).all(|v| v.is_finite()) {
            return;
        }
        let start = out.len();
        match self.kind {
            ClosedFormKind::SphericalWrist => self.solve_spherical(flange, ws, start, out),
            ClosedFormKind::Ur => self.solve_ur(flange, ws, start, out),
        }
    }

    /// The point `x` rotated by `angle` (rad) about joint `j`'s axis at q = 0.
    fn turn(&self, j: usize, angle: f64, x: &Vector3<f64>) -> Vector3<f64> {
        self.c[j] + rot(&self.z[j], angle) * (x - self.c[j])
    }

    /// The q1 (at most two) that put the point `x` (base frame) at the height along axis 2 that
    /// `x0` has at q = 0: `E_1(−q1)·x` is then reachable by the joints about parallel axes.
    fn shoulder(&self, x: &Vector3<f64>, x0: &Vector3<f64>) -> ([f64; 2], usize) {
        let (z1, z2) = (&self.z[0], &self.z[1]);
        let g = z1.dot(z2);
        let v = x - self.c[0];
        // z2 · R(z1, −q1) v = (R(z1, q1) z2) · v, and R(z1, q1) z2 = g z1 + cos q1 (z2 − g z1) + sin q1 (z1 × z2).
        let a = (z2 - z1 * g).dot(&v);
        let b = z1.cross(z2).dot(&v);
        let d = z2.dot(&(x0 - self.c[0])) - g * z1.dot(&v);
        trig(a, b, d, DEGENERATE)
    }

    /// The (q2, q3) (at most two: the elbows) with `E_2(q2)·E_3(q3)·x0 = u`, up to `u`'s height
    /// along axis 2 (set by q1): q3 from the distance to axis 2, q2 from the planar angle.
    fn planar(&self, u: &Vector3<f64>, x0: &Vector3<f64>) -> ([(f64, f64); 2], usize) {
        let (z2, z3) = (&self.z[1], &self.z[2]);
        let e = perpendicular(z2, &(self.c[2] - self.c[1]));
        let r = perpendicular(z2, &(x0 - self.c[2]));
        let rho2 = perpendicular(z2, &(u - self.c[1])).norm_squared();
        // |e + R(z3, q3) r|² = |e|² + |r|² + 2 (cos q3 e·r + sin q3 e·(z3 × r)).
        let (q3s, n) = trig(2.0 * e.dot(&r), 2.0 * e.dot(&z3.cross(&r)), rho2 - e.norm_squared() - r.norm_squared(), DEGENERATE);
        let mut out = [(0.0, 0.0); 2];
        for (k, &q3) in q3s[..n].iter().enumerate() {
            let at = self.turn(2, q3, x0);
            out[k] = (angle_about(z2, &(at - self.c[1]), &(u - self.c[1])), q3);
        }
        (out, n)
    }

    /// The (q4, q5, q6) (at most two) of the spherical wrist with `R_4 R_5 R_6 = m`: axis 6's
    /// direction `m z6` reached from `z6` by q5 about axis 5 then q4 about axis 4 (two cones).
    fn wrist(&self, m: &Matrix3<f64>) -> ([[f64; 3]; 2], usize) {
        let (z4, z5, z6) = (&self.z[3], &self.z[4], &self.z[5]);
        let t = m * z6;
        // c = R(z4, −q4) t = R(z5, q5) z6 has z4·c = z4·t and z5·c = z5·z6: c = α z4 + β z5 + γ (z4 × z5).
        let (g, t4, s5) = (z4.dot(z5), z4.dot(&t), z5.dot(z6));
        let den = 1.0 - g * g;
        let (alpha, beta) = ((t4 - g * s5) / den, (s5 - g * t4) / den);
        let n = z4.cross(z5);
        let gamma2 = (1.0 - (alpha * alpha + beta * beta + 2.0 * alpha * beta * g)) / n.norm_squared();
        if !(gamma2 >= -REACH_SLACK) {
            return ([[0.0; 3]; 2], 0);
        }
        let gamma = gamma2.max(0.0).sqrt();
        let count = if gamma > 0.0 { 2 } else { 1 };
        let mut out = [[0.0; 3]; 2];
        for (k, sign) in [1.0, -1.0].into_iter().take(count).enumerate() {
            let c = z4 * alpha + z5 * beta + n * (sign * gamma);
            let q5 = angle_about(z5, z6, &c);
            let q4 = angle_about(z4, &c, &t);
            let r6 = rot(z5, -q5) * rot(z4, -q4) * m;
            out[k] = [q4, q5, angle_about(z6, &self.perp[5], &(r6 * self.perp[5]))];
        }
        (out, count)
    }

    /// The solutions of a spherical-wrist arm (module docs).
    fn solve_spherical(&self, t: &Frame, ws: &mut FkWork, start: usize, out: &mut Vec<[f64; 6]>) {
        let w = t.point(&self.centre_local);
        let turn = t.rot * self.home.rot.transpose();
        let (q1s, n1) = self.shoulder(&w, &self.centre);
        for &q1 in &q1s[..n1] {
            let u = self.turn(0, -q1, &w);
            let (arms, na) = self.planar(&u, &self.elbow_point);
            for &(q2, q3) in &arms[..na] {
                let r123 = rot(&self.z[0], q1) * rot(&self.z[1], q2) * rot(&self.z[2], q3);
                let (wrists, nw) = self.wrist(&(r123.transpose() * turn));
                for &[q4, q5, q6] in &wrists[..nw] {
                    self.finish(t, [q1, q2, q3, q4, q5, q6], ws, start, out);
                }
            }
        }
    }

    /// The solutions of a UR-family arm (module docs).
    fn solve_ur(&self, t: &Frame, ws: &mut FkWork, start: usize, out: &mut Vec<[f64; 6]>) {
        let z = &self.z;
        let x = t.point(&self.centre_local);
        let turn = t.rot * self.home.rot.transpose();
        let (q1s, n1) = self.shoulder(&x, &self.centre);
        for &q1 in &q1s[..n1] {
            // m = R_2 R_3 R_4 R_5 R_6, and z2ᵀ R_2 R_3 R_4 = z2ᵀ: z2 · m z6 = z2 · R(z5, q5) z6.
            let m = rot(&z[0], -q1) * turn;
            let g5 = z[4].dot(&z[5]);
            let a = z[1].dot(&(z[5] - z[4] * g5));
            let b = z[1].dot(&z[4].cross(&z[5]));
            let (q5s, n5) = trig(a, b, z[1].dot(&(m * z[5])) - g5 * z[1].dot(&z[4]), DEGENERATE);
            for &q5 in &q5s[..n5] {
                // z2ᵀ R_5 R_6 = z2ᵀ m: R_6 (mᵀ z2) = R_5ᵀ z2.
                let q6 = angle_about(&z[5], &(m.transpose() * z[1]), &(rot(&z[4], -q5) * z[1]));
                self.ur_arm(t, [q1, q5, q6], &m, ws, start, out);
            }
        }
    }

    /// The UR solutions with q1, q5, q6 known (`m` = R_2…R_6): the point of axis 4 that the pose
    /// puts, reached by the planar 2R of axes 2 and 3, then q4 from the rest of `m`.
    fn ur_arm(&self, t: &Frame, [q1, q5, q6]: [f64; 3], m: &Matrix3<f64>, ws: &mut FkWork, start: usize, out: &mut Vec<[f64; 6]>) {
        let z = &self.z;
        // E_1…E_4 = (T · T(0)⁻¹) · E_6(−q6) · E_5(−q5); E_4 leaves a point of axis 4 in place.
        let back = self.turn(5, -q6, &self.turn(4, -q5, &self.elbow_point));
        let on_axis4 = t.rot * (self.home.rot.transpose() * (back - self.home.pos)) + t.pos;
        let u = self.turn(0, -q1, &on_axis4);
        let (arms, na) = self.planar(&u, &self.elbow_point);
        for &(q2, q3) in &arms[..na] {
            let r4 = rot(&z[2], -q3) * rot(&z[1], -q2) * m * rot(&z[5], -q6) * rot(&z[4], -q5);
            let q4 = angle_about(&z[3], &self.perp[3], &(r4 * self.perp[3]));
            self.finish(t, [q1, q2, q3, q4, q5, q6], ws, start, out);
        }
    }

    /// Finishes a closed-form candidate (Gauss-Newton steps), and pushes it wrapped if it
    /// reproduces the pose and is not already among `out[start..]`.
    fn finish(&self, t: &Frame, mut q: [f64; 6], ws: &mut FkWork, start: usize, out: &mut Vec<[f64; 6]>) {
        let (dp, dr) = self.refine(t, &mut q, ws);
        if !(dp <= ACCEPT_M && dr <= ACCEPT_RAD) {
            return;
        }
        let q = q.map(wrap);
        let same = |s: &[f64; 6]| s.iter().zip(&q).all(|(a, b)| wrap(a - b).abs() < DUPLICATE_RAD);
        if !out[start..].iter().any(same) {
            out.push(q);
        }
    }

    /// Pose error of the flange at the last forward kinematics against `t`: the position
    /// difference (m) and the rotation vector (rad) taking the flange's orientation onto `t`'s,
    /// both in the base frame.
    fn pose_error(&self, t: &Frame, ws: &FkWork) -> Vector6<f64> {
        let f = self.chain.frame(ws, self.chain.flange());
        let d = t.rot * f.rot.transpose();
        let v = Vector3::new(d[(2, 1)] - d[(1, 2)], d[(0, 2)] - d[(2, 0)], d[(1, 0)] - d[(0, 1)]) / 2.0;
        let angle = v.norm().atan2((d.trace() - 1.0) / 2.0);
        let w = if v.norm() > 0.0 { v * (angle / v.norm()) } else { Vector3::zeros() };
        let dp = t.pos - f.pos;
        Vector6::new(dp.x, dp.y, dp.z, w.x, w.y, w.z)
    }

    /// The flange's geometric Jacobian at the last forward kinematics: rows 0..3 the position
    /// (m/rad), rows 3..6 the rotation vector (rad/rad), both in the base frame.
    fn pose_jacobian(&self, ws: &FkWork) -> Matrix6<f64> {
        let p = self.chain.frame(ws, self.chain.flange()).pos;
        let mut j = Matrix6::zeros();
        for (col, &k) in self.joint_op.iter().enumerate() {
            let fr = &ws.pre[k];
            let w = fr.rot * self.chain.ops[k].axis;
            let v = w.cross(&(p - fr.pos));
            j.fixed_view_mut::<3, 1>(0, col).copy_from(&v);
            j.fixed_view_mut::<3, 1>(3, col).copy_from(&w);
        }
        j
    }

    /// Gauss-Newton steps on the pose error (damped by [`NEWTON_DAMPING`]) until it is below
    /// [`NEWTON_GOAL_M`] and [`NEWTON_GOAL_RAD`] or [`NEWTON_STEPS`] are done; `q` becomes the
    /// best iterate. Returns its position (m) and orientation (rad) errors.
    fn refine(&self, t: &Frame, q: &mut [f64; 6], ws: &mut FkWork) -> (f64, f64) {
        let mut best = (f64::INFINITY, f64::INFINITY);
        let mut best_q = *q;
        for step in 0..=NEWTON_STEPS {
            self.chain.forward(q, &self.p, 1.0, ws);
            let e = self.pose_error(t, ws);
            let (dp, dr) = (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm());
            if !(dp.max(dr) < best.0.max(best.1)) {
                break;
            }
            (best, best_q) = ((dp, dr), *q);
            if (dp <= NEWTON_GOAL_M && dr <= NEWTON_GOAL_RAD) || step == NEWTON_STEPS {
                break;
            }
            let j = self.pose_jacobian(ws);
            let normal = j.transpose() * j + Matrix6::identity() * (NEWTON_DAMPING * NEWTON_DAMPING);
            let Some(dq) = normal.cholesky().map(|c| c.solve(&(j.transpose() * e))) else { break };
            q.iter_mut().zip(dq.iter()).for_each(|(a, d)| *a += d);
        }
        *q = best_q;
        best
    }
}

/// The spherical-wrist structure at q = 0 (axes `c`, `z`): its kind, wrist centre and the point
/// the planar 2R reaches (the wrist centre too).
fn spherical_wrist(c: &[Vector3<f64>; 6], z: &[Vector3<f64>; 6]) -> Option<(ClosedFormKind, Vector3<f64>, Vector3<f64>)> {
    if !(parallel(&z[1], &z[2]) && orthogonal(&z[0], &z[1])) {
        return None;
    }
    let a = meeting(&c[3], &z[3], &c[4], &z[4])?;
    let b = meeting(&c[4], &z[4], &c[5], &z[5])?;
    let w = (a + b) / 2.0;
    ((a - b).norm() <= STRUCTURE_TOL_M).then_some((ClosedFormKind::SphericalWrist, w, w))
}

/// The UR structure at q = 0 (axes `c`, `z`): its kind, where axes 5 and 6 meet, and a point of
/// axis 4 (its origin) for the planar 2R.
fn ur(c: &[Vector3<f64>; 6], z: &[Vector3<f64>; 6]) -> Option<(ClosedFormKind, Vector3<f64>, Vector3<f64>)> {
    let shape = parallel(&z[1], &z[2]) && parallel(&z[1], &z[3]) && orthogonal(&z[0], &z[1]) && orthogonal(&z[3], &z[4]) && orthogonal(&z[4], &z[5]);
    if !shape {
        return None;
    }
    let p = meeting(&c[4], &z[4], &c[5], &z[5])?;
    Some((ClosedFormKind::Ur, p, c[3]))
}

/// Adds to `out` every configuration equivalent to the solution `q` (rad) within the joint
/// limits `limits` (one (lower, upper) per joint, rad): each angle `q_j + 2π·k` for every whole
/// k that keeps it within its limits, in every combination (a joint spanning ±400° has up to
/// three, a UR joint's ±360° two or three), so a caller gets every solution the controller can
/// reach. An angle beyond a limit by less than [`LIMIT_SLACK_RAD`] is clamped onto it. Nothing is
/// added if some joint has no such angle, if `limits` has fewer than six entries, or if any value
/// is not finite.
pub fn within_limits(q: &[f64; 6], limits: &[(f64, f64)], out: &mut Vec<[f64; 6]>) {
    if limits.len() < 6 || !q.iter().chain(limits.iter().flat_map(|(a, b)| [a, b])).all(|v| v.is_finite()) {
        return;
    }
    let (mut first, mut count) = ([0.0; 6], [0usize; 6]);
    for j in 0..6 {
        let (lo, hi) = limits[j];
        let k_lo = ((lo - LIMIT_SLACK_RAD - q[j]) / TAU).ceil();
        let k_hi = ((hi + LIMIT_SLACK_RAD - q[j]) / TAU).floor();
        if k_hi < k_lo {
            return;
        }
        (first[j], count[j]) = (k_lo, (k_hi - k_lo) as usize + 1);
    }
    // A mixed-radix counter over the turns of each joint.
    let mut turns = [0usize; 6];
    loop {
        out.push(std::array::from_fn(|j| (q[j] + TAU * (first[j] + turns[j] as f64)).clamp(limits[j].0, limits[j].1)));
        let Some(j) = (0..6).find(|&j| turns[j] + 1 < count[j]) else { return };
        turns[j] += 1;
        turns[..j].iter_mut().for_each(|t| *t = 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::kinematics::ChainBuilder;
    use crate::robot::Robot;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Random configurations per arm.
    const N_CONFIGS: usize = 10_000;
    /// A configuration whose pose Jacobian's smallest singular value is below this (m or rad per
    /// rad) is near a singularity: its own solution may be merged with a neighbour's.
    const NEAR_SINGULAR: f64 = 1e-4;
    /// The original configuration must be among the solutions to this, rad.
    const FOUND_RAD: f64 = 1e-7;

    fn arm(name: &str) -> Robot {
        let text = match name {
            "irb120" => return Robot::irb120(),
            "kr6" => include_str!("../../urdf/kr6.urdf"),
            "ur5" => include_str!("../../urdf/ur5.urdf"),
            "ur10" => include_str!("../../urdf/ur10.urdf"),
            "wam" => include_str!("../../urdf/wam.urdf"),
            _ => unreachable!(),
        };
        Robot::from_urdf_str(text, name).unwrap()
    }

    fn flange(chain: &Chain, p: &[f64], q: &[f64], ws: &mut FkWork) -> Frame {
        chain.forward(q, p, 1.0, ws);
        chain.frame(ws, chain.flange())
    }

    /// Position (m) and orientation (rad) differences of two frames.
    fn pose_distance(a: &Frame, b: &Frame) -> (f64, f64) {
        let d = a.rot * b.rot.transpose();
        let v = Vector3::new(d[(2, 1)] - d[(1, 2)], d[(0, 2)] - d[(2, 0)], d[(1, 0)] - d[(0, 1)]) / 2.0;
        ((a.pos - b.pos).norm(), v.norm().atan2((d.trace() - 1.0) / 2.0))
    }

    fn same_angles(a: &[f64; 6], b: &[f64; 6], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| wrap(x - y).abs() <= tol)
    }

    /// What a sweep of random configurations found.
    #[derive(Debug, Default)]
    struct Sweep {
        worst_m: f64,
        worst_rad: f64,
        near_singular: usize,
        missed_near_singular: usize,
        counts: [usize; 9],
    }

    /// Solves the forward pose of `n` random configurations within `limits`; panics on any
    /// solution off the pose or on a generic configuration missing from its solutions.
    fn sweep(cf: &ClosedForm, chain: &Chain, p: &[f64], limits: &[(f64, f64)], n: usize, seed: u64) -> Sweep {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (mut ws, mut s, mut sols) = (FkWork::new(chain), Sweep::default(), Vec::new());
        for i in 0..n {
            let q: [f64; 6] = std::array::from_fn(|j| rng.random_range(limits[j].0..limits[j].1));
            let target = flange(chain, p, &q, &mut ws);
            let sigma = cf.pose_jacobian(&ws).singular_values().min();
            sols.clear();
            cf.solve(&target, &mut sols);
            assert!(sols.len() <= 8, "config {i}: {} solutions", sols.len());
            for sol in &sols {
                assert!(sol.iter().all(|a| *a > -PI && *a <= PI), "{sol:?} not wrapped");
                let (dm, dr) = pose_distance(&flange(chain, p, sol, &mut ws), &target);
                (s.worst_m, s.worst_rad) = (s.worst_m.max(dm), s.worst_rad.max(dr));
            }
            let distinct = sols.iter().enumerate().filter(|(k, a)| !sols[..*k].iter().any(|b| same_angles(a, b, 1e-6))).count();
            s.counts[distinct] += 1;
            let found = sols.iter().any(|sol| same_angles(sol, &q, FOUND_RAD));
            if sigma < NEAR_SINGULAR {
                s.near_singular += 1;
                s.missed_near_singular += usize::from(!found);
            } else {
                assert!(found, "config {i} {q:?} (σ_min {sigma:.2e}) not among {sols:?}");
            }
        }
        assert!(s.worst_m <= 1e-12 && s.worst_rad <= 1e-9, "{s:?}");
        s
    }

    /// The four arms: every solution reproduces the pose, the original configuration is among
    /// them, 8 distinct solutions for almost every configuration, few near a singularity.
    #[test]
    fn every_solution_of_random_poses_of_four_arms() {
        // The arm, its structure, the least share (%) of configurations with all 8 solutions: the
        // IRB 120 has no offset between axes 1 and 2, so every branch has the same reach.
        for (k, (name, kind, min_all_8)) in [
            ("irb120", ClosedFormKind::SphericalWrist, 99),
            ("kr6", ClosedFormKind::SphericalWrist, 80),
            ("ur5", ClosedFormKind::Ur, 70),
            ("ur10", ClosedFormKind::Ur, 70),
        ]
        .into_iter()
        .enumerate()
        {
            let robot = arm(name);
            let chain = robot.error_chain();
            let p = vec![0.0; chain.n_params()];
            let cf = ClosedForm::of(&chain, &p).unwrap_or_else(|| panic!("{name}: no closed form"));
            assert_eq!(cf.kind(), kind, "{name}");
            let t0 = std::time::Instant::now();
            let s = sweep(&cf, &chain, &p, &robot.limits(), N_CONFIGS, 7 + k as u64);
            eprintln!("{name}: {N_CONFIGS} configurations in {:.2} s: {s:?}", t0.elapsed().as_secs_f64());
            assert!(s.near_singular * 100 <= N_CONFIGS, "{name}: {s:?}");
            // All 8 for (nearly) every configuration where the arm's offsets do not put a
            // branch out of reach (`a_numerical_solver_finds_no_other_solution` shows those
            // branches do not exist).
            assert!(s.counts[8] * 100 >= N_CONFIGS * min_all_8, "{name}: {s:?}");
        }
    }

    /// The arm `name` and its absolute D-H calibration model (nonzero nominal parameters).
    fn dh_model(name: &str) -> (Robot, crate::calib::model::CalibModel) {
        use crate::calib::model::{CalibModel, DrawWireGuess};
        let g = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.062, 0.004, -0.003] };
        let robot = arm(name);
        let m = CalibModel::dh(&robot, &g, false);
        (robot, m)
    }

    /// A model whose parameters are not zero (the absolute D-H model, its nominal values in `p`)
    /// and a chain whose structure holds only to the tolerance are solved exactly.
    #[test]
    fn nonzero_parameters_and_a_structure_within_the_tolerance() {
        for name in ["irb120", "ur5"] {
            let (robot, m) = dh_model(name);
            let p = &m.nominal[..m.n_chain()];
            let cf = ClosedForm::of(&m.chain, p).unwrap_or_else(|| panic!("{name}: D-H model has no closed form"));
            sweep(&cf, &m.chain, p, &robot.limits(), 500, 3);
            // Every length of the error chain off by a fraction of the tolerance.
            let chain = robot.error_chain();
            let p: Vec<f64> = (0..chain.n_params()).map(|i| 3e-10 * ((i as f64) * 1.3).sin()).collect();
            let cf = ClosedForm::of(&chain, &p).unwrap_or_else(|| panic!("{name}: not within the tolerance"));
            sweep(&cf, &chain, &p, &robot.limits(), 500, 4);
            // Ten times the tolerance is another structure.
            let p: Vec<f64> = p.iter().map(|v| v * 1e2).collect();
            assert!(ClosedForm::of(&chain, &p).is_none(), "{name}");
        }
    }

    /// Levenberg-Marquardt (adaptive damping) on the pose error from `q`, independent of the
    /// closed form: the configuration it ends at (wrapped) and its pose error (m and rad, one norm).
    fn levenberg_marquardt(cf: &ClosedForm, target: &Frame, mut q: [f64; 6], ws: &mut FkWork) -> ([f64; 6], f64) {
        cf.chain.forward(&q, &cf.p, 1.0, ws);
        let mut e = cf.pose_error(target, ws);
        let mut lambda = 1e-6;
        for _ in 0..1000 {
            if e.norm() < 1e-14 {
                break;
            }
            let j = cf.pose_jacobian(ws);
            let jtj = j.transpose() * j;
            let Some(dq) = (jtj + Matrix6::from_diagonal(&jtj.diagonal()) * lambda).cholesky().map(|c| c.solve(&(j.transpose() * e))) else { break };
            let trial: [f64; 6] = std::array::from_fn(|k| q[k] + dq[k]);
            cf.chain.forward(&trial, &cf.p, 1.0, ws);
            let e_trial = cf.pose_error(target, ws);
            if e_trial.norm() < e.norm() {
                (q, e, lambda) = (trial, e_trial, (lambda / 3.0).max(1e-15));
            } else if lambda > 1e12 {
                break;
            } else {
                lambda *= 4.0;
            }
        }
        (q.map(wrap), e.norm())
    }

    /// Largest position (m) and orientation (rad) perturbations of [`perturbed_sweep`].
    const PERTURB_M: f64 = 5e-4;
    const PERTURB_RAD: f64 = 1e-3;
    /// σ_min(J) (m or rad per rad) at or below which a configuration is near a singularity.
    const PERTURBED_SINGULAR: f64 = 1e-3;
    /// σ_min(J) above which a configuration is clear of every singularity for the perturbations:
    /// the first-order joint change |δx| / σ_min ≤ 1.1e-3 / 2e-2 stays within [`NEAR_RAD`], and
    /// a stretched elbow's reach margin (second order) exceeds the 0.5 mm.
    const CLEAR_OF_SINGULAR: f64 = 2e-2;
    /// A solution within this of each joint of the configuration (rad) is its continuation.
    const NEAR_RAD: f64 = 0.05;

    /// What a sweep of perturbed poses found.
    #[derive(Debug, Default)]
    struct Perturbed {
        /// Configurations with σ_min(J) ≤ [`PERTURBED_SINGULAR`], and in (it, [`CLEAR_OF_SINGULAR`]].
        near_singular: usize,
        close_to_singular: usize,
        /// Perturbed poses with no solution: each beyond the arm's reach (the independent
        /// Levenberg-Marquardt from the configuration and from random starts finds none either);
        /// with σ_min(J) above [`PERTURBED_SINGULAR`], and at or below it.
        beyond_reach: usize,
        beyond_reach_near_singular: usize,
        /// Poses with solutions but none within [`NEAR_RAD`] of the configuration (the nearest
        /// solution is the independent solver's from the configuration): with σ_min(J) above
        /// [`PERTURBED_SINGULAR`], and at or below it; none above [`CLEAR_OF_SINGULAR`].
        moved: usize,
        moved_near_singular: usize,
        /// Largest σ_min(J) of a configuration beyond reach or moved.
        worst_sigma: f64,
        /// Least pose error the independent solver reached on a pose beyond reach (m and rad).
        least_unreachable: f64,
        /// Worst residuals of the returned solutions, m and rad.
        worst_m: f64,
        worst_rad: f64,
        /// Largest joint change (rad) from a configuration clear of singularities to its nearest solution.
        worst_change: f64,
    }

    /// Solves the poses of `n` random configurations within `limits`, each moved by up to
    /// [`PERTURB_M`] and turned by up to [`PERTURB_RAD`] (random directions); panics on a
    /// solution off the pose, a pose without solution that the independent solver reaches, a
    /// solution it finds from the configuration that is not among the closed form's, and a
    /// configuration clear of singularities without a solution near it.
    fn perturbed_sweep(cf: &ClosedForm, chain: &Chain, p: &[f64], limits: &[(f64, f64)], n: usize, seed: u64) -> Perturbed {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (mut ws, mut sols) = (FkWork::new(chain), Vec::new());
        let mut s = Perturbed { least_unreachable: f64::INFINITY, ..Perturbed::default() };
        let unit = |rng: &mut ChaCha8Rng| loop {
            let v = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
            if v.norm() <= 1.0 && v.norm() > 1e-3 {
                return v.normalize();
            }
        };
        for i in 0..n {
            let q: [f64; 6] = std::array::from_fn(|j| rng.random_range(limits[j].0..limits[j].1));
            let mut target = flange(chain, p, &q, &mut ws);
            let sigma = cf.pose_jacobian(&ws).singular_values().min();
            let (dm, dr) = (rng.random_range(0.0..PERTURB_M), rng.random_range(0.0..PERTURB_RAD));
            target.pos += unit(&mut rng) * dm;
            target.rot = rot(&unit(&mut rng), dr) * target.rot;
            sols.clear();
            cf.solve(&target, &mut sols);
            assert!(sols.len() <= 8, "config {i}: {} solutions", sols.len());
            for sol in &sols {
                assert!(sol.iter().all(|a| *a > -PI && *a <= PI), "{sol:?} not wrapped");
                let (em, er) = pose_distance(&flange(chain, p, sol, &mut ws), &target);
                (s.worst_m, s.worst_rad) = (s.worst_m.max(em), s.worst_rad.max(er));
            }
            let singular = sigma <= PERTURBED_SINGULAR;
            s.near_singular += usize::from(singular);
            s.close_to_singular += usize::from(!singular && sigma <= CLEAR_OF_SINGULAR);
            // The independent solver from the configuration: what it reaches is among the solutions.
            let (local, residual) = levenberg_marquardt(cf, &target, q, &mut ws);
            if residual < 1e-12 {
                assert!(sols.iter().any(|x| same_angles(x, &local, 1e-6)), "config {i} {q:?}: {local:?} not among {sols:?}");
            }
            let change = |sol: &[f64; 6]| sol.iter().zip(&q).map(|(a, b)| wrap(a - b).abs()).fold(0.0, f64::max);
            if sols.is_empty() {
                // Beyond reach: no start of the independent solver reaches the pose either.
                let least =
                    (0..20).map(|_| levenberg_marquardt(cf, &target, std::array::from_fn(|_| rng.random_range(-PI..PI)), &mut ws).1).fold(residual, f64::min);
                assert!(least > 1e-9, "config {i} {q:?} (σ_min {sigma:.2e}): no solution, but the pose is reached to {least:.1e}");
                s.least_unreachable = s.least_unreachable.min(least);
                s.worst_sigma = s.worst_sigma.max(sigma);
                *if singular { &mut s.beyond_reach_near_singular } else { &mut s.beyond_reach } += 1;
                assert!(sigma <= CLEAR_OF_SINGULAR, "config {i} {q:?} (σ_min {sigma:.2e}): no solution");
                continue;
            }
            let nearest = sols.iter().map(change).fold(f64::INFINITY, f64::min);
            if nearest > NEAR_RAD {
                s.worst_sigma = s.worst_sigma.max(sigma);
                *if singular { &mut s.moved_near_singular } else { &mut s.moved } += 1;
                assert!(sigma <= CLEAR_OF_SINGULAR, "config {i} {q:?} (σ_min {sigma:.2e}): nearest solution {nearest:.3} rad away among {sols:?}");
            }
            if sigma > CLEAR_OF_SINGULAR {
                s.worst_change = s.worst_change.max(nearest);
            }
        }
        assert!(s.worst_m <= 1e-12 && s.worst_rad <= 1e-9, "{s:?}");
        s
    }

    /// Poses near the chain's but not on it (a target taught on the true arm, read on the
    /// nominal model: up to 0.5 mm and 1 mrad off): every solution reproduces the perturbed
    /// pose, a pose without solution is beyond the arm's reach (at a nearly stretched elbow), no
    /// solution an independent solver finds is missing, and away from singularities a solution
    /// is near the configuration the pose came from.
    #[test]
    fn perturbed_poses_of_four_arms() {
        for (k, name) in ["irb120", "kr6", "ur5", "ur10"].into_iter().enumerate() {
            let robot = arm(name);
            let chain = robot.error_chain();
            let p = vec![0.0; chain.n_params()];
            let cf = ClosedForm::of(&chain, &p).unwrap();
            let t0 = std::time::Instant::now();
            let s = perturbed_sweep(&cf, &chain, &p, &robot.limits(), N_CONFIGS, 40 + k as u64);
            eprintln!("{name}: {N_CONFIGS} perturbed poses in {:.2} s (with the independent solver): {s:?}", t0.elapsed().as_secs_f64());
            // Few near a singularity or beyond reach.
            assert!(s.near_singular * 50 <= N_CONFIGS && (s.beyond_reach + s.moved) * 20 <= N_CONFIGS, "{name}: {s:?}");
        }
    }

    /// The same for a chain whose structure holds only to the tolerance (the Gauss-Newton steps
    /// finish every solution) and for the absolute D-H model (nonzero parameters).
    #[test]
    fn perturbed_poses_within_the_tolerance() {
        for name in ["irb120", "ur5"] {
            let (robot, m) = dh_model(name);
            let p = &m.nominal[..m.n_chain()];
            let cf = ClosedForm::of(&m.chain, p).unwrap();
            perturbed_sweep(&cf, &m.chain, p, &robot.limits(), 1000, 5);
            let chain = robot.error_chain();
            let p: Vec<f64> = (0..chain.n_params()).map(|i| 3e-10 * ((i as f64) * 1.3).sin()).collect();
            let cf = ClosedForm::of(&chain, &p).unwrap();
            let s = perturbed_sweep(&cf, &chain, &p, &robot.limits(), 1000, 6);
            eprintln!("{name} within the tolerance: {s:?}");
        }
    }

    /// The 7-joint WAM, a 6-joint chain of another shape, a wrong parameter vector: no closed form.
    #[test]
    fn other_shapes_have_none() {
        let wam = arm("wam").error_chain();
        assert!(ClosedForm::of(&wam, &vec![0.0; wam.n_params()]).is_none());
        // Six joints alternating z and x with offsets along every axis: no two axes parallel.
        let mut b = ChainBuilder::new();
        for j in 0..6 {
            b.origin([0.1, 0.05 * j as f64, 0.2], [0.3, 0.0, 0.0]);
            b.joint(if j % 2 == 0 { Vector3::z() } else { Vector3::x() }, 0.0, None);
        }
        let odd = b.finish();
        assert!(ClosedForm::of(&odd, &[]).is_none());
        let irb = arm("irb120").error_chain();
        assert!(ClosedForm::of(&irb, &[0.0; 3]).is_none());
        // The IRB 120's axis 3 tilted by 1e-6 rad: axes 2 and 3 no longer parallel.
        let mut p = vec![0.0; irb.n_params()];
        p[irb.param_names.iter().position(|n| n == "joint_3.rx").unwrap()] = 1e-6;
        assert!(ClosedForm::of(&irb, &p).is_none());
    }

    fn solutions(name: &str, q: &[f64; 6]) -> Vec<[f64; 6]> {
        let chain = arm(name).error_chain();
        let p = vec![0.0; chain.n_params()];
        let cf = ClosedForm::of(&chain, &p).unwrap();
        let mut ws = FkWork::new(&chain);
        let target = flange(&chain, &p, q, &mut ws);
        let mut sols = Vec::new();
        cf.solve(&target, &mut sols);
        assert!(!sols.is_empty() && sols.len() <= 8, "{name} {q:?}: {sols:?}");
        for sol in &sols {
            let (dm, dr) = pose_distance(&flange(&chain, &p, sol, &mut ws), &target);
            assert!(dm <= ACCEPT_M && dr <= ACCEPT_RAD, "{name} {sol:?}: {dm:e} m {dr:e} rad");
        }
        sols
    }

    /// Singular poses give one representative solution each (the documented convention), on the
    /// pose; unreachable and non-finite poses give none.
    #[test]
    fn singular_poses_give_representatives() {
        let near = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| wrap(x - y).abs() < 1e-9);
        // IRB 120 wrist singular (q5 = 0): q4 = 0, q6 takes the turn (axes 4 and 6 both along x).
        let sols = solutions("irb120", &[0.3, 0.2, -0.4, 0.7, 0.0, -0.5]);
        assert!(sols.iter().any(|s| near(s, &[0.3, 0.2, -0.4, 0.0, 0.0, 0.2])), "{sols:?}");
        // Wrist centre on axis 1: 0.27 sin q2 + 0.302 cos(q2 + q3) + 0.07 sin(q2 + q3) = 0 (m; the
        // arm plane's x): q1 = 0 for every solution; two elbows, two wrists.
        let q2 = 0.3f64;
        let q3 = (0.07f64).atan2(0.302) - (-0.27 * q2.sin() / 0.302f64.hypot(0.07)).acos() - q2;
        let sols = solutions("irb120", &[0.3, q2, q3, 0.4, 0.6, 0.2]);
        assert!(sols.len() == 4 && sols.iter().all(|s| s[0] == 0.0), "{sols:?}");
        // Both at once, on the KR 6.
        let sols = solutions("kr6", &[0.0, -1.2, 0.4, 0.0, 0.0, 1.0]);
        assert!(sols.iter().any(|s| near(&s[..5], &[0.0, -1.2, 0.4, 0.0, 0.0])), "{sols:?}");
        // UR: axis 6 parallel to axes 2..4 (q5 = 0), four parallel axes: q6 = 0, the planar 3R
        // of axes 2, 3, 4 takes the rest.
        let sols = solutions("ur5", &[0.4, -1.0, 0.8, 0.3, 0.0, 0.6]);
        assert!(sols.iter().any(|s| near(&[s[0], s[4], s[5]], &[0.4, 0.0, 0.0])), "{sols:?}");
        // UR elbow stretched (q3 = 0): the two elbows are one.
        let sols = solutions("ur10", &[0.4, -1.0, 0.0, 0.3, 1.1, 0.6]);
        assert!(sols.iter().any(|s| near(s, &[0.4, -1.0, 0.0, 0.3, 1.1, 0.6])), "{sols:?}");
        let chain = arm("irb120").error_chain();
        let cf = ClosedForm::of(&chain, &vec![0.0; chain.n_params()]).unwrap();
        let mut sols = Vec::new();
        cf.solve(&Frame { rot: Matrix3::identity(), pos: Vector3::new(3.0, 0.0, 0.5) }, &mut sols);
        cf.solve(&Frame { rot: Matrix3::identity(), pos: Vector3::new(f64::NAN, 0.0, 0.5) }, &mut sols);
        assert!(sols.is_empty(), "{sols:?}");
    }

    /// Damped Newton from `q`: the configuration it converges to (pose within 1e-12), if any.
    fn numeric(cf: &ClosedForm, target: &Frame, mut q: [f64; 6], ws: &mut FkWork) -> Option<[f64; 6]> {
        for _ in 0..60 {
            cf.chain.forward(&q, &cf.p, 1.0, ws);
            let e = cf.pose_error(target, ws);
            if e.norm() < 1e-12 {
                return Some(q.map(wrap));
            }
            let j = cf.pose_jacobian(ws);
            let dq = (j.transpose() * j + Matrix6::identity() * 1e-4).cholesky()?.solve(&(j.transpose() * e));
            let scale = (0.5 / dq.amax()).min(1.0);
            q.iter_mut().zip(dq.iter()).for_each(|(a, d)| *a += d * scale);
        }
        None
    }

    /// No solution is missing: whatever a numerical solver finds from many random starts is
    /// among the closed form's (where fewer than 8 are returned, the others do not exist).
    #[test]
    fn a_numerical_solver_finds_no_other_solution() {
        for (k, name) in ["irb120", "kr6", "ur5", "ur10"].into_iter().enumerate() {
            let robot = arm(name);
            let chain = robot.error_chain();
            let p = vec![0.0; chain.n_params()];
            let cf = ClosedForm::of(&chain, &p).unwrap();
            let limits = robot.limits();
            let mut rng = ChaCha8Rng::seed_from_u64(100 + k as u64);
            let (mut ws, mut sols, mut found) = (FkWork::new(&chain), Vec::new(), 0);
            for _ in 0..40 {
                let q: [f64; 6] = std::array::from_fn(|j| rng.random_range(limits[j].0..limits[j].1));
                let target = flange(&chain, &p, &q, &mut ws);
                sols.clear();
                cf.solve(&target, &mut sols);
                for _ in 0..60 {
                    let start: [f64; 6] = std::array::from_fn(|_| rng.random_range(-PI..PI));
                    if let Some(n) = numeric(&cf, &target, start, &mut ws) {
                        found += 1;
                        assert!(sols.iter().any(|s| same_angles(s, &n, 1e-6)), "{name} {q:?}: {n:?} not among {sols:?}");
                    }
                }
            }
            eprintln!("{name}: {found} numerical solutions, all among the closed form's");
            assert!(found > 100, "{name}: {found}");
        }
    }

    /// Equivalent angles within the limits: ±400° gives a joint up to three, ±360° two or three.
    #[test]
    fn equivalent_angles_within_limits() {
        let irb = Robot::irb120().limits();
        let mut out = Vec::new();
        within_limits(&[0.1, 0.2, 0.3, 0.4, 0.5, 0.5], &irb, &mut out);
        assert_eq!(out.len(), 3, "{out:?}");
        assert!(out.iter().all(|q| q[..5] == [0.1, 0.2, 0.3, 0.4, 0.5]));
        out.clear();
        within_limits(&[0.1, 0.2, 0.3, 0.4, 0.5, 1.0], &irb, &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        // Joint 2 beyond its limits in every turn: nothing.
        out.clear();
        within_limits(&[0.1, 2.5, 0.3, 0.4, 0.5, 1.0], &irb, &mut out);
        assert!(out.is_empty());
        let ur = arm("ur5").limits();
        let q = [0.5, -0.5, 3.0, -3.0, 0.0, PI];
        within_limits(&q, &ur, &mut out);
        assert_eq!(out.len(), 2 * 2 * 2 * 2 * 3 * 2, "{out:?}");
        for s in &out {
            assert!(s.iter().zip(&ur).all(|(a, (lo, hi))| lo <= a && a <= hi));
            assert!(same_angles(s, &q, 1e-12));
        }
        let distinct = out.iter().enumerate().all(|(k, a)| !out[..k].contains(a));
        assert!(distinct);
    }
}
