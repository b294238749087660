//! The generic arm (6 or 7 revolute joints), for arms without a published nominal.
//!
//! **Parametrisation.** A calibration sees the arm only where the data put it; on a narrow range
//! of joint angles what the readings determine is where each joint axis lies *there*. So the
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
//! **Search.** Starts are plausible industrial shapes at q̄ ([`shapes`]: seeded draws of link
//! lengths, signs and angles). Under a draw-wire they are 6R spherical-wrist arms, the cable's
//! exit point a median reading away from the tool point in a drawn direction; under a tracker
//! every shape of the data's joint count in turn, the tracker (and a 6-D probe) placed by the
//! instrument's own rigid fit. They go through successive stages (`STAGES`, `TRACKER_STAGES`):
//! every start is fitted briefly on a few rows, the best survive to a longer fit on more rows,
//! and the last few converge on every training row (in fresh charts, see [`converge`]), where
//! the lowest *converged* cost wins (ranking after a short polish picks the candidate that is
//! quickest to polish, not the best basin); [`SearchReport`] says how many reached it. Starts are
//! drawn from the seed alone and fitted in parallel: the result does not depend on the number of
//! threads.

pub mod shapes;

use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::{CalibModel, Kind, Placement};
use crate::error::{Error, Result};
use crate::measurement::Measurement;
use crate::optim::{LeastSquares, LevenbergMarquardt, NoObserver};
use crate::robot::kinematics::{ChainBuilder, Frame};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use shapes::Shape;

/// The search's successive stages: (starts kept, rows seen at most, LM iterations). Every start
/// is screened briefly on a few rows, the best 16 survive to a longer fit on more rows, and the
/// best 2 of those are polished to convergence on every training row, where the ranking is made
/// (on HSR the winner of 4 finalists was always among the first 2: the same model on seeds 0–4,
/// 2 s sooner).
const STAGES: [(usize, usize, usize); 2] = [(16, 150, 25), (2, 650, 150)];
/// The stages under a tracker: three values a row tell the shapes apart sooner, and eight
/// finalists say how many of the screened shapes reach the best basin.
const TRACKER_STAGES: [(usize, usize, usize); 2] = [(16, 150, 25), (8, 650, 150)];
/// Starts at effort 1.
pub const STARTS: usize = 320;

/// An axis line in the base frame at the reference pose.
#[derive(Clone, Copy, Debug)]
pub struct Line {
    /// A point on the axis, m.
    pub point: Vector3<f64>,
    /// The axis direction.
    pub dir: Vector3<f64>,
}

/// Farthest a joint frame's origin is put from the previous one, m: where two axes come closest
/// farther away than any arm's link, the frame goes to the previous origin's foot instead.
const MAX_ORIGIN_STEP_M: f64 = 5.0;

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
                    if (foot - op).norm() > MAX_ORIGIN_STEP_M {
                        // Lines nearly parallel far from the arm (a joint the data never move
                        // is free to tilt): the previous origin's foot keeps the frame near.
                        let near = l.point + z * z.dot(&(op - l.point));
                        (near, near - op)
                    } else {
                        (foot, if gap.norm() > 1e-6 { gap } else { cross })
                    }
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
pub fn model_around(frames: &[Frame], q_ref: &[f64], placement: &Placement) -> CalibModel {
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
    let name = if frames.len() == 6 { "generic6r".to_string() } else { format!("generic{}r", frames.len()) };
    CalibModel::of_chain(&name, chain, kinds, placement)
}

