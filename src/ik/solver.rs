//! Position inverse kinematics on a calibrated model (the paper's neuro-physical hybrid Jacobian
//! solver, NPHJ) and its validation on the twin.
//!
//! # Forward model
//!
//! The calibrated tool position at commanded angles q is the geometric tool point at the
//! effect-applied angles, `p(q)` ([`CalibModel::tool_point_with`]), plus the learned length
//! correction δ(q) (mm, any [`Correct`]) applied along the cable direction
//! `u = (p − e)/|p − e|` from the exit point e: `p̂(q) = p(q) + δ(q)·u(q)`. The sensor measures
//! one length, so the direction along the cable is the only one the data speak about.
//!
//! # Jacobians (the paper's Table 11)
//!
//! * analytic: `J_p`, the chain's point Jacobian (the rigid backbone);
//! * neural: `u ∇δᵀ`, the correction's own gradient only (rank one: it cannot steer three
//!   coordinates, kept because the paper compares it);
//! * hybrid: `J_p + u ∇δᵀ + δ·(I − u uᵀ) J_p / |p − e|`, the exact Jacobian of p̂ (the last term
//!   is the turning of the cable direction).
//!
//! Every variant iterates on the same forward model p̂, so they differ only in the step.
//!
//! # Solver
//!
//! Damped least squares with a fixed damping λ (mm/rad), `Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ (t − p̂)`, the
//! step limited to `max_step` rad, the joints clamped to their limits after every step. It starts
//! from the middle of the joint ranges and, when that does not converge, from a few seeded
//! random configurations (the same for every variant). Each target gets a status:
//! `converged` (model residual ≤ `tol_mm`), `unreachable` (farther from the base than the arm
//! reaches), `joint_limit` (stuck with a joint at a limit), `singular` (stuck where the
//! Jacobian loses rank), `not_converged` or `invalid` (non-finite target). Never NaN, never a panic.

use crate::calib::correctors::Correct;
use crate::calib::effects::RowInputs;
use crate::calib::model::{CalibModel, ModelWork};
use crate::error::{Error, Result};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// Which Jacobian the solver steps with (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JacobianKind {
    /// The chain's point Jacobian `J_p` alone.
    Analytic,
    /// The correction's own gradient `u ∇δᵀ` alone (rank one).
    Neural,
    /// The exact Jacobian of p̂: `J_p + u ∇δᵀ + δ·(I − u uᵀ) J_p / |p − e|`.
    Hybrid,
}

impl JacobianKind {
    /// Every variant, in the order the paper's table lists them.
    pub const ALL: [JacobianKind; 3] = [JacobianKind::Analytic, JacobianKind::Neural, JacobianKind::Hybrid];
    /// The variant's name as files and tables write it (`analytic`, `neural`, `hybrid`).
    pub fn name(self) -> &'static str {
        match self {
            JacobianKind::Analytic => "analytic",
            JacobianKind::Neural => "neural",
            JacobianKind::Hybrid => "hybrid",
        }
    }
}

/// Which Jacobians a request solves with: one of them, or all three side by side (the paper's
/// comparison).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum JacobianChoice {
    /// The chain's point Jacobian alone.
    Analytic,
    /// The correction's own gradient alone.
    Neural,
    /// The exact Jacobian of the corrected model (the method's own).
    #[default]
    Hybrid,
    /// The three, each a run of its own.
    All,
}

impl JacobianChoice {
    /// The Jacobians to run.
    pub fn kinds(self) -> Vec<JacobianKind> {
        match self {
            JacobianChoice::Analytic => vec![JacobianKind::Analytic],
            JacobianChoice::Neural => vec![JacobianKind::Neural],
            JacobianChoice::Hybrid => vec![JacobianKind::Hybrid],
            JacobianChoice::All => JacobianKind::ALL.to_vec(),
        }
    }
}

impl std::str::FromStr for JacobianChoice {
    type Err = crate::error::Error;
    /// `analytic`, `neural`, `hybrid` or `all`, in any case.
    fn from_str(s: &str) -> crate::error::Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "analytic" => Ok(JacobianChoice::Analytic),
            "neural" => Ok(JacobianChoice::Neural),
            "hybrid" => Ok(JacobianChoice::Hybrid),
            "all" => Ok(JacobianChoice::All),
            _ => Err(crate::error::Error::Invalid(format!("unknown jacobian '{s}' (expected analytic, neural, hybrid or all)"))),
        }
    }
}

/// What happened to one target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IkStatus {
    /// Model residual within `tol_mm`.
    Converged,
    /// The target is farther from the base than the arm reaches.
    Unreachable,
    /// Stuck with a joint at one of its limits.
    JointLimit,
    /// Stuck where the Jacobian loses rank.
    Singular,
    /// No start reached `tol_mm` within `max_iter` iterations, for none of the reasons above.
    NotConverged,
    /// The target is not finite.
    Invalid,
}

impl IkStatus {
    /// The status's name as files and tables write it (`converged`, `joint_limit`, ...).
    pub fn name(self) -> &'static str {
        match self {
            IkStatus::Converged => "converged",
            IkStatus::Unreachable => "unreachable",
            IkStatus::JointLimit => "joint_limit",
            IkStatus::Singular => "singular",
            IkStatus::NotConverged => "not_converged",
            IkStatus::Invalid => "invalid",
        }
    }
}

