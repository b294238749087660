//! The arm's set-up as a program sees it (the controller's base and flange frames, the
//! calibrated tool point), and the arm's branch as configuration data state it.
//!
//! The branch of a six-axis arm with a wrist is three choices, read on the nominal model at
//! the joint angles: the *shoulder* (the wrist centre — joint 5's origin — behind axis 1: its
//! offset from axis 1 along the arm's forward direction `axis2 × axis1` is negative), the
//! *elbow* (the forearm bent the other way: `((p3 − p2) × (w − p3))·axis2 < 0`, with `p2`,
//! `p3` the origins of joints 2 and 3) and the *wrist* (joint 5 below zero). RAPID writes them as
//! `cfx = 4·shoulder + 2·elbow + wrist` and each of joints 1, 4 and 6 as its quadrant
//! (`cf = ⌊angle / 90°⌋`); KRL as `S = shoulder + 2·elbow + 4·wrist` and `T`, bit `j` set where
//! joint `j + 1` is below zero. These are twincal's readings of the makers' definitions for an
//! arm whose URDF angles are its controller's: a controller whose zeros or directions differ
//! needs its angles mapped first.

use super::Layout;
use crate::calib::model::CalibModel;
use crate::calib::pipeline::CalibResult;
use crate::robot::kinematics::FkWork;
use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

/// The arm as a program sees it.
pub struct Setup {
    /// The arm's joints.
    pub n_joints: usize,
    /// The calibrated tool point (and a 6-D probe's orientation) in the model's flange frame, mm.
    probe: Isometry3<f64>,
    /// The controller's flange frame (tool0) in the model's flange frame, mm.
    tool0: Isometry3<f64>,
    /// The controller's base frame in the model's base frame, mm.
    base: Isometry3<f64>,
    /// The nominal model, for the branch of a command.
    model: CalibModel,
    x_nom: Vec<f64>,
}

/// The branch of a six-axis arm at some joint angles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArmBranch {
    /// The wrist centre behind axis 1.
    pub shoulder: bool,
    /// The elbow bent the other way.
    pub elbow: bool,
    /// Joint 5 below zero.
    pub wrist: bool,
}

fn iso(f: &crate::robot::kinematics::Frame) -> Isometry3<f64> {
    let t = Translation3::from(f.pos * 1000.0);
    Isometry3::from_parts(t, UnitQuaternion::from_matrix(&f.rot))
}

impl Setup {
    /// The set-up of the calibration `r` (nominal parameters `x_nom`) on the arm `robot` (its
    /// URDF's controller frames; `None`: the model's base and flange are the controller's).
    pub fn new(r: &CalibResult, x_nom: &[f64], robot: Option<&crate::robot::Robot>) -> Setup {
        let m = &r.model;
        let placement = m.placement(&r.x);
        let rot = match m.measurement {
            crate::measurement::Measurement::Pose => crate::measurement::pose::probe_rotation(&placement.own),
            _ => Matrix3::identity(),
        };
        let probe = Isometry3::from_parts(Translation3::from(placement.tool * 1000.0), UnitQuaternion::from_matrix(&rot));
        let (base, tool0) = robot.map_or((Isometry3::identity(), Isometry3::identity()), |rb| {
            let (b, t) = rb.controller_frames();
            (iso(&b), iso(&t))
        });
        Setup { n_joints: m.chain.n_joints, probe, tool0, base, model: m.clone(), x_nom: x_nom.to_vec() }
    }

    /// The model's tool target (its tool point, mm, and its tool orientation, as
    /// [`crate::ik::IkModel::pose`] gives them) that puts the controller's flange (tool0) at
    /// `tool0` (mm, the controller's base frame).
    pub fn model_target(&self, tool0: &Isometry3<f64>) -> (Vector3<f64>, Matrix3<f64>) {
        let flange = self.base * tool0 * self.tool0.inverse();
        let t = flange * self.probe;
        (t.translation.vector, t.rotation.to_rotation_matrix().into_inner())
    }

    /// The controller's flange (tool0) pose (mm, the controller's base frame) where the model's
    /// tool stands at `p` (mm) turned `r`: the inverse of [`Self::model_target`].
    pub fn program_pose(&self, p: &Vector3<f64>, r: &Matrix3<f64>) -> Isometry3<f64> {
        let t = Isometry3::from_parts(Translation3::from(*p), UnitQuaternion::from_matrix(r));
        self.base.inverse() * t * self.probe.inverse() * self.tool0
    }