/// The start of one topology: the model around its lines, the cable's exit point a median
/// reading away from the tool point in a drawn direction (the cable's length says how far the
/// exit is, not where), the offset then the median misfit.
fn start(lines: &[Line], tool: &Vector3<f64>, exit_dir: &Vector3<f64>, q_ref: &[f64], data: &Samples) -> Option<CalibModel> {
    let reach = crate::stats::median(&data.y);
    let exit = tool + exit_dir * reach;
    let mut model = model_around(&frames_of(lines), q_ref, &Placement::cable(exit, 0.0, *tool));
    let mut w = model.work();
    let misfit: Vec<f64> =
        data.q.iter().zip(&data.y).map(|(q, l)| l - model.length(&model.nominal, q, &crate::calib::effects::RowInputs::default(), &mut w)).collect();
    if let Some(k) = model.length_offset_index() {
        model.nominal[k] = crate::stats::median(&misfit);
    }
    model.nominal.iter().all(|v| v.is_finite()).then_some(model)
}

/// Fits the identifiable parameters of `model` from its nominal on `data`: (cost, x, converged
/// within few iterations).
fn fit(model: &CalibModel, data: &Samples, lm: &LevenbergMarquardt, rank_tol: f64) -> (f64, Vec<f64>, bool) {
    let fit = ReadingFit { model, data };
    let id = crate::calib::fit::identify::identify(&fit, &model.nominal, rank_tol);
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
    let p = model.placement(x).on_flange(&flange.rot, &flange.pos);
    model_around(&frames_of(&lines), &q_ref, &p)
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

/// What the generic search did: how many starts it drew, how many it converged on every
/// training row, and how many of those reached the best cost (within [`SAME_BASIN`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchReport {
    /// Arm shapes drawn (seeded).
    pub starts: usize,
    /// Candidates converged on every training row after the screening stages.
    pub finalists: usize,
    /// Finalists whose converged cost is within [`SAME_BASIN`] of the best.
    pub in_best_basin: usize,
}

/// Two converged costs within this relative difference are the same basin.
pub const SAME_BASIN: f64 = 1e-3;

/// The searched model (its `nominal` the parameter vector polished on the search rows) and
/// what the search did.
pub struct Searched {
    /// The best candidate.
    pub model: CalibModel,
    /// Starts, finalists and how many reached the best basin.
    pub report: SearchReport,
}

/// The candidate arms of a search: each start's model, in draw order (`None` where the start
/// could not place its instrument). A draw-wire is searched with spherical-wrist arms (its
/// results since the first version depend on that stream); a tracker with every shape of the
/// data's joint count in turn.
fn candidates(train: &Samples, starts: usize, q_ref: &[f64], seed: u64) -> Result<Vec<Option<CalibModel>>> {
    let n = q_ref.len();
    let measurement = train.measurement;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6765_6e65_7269_6336);
    if measurement == Measurement::Length {
        if n != 6 {
            return Err(Error::Calibration(format!("the generic model searches a 6R arm under a draw-wire; the data hold {n} joint angles")));
        }
        let draws: Vec<(Vec<Line>, Vector3<f64>, Vector3<f64>)> = (0..starts)
            .map(|_| {
                let (lines, tool) = shapes::spherical_wrist(&mut rng);
                let d = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
                (lines, tool, if d.norm() > 1e-3 { d.normalize() } else { Vector3::z() })
            })
            .collect();
        return Ok(draws.par_iter().map(|(lines, tool, dir)| start(lines, tool, dir, q_ref, train)).collect());
    }
    let family = Shape::of_joints(n);
    if family.is_empty() {
        return Err(Error::Calibration(format!("the generic model searches arms of 6 or 7 joints; the data hold {n} joint angles")));
    }
    let draws: Vec<(Vec<Line>, Vector3<f64>)> = (0..starts).map(|i| family[i % family.len()].draw(&mut rng)).collect();
    Ok(draws.par_iter().map(|(lines, tool)| start_tracker(lines, tool, q_ref, train, measurement)).collect())
}