/// The answer for one target.
#[derive(Clone, Debug, Serialize)]
pub struct IkSolution {
    /// How the solve ended.
    pub status: IkStatus,
    /// Joint angles, rad (the best found, also when not converged; the start for `invalid`).
    pub q: Vec<f64>,
    /// Iterations over all starts.
    pub iterations: usize,
    /// |t − p̂(q)|, mm (NaN never: +∞ is not produced either; `invalid` reports 0).
    pub residual_mm: f64,
}

/// Largest `--tol-mm`: beyond a centimetre a "solution" says nothing about where the tool is.
pub const MAX_TOL_MM: f64 = 10.0;

/// The check of `--tol-mm` (and of Python's `Result.ik(tol_mm=...)`, `option` naming it as its
/// caller spells it): within (0, [`MAX_TOL_MM`]].
pub fn check_tol_mm(tol_mm: f64, option: &str) -> Result<()> {
    if !(tol_mm > 0.0 && tol_mm <= MAX_TOL_MM) {
        return Err(Error::Invalid(format!("{option} must be in (0, {MAX_TOL_MM}] mm, got {tol_mm}")));
    }
    Ok(())
}

/// Solver settings.
#[derive(Clone, Debug, PartialEq)]
pub struct IkOptions {
    /// Model residual that counts as converged, mm.
    pub tol_mm: f64,
    /// Damping λ of the damped least-squares step, mm/rad.
    pub damping: f64,
    /// Iterations per start.
    pub max_iter: usize,
    /// Random restarts after the mid-range start.
    pub restarts: usize,
    /// Largest change of any joint in one step, rad.
    pub max_step: f64,
    /// Seed of the random restarts.
    pub seed: u64,
    /// Orientation error that counts as converged for a pose target, degrees.
    pub tol_deg: f64,
    /// Descend from the start only, with no random restart: a solve that must stay on the
    /// start's branch (a compensated command beside its nominal one).
    pub local: bool,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions { tol_mm: 0.01, damping: 0.5, max_iter: 60, restarts: 6, max_step: 0.35, seed: 0, tol_deg: 0.001, local: false }
    }
}

/// Reusable buffers of [`IkModel`]: the model's own workspace and the per-joint columns, so a
/// solve allocates nothing per iteration. One per thread ([`IkModel::work`]).
pub struct IkWork {
    /// The calibrated model's own workspace.
    pub model: ModelWork,
    /// The chosen Jacobian of the last [`IkModel::position`] call with one, mm/rad, a column per joint.
    pub cols: Vec<Vector3<f64>>,
    /// The orientation's Jacobian of the last [`IkModel::pose`] call, rad/rad, a column per joint.
    pub rcols: Vec<Vector3<f64>>,
    dp: Vec<Vector3<f64>>,
    g: Vec<f64>,
}

/// A calibrated model as an IK forward model: geometry, optional learned corrector, limits.
pub struct IkModel<'a> {
    /// The calibrated model.
    pub model: &'a CalibModel,
    /// Its parameter vector (internal units m / rad).
    pub x: &'a [f64],
    /// The learned corrector added to the geometry, if any.
    pub corrector: Option<&'a dyn Correct>,
    /// Joint limits (lower, upper), rad, one pair per joint.
    pub limits: Vec<(f64, f64)>,
    inp: RowInputs,
    /// The loads on the joints, when the joints' static torques at each configuration feed the
    /// model (a compliance block, a backlash block's load rule): [`Self::with_loads`].
    loads: Option<crate::calib::effects::inputs::TorqueModel>,
    exit: Vector3<f64>,
    /// For a corrector of a tracker's x, y, z: the tracker-to-base rotation Rᵀ that carries its
    /// corrections (tracker frame) to the base frame the targets are in.
    to_base: Option<nalgebra::Matrix3<f64>>,
    /// Largest distance of the tool point from the base origin over a sample of configurations, mm.
    reach_mm: f64,
}