    /// The calibrated tool point (and a 6-D probe's orientation) as a tool of the controller: its
    /// pose in the controller's flange frame (tool0), mm.
    pub fn probe_tool(&self) -> Isometry3<f64> {
        self.tool0.inverse() * self.probe
    }

    /// The configuration data a target of `layout` states for joint angles `q` (rad).
    pub fn config(&self, layout: Layout, q: &[f64]) -> Vec<i64> {
        config_of(layout, &self.branch(q), q)
    }

    /// The branch of the nominal arm at `q` (rad).
    pub fn branch(&self, q: &[f64]) -> ArmBranch {
        let chain = &self.model.chain;
        let mut fk = FkWork::new(chain);
        chain.forward(q, &self.x_nom[..chain.n_params()], 1.0, &mut fk);
        let origin = |f: usize| chain.frame(&fk, f).pos;
        let mut axes = vec![Vector3::zeros(); chain.n_joints];
        chain.angular_jacobian(&fk, chain.flange(), &mut axes);
        let (p1, p2, p3, w) = (origin(1), origin(2), origin(3), origin(5));
        let forward = axes[1].cross(&axes[0]);
        ArmBranch { shoulder: (w - p1).dot(&forward) < 0.0, elbow: (p3 - p2).cross(&(w - p3)).dot(&axes[1]) < 0.0, wrist: q[4] < 0.0 }
    }
}

/// The configuration data of a layout for the branch `b` at `q` (rad).
pub(super) fn config_of(layout: Layout, b: &ArmBranch, q: &[f64]) -> Vec<i64> {
    let (s, e, w) = (b.shoulder as i64, b.elbow as i64, b.wrist as i64);
    match layout {
        Layout::RapidPose => vec![quadrant(q[0]), quadrant(q[3]), quadrant(q[5]), 4 * s + 2 * e + w],
        Layout::KrlPose { .. } => vec![s + 2 * e + 4 * w, q.iter().take(6).enumerate().map(|(j, v)| ((*v < 0.0) as i64) << j).sum()],
        _ => Vec::new(),
    }
}

/// RAPID's quadrant of an angle (rad): ⌊degrees / 90⌋.
fn quadrant(q: f64) -> i64 {
    (q.to_degrees() / 90.0).floor() as i64
}

/// How far (degrees) a joint may stand beyond the quadrant or the sign the configuration data
/// state and still agree with them: a target taught at a quadrant's edge, or moved across it by
/// its compensation, keeps its branch. Joint 5 within it of zero agrees with either wrist.
pub const MARGIN_DEG: f64 = 1.0;

/// Whether joint angles `q` (rad) agree with the configuration data `cfg` of a layout: the
/// shoulder and the elbow as stated, the wrist as stated (or joint 5 within [`MARGIN_DEG`] of
/// zero), each stated quadrant (RAPID) or sign (KRL's T) within [`MARGIN_DEG`].
pub(super) fn agrees(layout: Layout, cfg: &[i64], q: &[f64], setup: &Setup) -> bool {
    let m = MARGIN_DEG.to_radians();
    let b = setup.branch(q);
    let wrist_free = q[4].abs() < m;
    let arm = |shoulder: bool, elbow: bool, wrist: bool| shoulder == b.shoulder && elbow == b.elbow && (wrist == b.wrist || wrist_free);
    match layout {
        Layout::RapidPose => {
            let quadrant_ok = |v: f64, want: i64| v >= (want as f64 * 90.0).to_radians() - m && v <= ((want + 1) as f64 * 90.0).to_radians() + m;
            quadrant_ok(q[0], cfg[0])
                && quadrant_ok(q[3], cfg[1])
                && quadrant_ok(q[5], cfg[2])
                && arm(cfg[3] >> 2 & 1 == 1, cfg[3] >> 1 & 1 == 1, cfg[3] & 1 == 1)
        }
        Layout::KrlPose { .. } => {
            let signs = (0..6).all(|j| if cfg[1] >> j & 1 == 1 { q[j] <= m } else { q[j] >= -m });
            signs && arm(cfg[0] & 1 == 1, cfg[0] >> 1 & 1 == 1, cfg[0] >> 2 & 1 == 1)
        }
        _ => true,
    }
}

