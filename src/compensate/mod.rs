//! Compensation: the joint commands that make the calibrated arm reach given targets.
//!
//! A target is a point in the robot's base frame (mm), a pose (the point and the tool's
//! orientation: the flange's axes, turned by a 6-D probe's calibrated orientation when the
//! calibration measured poses), or a joint configuration taught on the nominal model (its
//! nominal tool point is the target). For each, the nominal controller's
//! command is the nominal model's inverse kinematics (or the taught angles); the compensated
//! command is the calibrated model's: its geometry, its effects (compliance under the static
//! torques of the links and the stated payload at that very configuration, encoder
//! eccentricity, ...) and its learned corrector, solved by damped least squares from the
//! nominal command ([`IkModel::solve_from`]). For a controller that takes Cartesian targets
//! through its own nominal kinematics, the *filtered* target is the nominal forward kinematics
//! of the compensated command: sent as a Cartesian target, the controller's nominal inverse
//! kinematics turns it back into that command.
//!
//! Both models keep the calibrated tool point (TCP), so what the compensation gains is the
//! arm's own, not the tool's.
//!
//! A command stays on its nominal command's branch: the calibrated solve descends from the
//! nominal command alone, and only where that fails do restarts run, their answer kept only
//! within [`BRANCH_DEG`] of the nominal command on every joint. Each angle is written as the
//! turn nearest its reference within the joint's limits (the nominal command's nearest zero,
//! the compensated one's nearest the nominal), so that −12° is never written 348°.

pub mod branches;
pub mod verify;

#[cfg(test)]
mod tests;

use crate::calib::correctors::Correct;
use crate::calib::effects::inputs::TorqueModel;
use crate::calib::pipeline::CalibResult;
use crate::error::{Error, Result};
use crate::ik::closed_form::{within_limits, ClosedForm};
use crate::ik::{solver::check_tol_mm, IkModel, IkOptions, IkStatus, IkWork, JacobianKind};
use crate::measurement::Euler;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

/// One target.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// A point in the robot's base frame, mm.
    Point(Vector3<f64>),
    /// A point (mm) and the tool's orientation there (base frame).
    Pose(Vector3<f64>, Matrix3<f64>),
    /// Joint angles taught on the nominal model, rad: the target is their nominal tool point.
    Joints(Vec<f64>),
}

/// What became of one target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// The calibrated model reaches it within the tolerance.
    Reachable,
    /// Only with a joint at its limit, not within the tolerance.
    Limit,
    /// The solve stalled where the Jacobian loses rank.
    Singular,
    /// Beyond the arm's reach, or not solved.
    Unreachable,
    /// Not a finite target.
    Invalid,
}

impl Status {
    fn of(s: IkStatus) -> Status {
        match s {
            IkStatus::Converged => Status::Reachable,
            IkStatus::JointLimit => Status::Limit,
            IkStatus::Singular => Status::Singular,
            IkStatus::Unreachable | IkStatus::NotConverged => Status::Unreachable,
            IkStatus::Invalid => Status::Invalid,
        }
    }
    /// Its name in files.
    pub fn name(self) -> &'static str {
        match self {
            Status::Reachable => "reachable",
            Status::Limit => "limit",
            Status::Singular => "singular",
            Status::Unreachable => "unreachable",
            Status::Invalid => "invalid",
        }
    }
}

/// One compensated target.
#[derive(Clone, Debug, Serialize)]
pub struct Compensated {
    /// The target point, base frame, mm.
    pub target_mm: [f64; 3],
    /// The nominal controller's command, rad (its inverse kinematics, or the taught angles).
    pub nominal_q: Vec<f64>,
    /// The compensated command, rad.
    pub command_q: Vec<f64>,
    /// How the compensation went.
    pub status: Status,
    /// |calibrated model at the command − target|, mm: what the calibration predicts is left.
    pub residual_mm: f64,
    /// |calibrated model at the nominal command − target|, mm: the error the calibration
    /// predicts without the compensation.
    pub nominal_error_mm: f64,
    /// The nominal forward kinematics of the command, mm: the Cartesian target to send a
    /// controller that applies its own nominal kinematics.
    pub filtered_mm: [f64; 3],
    /// For a pose target, the orientations: [`PoseParts`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseParts>,
}