impl<'a> IkModel<'a> {
    /// The forward model of `model` at `x`, with `corrector`, clamped to `limits` (rad); estimates
    /// the arm's reach from 2000 seeded random configurations.
    pub fn new(model: &'a CalibModel, x: &'a [f64], corrector: Option<&'a dyn Correct>, limits: Vec<(f64, f64)>) -> IkModel<'a> {
        // A draw-wire's corrector corrects the cable length, applied along the cable from its
        // exit point; a tracker's corrects x, y, z in the tracker's frame (result files are
        // checked for the corrector's dimension).
        let placement = model.placement(x);
        let exit = placement.exit().unwrap_or_else(Vector3::zeros);
        // A pose's corrector also corrects its axes: its first three values are the origin's.
        let to_base =
            model.measurement.def().frame(&placement.own).axes.filter(|_| corrector.is_some_and(|c| c.dim() == model.measurement.dim() && c.dim() >= 3));
        let mut m = IkModel { model, x, corrector, limits, inp: RowInputs::default(), loads: None, exit, to_base, reach_mm: f64::INFINITY };
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut w = model.work();
        let mut reach = 0.0f64;
        for _ in 0..2000 {
            let q = m.random_q(&mut rng);
            reach = reach.max(crate::units::to_mm(model.tool_point_with(x, &q, &m.inp, &mut w).norm()));
        }
        m.reach_mm = reach * 1.01 + 1.0;
        m
    }
    /// The model read with the joints' static torques under `loads` at every configuration
    /// (gravity on the links and the payload), and each backlash flank the one the load pushes
    /// to where the torque exceeds the load rule's threshold (unknown, the band's middle,
    /// elsewhere: a target carries no approach history).
    pub fn with_loads(mut self, loads: crate::calib::effects::inputs::TorqueModel) -> Self {
        self.loads = Some(loads);
        self
    }
    /// The row inputs at joint angles `q`: the loads' torques and flanks, or none.
    pub fn inputs_at(&self, q: &[f64]) -> RowInputs {
        match &self.loads {
            Some(tm) => {
                let torque = tm.torques(q);
                let side = torque.iter().map(|t| if t.abs() > tm.torque_threshold_nm { t.signum() } else { 0.0 }).collect();
                RowInputs { torque, side, ..RowInputs::default() }
            }
            None => self.inp.clone(),
        }
    }
    /// A workspace sized for this model's joints.
    pub fn work(&self) -> IkWork {
        let n = self.model.chain.n_joints;
        IkWork { model: self.model.work(), cols: vec![Vector3::zeros(); n], rcols: vec![Vector3::zeros(); n], dp: vec![Vector3::zeros(); n], g: vec![0.0; n] }
    }
    /// Uniformly random joint angles inside the limits, rad.
    pub fn random_q(&self, rng: &mut ChaCha8Rng) -> Vec<f64> {
        self.limits.iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect()
    }
    /// p̂(q) in mm and, when `jac` is given, the chosen Jacobian (mm/rad, 3 × N, a column per
    /// joint) into `w.cols`.
    pub fn position(&self, q: &[f64], w: &mut IkWork, jac: Option<JacobianKind>) -> Vector3<f64> {
        let loaded = self.loads.as_ref().map(|_| self.inputs_at(q));
        let inp = loaded.as_ref().unwrap_or(&self.inp);
        if let (Some(rt), Some(c)) = (self.to_base, self.corrector) {
            return self.position_point(q, inp, w, jac, &rt, c);
        }
        let IkWork { model: mw, cols, dp, g, .. } = w;
        let p = crate::units::to_mm(self.model.tool_point_jac_q(self.x, q, inp, mw, dp));
        let d = p - crate::units::to_mm(self.exit);
        let dist = d.norm().max(1e-9);
        let u = d / dist;
        let delta = match self.corrector {
            Some(c) => c.correction_grad_mm(q, inp, g),
            None => {
                g.fill(0.0);
                0.0
            }
        };
        if let Some(kind) = jac {
            for (j, out) in cols.iter_mut().enumerate() {
                let jp = crate::units::to_mm(dp[j]);
                *out = match kind {
                    JacobianKind::Analytic => jp,
                    JacobianKind::Neural => u * g[j],
                    JacobianKind::Hybrid => jp + u * g[j] + (jp - u * u.dot(&jp)) * (delta / dist),
                };
            }
        }
        p + u * delta
    }

    /// [`Self::position`] with a corrector of a tracker's x, y, z: `p̂ = p + Rᵀ·δ(q)`, the
    /// correction carried from the tracker's frame to the base; its Jacobian `J_p + Rᵀ·∂δ/∂q`
    /// is exact (Rᵀ is constant), `Neural` is `Rᵀ·∂δ/∂q` alone.
    fn position_point(
        &self,
        q: &[f64],
        inp: &RowInputs,
        w: &mut IkWork,
        jac: Option<JacobianKind>,
        rt: &nalgebra::Matrix3<f64>,
        c: &dyn Correct,
    ) -> Vector3<f64> {
        let IkWork { model: mw, cols, dp, g, .. } = w;
        let n = q.len();
        let p = crate::units::to_mm(self.model.tool_point_jac_q(self.x, q, inp, mw, dp));
        let mut all = [0.0; crate::measurement::MAX_DIM];
        let delta = &mut all[..c.dim()];
        g.resize(c.dim() * n, 0.0);
        c.corrections_grad_mm(q, inp, delta, g);
        let delta = [delta[0], delta[1], delta[2]];
        if let Some(kind) = jac {
            for (j, out) in cols.iter_mut().enumerate() {
                let jp = crate::units::to_mm(dp[j]);
                let jd = rt * Vector3::new(g[j], g[n + j], g[2 * n + j]);
                *out = match kind {
                    JacobianKind::Analytic => jp,
                    JacobianKind::Neural => jd,
                    JacobianKind::Hybrid => jp + jd,
                };
            }
        }
        p + rt * Vector3::from(delta)
    }

    fn mid(&self) -> Vec<f64> {
        self.limits.iter().map(|(lo, hi)| 0.5 * (lo + hi)).collect()
    }

    /// Solves one target (mm, in the model's frame).
    pub fn solve(&self, target: &Vector3<f64>, kind: JacobianKind, o: &IkOptions, w: &mut IkWork) -> IkSolution {
        self.solve_from(target, None, kind, o, w)
    }

    /// Solves one target starting from `start` (rad; clamped to the limits) when given, else from
    /// the middle of the ranges; then from the seeded random restarts while it has not converged.
    pub fn solve_from(&self, target: &Vector3<f64>, start: Option<&[f64]>, kind: JacobianKind, o: &IkOptions, w: &mut IkWork) -> IkSolution {
        if !target.iter().all(|v| v.is_finite()) {
            return IkSolution { status: IkStatus::Invalid, q: self.mid(), iterations: 0, residual_mm: 0.0 };
        }
        let mut cols = vec![Vector3::zeros(); self.limits.len()];
        let eval = |q: &[f64], w: &mut IkWork, cols: &mut [Vector3<f64>]| {
            let p = self.position(q, w, Some(kind));
            cols.copy_from_slice(&w.cols);
            target - p
        };
        let judge = |e: &Vector3<f64>| (e.norm(), e.norm() <= o.tol_mm);
        let (res, q, stuck, iterations) = self.search(self.first(start), o, w, &mut cols, &eval, &judge);
        let status = if res <= o.tol_mm {
            IkStatus::Converged
        } else if target.norm() > self.reach_mm {
            IkStatus::Unreachable
        } else {
            stuck
        };
        IkSolution { status, q, iterations, residual_mm: res }
    }

    /// The start of a solve: `start` clamped to the limits, else the middle of the ranges.
    fn first(&self, start: Option<&[f64]>) -> Vec<f64> {
        match start {
            Some(q) if q.len() == self.limits.len() && q.iter().all(|v| v.is_finite()) => {
                q.iter().zip(&self.limits).map(|(v, (lo, hi))| v.clamp(*lo, *hi)).collect()
            }
            _ => self.mid(),
        }
    }

    /// Descents from `first`, then from the seeded random restarts while none has converged:
    /// (the best one's score, its angles, why it stopped, iterations over all starts).
    fn search<const D: usize>(
        &self,
        first: Vec<f64>,
        o: &IkOptions,
        w: &mut IkWork,
        cols: &mut [SVector<f64, D>],
        eval: &Eval<D>,
        judge: &Judge<D>,
    ) -> (f64, Vec<f64>, IkStatus, usize) {
        let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
        let mut best: Option<(f64, Vec<f64>, IkStatus)> = None;
        let mut iterations = 0;
        for start in 0..=(if o.local { 0 } else { o.restarts }) {
            let q0 = if start == 0 { first.clone() } else { self.random_q(&mut rng) };
            let (res, q, it, stuck) = self.descend(q0, o, w, cols, eval, judge);
            iterations += it;
            let done = stuck == IkStatus::Converged;
            // A start that converged is kept even where its score is higher than a failed one's (a
            // pose's score weighs position and orientation together; converging is judged on each).
            if done || best.as_ref().is_none_or(|b| res < b.0) {
                best = Some((res, q, stuck));
            }
            if done {
                break;
            }
        }
        let (res, q, stuck) = best.expect("at least one start");
        (res, q, stuck, iterations)
    }

    /// One damped least-squares descent on the weighted error `eval` returns (target − model, D
    /// coordinates, its Jacobian columns into `cols`): (the score `judge` gives the last error,
    /// q, iterations, `Converged` or why it stopped).
    fn descend<const D: usize>(
        &self,
        mut q: Vec<f64>,
        o: &IkOptions,
        w: &mut IkWork,
        cols: &mut [SVector<f64, D>],
        eval: &Eval<D>,
        judge: &Judge<D>,
    ) -> (f64, Vec<f64>, usize, IkStatus) {
        let lam2 = o.damping * o.damping;
        let mut res = f64::INFINITY;
        for it in 0..o.max_iter {
            let e = eval(&q, w, cols);
            let (score, done) = judge(&e);
            res = score;
            if !res.is_finite() {
                return (f64::INFINITY, q, it, IkStatus::NotConverged);
            }
            if done {
                return (res, q, it, IkStatus::Converged);
            }
            let Some(inv) = (gram(cols) + SMatrix::<f64, D, D>::identity() * lam2).try_inverse() else {
                return (res, q, it, IkStatus::Singular);
            };
            let y = inv * e;
            // Step: J^T y, scaled so that no joint moves more than `max_step`.
            let big = cols.iter().fold(0.0f64, |m, c| m.max(c.dot(&y).abs()));
            let shrink = if big > o.max_step { o.max_step / big } else { 1.0 };
            for (j, c) in cols.iter().enumerate() {
                q[j] = (q[j] + c.dot(&y) * shrink).clamp(self.limits[j].0, self.limits[j].1);
            }
        }
        let e = eval(&q, w, cols);
        let (score, done) = judge(&e);
        if score.is_finite() {
            res = score;
        }
        if done {
            return (res, q, o.max_iter, IkStatus::Converged);
        }
        let jjt = gram(cols);
        // (dynamically sized: a generic fixed size has no eigen-decomposition; once per failed start)
        let eig = nalgebra::DMatrix::from_column_slice(D, D, jjt.as_slice()).symmetric_eigenvalues();
        let (lo, hi) = (eig.min().max(0.0), eig.max());
        let smin_ratio = if hi > 0.0 { (lo / hi).sqrt() } else { 0.0 };
        let at_limit = q.iter().zip(&self.limits).any(|(v, (lo, hi))| (v - lo).abs() < 1e-9 || (v - hi).abs() < 1e-9);
        let why = if at_limit {
            IkStatus::JointLimit
        } else if smin_ratio < 1e-3 {
            IkStatus::Singular
        } else {
            IkStatus::NotConverged
        };
        (res, q, o.max_iter, why)
    }

    /// The tool's position p̂ (mm, as [`Self::position`]) and orientation (the model's
    /// [`CalibModel::tool_rotation_jac_q`]) at `q`; with `jac`, the position's Jacobian into
    /// `w.cols` and the orientation's (rad/rad) into `w.rcols`.
    pub fn pose(&self, q: &[f64], w: &mut IkWork, jac: Option<JacobianKind>) -> (Vector3<f64>, Matrix3<f64>) {
        let p = self.position(q, w, Some(jac.unwrap_or(JacobianKind::Analytic)));
        let IkWork { model, rcols, .. } = w;
        let r = self.model.tool_rotation_jac_q(self.x, model, rcols);
        (p, r)
    }

    /// How well the pose at `q` (rad) pins the joints down: the smallest singular value of the
    /// pose Jacobian (the chain's, mm/rad; the orientation rows weighed by
    /// [`crate::measurement::pose::LEVER_MM`] as the pose solve weighs them). Below
    /// [`NEAR_SINGULAR_MM_PER_RAD`] the configuration is next to a singularity: a joint (or two
    /// together) turns by a degree or more for a few hundredths of a mm.
    pub fn pose_conditioning(&self, q: &[f64], w: &mut IkWork) -> f64 {
        self.pose(q, w, Some(JacobianKind::Analytic));
        let lever = crate::measurement::pose::LEVER_MM;
        nalgebra::DMatrix::from_fn(6, q.len(), |i, k| if i < 3 { w.cols[k][i] } else { lever * w.rcols[k][i - 3] }).singular_values().min()
    }

    /// Solves one pose target — the tool point `target` (mm) with the tool's orientation `rot`
    /// (base frame) — as [`Self::solve_from`] solves a point: damped least squares on the
    /// position error and the orientation error's rotation vector, weighted by
    /// [`crate::measurement::pose::LEVER_MM`] (an orientation error of δ rad weighs as δ·100 mm);
    /// converged when the position is within `tol_mm` and the orientation within `tol_deg`.
    /// The orientation is the geometric model's with its effects: a corrector corrects the
    /// position only.
    pub fn solve_pose_from(
        &self,
        target: &Vector3<f64>,
        rot: &Matrix3<f64>,
        start: Option<&[f64]>,
        kind: JacobianKind,
        o: &IkOptions,
        w: &mut IkWork,
    ) -> PoseSolution {
        let lever = crate::measurement::pose::LEVER_MM;
        if !target.iter().chain(rot.iter()).all(|v| v.is_finite()) {
            return PoseSolution { status: IkStatus::Invalid, q: self.mid(), iterations: 0, residual_mm: 0.0, residual_deg: 0.0 };
        }
        let mut cols = vec![Vector6::zeros(); self.limits.len()];
        let eval = |q: &[f64], w: &mut IkWork, cols: &mut [Vector6<f64>]| {
            let (p, r) = self.pose(q, w, Some(kind));
            for (c, (a, b)) in cols.iter_mut().zip(w.cols.iter().zip(&w.rcols)) {
                *c = Vector6::new(a.x, a.y, a.z, lever * b.x, lever * b.y, lever * b.z);
            }
            let dp = target - p;
            let da = turn(rot, &r) * lever;
            Vector6::new(dp.x, dp.y, dp.z, da.x, da.y, da.z)
        };
        let tol_rad = o.tol_deg.to_radians();
        let judge = |e: &Vector6<f64>| {
            let (dp, da) = (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm() / lever);
            (e.norm(), dp <= o.tol_mm && da <= tol_rad)
        };
        // A pose has more local minima than a point (the wrist's branches): at least
        // POSE_RESTARTS random starts (on a UR10, 6 restarts reach 92 of 100 random reachable
        // poses, 20 every one).
        let o = &IkOptions { restarts: o.restarts.max(POSE_RESTARTS), ..o.clone() };
        let (_, q, stuck, iterations) = self.search(self.first(start), o, w, &mut cols, &eval, &judge);
        let (p, r) = self.pose(&q, w, None);
        let (residual_mm, residual_deg) = ((target - p).norm(), turn(rot, &r).norm().to_degrees());
        let status = if residual_mm <= o.tol_mm && residual_deg <= o.tol_deg {
            IkStatus::Converged
        } else if target.norm() > self.reach_mm {
            IkStatus::Unreachable
        } else if stuck == IkStatus::Converged {
            IkStatus::NotConverged
        } else {
            stuck
        };
        PoseSolution { status, q, iterations, residual_mm, residual_deg }
    }
}

/// J Jᵀ of the Jacobian whose columns are `cols`.
fn gram<const D: usize>(cols: &[SVector<f64, D>]) -> SMatrix<f64, D, D> {
    cols.iter().fold(SMatrix::zeros(), |m, c| m + c * c.transpose())
}

/// Below this [`IkModel::pose_conditioning`] (mm/rad) a configuration is next to a singularity.
pub const NEAR_SINGULAR_MM_PER_RAD: f64 = 5.0;

/// Fewest random restarts of a pose solve ([`IkModel::solve_pose_from`]).
pub const POSE_RESTARTS: usize = 24;

/// The rotation vector (axis × angle, rad, base frame) that turns `r` onto `target`: the angle
/// from the product's antisymmetric part and trace (atan2, so that a product a rounding error
/// away from orthonormal near no turn at all gives a tiny vector, never NaN, as an arccosine of
/// a cosine above one did and sent converged solves to restarts on other branches); near a half
/// turn, the rotation nearest the product.
pub fn turn(target: &Matrix3<f64>, r: &Matrix3<f64>) -> Vector3<f64> {
    crate::math::rotation_vector(&(target * r.transpose()))
}

/// A descent's error and Jacobian: target − model at q (D weighted coordinates), its columns.
type Eval<'e, const D: usize> = dyn Fn(&[f64], &mut IkWork, &mut [SVector<f64, D>]) -> SVector<f64, D> + 'e;
/// A descent's score of an error and whether it counts as converged.
type Judge<'e, const D: usize> = dyn Fn(&SVector<f64, D>) -> (f64, bool) + 'e;

/// The answer for one pose target.
#[derive(Clone, Debug, Serialize)]
pub struct PoseSolution {
    /// How the solve ended (converged: position and orientation within their tolerances).
    pub status: IkStatus,
    /// Joint angles, rad.
    pub q: Vec<f64>,
    /// Iterations over all starts.
    pub iterations: usize,
    /// |t − p̂(q)|, mm.
    pub residual_mm: f64,
    /// The angle between the target's orientation and the model's, degrees.
    pub residual_deg: f64,
}

/// The rigid transform (R, t) minimising Σ |R a_i + t − b_i|² (Kabsch).
pub fn rigid_fit(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> (Matrix3<f64>, Vector3<f64>) {
    let n = a.len().max(1) as f64;
    let ca = a.iter().sum::<Vector3<f64>>() / n;
    let cb = b.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (p, q) in a.iter().zip(b) {
        h += (p - ca) * (q - cb).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.unwrap_or_else(Matrix3::identity), svd.v_t.unwrap_or_else(Matrix3::identity));
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    (r, cb - r * ca)
}

#[cfg(test)]
mod tests {
    /// `turn` is nalgebra's rotation vector of the product for any turn, and stays finite (a tiny
    /// vector) for a product a rounding error away from orthonormal near no turn at all.
    #[test]
    fn a_turn_is_the_rotation_vector_and_never_nan() {
        use nalgebra::Rotation3;
        for k in 0..200 {
            let f = k as f64;
            let a = Rotation3::from_euler_angles(0.7 * f, -0.3 * f, 1.1 * f).into_inner();
            let b = Rotation3::from_euler_angles(0.2 * f.sin(), 3.0 * f.cos(), 0.05 * f).into_inner();
            let want = Rotation3::from_matrix_unchecked(a * b.transpose()).scaled_axis();
            let got = turn(&a, &b);
            assert!((got - want).norm() < 1e-9 || (got.norm() - std::f64::consts::PI).abs() < 1e-6, "{k}: {got} vs {want}");
        }
        let r = Rotation3::from_euler_angles(0.4, -1.2, 2.9).into_inner();
        let nearly = r * (1.0 + 4e-16) + Matrix3::from_element(1e-16);
        let t = turn(&nearly, &r);
        assert!(t.iter().all(|v| v.is_finite()) && t.norm() < 1e-12, "{t}");
    }
    use super::*;
    use crate::calib::correctors::gkan::{Gkan, GkanShape};
    use crate::calib::model::DrawWireGuess;
    use crate::robot::Robot;

    fn model() -> (CalibModel, Vec<(f64, f64)>) {
        let robot = Robot::irb120();
        let guess = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.062, 0.004, -0.003] };
        (CalibModel::dh(&robot, &guess, true), robot.limits())
    }