/// Whether joint angles `q` (rad) have the configuration `cfg` ([`agrees`]), after moving joints
/// by whole turns (within `limits`) to the turn the configuration states.
pub(super) fn matches(layout: Layout, cfg: &[i64], q: &mut [f64], limits: &[(f64, f64)], setup: &Setup) -> bool {
    use std::f64::consts::TAU;
    let m = MARGIN_DEG.to_radians();
    let fits = |v: f64, j: usize| v >= limits[j].0 - 1e-9 && v <= limits[j].1 + 1e-9;
    // The range each joint's turn should fall in.
    let wanted = |j: usize| -> Option<(f64, f64)> {
        match layout {
            Layout::RapidPose => [(0usize, 0usize), (3, 1), (5, 2)]
                .iter()
                .find(|(jj, _)| *jj == j)
                .map(|(_, k)| ((cfg[*k] as f64 * 90.0).to_radians() - m, ((cfg[*k] + 1) as f64 * 90.0).to_radians() + m)),
            Layout::KrlPose { .. } if cfg[1] >> j & 1 == 1 => Some((f64::NEG_INFINITY, m)),
            Layout::KrlPose { .. } => Some((-m, f64::INFINITY)),
            _ => None,
        }
    };
    for (j, v) in q.iter_mut().enumerate().take(6) {
        if let Some((lo, hi)) = wanted(j) {
            if let Some(shifted) = [*v, *v - TAU, *v + TAU, *v - 2.0 * TAU, *v + 2.0 * TAU].into_iter().find(|x| *x >= lo && *x <= hi && fits(*x, j)) {
                *v = shifted;
            }
        }
    }
    agrees(layout, cfg, q, setup)
}

/// Start points for the nominal inverse kinematics of a target with configuration `cfg`: the
/// stated quadrants' (or signs') middles with the stated wrist, over a few shoulder and elbow
/// angles, then seeded random points inside the same quadrants or signs.
pub(super) fn seeds(layout: Layout, cfg: &[i64], limits: &[(f64, f64)]) -> Vec<Vec<f64>> {
    use rand::{Rng, SeedableRng};
    let clamp = |v: f64, j: usize| v.clamp(limits[j].0, limits[j].1);
    // Each joint's range as the configuration narrows it.
    let ranges: Vec<(f64, f64)> = (0..limits.len())
        .map(|j| {
            let (lo, hi) = limits[j];
            let narrowed = match layout {
                Layout::RapidPose => match j {
                    0 | 3 | 5 => {
                        let c = [cfg[0], 0, 0, cfg[1], 0, cfg[2]][j] as f64;
                        ((c * 90.0).to_radians(), ((c + 1.0) * 90.0).to_radians())
                    }
                    4 if cfg[3] & 1 == 1 => (lo, 0.0),
                    4 => (0.0, hi),
                    _ => (lo, hi),
                },
                Layout::KrlPose { .. } if cfg[1] >> j & 1 == 1 => (lo, 0.0),
                Layout::KrlPose { .. } => (0.0, hi),
                _ => (lo, hi),
            };
            (clamp(narrowed.0, j), clamp(narrowed.1, j))
        })
        .collect();
    let mid: Vec<f64> = ranges.iter().map(|(a, b)| 0.5 * (a + b)).collect();
    let mut out = Vec::new();
    for (d2, d3) in [(0.0f64, 0.0f64), (30.0, -30.0), (-30.0, 30.0), (30.0, 60.0), (-45.0, -60.0)] {
        let mut q = mid.clone();
        q[1] = clamp(d2.to_radians(), 1);
        q[2] = clamp(d3.to_radians(), 2);
        q[4] = if mid[4] < 0.0 { clamp(-45f64.to_radians(), 4) } else { clamp(45f64.to_radians(), 4) };
        out.push(q);
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0xC0F1_6DA7A);
    for _ in 0..24 {
        out.push(ranges.iter().map(|(a, b)| a + (b - a) * rng.random::<f64>()).collect());
    }
    out
}