/// The orientation side of a compensated pose target.
#[derive(Clone, Debug, Serialize)]
pub struct PoseParts {
    /// The target's orientation (base frame).
    #[serde(skip)]
    pub target: Matrix3<f64>,
    /// The angle left between the target's orientation and the calibrated model's at the
    /// command, degrees.
    pub residual_deg: f64,
    /// The angle between the target's orientation and the calibrated model's at the nominal
    /// command, degrees.
    pub nominal_error_deg: f64,
    /// The nominal model's tool orientation at the command (base frame): the orientation of
    /// the filtered Cartesian target.
    #[serde(skip)]
    pub filtered: Matrix3<f64>,
}

/// A calibrated result's compensation: the calibrated and the nominal model as IK models.
pub struct Compensator<'a> {
    calibrated: IkModel<'a>,
    nominal: IkModel<'a>,
    options: IkOptions,
    /// Every solution of the nominal arm in closed form, where its geometry allows
    /// ([`crate::ik::closed_form`]); else the nominal controller is read by numerical search.
    closed: Option<NominalClosedForm>,
}

/// The nominal arm's closed form and its tool on the flange (the tool's pose in the flange
/// frame: rotation, and translation in mm), which carries a tool target to a flange target.
struct NominalClosedForm {
    form: ClosedForm,
    tool_rot: Matrix3<f64>,
    tool_mm: Vector3<f64>,
}

/// Farthest (mm, and radians) the closed form's tool may lie from the nominal model's own at a
/// check configuration for the closed form to read the nominal controller (the model is then
/// plain geometry, with a fixed tool on the flange).
const CLOSED_FORM_CHECK: f64 = 1e-7;

impl NominalClosedForm {
    /// The closed form of `nominal` where it has one and its tool is fixed on the flange
    /// (checked at a few configurations).
    fn of(nominal: &IkModel) -> Option<NominalClosedForm> {
        let m = nominal.model;
        if m.chain.n_joints != 6 {
            return None;
        }
        let form = ClosedForm::of(&m.chain, &nominal.x[..m.n_chain()])?;
        let (mut w, mut mw) = (nominal.work(), m.work());
        let flange_and_tool = |q: &[f64], w: &mut IkWork, mw: &mut crate::calib::model::ModelWork| {
            let f = m.flange_frame(nominal.x, q, mw);
            let (p, r) = nominal.pose(q, w, None);
            (f, p, r)
        };
        let (f0, p0, r0) = flange_and_tool(&[0.0; 6], &mut w, &mut mw);
        let tool_rot = f0.rot.transpose() * r0;
        let tool_mm = f0.rot.transpose() * (p0 - crate::units::to_mm(f0.pos));
        let ok = [[0.3, -0.4, 0.5, 1.0, -0.7, 2.0], [-1.2, 0.2, -0.3, -2.0, 1.1, -0.5]].iter().all(|q| {
            let (f, p, r) = flange_and_tool(q, &mut w, &mut mw);
            let (tp, tr) = (crate::units::to_mm(f.pos) + f.rot * tool_mm, f.rot * tool_rot);
            (tp - p).norm() < CLOSED_FORM_CHECK && (tr - r).norm() < CLOSED_FORM_CHECK
        });
        ok.then_some(NominalClosedForm { form, tool_rot, tool_mm })
    }

    /// Every solution (rad) that puts the tool at `p` (mm) turned `r`, each angle at every turn
    /// within `limits`.
    fn solutions(&self, p: &Vector3<f64>, r: &Matrix3<f64>, limits: &[(f64, f64)]) -> Vec<Vec<f64>> {
        let rot = r * self.tool_rot.transpose();
        let flange = crate::robot::kinematics::Frame { rot, pos: crate::units::to_m(p - rot * self.tool_mm) };
        let (mut base, mut all) = (Vec::new(), Vec::new());
        self.form.solve(&flange, &mut base);
        for q in &base {
            within_limits(q, limits, &mut all);
        }
        all.into_iter().map(|q| q.to_vec()).collect()
    }
}

/// Random starts of [`Compensator::nominal_pose_nearest`] besides the present joints: enough to
/// find each of a six-axis arm's solutions.
const NEAREST_STARTS: usize = 32;

