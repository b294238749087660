//! The generic 6R model, for arms without a published nominal.
//!
//! **Parametrisation.** A calibration sees the arm only where the data put it; on a narrow range
//! of joint angles what the lengths determine is where each joint axis lies *there*. So the
//! model is a product of exponentials around the mean training pose q̄: each joint turns what
//! follows it about its own axis line, given in the base frame at q̄, by q − q̄
//! ([`model_around`]). A line's parameters (its origin moved, its direction tilted) move that
//! line alone, so the fit's columns are nearly independent and the identifiability analysis
//! keeps a well-conditioned subset (the joint zeros and the last joint's frame are what the tool
//! point and the lines absorb). Absolute D-H values were the previous choice: with near-parallel
//! axes d slides along an ill-defined common normal, and on the HSR data the fit crept towards a
//! 36 m link and a tool point 23 m out; serial per-joint frame errors, tried next, couple every
//! line to the errors upstream of it (condition number 1e7 against 1e5 here).
//!
//! **Search.** Starts are plausible industrial topologies at q̄ (seeded draws: joint 1 vertical;
//! joint 2 horizontal, offset from it by a shoulder link; joint 3 parallel to 2 at the end of an
//! upper arm of 0.3–1.1 m; a forearm of 0.3–1.3 m to a spherical wrist whose axes 4, 5, 6 meet;
//! a tool point 50–350 mm from the wrist centre; the cable's exit point a median reading away
//! from it in a drawn direction). They go through successive stages (`STAGES`): every start is
//! fitted briefly on a few rows, the best survive to a longer fit on more rows, and the last few
//! converge on every training row (in fresh charts, see [`converge`]), where the lowest
//! *converged* cost wins (ranking after a short polish picks the candidate that is quickest to
//! polish, not the best basin). Starts are drawn from the seed alone and fitted in parallel: the
//! result does not depend on the number of threads.

use super::options::CalibOptions;
use crate::calib::model::{CalibModel, Kind, SensorGuess};
use crate::calib::problem::{ReadingFit, Samples};
use crate::error::{Error, Result};
use crate::optim::{LeastSquares, LevenbergMarquardt, NoObserver};
use crate::robot::kinematics::{ChainBuilder, Frame};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// The search's successive stages: (starts kept, rows seen at most, LM iterations). Every start
/// is screened briefly on a few rows, the best 16 survive to a longer fit on more rows, and the
/// best 2 of those are polished to convergence on every training row, where the ranking is made
/// (on HSR the winner of 4 finalists was always among the first 2: the same model on seeds 0–4,
/// 2 s sooner).
const STAGES: [(usize, usize, usize); 2] = [(16, 150, 25), (2, 650, 150)];
/// Starts at effort 1.
const STARTS: usize = 320;

/// An axis line in the base frame at the reference pose.
#[derive(Clone, Copy, Debug)]
pub struct Line {
    /// A point on the axis, m.
    pub point: Vector3<f64>,
    /// The axis direction.
    pub dir: Vector3<f64>,
}

/// Unit vector perpendicular to `z`, as close as possible to `hint`.
fn perpendicular(z: &Vector3<f64>, hint: &Vector3<f64>) -> Vector3<f64> {
    let v = hint - z * z.dot(hint);
    if v.norm() > 1e-6 {
        return v.normalize();
    }
    let other = if z.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    (other - z * z.dot(&other)).normalize()
}

/// Joint frames at the reference pose: z on each axis line; the origin where the line comes
/// closest to the previous one (for near-parallel lines, the previous origin's foot on it), so
/// every origin lies near the arm; x along the common normal where there is one.
pub fn frames_of(lines: &[Line]) -> Vec<Frame> {
    let mut frames: Vec<Frame> = Vec::with_capacity(lines.len());
    for l in lines {
        let z = l.dir.normalize();
        let (origin, x_hint) = match frames.last() {
            None => (l.point - z * z.dot(&l.point), Vector3::x()),
            Some(prev) => {
                let (zp, op) = (prev.rot.column(2).into_owned(), prev.pos);
                let cross = zp.cross(&z);
                if cross.norm() < 0.05 {
                    let foot = l.point + z * z.dot(&(op - l.point));
                    (foot, foot - op)
                } else {
                    // Closest points of the previous axis (through op) and this one.
                    let w0 = op - l.point;
                    let (b, d, e) = (zp.dot(&z), zp.dot(&w0), z.dot(&w0));
                    let den = 1.0 - b * b;
                    let s = (b * e - d) / den;
                    let t = (e - b * d) / den;
                    let foot = l.point + z * t;
                    let gap = foot - (op + zp * s);
                    (foot, if gap.norm() > 1e-6 { gap } else { cross })
                }
            }
        };
        let x = perpendicular(&z, &x_hint);
        frames.push(Frame { rot: Matrix3::from_columns(&[x, z.cross(&x), z]), pos: origin });
    }
    frames
}