    /// Every column of the hybrid Jacobian `cols` at `q` against central differences of p̂.
    fn assert_hybrid_jacobian_matches_finite_differences(ik: &IkModel, q: &[f64], cols: &[Vector3<f64>], w: &mut IkWork) {
        for (j, col) in cols.iter().enumerate() {
            let (mut a, mut b) = (q.to_vec(), q.to_vec());
            a[j] += 1e-6;
            b[j] -= 1e-6;
            let fd = (ik.position(&a, w, None) - ik.position(&b, w, None)) / 2e-6;
            assert!((fd - col).norm() < 1e-4 * (1.0 + col.norm()), "joint {j}: {fd:?} vs {col:?}");
        }
    }

    #[test]
    fn hybrid_jacobian_matches_finite_differences_and_ik_reaches_targets() {
        let (m, limits) = model();
        let x = m.nominal.clone();
        let qs: Vec<Vec<f64>> = (0..40).map(|k| (0..6).map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin() * 1.2).collect()).collect();
        let (lo, hi) = Gkan::range_of(&qs);
        let mut g = Gkan::new(GkanShape::default(), lo, hi);
        g.coef.iter_mut().enumerate().for_each(|(k, c)| *c = 0.3 * ((k as f64) * 0.61).sin());
        let ik = IkModel::new(&m, &x, Some(&g), limits.clone());
        let mut w = ik.work();
        let q = qs[5].iter().map(|v| v * 0.9).collect::<Vec<_>>();
        ik.position(&q, &mut w, Some(JacobianKind::Hybrid));
        let cols = w.cols.clone();
        assert_hybrid_jacobian_matches_finite_differences(&ik, &q, &cols, &mut w);
        // Reachable targets (the model's own points inside the evo_nph scenario's sampled joint
        // ranges, as `ik --random` draws them) are all solved to 0.01 mm.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let o = IkOptions::default();
        let ranges = [[-90.0, 90.0], [-45.0, 80.0], [-90.0, 50.0], [-150.0, 150.0], [-100.0, 100.0], [-180.0, 180.0f64]];
        for _ in 0..30 {
            let qt: Vec<f64> = ranges.iter().map(|[lo, hi]| (lo + (hi - lo) * rng.random::<f64>()).to_radians()).collect();
            let t = ik.position(&qt, &mut w, None);
            let s = ik.solve(&t, JacobianKind::Hybrid, &o, &mut w);
            assert_eq!(s.status, IkStatus::Converged, "{s:?}");
            assert!(s.residual_mm <= 0.01 && (ik.position(&s.q, &mut w, None) - t).norm() <= 0.01);
            assert!(s.q.iter().zip(&limits).all(|(v, (lo, hi))| v >= lo && v <= hi));
        }
        // Bad targets get a status, not a panic or NaN.
        let far = ik.solve(&Vector3::new(5000.0, 0.0, 0.0), JacobianKind::Hybrid, &o, &mut w);
        assert_eq!(far.status, IkStatus::Unreachable);
        assert!(far.residual_mm.is_finite());
        let nan = ik.solve(&Vector3::new(f64::NAN, 0.0, 0.0), JacobianKind::Hybrid, &o, &mut w);
        assert_eq!(nan.status, IkStatus::Invalid);
    }

    #[test]
    fn a_tracker_corrector_is_applied_in_the_base_frame_with_its_exact_jacobian() {
        use crate::calib::correctors::rbf::{RbfNetwork, RbfOptions};
        use crate::calib::correctors::{Corrector, PerValue};
        use crate::calib::model::Placement;
        use crate::measurement::Measurement;
        let (m, limits) = model();
        let tracker = Placement { measurement: Measurement::Point, own: vec![2.0, -0.3, 0.2, 0.02, -0.01, 0.7], tool: Vector3::new(0.06, 0.0, 0.05) };
        let m = m.with_placement(&tracker);
        let x = m.nominal.clone();
        // A smooth correction per coordinate (mm), different on each.
        let qs: Vec<Vec<f64>> = (0..60).map(|k| (0..6).map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin() * 1.2).collect()).collect();
        let net = |c: usize| {
            let y: Vec<f64> = qs.iter().map(|q| 0.05 * (q[c] + 0.5 * q[c + 1]).sin()).collect();
            Corrector::Rbf(RbfNetwork::fit(&qs, &y, &RbfOptions { centers: 10, ..RbfOptions::default() }).unwrap())
        };
        let corr = Corrector::Values(PerValue { values: (0..3).map(net).collect() });
        let ik = IkModel::new(&m, &x, Some(corr.as_correct()), limits);
        let mut w = ik.work();
        let q = qs[5].iter().map(|v| v * 0.9).collect::<Vec<_>>();
        // p̂ = p + Rᵀ·δ: read back through the tracker, the corrected point is the model's
        // reading plus the corrections.
        let p_hat = ik.position(&q, &mut w, Some(JacobianKind::Hybrid));
        let cols = w.cols.clone();
        let (mut y, mut delta) = ([0.0; 3], [0.0; 3]);
        m.readings(&x, &q, &RowInputs::default(), &mut m.work(), &mut y);
        corr.as_correct().corrections_mm(&q, &RowInputs::default(), &mut delta);
        let mut seen = [0.0; 3];
        Measurement::Point.reading(&tracker.own, &(p_hat * 1e-3), &mut seen);
        for c in 0..3 {
            assert!((seen[c] * 1e3 - (y[c] * 1e3 + delta[c])).abs() < 1e-9, "value {c}: {} vs {}", seen[c] * 1e3, y[c] * 1e3 + delta[c]);
        }
        assert_hybrid_jacobian_matches_finite_differences(&ik, &q, &cols, &mut w);
    }

    #[test]
    fn rigid_fit_recovers_a_transform() {
        let r = nalgebra::Rotation3::from_euler_angles(0.01, -0.02, 0.3).into_inner();
        let t = Vector3::new(1.0, -2.0, 0.5);
        let a: Vec<Vector3<f64>> = (0..10).map(|k| Vector3::new((k as f64).sin(), (k as f64 * 0.7).cos(), k as f64 * 0.1)).collect();
        let b: Vec<Vector3<f64>> = a.iter().map(|p| r * p + t).collect();
        let (rr, tt) = rigid_fit(&a, &b);
        assert!((rr - r).norm() < 1e-9 && (tt - t).norm() < 1e-9);
    }

    /// A pose model with encoder eccentricity and compliance under a payload: the orientation's
    /// Jacobian is the central difference of the tool's orientation (the eccentricity's
    /// dependence on the angle included; the torques are held, as the position's Jacobian holds
    /// them), and pose targets at the model's own configurations are reached in position and
    /// orientation from a start 10° away on every joint; a pose the arm cannot take gets a
    /// status, not a false convergence.
    #[test]
    fn pose_targets_are_reached_with_an_exact_orientation_jacobian() {
        use crate::calib::effects::inputs::{JointLoads, TorqueModel};
        use crate::calib::effects::{EffectBlock, EffectKind};
        use crate::calib::model::Placement;
        use crate::measurement::Measurement;
        use crate::robot::statics::Payload;
        let robot = Robot::irb120();
        let (m, limits) = model();
        let probe =
            Placement { measurement: Measurement::Pose, own: vec![2.0, -0.3, 0.2, 0.02, -0.01, 0.7, 0.1, -0.2, 1.5], tool: Vector3::new(0.06, 0.08, 0.1) };
        let mut m = m.with_placement(&probe);
        for kind in [EffectKind::Eccentricity, EffectKind::Compliance] {
            for j in 0..6 {
                m.add_effect(EffectBlock::joint(kind, j), 1.0);
            }
        }
        let mut x = m.nominal.clone();
        for b in 0..12 {
            for (i, k) in m.effect_params(b).enumerate() {
                x[k] = if b < 6 { 0.01 * (1.0 + i as f64) } else { 1e-4 * (b as f64 - 5.0) };
            }
        }
        let ik = IkModel::new(&m, &x, None, limits.clone());
        let mut w = ik.work();
        let q = [0.3, 0.4, -0.5, 1.0, 0.8, -0.6];
        ik.pose(&q, &mut w, Some(JacobianKind::Analytic));
        let rcols = w.rcols.clone();
        for (j, col) in rcols.iter().enumerate() {
            let (mut a, mut b) = (q, q);
            a[j] += 1e-6;
            b[j] -= 1e-6;
            let d = ik.pose(&a, &mut w, None).1 * ik.pose(&b, &mut w, None).1.transpose();
            let fd = Vector3::new(d[(2, 1)] - d[(1, 2)], d[(0, 2)] - d[(2, 0)], d[(1, 0)] - d[(0, 1)]) / 4e-6;
            assert!((fd - col).norm() < 1e-6, "joint {j}: {fd:?} vs {col:?}");
        }
        let loads = JointLoads { payload: Some(Payload { mass_kg: 3.0, com_mm: [40.0, 0.0, 60.0] }), ..JointLoads::default() };
        let ik = IkModel::new(&m, &x, None, limits.clone()).with_loads(TorqueModel::new(&robot, &loads, None, probe.tool, false));
        let o = IkOptions { tol_mm: 0.001, tol_deg: 0.001, max_iter: 100, ..IkOptions::default() };
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..20 {
            let qt: Vec<f64> = limits.iter().map(|(lo, hi)| 0.8 * (lo + (hi - lo) * rng.random::<f64>())).collect();
            let (p, r) = ik.pose(&qt, &mut w, None);
            let start: Vec<f64> = qt.iter().map(|v| v + 10f64.to_radians()).collect();
            let s = ik.solve_pose_from(&p, &r, Some(&start), JacobianKind::Analytic, &o, &mut w);
            assert_eq!(s.status, IkStatus::Converged, "{s:?}");
            let (p2, r2) = ik.pose(&s.q, &mut w, None);
            assert!((p2 - p).norm() <= 0.001 && turn(&r, &r2).norm().to_degrees() <= 0.001, "{s:?}");
            // The same point turned 90° about its x axis: the wrist takes it, or it is named.
            let r90 = r * *nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), 1.5).matrix();
            let s = ik.solve_pose_from(&p, &r90, Some(&qt), JacobianKind::Analytic, &o, &mut w);
            let (p3, r3) = ik.pose(&s.q, &mut w, None);
            let met = (p3 - p).norm() <= 0.001 && turn(&r90, &r3).norm().to_degrees() <= 0.001;
            assert_eq!(met, s.status == IkStatus::Converged, "{s:?}");
        }
        let nan = ik.solve_pose_from(&Vector3::new(300.0, 0.0, 400.0), &Matrix3::from_element(f64::NAN), None, JacobianKind::Analytic, &o, &mut w);
        assert_eq!(nan.status, IkStatus::Invalid);
    }
}