/// Largest joint change (degrees) from the arm's present joints that the descent from them may
/// make and be taken as the arm's continuation ([`Compensator::nominal_pose_nearest`]).
const CONTINUATION_DEG: f64 = 45.0;

/// Largest change of any joint (degrees) between a nominal command and its compensated one
/// found by restarts: beyond it the restart found another arm configuration, not the nominal
/// command's.
pub const BRANCH_DEG: f64 = 10.0;

/// The largest change of any joint between `a` and `b` (rad).
fn max_change(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Each angle of `q` (rad) moved by whole turns to the one nearest `reference` that stays within
/// its joint's `limits`.
fn nearest_turns(q: &mut [f64], reference: &[f64], limits: &[(f64, f64)]) {
    use std::f64::consts::TAU;
    for ((v, r), (lo, hi)) in q.iter_mut().zip(reference).zip(limits) {
        let k = ((*r - *v) / TAU).round();
        let candidates = [k - 1.0, k, k + 1.0].map(|k| *v + k * TAU);
        if let Some(best) = candidates.into_iter().filter(|c| (*lo - 1e-9..=*hi + 1e-9).contains(c)).min_by(|a, b| (a - r).abs().total_cmp(&(b - r).abs())) {
            *v = best;
        }
    }
}

/// A solve's answer: its status and its angles (a point's or a pose's solution).
trait Solved {
    fn status(&self) -> IkStatus;
    fn q_mut(&mut self) -> &mut Vec<f64>;
}

impl Solved for crate::ik::IkSolution {
    fn status(&self) -> IkStatus {
        self.status
    }
    fn q_mut(&mut self) -> &mut Vec<f64> {
        &mut self.q
    }
}

impl Solved for crate::ik::solver::PoseSolution {
    fn status(&self) -> IkStatus {
        self.status
    }
    fn q_mut(&mut self) -> &mut Vec<f64> {
        &mut self.q
    }
}

/// Whether every joint of `q` lies within [`BRANCH_DEG`] of `nominal` (rad).
fn on_branch(q: &[f64], nominal: &[f64]) -> bool {
    q.iter().zip(nominal).all(|(a, b)| (a - b).abs() <= BRANCH_DEG.to_radians())
}

/// The nominal parameter vector of `r`: the chain at the model's nominal values (never the
/// parameter report's, which a diagnosis starts from its geometric fit and an editor may change),
/// no effect, the calibrated placement (the TCP) kept.
pub fn nominal_x(r: &CalibResult) -> Vec<f64> {
    let m = &r.model;
    let mut x = r.x.clone();
    let n = m.n_chain();
    x[..n].copy_from_slice(&m.nominal[..n]);
    for b in 0..m.effects.len() {
        for k in m.effect_params(b) {
            x[k] = 0.0;
        }
    }
    x
}

impl<'a> Compensator<'a> {
    /// The compensation of `r` (with `x_nom` = [`nominal_x`]`(r)`) under `loads` (the joints'
    /// static torques: the result's torque model with the payload the program runs with), to a
    /// tolerance of `tol_mm` (and `tol_deg` on a pose target's orientation). Example: the whole job (the twin's data, this call, the others) runs as a doctest in [`crate::prelude`].
    pub fn new(r: &'a CalibResult, x_nom: &'a [f64], loads: Option<TorqueModel>, tol_mm: f64, tol_deg: f64) -> Result<Compensator<'a>> {
        check_tol_mm(tol_mm, "--tol-mm")?;
        if !(tol_deg > 0.0 && tol_deg <= 1.0) {
            return Err(Error::Invalid(format!("--tol-deg must be in (0, 1] degrees, got {tol_deg}")));
        }
        if x_nom.len() != r.x.len() {
            return Err(Error::Invalid("the nominal parameters do not match the model".into()));
        }
        let limits = r.model.joint_limits();
        let corr: Option<&dyn Correct> = r.corrector.as_ref().map(|c| c.as_correct());
        let mut calibrated = IkModel::new(&r.model, &r.x, corr, limits.clone());
        if let Some(l) = loads {
            calibrated = calibrated.with_loads(l);
        }
        let nominal = IkModel::new(&r.model, x_nom, None, limits);
        let options = IkOptions { tol_mm, tol_deg, max_iter: 100, ..IkOptions::default() };
        let closed = NominalClosedForm::of(&nominal);
        Ok(Compensator { calibrated, nominal, options, closed })
    }

    /// The rigid transform (rotation, translation) that best maps the points `truth` (mm)
    /// measured at configurations `qs` (rad) onto the calibrated model's predictions there (the
    /// nominal model's with `nominal`): a registration of the model's base frame to the
    /// measuring frame, as an accuracy test makes one.
    pub fn registration(&self, qs: &[Vec<f64>], truth: &[Vector3<f64>], nominal: bool) -> (nalgebra::Matrix3<f64>, Vector3<f64>) {
        let m = if nominal { &self.nominal } else { &self.calibrated };
        let mut w = m.work();
        let predicted: Vec<Vector3<f64>> = qs.iter().map(|q| m.position(q, &mut w, None)).collect();
        crate::ik::rigid_fit(truth, &predicted)
    }

    /// Where the calibrated model puts the tool at joint angles `q` (rad), mm, in its frame.
    pub fn predicted(&self, q: &[f64]) -> Vector3<f64> {
        self.calibrated.position(q, &mut self.calibrated.work(), None)
    }

    /// The nominal controller's command for each point (its inverse kinematics), without the
    /// compensation (in parallel); `None` where the nominal model does not reach the point (a
    /// controller would refuse it).
    pub fn nominal_commands(&self, points: &[Vector3<f64>]) -> Vec<Option<Vec<f64>>> {
        points
            .par_iter()
            .map_init(
                || self.nominal.work(),
                |wn, p| {
                    Some(self.nominal.solve(p, JacobianKind::Analytic, &self.options, wn)).filter(|s| s.status == IkStatus::Converged).map(|s| self.turned(s.q))
                },
            )
            .collect()
    }

    /// The nominal controller's command for each pose (its inverse kinematics of the point and
    /// the orientation), without the compensation (in parallel); `None` where the nominal model
    /// does not reach the pose.
    pub fn nominal_pose_commands(&self, poses: &[(Vector3<f64>, Matrix3<f64>)]) -> Vec<Option<Vec<f64>>> {
        poses
            .par_iter()
            .map_init(
                || self.nominal.work(),
                |wn, (p, r)| {
                    Some(self.nominal.solve_pose_from(p, r, None, JacobianKind::Analytic, &self.options, wn))
                        .filter(|s| s.status == IkStatus::Converged)
                        .map(|s| self.turned(s.q))
                },
            )
            .collect()
    }

    /// A nominal command's angles at the turns nearest zero within the limits.
    fn turned(&self, mut q: Vec<f64>) -> Vec<f64> {
        let zero = vec![0.0; q.len()];
        nearest_turns(&mut q, &zero, &self.nominal.limits);
        q
    }

    /// The calibrated solve `solve(options, start)` kept on `nominal`'s branch: from the nominal
    /// command alone first; where that fails, with restarts, whose answer is kept only within
    /// [`BRANCH_DEG`] of the nominal command (else the local answer, not converged, stands).
    /// The answer's angles at the turns nearest the nominal command's.
    fn on_nominal_branch<S: Solved>(&self, nominal: &[f64], mut solve: impl FnMut(&IkOptions, &[f64]) -> S) -> S {
        let turned = |mut s: S| {
            nearest_turns(s.q_mut(), nominal, &self.calibrated.limits);
            s
        };
        let local = turned(solve(&IkOptions { local: true, ..self.options.clone() }, nominal));
        if local.status() == IkStatus::Converged {
            return local;
        }
        let mut again = turned(solve(&self.options, nominal));
        match again.status() == IkStatus::Converged && on_branch(again.q_mut(), nominal) {
            true => again,
            false => local,
        }
    }

    /// Whether the calibrated model at `q` (rad) puts the tool on the pose `p` (mm), `r` within
    /// `factor` times the tolerances (and never closer than a program writes its numbers:
    /// 1e-5 mm, 1e-6°).
    pub fn reaches(&self, q: &[f64], p: &Vector3<f64>, r: &Matrix3<f64>, factor: f64) -> bool {
        let (cp, cr) = self.predicted_pose(q);
        (cp - p).norm() <= (factor * self.options.tol_mm).max(1e-5)
            && crate::ik::solver::turn(r, &cr).norm().to_degrees() <= (factor * self.options.tol_deg).max(1e-6)
    }

    /// Where the calibrated model puts the tool and how it turns it at joint angles `q` (rad):
    /// mm and the orientation, in its frame.
    pub fn predicted_pose(&self, q: &[f64]) -> (Vector3<f64>, Matrix3<f64>) {
        self.calibrated.pose(q, &mut self.calibrated.work(), None)
    }

    /// Every target compensated (in parallel, each thread with its own workspaces).
    pub fn compensate(&self, targets: &[Target]) -> Vec<Compensated> {
        targets
            .par_iter()
            .map_init(
                || (self.calibrated.work(), self.nominal.work()),
                |(wc, wn), t| {
                    let (target, nominal_q) = match t {
                        Target::Pose(p, r) => return self.compensate_pose(p, r, wc, wn),
                        Target::Point(p) => {
                            let s = self.nominal.solve(p, JacobianKind::Analytic, &self.options, wn);
                            (*p, self.turned(s.q))
                        }
                        Target::Joints(q) => (self.nominal.position(q, wn, None), q.clone()),
                    };
                    let s = self.on_nominal_branch(&nominal_q, |o, start| self.calibrated.solve_from(&target, Some(start), JacobianKind::Hybrid, o, wc));
                    let nominal_error_mm = (self.calibrated.position(&nominal_q, wc, None) - target).norm();
                    let filtered = self.nominal.position(&s.q, wn, None);
                    Compensated {
                        target_mm: target.into(),
                        nominal_error_mm: if s.status == IkStatus::Invalid { 0.0 } else { nominal_error_mm },
                        status: Status::of(s.status),
                        residual_mm: s.residual_mm,
                        filtered_mm: filtered.into(),
                        nominal_q,
                        command_q: s.q,
                        pose: None,
                    }
                },
            )
            .collect()
    }

    /// One pose target: the nominal controller's pose IK, then the calibrated model's from it.
    fn compensate_pose(&self, p: &Vector3<f64>, r: &Matrix3<f64>, wc: &mut IkWork, wn: &mut IkWork) -> Compensated {
        let nominal_q = self.turned(self.nominal.solve_pose_from(p, r, None, JacobianKind::Analytic, &self.options, wn).q);
        self.compensate_commanded(p, r, nominal_q, wc, wn)
    }

    /// Workspaces for [`Self::compensate_commanded`] and [`Self::nominal_pose_command`]: the
    /// calibrated model's, the nominal model's.
    pub fn works(&self) -> (IkWork, IkWork) {
        (self.calibrated.work(), self.nominal.work())
    }

    /// The tolerances a target is reached within: mm, and degrees for a pose's orientation.
    pub fn tolerances(&self) -> (f64, f64) {
        (self.options.tol_mm, self.options.tol_deg)
    }

    /// The joints' limits (rad).
    pub fn limits(&self) -> &[(f64, f64)] {
        &self.nominal.limits
    }

    /// Where the nominal model puts the tool and how it turns it at `q` (rad): mm, base frame.
    pub fn nominal_pose(&self, q: &[f64], wn: &mut IkWork) -> (Vector3<f64>, Matrix3<f64>) {
        self.nominal.pose(q, wn, None)
    }

    /// The nominal arm's solutions for the pose `p` (mm), `r`: every one within the joint limits
    /// where the arm has a closed form, else the one a numerical search finds (if any).
    pub fn nominal_pose_solutions(&self, p: &Vector3<f64>, r: &Matrix3<f64>, wn: &mut IkWork) -> Vec<Vec<f64>> {
        match &self.closed {
            Some(cf) => cf.solutions(p, r, &self.nominal.limits),
            None => self.nominal_pose_command(p, r, &[], &|_| true, wn).into_iter().collect(),
        }
    }

    /// Whether the nominal controller is read in closed form (every solution found).
    pub fn closed_form(&self) -> bool {
        self.closed.is_some()
    }

    /// The nominal controller's command for the pose `p` (mm), `r`, where the controller chooses
    /// among the arm's solutions by what the program states (its configuration data, or the
    /// arm's last position): where the arm has a closed form, every solution, nearest the first
    /// start first; else local solves from each of `starts` in turn, then one with random
    /// restarts; the first answer `accept` takes (it may move angles by whole turns to the ones
    /// the program states). `None` where none is accepted.
    pub fn nominal_pose_command(
        &self,
        p: &Vector3<f64>,
        r: &Matrix3<f64>,
        starts: &[Vec<f64>],
        accept: &dyn Fn(&mut Vec<f64>) -> bool,
        wn: &mut IkWork,
    ) -> Option<Vec<f64>> {
        if let Some(cf) = &self.closed {
            // Every solution, nearest the first start first: the first the program accepts.
            let mut all = cf.solutions(p, r, &self.nominal.limits);
            if let Some(s0) = starts.first() {
                all.sort_by(|a, b| max_change(a, s0).total_cmp(&max_change(b, s0)));
            }
            return all.into_iter().find_map(|mut q| accept(&mut q).then_some(q));
        }
        let local = IkOptions { local: true, ..self.options.clone() };
        for start in starts {
            let mut s = self.nominal.solve_pose_from(p, r, Some(start), JacobianKind::Analytic, &local, wn);
            if s.status == IkStatus::Converged && accept(&mut s.q) {
                return Some(s.q);
            }
        }
        let mut s = self.nominal.solve_pose_from(p, r, starts.first().map(Vec::as_slice), JacobianKind::Analytic, &self.options, wn);
        (s.status == IkStatus::Converged && accept(&mut s.q)).then_some(s.q)
    }

    /// The nominal controller's command for the pose `p` (mm), `r` where the controller takes
    /// the arm's solution nearest its present joints `previous` (rad; a UR's `movej` and
    /// `movel` to a pose): where the arm has a closed form, the nearest of every solution; else
    /// the descent from `previous` where it ends within
    /// `CONTINUATION_DEG` of it, else local solves from seeded random starts, the converged
    /// answer nearest `previous` (the largest joint difference, each angle at its turn nearest
    /// `previous`).
    pub fn nominal_pose_nearest(&self, p: &Vector3<f64>, r: &Matrix3<f64>, previous: &[f64], wn: &mut IkWork) -> Option<Vec<f64>> {
        use rand::SeedableRng;
        if let Some(cf) = &self.closed {
            return cf.solutions(p, r, &self.nominal.limits).into_iter().min_by(|a, b| max_change(a, previous).total_cmp(&max_change(b, previous)));
        }
        let local = IkOptions { local: true, ..self.options.clone() };
        let distance = |q: &[f64]| q.iter().zip(previous).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        // The solution the arm continues to from where it stands, where the descent from there
        // finds one near (it follows the target as the arm would).
        let mut s =
            self.nominal.solve_pose_from(p, r, Some(previous), JacobianKind::Analytic, &IkOptions { max_iter: 4 * local.max_iter, ..local.clone() }, wn);
        nearest_turns(&mut s.q, previous, &self.nominal.limits);
        if s.status == IkStatus::Converged && distance(&s.q) <= CONTINUATION_DEG.to_radians() {
            return Some(s.q);
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x4EA2_E570);
        let starts = (0..NEAREST_STARTS).map(|_| self.nominal.random_q(&mut rng)).collect::<Vec<_>>();
        starts
            .iter()
            .filter_map(|start| {
                let mut s = self.nominal.solve_pose_from(p, r, Some(start), JacobianKind::Analytic, &local, wn);
                nearest_turns(&mut s.q, previous, &self.nominal.limits);
                (s.status == IkStatus::Converged).then_some(s.q)
            })
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))
    }

    /// A pose target (`p` mm, `r`, base frame) whose nominal command `nominal_q` (rad) is known
    /// (a program's interpretation by its controller): the calibrated model's command from it, on
    /// its branch.
    pub fn compensate_commanded(&self, p: &Vector3<f64>, r: &Matrix3<f64>, nominal_q: Vec<f64>, wc: &mut IkWork, wn: &mut IkWork) -> Compensated {
        let s = self.on_nominal_branch(&nominal_q, |o, start| self.calibrated.solve_pose_from(p, r, Some(start), JacobianKind::Hybrid, o, wc));
        let (np, nr) = self.calibrated.pose(&nominal_q, wc, None);
        let (fp, fr) = self.nominal.pose(&s.q, wn, None);
        let invalid = s.status == IkStatus::Invalid;
        Compensated {
            target_mm: (*p).into(),
            nominal_error_mm: if invalid { 0.0 } else { (np - p).norm() },
            status: Status::of(s.status),
            residual_mm: s.residual_mm,
            filtered_mm: fp.into(),
            pose: Some(PoseParts {
                target: *r,
                residual_deg: s.residual_deg,
                nominal_error_deg: if invalid { 0.0 } else { crate::ik::solver::turn(r, &nr).norm().to_degrees() },
                filtered: fr,
            }),
            nominal_q,
            command_q: s.q,
        }
    }
}