/// The generic model around joint axis frames at the reference pose `q_ref` (rad), as a
/// product of exponentials: joint j turns everything after it by q_j − q_ref_j about its own
/// line, given in the base frame (the frame's origin and z axis), so each line's parameters —
/// its origin moved along the base axes (`joint_j.x/y/z`, m) and tilted about the frame's own
/// x and y (`joint_j.tilt_x/tilt_y`, rad) — move that line alone. At q_ref the arm is the
/// identity and the tool point is in the base frame. In chain form each exponential is
/// G·Rz·G⁻¹ with G's parameters entering both sides (the second with factor −1).
pub fn model_around(frames: &[Frame], q_ref: &[f64], sensor: &SensorGuess) -> CalibModel {
    let mut b = ChainBuilder::new();
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let mut kinds = Vec::new();
    for (j, f) in frames.iter().enumerate() {
        let idx: Vec<usize> = ["x", "y", "z", "tilt_x", "tilt_y"].iter().map(|s| b.param(format!("joint_{}.{s}", j + 1))).collect();
        kinds.extend([Kind::Length, Kind::Length, Kind::Length, Kind::Angle, Kind::Angle]);
        let (roll, pitch, yaw) = Rotation3::from_matrix_unchecked(f.rot).euler_angles();
        b.trans_coef(x, f.pos.x, idx[0], 1.0, true);
        b.trans_coef(y, f.pos.y, idx[1], 1.0, true);
        b.trans_coef(z, f.pos.z, idx[2], 1.0, true);
        b.rot(z, yaw, None);
        b.rot(y, pitch, None);
        b.rot(x, roll, None);
        b.rot_coef(x, 0.0, idx[3], 1.0);
        b.rot_coef(y, 0.0, idx[4], 1.0);
        b.joint(z, -q_ref[j], None);
        b.rot_coef(y, 0.0, idx[4], -1.0);
        b.rot_coef(x, 0.0, idx[3], -1.0);
        b.rot(x, -roll, None);
        b.rot(y, -pitch, None);
        b.rot(z, -yaw, None);
        b.trans_coef(z, -f.pos.z, idx[2], -1.0, true);
        b.trans_coef(y, -f.pos.y, idx[1], -1.0, true);
        b.trans_coef(x, -f.pos.x, idx[0], -1.0, true);
    }
    let chain = b.finish();
    CalibModel::with_sensor("generic6r", chain, kinds, sensor)
}

/// A plausible industrial 6R topology at the reference pose (m), and a tool point.
fn topology(rng: &mut ChaCha8Rng) -> (Vec<Line>, Vector3<f64>) {
    let mut sign = || if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let (s2, s3, s4, s5, s6) = (sign(), sign(), sign(), sign(), sign());
    let up = Line { point: Vector3::zeros(), dir: Vector3::z() };
    let shoulder = Vector3::new(rng.random_range(0.0..0.3), 0.0, 0.0);
    let j2 = Line { point: shoulder, dir: Vector3::y() * s2 };
    let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let elbow = shoulder + Vector3::new(phi.cos(), 0.0, phi.sin()) * rng.random_range(0.3..1.1);
    let j3 = Line { point: elbow, dir: Vector3::y() * s3 };
    let psi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let forearm = Vector3::new(psi.cos(), 0.0, psi.sin());
    let normal = Vector3::y().cross(&forearm);
    let wrist = elbow + normal * rng.random_range(-0.25..0.25) + forearm * rng.random_range(0.3..1.3);
    let j4 = Line { point: wrist, dir: forearm * s4 };
    let chi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let w5 = Vector3::y() * chi.cos() + normal * chi.sin();
    let j5 = Line { point: wrist, dir: w5 * s5 };
    let omega: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let across = w5.cross(&forearm);
    let w6 = forearm * omega.cos() + across * omega.sin();
    let j6 = Line { point: wrist, dir: w6 * s6 };
    let tool = wrist + w6 * rng.random_range(0.05..0.35);
    (vec![up, j2, j3, j4, j5, j6], tool)
}