/// The start of one arm under a tracker: the model around its lines, the tracker (and a
/// probe's orientation and origin on the flange) placed by the instrument's own rigid fit of
/// the arm's predicted points to the readings.
fn start_tracker(lines: &[Line], tool: &Vector3<f64>, q_ref: &[f64], data: &Samples, measurement: Measurement) -> Option<CalibModel> {
    let frames = frames_of(lines);
    let bare = model_around(&frames, q_ref, &Placement::cable(Vector3::zeros(), 0.0, *tool));
    let mut w = bare.work();
    let flanges: Vec<_> = data.q.iter().map(|q| bare.flange_frame(&bare.nominal, q, &mut w)).collect();
    let rots: Vec<_> = flanges.iter().map(|f| f.rot).collect();
    let pts: Vec<_> = match measurement {
        Measurement::Pose => flanges.iter().map(|f| f.pos).collect(),
        _ => flanges.iter().map(|f| f.point(tool)).collect(),
    };
    let (own, found) = measurement.def().locate(&pts, &rots, &data.y)?;
    let tool = if measurement == Measurement::Pose { found } else { *tool };
    let model = bare.with_placement(&Placement { measurement, own, tool });
    model.nominal.iter().all(|v| v.is_finite()).then_some(model)
}

/// The search's reference pose: each joint's mean angle over the rows, or exactly its angle
/// where it never moves (a mean a rounding away from it would turn a still joint by 1e-16 rad,
/// and the column-scaled identifiability analysis would take its axis for one the data see).
fn reference_of(train: &Samples, n: usize) -> Vec<f64> {
    (0..n)
        .map(|j| {
            let (lo, hi) = train.q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| (a.min(q[j]), b.max(q[j])));
            if hi - lo < 1e-12 {
                lo
            } else {
                train.q.iter().map(|q| q[j]).sum::<f64>() / train.len() as f64
            }
        })
        .collect()
}

/// How a search runs: its budget, its seed and the identifiability threshold of its fits.
#[derive(Clone, Copy, Debug)]
pub struct SearchSettings {
    /// Multiplies the number of starts (1 = [`STARTS`]).
    pub effort: f64,
    /// Seeds the shapes drawn.
    pub seed: u64,
    /// The fits' identifiability threshold (relative singular value).
    pub rank_tol: f64,
}

/// Global search for the generic model (see the module docs).
pub fn search(train: &Samples, opts: &SearchSettings) -> Result<Searched> {
    let n = train.q.first().map_or(0, |q| q.len());
    let q_ref = reference_of(train, n);
    let every = |rows: usize| train.subset(&(0..train.len()).step_by(train.len().div_ceil(rows).max(1)).collect::<Vec<_>>());
    let stages = if train.dim == 1 { STAGES } else { TRACKER_STAGES };
    let starts = ((STARTS as f64 * opts.effort).ceil() as usize).max(stages[0].0);
    let first = every(stages[0].1);
    let mut pool: Vec<(f64, usize, CalibModel)> =
        candidates(&first, starts, &q_ref, opts.seed)?.into_iter().enumerate().filter_map(|(i, m)| m.map(|m| (f64::INFINITY, i, m))).collect();
    for &(keep, rows, iters) in &stages {
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
        .filter(|c| c.0.is_finite())
        .collect();
    let best_cost = finalists.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
    let report = SearchReport { starts, finalists: finalists.len(), in_best_basin: finalists.iter().filter(|c| c.0 <= best_cost * (1.0 + SAME_BASIN)).count() };
    finalists
        .into_iter()
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        .map(|c| Searched { model: c.2, report })
        .ok_or_else(|| Error::Calibration("the generic model's search found no start that fits the data".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_puts_its_axes_on_the_lines_at_the_reference_pose() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (lines, tool) = shapes::spherical_wrist(&mut rng);
        let q_ref = [0.3, -1.2, 3.7, -2.9, 0.7, 1.1];
        let frames = frames_of(&lines);
        for (f, l) in frames.iter().zip(&lines) {
            let z = f.rot.column(2).into_owned();
            assert!((z - l.dir).norm() < 1e-12, "axis direction");
            assert!((f.pos - l.point).cross(&l.dir).norm() < 1e-12, "origin on the line");
        }
        let m = model_around(&frames, &q_ref, &Placement::cable(Vector3::zeros(), 0.0, tool));
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