/// The targets of a CSV: columns `x, y, z` (mm, base frame), with `rx, ry, rz` (degrees, the
/// tool's orientation in the Euler convention `euler`) for poses, else `q1..qN` (degrees, taught
/// on the nominal model), by the dataset reader's rules (read once); or what is wrong with it.
pub fn read_targets(path: &std::path::Path, n_joints: usize, euler: Euler) -> Result<Vec<Target>> {
    let far = crate::measurement::point::MAX_COORD_MM;
    let max_angle = crate::measurement::pose::MAX_ANGLE_DEG;
    let bad = |m: String| Error::data(path.display(), m);
    let t = crate::dataset::CsvColumns::read(path)?;
    // A file is points, poses or joints, for this arm: both kinds of columns, or a joint beyond
    // the arm's, is a file meant for something else.
    if t.has(&format!("q{}", n_joints + 1)) {
        return Err(bad(format!("the targets have a column q{}: the model's arm has {n_joints} joints", n_joints + 1)));
    }
    if t.has("x") && t.has("q1") {
        return Err(bad("the targets have both x, y, z and joint columns: give points or joint targets, not both".into()));
    }
    let angles = ["rx", "ry", "rz"].iter().filter(|a| t.has(a)).count();
    if angles > 0 && angles < 3 {
        return Err(bad(format!("the targets have {angles} of the orientation columns rx, ry, rz (header '{}'): a pose needs all three", t.header())));
    }
    if angles == 3 && !t.has("x") {
        return Err(bad("the targets have rx, ry, rz but no x, y, z: a pose target needs its point (mm, base frame)".into()));
    }
    let targets: Vec<Target> = if t.has("x") {
        let pose = angles == 3;
        let rows = t.columns(if pose { &["x", "y", "z", "rx", "ry", "rz"] } else { &["x", "y", "z"] })?;
        if rows.is_empty() {
            return Err(bad("no targets after the header".into()));
        }
        if let Some((i, v)) = rows.iter().enumerate().find(|(_, v)| v[..3].iter().any(|c| !c.is_finite() || c.abs() > far)) {
            return Err(bad(format!("target {} ({:?}) mm is not a point (a coordinate not finite or beyond {far} mm)", i + 1, &v[..3])));
        }
        if let Some((i, v)) = rows.iter().enumerate().find(|(_, v)| v[3..].iter().any(|c| !c.is_finite() || c.abs() > max_angle)) {
            return Err(bad(format!("target {} has the orientation {:?}: each angle must be finite degrees within ±{max_angle}", i + 1, &v[3..])));
        }
        let angles: Vec<Vec<f64>> = rows.iter().map(|v| v[3..].to_vec()).collect();
        if let Some((largest, j, span)) = crate::dataset::looks_like_radians(&angles, crate::dataset::POSE_RADIANS_MAX_ABS) {
            return Err(bad(format!(
                "columns rx, ry, rz look like radians (all {} targets have |angle| <= {largest:.3}, {} spans {span:.3}): a pose target's angles are degrees (x 180/pi)",
                rows.len(),
                ["rx", "ry", "rz"][j]
            )));
        }
        // Metres read as millimetres put every target inside the arm's base.
        if rows.iter().all(|v| v[..3].iter().all(|c| c.abs() < METRES_MM)) {
            return Err(bad(format!("every target lies within {METRES_MM} mm of the base origin: are the coordinates in metres? Targets are in mm")));
        }
        rows.into_iter()
            .map(|v| {
                let p = Vector3::new(v[0], v[1], v[2]);
                if pose {
                    Target::Pose(p, euler.matrix([v[3], v[4], v[5]].map(f64::to_radians)))
                } else {
                    Target::Point(p)
                }
            })
            .collect()
    } else {
        let names: Vec<String> = (1..=n_joints).map(|j| format!("q{j}")).collect();
        let cols: Vec<&str> = names.iter().map(String::as_str).collect();
        let rows = t.columns(&cols).map_err(|_| {
            bad(format!(
                "targets need columns x, y, z (mm, base frame; with rx, ry, rz in degrees for poses) or q1..q{n_joints} (degrees, taught on the nominal model): the header is '{}'",
                t.header()
            ))
        })?;
        if let Some((i, v)) = rows.iter().enumerate().find(|(_, v)| v.iter().any(|c| !c.is_finite() || c.abs() > 3600.0)) {
            return Err(bad(format!("target {} has joint angles {:?}: each must be finite degrees within ±3600", i + 1, v)));
        }
        if let Some((largest, j, span)) = crate::dataset::looks_like_radians(&rows, crate::dataset::RADIANS_MAX_ABS) {
            return Err(bad(format!(
                "columns q1..q{n_joints} look like radians (all {} targets have |q| <= {largest:.3}, q{} spans {span:.3}): joint targets are degrees (x 180/pi)",
                rows.len(),
                j + 1
            )));
        }
        rows.into_iter().map(|v| Target::Joints(v.iter().map(|d| d.to_radians()).collect())).collect()
    };
    if targets.is_empty() {
        return Err(bad("no targets after the header".into()));
    }
    Ok(targets)
}