/// The start of one topology: the model around its lines, the cable's exit point a median
/// reading away from the tool point in a drawn direction (the cable's length says how far the
/// exit is, not where), the offset then the median misfit.
fn start(lines: &[Line], tool: &Vector3<f64>, exit_dir: &Vector3<f64>, q_ref: &[f64], data: &Samples) -> Option<CalibModel> {
    let reach = crate::stats::median(&data.y);
    let exit = tool + exit_dir * reach;
    let guess = SensorGuess { exit_m: [exit.x, exit.y, exit.z], offset_m: 0.0, tool_m: [tool.x, tool.y, tool.z] };
    let mut model = model_around(&frames_of(lines), q_ref, &guess);
    let mut w = model.work();
    let misfit: Vec<f64> = data.q.iter().zip(&data.y).map(|(q, l)| l - model.predict(&model.nominal, q, &mut w)).collect();
    if let Some(k) = model.length_offset_index() {
        model.nominal[k] = crate::stats::median(&misfit);
    }
    model.nominal.iter().all(|v| v.is_finite()).then_some(model)
}

/// Fits the identifiable parameters of `model` from its nominal on `data`: (cost, x, converged
/// within few iterations).
fn fit(model: &CalibModel, data: &Samples, lm: &LevenbergMarquardt, rank_tol: f64) -> (f64, Vec<f64>, bool) {
    let fit = ReadingFit { model, data };
    let id = crate::calib::problem::identify::identify(&fit, &model.nominal, rank_tol);
    let rep = lm.minimize(&fit, &model.nominal, &id.fixed_mask, &mut NoObserver);
    let cost = LeastSquares::cost(&fit, &rep.x);
    let settled = rep.converged() && rep.iterations <= SETTLED_ITER;
    (if cost.is_finite() { cost } else { f64::INFINITY }, rep.x, settled)
}

/// The reference pose of a generic model (rad): its joints rotate by q − q_ref.
fn reference_pose(model: &CalibModel) -> Vec<f64> {
    (0..model.chain.n_joints).map(|j| -model.chain.ops[model.chain.joint_op(j).expect("every joint has an op")].base).collect()
}

/// The same arm at `x` re-expressed around its own axis lines at the reference pose, every
/// chain parameter back at zero (predictions are unchanged): a tilt is linear only near zero,
/// and a fresh chart straightens the valley Levenberg–Marquardt would otherwise cross in many
/// small steps.
pub fn rechart(model: &CalibModel, x: &[f64]) -> CalibModel {
    let q_ref = reference_pose(model);
    let nc = model.n_chain();
    let mut ws = crate::robot::kinematics::FkWork::new(&model.chain);
    model.chain.forward(&q_ref, &x[..nc], 1.0, &mut ws);
    let lines: Vec<Line> = (0..model.chain.n_joints)
        .map(|j| {
            let f = model.chain.frame(&ws, j + 1);
            Line { point: f.pos, dir: f.rot.column(2).into_owned() }
        })
        .collect();
    let flange = model.chain.frame(&ws, model.chain.flange());
    let p = model.placement(x);
    let tool = flange.point(&p.tool);
    let sensor = SensorGuess { exit_m: [p.own[0], p.own[1], p.own[2]], offset_m: p.own[3], tool_m: tool.into() };
    model_around(&frames_of(&lines), &q_ref, &sensor)
}

/// Polishes a generic model on `data` until a fit in a fresh chart settles within
/// `SETTLED_ITER` iterations (at most `MAX_CHARTS` charts): (cost, the model with its
/// polished vector as nominal, settled).
pub fn converge(model: &CalibModel, data: &Samples, rank_tol: f64) -> (f64, CalibModel, bool) {
    let lm = LevenbergMarquardt::budget(CHART_ITER);
    let mut m = model.clone();
    for _ in 0..MAX_CHARTS {
        let (cost, x, settled) = fit(&m, data, &lm, rank_tol);
        m = rechart(&m, &x);
        if settled || !cost.is_finite() {
            return (cost, m, settled);
        }
    }
    let cost = LeastSquares::cost(&ReadingFit { model: &m, data }, &m.nominal);
    (cost, m, false)
}