/// Below this (mm) on every coordinate of every target, a target file is taken for metres.
const METRES_MM: f64 = 5.0;

/// The commands as CSV: per target its point (mm; for a pose also its orientation, degrees in
/// the convention `euler`), the command (degrees), the status, the predicted residual and the
/// uncompensated error (mm; degrees for a pose's orientation), the filtered Cartesian target
/// (mm, degrees) and the nominal command (degrees).
pub fn commands_csv(rows: &[Compensated], euler: Euler) -> String {
    use std::fmt::Write;
    let n = rows.first().map_or(0, |r| r.command_q.len());
    let pose = rows.iter().any(|r| r.pose.is_some());
    let q = |p: &str| (1..=n).map(|j| format!("{p}q{j}_deg")).collect::<Vec<_>>().join(",");
    let mut out = if pose {
        format!(
            "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,{},status,residual_mm,residual_deg,nominal_error_mm,nominal_error_deg,x_filtered_mm,y_filtered_mm,z_filtered_mm,rx_filtered_deg,ry_filtered_deg,rz_filtered_deg,{}\n",
            q(""),
            q("nominal_")
        )
    } else {
        format!("x_mm,y_mm,z_mm,{},status,residual_mm,nominal_error_mm,x_filtered_mm,y_filtered_mm,z_filtered_mm,{}\n", q(""), q("nominal_"))
    };
    let deg = |v: &[f64]| v.iter().map(|a| format!("{:.9}", a.to_degrees())).collect::<Vec<_>>().join(",");
    let angles = |m: &Matrix3<f64>| deg(&euler.angles(m));
    for r in rows {
        let [x, y, z] = r.target_mm;
        let [fx, fy, fz] = r.filtered_mm;
        let _ = match &r.pose {
            Some(o) => writeln!(
                out,
                "{x:.6},{y:.6},{z:.6},{},{},{},{:.6},{:.6},{:.6},{:.6},{fx:.6},{fy:.6},{fz:.6},{},{}",
                angles(&o.target),
                deg(&r.command_q),
                r.status.name(),
                r.residual_mm,
                o.residual_deg,
                r.nominal_error_mm,
                o.nominal_error_deg,
                angles(&o.filtered),
                deg(&r.nominal_q)
            ),
            None => writeln!(
                out,
                "{x:.6},{y:.6},{z:.6},{},{},{:.6},{:.6},{fx:.6},{fy:.6},{fz:.6},{}",
                deg(&r.command_q),
                r.status.name(),
                r.residual_mm,
                r.nominal_error_mm,
                deg(&r.nominal_q)
            ),
        };
    }
    out
}