/// A fit in a fresh chart that converges within this many iterations has settled.
const SETTLED_ITER: usize = 30;
/// Iterations per chart, and most charts.
const CHART_ITER: usize = 100;
const MAX_CHARTS: usize = 6;

/// Global search for the generic model (see the module docs): the best candidate, its
/// `nominal` the parameter vector polished on the search rows.
pub fn search(train: &Samples, opts: &CalibOptions) -> Result<CalibModel> {
    let n = train.q.first().map_or(0, |q| q.len());
    if n != 6 {
        return Err(Error::Calibration(format!("the generic model is a 6R arm; the data hold {n} joint angles")));
    }
    let q_ref: Vec<f64> = (0..n).map(|j| train.q.iter().map(|q| q[j]).sum::<f64>() / train.len() as f64).collect();
    let every = |rows: usize| train.subset(&(0..train.len()).step_by(train.len().div_ceil(rows).max(1)).collect::<Vec<_>>());
    let starts = ((STARTS as f64 * opts.effort).ceil() as usize).max(STAGES[0].0);
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed ^ 0x6765_6e65_7269_6336);
    let topologies: Vec<(Vec<Line>, Vector3<f64>, Vector3<f64>)> = (0..starts)
        .map(|_| {
            let (lines, tool) = topology(&mut rng);
            let d = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            (lines, tool, if d.norm() > 1e-3 { d.normalize() } else { Vector3::z() })
        })
        .collect();
    let first = every(STAGES[0].1);
    let mut pool: Vec<(f64, usize, CalibModel)> = topologies
        .par_iter()
        .enumerate()
        .filter_map(|(i, (lines, tool, dir))| start(lines, tool, dir, &q_ref, &first).map(|m| (f64::INFINITY, i, m)))
        .collect();
    for &(keep, rows, iters) in &STAGES {
        let data = every(rows);
        let lm = LevenbergMarquardt::budget(iters).tolerances(1e-8, 1e-10);
        pool = pool
            .into_par_iter()
            .map(|(_, i, model)| {
                let (cost, x, _) = fit(&model, &data, &lm, opts.rank_tol);
                (cost, i, rechart(&model, &x))
            })
            .collect();
        pool.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        pool.truncate(keep);
    }
    // The finalists converge on every training row, in fresh charts; the lowest converged cost
    // wins, and the calibration that follows starts at its optimum.
    let finalists: Vec<(f64, usize, CalibModel)> = pool
        .into_par_iter()
        .map(|(_, i, model)| {
            let (cost, model, _) = converge(&model, train, opts.rank_tol);
            (cost, i, model)
        })
        .collect();
    finalists
        .into_iter()
        .filter(|c| c.0.is_finite())
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        .map(|c| c.2)
        .ok_or_else(|| Error::Calibration("the generic model's search found no start that fits the data".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_puts_its_axes_on_the_lines_at_the_reference_pose() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (lines, tool) = topology(&mut rng);
        let q_ref = [0.3, -1.2, 3.7, -2.9, 0.7, 1.1];
        let frames = frames_of(&lines);
        for (f, l) in frames.iter().zip(&lines) {
            let z = f.rot.column(2).into_owned();
            assert!((z - l.dir).norm() < 1e-12, "axis direction");
            assert!((f.pos - l.point).cross(&l.dir).norm() < 1e-12, "origin on the line");
        }
        let m = model_around(&frames, &q_ref, &SensorGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [tool.x, tool.y, tool.z] });
        let mut w = m.work();
        assert!((m.tool_point(&m.nominal, &q_ref, &mut w) - tool).norm() < 1e-12);
        // Rotating joint 2 by 0.1 rad turns the tool point about line 2.
        let mut q = q_ref;
        q[1] += 0.1;
        let p = m.tool_point(&m.nominal, &q, &mut w);
        let l = &lines[1];
        let rot = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(l.dir), 0.1);
        assert!((p - (l.point + rot * (tool - l.point))).norm() < 1e-12);
    }
}
