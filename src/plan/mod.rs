//! Measurement planning: which poses to measure so that a calibration identifies its parameters
//! best, before the arm is touched.
//!
//! 1. **Candidates** ([`candidates`]): a large pool of commanded poses drawn by a Halton sequence
//!    over the scenario's joint ranges, each kept only when the scenario's cell finds it
//!    feasible ([`crate::sim::workspace`]: joint ranges, the tool above the floor height, the
//!    instrument's range, link capsules clear of the floor, keep-out boxes and each other, the
//!    instrument's line of sight).
//! 2. **Identification Jacobian** ([`Model`]): the calibration model (the nominal arm in the
//!    chosen parametrisation, the instrument at the scenario's placement) differentiated at
//!    every candidate, one block of rows per pose. The parameters the whole pool cannot tell
//!    apart are held, as a calibration holds them ([`crate::calib::fit::identify`]); the
//!    others' columns are scaled to unit RMS over the pool.
//! 3. **Design** ([`design`]): N candidates chosen by an observability index with an exchange
//!    algorithm. The default is I-optimal, the mean prediction variance over the pool (the
//!    workspace the arm will be used in): D-optimality (O1) also rewards sharpening parameter
//!    combinations the readings barely see, which buys no accuracy (on the IRB 120 tracker
//!    scenario its plans were no better than random sets of 1.5 N, see `twincal bench plan`).
//! 4. **Tour** ([`tour`]): the chosen poses ordered into a short acquisition, timed by the twin's
//!    motion model.
//!
//! The plan never sees the twin's true parameters: only the nominal arm, the instrument's
//! placement as the engineer sets it up, and the cell.

pub mod artifact;
pub mod bound;
pub mod design;
pub mod tour;
pub mod verify;

#[cfg(test)]
mod tests;

pub use design::{criterion, Criterion, Design, Pool, CRITERIA};

use crate::calib::effects::inputs::{block_for, row_inputs, time_span, JointLoads, TorqueModel};
use crate::calib::effects::{EffectKind, RowInputs};
use crate::calib::fit::{identify::analyse, ReadingFit, Samples};
use crate::calib::model::{CalibModel, DrawWireGuess, Parametrisation};
use crate::calib::pipeline::placement::build_model;
use crate::calib::pipeline::{CalibResult, ModelSpec};
use crate::dataset::{Dataset, Row};
use crate::error::{Error, Result};
use crate::optim::LeastSquares;
use crate::robot::statics::Payload;
use crate::robot::Robot;
use crate::seed::{stream_seed, Stream};
use crate::sim::generate::commanded_pose;
use crate::sim::scenario::{halton, Scenario, HALTON_BASES};
use crate::sim::workspace::{Refusal, Workspace};
use nalgebra::{DMatrix, SymmetricEigen, Vector3};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::BTreeMap;

/// A feasible candidate pool.
#[derive(Clone, Debug, Serialize)]
pub struct Candidates {
    /// The feasible poses, rad, at the scenario's commanded precision.
    #[serde(skip)]
    pub q: Vec<Vec<f64>>,
    /// Poses drawn to find them.
    pub drawn: usize,
    /// Poses refused, by reason.
    pub refused: BTreeMap<String, usize>,
}

/// `count` feasible commanded poses of scenario `s` (Halton over its joint ranges, started
/// from `seed`; angles rounded to `sampling.angle_decimals` as the twin commands them), with
/// the counts of those refused. The scenario's [`Scenario::cell`] judges them, with the default
/// [`Workspace`] (link capsules kept apart, the instrument's line of sight) when it has none. Fewer when the cell refuses nearly everything (at most
/// 50·count + 10 000 draws).
pub fn candidates(s: &Scenario, robot: &Robot, count: usize, seed: u64) -> Result<Candidates> {
    let n = robot.dof();
    if n > HALTON_BASES.len() {
        return Err(Error::Invalid(format!("Halton sampling supports up to {} joints", HALTON_BASES.len())));
    }
    let ranges = s.ranges_rad(robot);
    // A plan always keeps the links apart and the instrument's line clear: without a
    // [workspace], with its defaults.
    let cell = match &s.workspace {
        Some(_) => s.cell(robot),
        None => Scenario { workspace: Some(Workspace::default()), ..s.clone() }.cell(robot),
    };
    let mut fk = cell.work();
    let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, Stream::Plan, 0));
    let start: u64 = rand::Rng::random_range(&mut rng, 100..1_000_000);
    let mut refused: BTreeMap<Refusal, usize> = BTreeMap::new();
    let mut q = Vec::with_capacity(count);
    let limit = 50 * count as u64 + 10_000;
    let mut drawn = 0u64;
    while q.len() < count && drawn < limit {
        let i = start + drawn;
        drawn += 1;
        let pose = commanded_pose(&ranges, |j| halton(i, HALTON_BASES[j]), s.sampling.angle_decimals);
        match cell.check(&pose, &mut fk) {
            Ok(()) => q.push(pose),
            Err(r) => *refused.entry(r).or_default() += 1,
        }
    }
    Ok(Candidates { q, drawn: drawn as usize, refused: refused.into_iter().map(|(r, k)| (r.name().to_string(), k)).collect() })
}

/// The calibration model a plan designs for: the geometry, the instrument and the effect blocks
/// the calibration will fit, with the static torques that drive the load-driven ones.
pub struct Model {
    /// The model: the nominal arm in the parametrisation, the instrument at the scenario's
    /// placement, the effect blocks at their nominal values (or a calibrated result's model).
    pub model: CalibModel,
    /// The parameters the design linearises the model at: its nominal values, or a calibrated
    /// result's.
    pub x: Vec<f64>,
    /// The static-torque model of the effect blocks (the links and the payload mounted).
    pub torque: Option<TorqueModel>,
    /// The station of each candidate, where the model has several (an artifact's sockets or
    /// faces, each a station); empty: every candidate at the first.
    pub stations: Vec<usize>,
}

impl Model {
    /// The model of scenario `s`'s arm in parametrisation `p` with its instrument placed as the
    /// scenario places it and the effect blocks `effects` (a kind, on one joint or, for
    /// per-joint kinds without a joint, on every joint) loaded by `loads` (the payload the
    /// engineer mounts, the cable's tension from its data sheet).
    pub fn new(s: &Scenario, robot: &Robot, p: Parametrisation, effects: &[(EffectKind, Option<usize>)], loads: &JointLoads) -> Result<Model> {
        let zero = DrawWireGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
        let placement = crate::sim::instrument::placement(&s.draw_wire, &s.instruments);
        let mut model = build_model(&ModelSpec::nominal(robot.clone(), p), &zero).with_placement(&placement);
        if effects.is_empty() {
            return Ok(Model { x: model.nominal.clone(), model, torque: None, stations: Vec::new() });
        }
        let exit = (s.instruments.active().is_none()).then(|| s.draw_wire.exit_point_m());
        let torque = TorqueModel::new(robot, loads, exit, s.draw_wire.tool_point_m(), false);
        // The effects are configured on the candidates as a calibration configures them on its
        // data: a dataset of nominal readings at every candidate of a small Halton pool.
        let probe = candidates(s, robot, 200, s.seed)?.q;
        let data = Model { x: model.nominal.clone(), model: model.clone(), torque: None, stations: Vec::new() }.dataset(&probe, None);
        for &(kind, joint) in effects {
            let joints: Vec<Option<usize>> = if joint.is_none() && kind.per_joint() { (0..robot.dof()).map(Some).collect() } else { vec![joint] };
            for j in joints {
                model.add_effect(block_for(&data, kind, j, true)?, time_span(&data));
            }
        }
        Ok(Model { x: model.nominal.clone(), model, torque: Some(torque), stations: Vec::new() })
    }

    /// The model of a calibrated result (its chain in its parametrisation, its instrument's
    /// calibrated placement, its effect blocks), linearised at its calibrated values, for
    /// scenario `s`'s arm `robot`: the plan of its next calibration. Its torque model carries
    /// `payload` when given, else the payload it was calibrated with. A result for another arm
    /// (joint count) or another instrument than the scenario's is refused.
    pub fn from_result(r: &CalibResult, s: &Scenario, robot: &Robot, payload: Option<&Payload>) -> Result<Model> {
        let n = r.model.chain.n_joints;
        if n != robot.dof() {
            return Err(Error::Invalid(format!("the model's arm has {n} joints, the scenario's robot {} has {}", robot.name, robot.dof())));
        }
        let theirs = crate::sim::instrument::placement(&s.draw_wire, &s.instruments).measurement;
        if r.model.measurement != theirs {
            return Err(Error::Invalid(format!(
                "the model was calibrated on {} readings, the scenario measures {}: plan with the scenario of the instrument the model was calibrated with",
                r.model.measurement.name(),
                theirs.name()
            )));
        }
        let mut torque = r.torque_model.clone();
        if let (Some(t), Some(p)) = (&mut torque, payload) {
            t.payload = Some((p.mass_kg, p.com_mm.map(crate::units::to_m)));
        }
        Ok(Model { model: r.model.clone(), x: r.x.clone(), torque, stations: Vec::new() })
    }

    /// The nominal model's readings at `q` as a dataset (mm, degrees), for configuring blocks
    /// and computing row inputs; with `payload_kg`, each row's payload.
    fn dataset(&self, q: &[Vec<f64>], payload_kg: Option<&[f64]>) -> Dataset {
        let dim = self.model.measurement.dim();
        let mut w = self.model.work();
        let mut y = vec![0.0; dim];
        let rows = q
            .iter()
            .enumerate()
            .map(|(i, q)| {
                self.model.readings(&self.x, q, &RowInputs::default(), &mut w, &mut y);
                // Lengths in mm (a 6-D probe's angle values too: no block reads them).
                let reading: Vec<f64> = y.iter().map(|v| crate::units::to_mm(*v)).collect();
                Row {
                    q_deg: q.iter().map(|v| v.to_degrees()).collect(),
                    reading_mm: reading,
                    t_s: None,
                    temp_c: None,
                    split: None,
                    std_mm: None,
                    block: None,
                    payload_kg: payload_kg.map(|p| p[i]),
                    station: None,
                    mount: None,
                    feature: None,
                }
            })
            .collect();
        Dataset { rows, source: "plan candidates".into() }
    }

    /// What each pose carries besides its angles: the static torques (under the payload) of the
    /// load-driven effects.
    pub fn inputs(&self, q: &[Vec<f64>], payload_kg: Option<&[f64]>) -> Vec<RowInputs> {
        let mut inputs = match &self.torque {
            Some(t) => row_inputs(&self.dataset(q, payload_kg), Some(t)),
            None => vec![RowInputs::default(); q.len()],
        };
        inputs.iter_mut().zip(&self.stations).for_each(|(i, s)| i.station = *s);
        inputs
    }

    /// The Jacobian of the readings (mm) at the model's parameters `x` for poses `q` (with
    /// `payload_kg`, each under its own payload): one row per reading value, pose after pose.
    pub fn jacobian(&self, q: &[Vec<f64>], payload_kg: Option<&[f64]>) -> DMatrix<f64> {
        let dim = self.model.measurement.dim();
        let mut data = Samples::readings(q.to_vec(), vec![0.0; q.len() * dim], dim);
        data.inputs = self.inputs(q, payload_kg);
        let fit = ReadingFit { model: &self.model, data: &data };
        let mut j = DMatrix::zeros(q.len() * dim, self.model.n_params());
        fit.jacobian(&self.x, &mut j);
        j
    }
}

/// The design problem of a pool: which parameters it identifies, and their scaled rows.
pub struct PoolDesign {
    /// The scaled rows of the identifiable columns, per candidate.
    pub pool: Pool,
    /// The parameters the pool identifies (the design's columns).
    pub identifiable: Vec<String>,
    /// The parameters no pose of the pool tells apart from the others (held at nominal).
    pub fixed: Vec<String>,
    /// Each identifiable column's RMS over the pool (mm per parameter unit): the scale.
    pub scale: Vec<f64>,
}

/// Relative singular value below which a parameter combination is left out of the design. A
/// calibration fits down to [`DEFAULT_RANK_TOL`](crate::calib::pipeline::DEFAULT_RANK_TOL) (1e-7); a combination the whole pool sees
/// that weakly moves no reading by more than rounding, and an index of its singular value
/// (O3, O4, O5) would measure rounding too.
pub const DESIGN_RANK_TOL: f64 = 1e-4;

/// The design problem of `model` over the poses `q` (with `payload_kg`, each candidate under its
/// own payload).
pub fn pool_design(model: &Model, q: &[Vec<f64>], payload_kg: Option<&[f64]>) -> PoolDesign {
    let j = model.jacobian(q, payload_kg);
    let m = &model.model;
    // JᵀJ = RᵀR with R = Λ^½Vᵀ: the identifiability analysis of R is that of J (same column
    // norms, singular values, right vectors and Gram–Schmidt residuals) at p×p instead of rows×p.
    let eig = SymmetricEigen::new(j.transpose() * &j);
    let r = DMatrix::from_diagonal(&eig.eigenvalues.map(|l| l.max(0.0).sqrt())) * eig.eigenvectors.transpose();
    let nc = m.n_chain();
    let priority: Vec<usize> = (nc..m.n_params()).chain(0..nc).collect();
    // A column the pool never moves (a compliance of a joint no load turns) is held outright:
    // R's rounding would give it a tiny norm of noise instead of zero.
    let norms: Vec<f64> = (0..m.n_params()).map(|k| j.column(k).norm()).collect();
    let top = norms.iter().copied().fold(0.0, f64::max);
    let dead: Vec<bool> = norms.iter().map(|n| !(*n > 1e-9 * top)).collect();
    let id = analyse(&r, &m.names, &dead, DESIGN_RANK_TOL, &priority);
    let keep: Vec<usize> = (0..m.n_params()).filter(|&k| !id.fixed_mask[k]).collect();
    let rows = j.nrows().max(1) as f64;
    let scale: Vec<f64> = keep.iter().map(|&k| (j.column(k).norm_squared() / rows).sqrt()).collect();
    let d = m.measurement.dim();
    let p = keep.len();
    let mut scaled = vec![0.0; j.nrows() * p];
    for row in 0..j.nrows() {
        for (c, &k) in keep.iter().enumerate() {
            scaled[row * p + c] = j[(row, k)] / scale[c];
        }
    }
    let target = tool_point_information(model, q, payload_kg, &keep, &scale);
    PoolDesign { pool: Pool::new(scaled, d, p).with_target(target, 3), identifiable: id.identifiable, fixed: id.fixed, scale }
}

/// What a calibration is judged on: the mean information per pose over the pool of the
/// predicted tool point (mm, base frame, per scaled parameter of the `keep` columns), rigid
/// motions of the whole arm aside — W = E[GᵀG] − E[GᵀB] E[BᵀB]⁻¹ E[BᵀG], with G the tool point's
/// Jacobian and B = [I, −[p]ₓ] the motion of the point under a small turn and shift of the base.
/// An accuracy test registers the arm's base frame to the cell before it measures (no reading
/// of the arm fixes where it stands), and a draw-wire's one length per pose is not the tool's
/// 3-D position: trace(M⁻¹W)/3 is the variance of the calibrated arm's tool point over its
/// workspace with the registration that best fits the whole pool — close to, and a little below,
/// what [`verify::true_error`] measures (which registers on the calibration's own poses). With
/// payloads to choose from, the pool is every pose under every payload, and so is the average.
fn tool_point_information(model: &Model, q: &[Vec<f64>], payload_kg: Option<&[f64]>, keep: &[usize], scale: &[f64]) -> DMatrix<f64> {
    let (m, p) = (&model.model, keep.len());
    let inputs = model.inputs(q, payload_kg);
    let mut w = m.work();
    let mut dx = vec![Vector3::zeros(); m.n_params()];
    let pts: Vec<(Vector3<f64>, DMatrix<f64>)> = q
        .iter()
        .zip(&inputs)
        .map(|(q, inp)| {
            let pt = m.tool_point_grad_with(&model.x, q, inp, &mut w, &mut dx);
            let g = DMatrix::from_fn(3, p, |r, c| crate::units::to_mm(dx[keep[c]][r]) / scale[c]);
            (pt, g)
        })
        .collect();
    let n = pts.len().max(1) as f64;
    let centre = pts.iter().fold(Vector3::zeros(), |a, (pt, _)| a + pt) / n;
    let (mut gg, mut bg, mut bb) = (DMatrix::zeros(p, p), DMatrix::zeros(6, p), DMatrix::zeros(6, 6));
    for (pt, g) in &pts {
        // Lever in m, centred: the projection does not depend on B's scale, its conditioning does.
        let r = pt - centre;
        let mut b = DMatrix::zeros(3, 6);
        b.view_mut((0, 0), (3, 3)).fill_with_identity();
        b.view_mut((0, 3), (3, 3)).copy_from(&(-r.cross_matrix()));
        gg += g.transpose() * g;
        bg += b.transpose() * g;
        bb += b.transpose() * &b;
    }
    // A pool whose tool points leave a rigid motion unseen (all on a line) still registers the
    // rest: the least-squares motion by the pseudo-inverse.
    let fit = bb.svd(true, true).solve(&bg, 1e-12).unwrap_or_else(|_| DMatrix::zeros(6, p));
    let w = (gg - bg.transpose() * fit) / n;
    // Symmetric to the last bit.
    (&w + w.transpose()) * 0.5
}

/// Every criterion's value of a design, with the condition number.
#[derive(Clone, Debug, Serialize)]
pub struct Indices {
    /// O1, D-optimal.
    pub o1_d: f64,
    /// I-optimal: the mean prediction variance over the pool, per unit noise variance
    /// (smaller is better).
    pub i_prediction_variance: f64,
    /// O3, the smallest singular value.
    pub o3_min_sv: f64,
    /// O4, noise amplification.
    pub o4_noise: f64,
    /// O5.
    pub o5_a: f64,
    /// Largest over smallest singular value of the scaled Jacobian.
    pub condition: f64,
}

impl Indices {
    /// The indices of the candidates `set` of `pool`.
    pub fn of(pool: &Pool, set: &[usize]) -> Indices {
        use design::SingularIndex;
        let info = pool.information(set);
        let sv = design::singular_values(&info);
        let m = set.len() * pool.d;
        let (lo, hi) = (sv.last().copied().unwrap_or(0.0), sv.first().copied().unwrap_or(0.0));
        Indices {
            o1_d: design::DOptimal.of_sv(&sv, m),
            i_prediction_variance: design::prediction_variance(&info, pool),
            o3_min_sv: design::MinSingular.of_sv(&sv, m),
            o4_noise: design::NoiseAmplification.of_sv(&sv, m),
            o5_a: design::AOptimal.of_sv(&sv, m),
            condition: if lo > 0.0 { hi / lo } else { f64::INFINITY },
        }
    }
}

/// What a plan is asked for.
#[derive(Clone, Debug)]
pub struct PlanOptions {
    /// Poses to plan.
    pub n: usize,
    /// Feasible candidates to choose from.
    pub candidates: usize,
    /// The observability index maximised ([`CRITERIA`]'s names).
    pub criterion: String,
    /// The parametrisation the calibration will use.
    pub parametrisation: Parametrisation,
    /// Seed of the candidate pool and of the random comparison sets.
    pub seed: u64,
    /// Most exchange sweeps.
    pub max_sweeps: usize,
    /// Effect blocks the calibration will fit beside the geometry (a kind, on one joint or on
    /// every joint): their parameters join the design.
    pub effects: Vec<(EffectKind, Option<usize>)>,
    /// What loads the joints while measuring (the payload mounted, the cable's tension), for
    /// the load-driven effects.
    pub loads: JointLoads,
    /// Payloads the engineer can mount, kg: each candidate pose is offered under each, and the
    /// plan says which payload every pose is measured with (empty: `loads.payload` throughout).
    pub payloads: Vec<f64>,
    /// Plan for this calibrated arm ([`Model::from_result`]) instead of the scenario's nominal
    /// one: `parametrisation` and `effects` are then the result's, and `loads.payload`, when
    /// given, replaces the payload it was calibrated with.
    pub calibrated: Option<std::sync::Arc<CalibResult>>,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            n: 30,
            candidates: 10_000,
            criterion: "i".into(),
            parametrisation: Parametrisation::Hayati,
            seed: 1,
            max_sweeps: 8,
            effects: Vec::new(),
            loads: JointLoads::default(),
            payloads: Vec::new(),
            calibrated: None,
        }
    }
}

/// Random feasible sets drawn to compare a plan with.
pub const RANDOM_SETS: usize = 25;

/// A measurement plan.
#[derive(Clone, Debug, Serialize)]
pub struct Plan {
    /// The scenario planned for.
    pub scenario: String,
    /// The robot.
    pub robot: String,
    /// The instrument (`length`, `point`, `pose`).
    pub measurement: String,
    /// The parametrisation designed for.
    pub parametrisation: String,
    /// The criterion maximised, and what it is.
    pub criterion: String,
    /// What the criterion is.
    pub criterion_describe: String,
    /// Seed of the pool.
    pub seed: u64,
    /// The candidate pool.
    pub candidates: Candidates,
    /// The parameters the pool identifies (the design's), and those held.
    pub identifiable: Vec<String>,
    /// Parameters held at nominal: no pose of the pool tells them apart.
    pub fixed: Vec<String>,
    /// The planned poses, rad, in tour order.
    #[serde(skip)]
    pub poses: Vec<Vec<f64>>,
    /// The planned poses, degrees, in tour order.
    pub poses_deg: Vec<Vec<f64>>,
    /// The payload each planned pose is measured with, kg (with payloads to choose from).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub payload_kg: Option<Vec<f64>>,
    /// The plan's indices.
    pub indices: Indices,
    /// The median indices of [`RANDOM_SETS`] random feasible sets of the same size.
    pub random_median: Indices,
    /// The best any set of as many poses of the pool could do (a certified bound on the mean
    /// prediction variance), and how many random feasible poses the plan and that best are
    /// worth; `None` when the plan reads fewer values than there are parameters, or the pool
    /// gives no finite bound ([`Plan::ceiling_note`] says which).
    pub ceiling: Option<bound::Ceiling>,
    /// Why there is no ceiling, when there is none.
    pub ceiling_note: Option<String>,
    /// What the plan was asked that changes nothing (a payload no planned effect sees), in words.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The search.
    pub design: Design,
    /// The tour's timing, and that of the same poses in the order the design chose them.
    pub tour: tour::TourTime,
    /// The same poses, unordered.
    pub unordered: tour::TourTime,
    /// Wall time of planning, s.
    pub seconds: f64,
    /// For an artifact's plan, each pose's feature (`placement/socket`, `placement/face`), in
    /// the tour's order: where to seat the ball or touch the probe.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub features: Option<Vec<String>>,
}

/// `n` distinct indices of `0..len`, seeded.
pub fn random_set(len: usize, n: usize, seed: u64) -> Vec<usize> {
    let mut all: Vec<usize> = (0..len).collect();
    all.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    all.truncate(n.min(len));
    all
}

/// The median of each index over `sets`.
fn median_indices(pool: &Pool, sets: &[Vec<usize>]) -> Indices {
    let all: Vec<Indices> = sets.iter().map(|s| Indices::of(pool, s)).collect();
    let med = |f: &dyn Fn(&Indices) -> f64| crate::stats::median(&all.iter().map(f).collect::<Vec<f64>>());
    Indices {
        o1_d: med(&|i| i.o1_d),
        i_prediction_variance: med(&|i| i.i_prediction_variance),
        o3_min_sv: med(&|i| i.o3_min_sv),
        o4_noise: med(&|i| i.o4_noise),
        o5_a: med(&|i| i.o5_a),
        condition: med(&|i| i.condition),
    }
}

/// Plans `opts.n` poses for scenario `s` on `robot` (see the module docs).
pub fn plan(s: &Scenario, robot: &Robot, opts: &PlanOptions) -> Result<Plan> {
    if s.sockets.is_some() || s.planes.is_some() {
        return artifact::plan(s, robot, opts);
    }
    let t0 = std::time::Instant::now();
    let crit = criterion(&opts.criterion)?;
    if opts.n == 0 || opts.candidates < opts.n {
        return Err(Error::Invalid(format!("a plan needs 1 <= poses <= candidates, got {} poses of {} candidates", opts.n, opts.candidates)));
    }
    let cands = candidates(s, robot, opts.candidates, opts.seed)?;
    if cands.q.len() < opts.n {
        return Err(Error::Invalid(format!(
            "only {} feasible poses in {} drawn (refused: {}); {} asked: widen the ranges or the [workspace]",
            cands.q.len(),
            cands.drawn,
            cands.refused.iter().map(|(k, v)| format!("{k} {v}")).collect::<Vec<_>>().join(", "),
            opts.n
        )));
    }
    let model = match &opts.calibrated {
        Some(r) => Model::from_result(r, s, robot, opts.loads.payload.as_ref())?,
        None => Model::new(s, robot, opts.parametrisation, &opts.effects, &opts.loads)?,
    };
    // With payloads, every candidate pose under every payload: candidate k·M + i is pose i under
    // payload k.
    let offered: Option<Vec<f64>> = (!opts.payloads.is_empty()).then(|| opts.payloads.iter().flat_map(|&m| std::iter::repeat_n(m, cands.q.len())).collect());
    let pool_q: Vec<Vec<f64>> = match &offered {
        Some(_) => opts.payloads.iter().flat_map(|_| cands.q.iter().cloned()).collect(),
        None => cands.q.clone(),
    };
    let prob = pool_design(&model, &pool_q, offered.as_deref());
    let d = design::design(&prob.pool, opts.n, crit, opts.max_sweeps);
    let motion = tour::Motion::new(robot, s.sampling.speed_fraction, s.acquisition.ramp_s, s.draw_wire.hold_s + s.draw_wire.window_s());
    let home = vec![0.0; robot.dof()];
    // The tour: one payload after the other (in the order given), each payload's poses ordered.
    let groups: Vec<Vec<usize>> = match &offered {
        Some(p) => opts.payloads.iter().map(|m| d.chosen.iter().copied().filter(|&c| p[c] == *m).collect()).filter(|g: &Vec<usize>| !g.is_empty()).collect(),
        None => vec![d.chosen.clone()],
    };
    let mut toured: Vec<usize> = Vec::with_capacity(d.chosen.len());
    for g in &groups {
        let qs: Vec<Vec<f64>> = g.iter().map(|&c| pool_q[c].clone()).collect();
        toured.extend(motion.order(&home, &qs).into_iter().map(|i| g[i]));
    }
    let poses: Vec<Vec<f64>> = toured.iter().map(|&c| pool_q[c].clone()).collect();
    let chosen: Vec<Vec<f64>> = d.chosen.iter().map(|&c| pool_q[c].clone()).collect();
    let indices = Indices::of(&prob.pool, &d.chosen);
    let (ceiling, ceiling_note) = match bound::ceiling(&prob.pool, &d.chosen, indices.i_prediction_variance, opts.seed) {
        Ok(c) => (Some(c), None),
        Err(why) => (None, Some(why)),
    };
    let sets: Vec<Vec<usize>> = (0..RANDOM_SETS).map(|k| random_set(pool_q.len(), opts.n, stream_seed(opts.seed, Stream::Plan, 1 + k as u64))).collect();
    Ok(Plan {
        scenario: s.name.clone(),
        robot: robot.name.clone(),
        measurement: model.model.measurement.name().to_string(),
        parametrisation: match &opts.calibrated {
            Some(r) => format!("{} (calibrated, {})", r.provenance.model_name, r.provenance.data),
            None => opts.parametrisation.name().to_string(),
        },
        criterion: crit.name().to_string(),
        criterion_describe: crit.describe().to_string(),
        seed: opts.seed,
        identifiable: prob.identifiable.clone(),
        fixed: prob.fixed.clone(),
        poses_deg: poses.iter().map(|q| q.iter().map(|v| crate::units::round_decimals(v.to_degrees(), s.sampling.angle_decimals)).collect()).collect(),
        payload_kg: offered.as_ref().map(|p| toured.iter().map(|&c| p[c]).collect()),
        indices,
        ceiling,
        ceiling_note,
        warnings: Vec::new(),
        random_median: median_indices(&prob.pool, &sets),
        tour: {
            let mut t = motion.time(&home, &poses);
            t.payload_changes_s = groups.len().saturating_sub(1) as f64 * crate::sim::pose_list::PAYLOAD_CHANGE_S;
            t.total_s += t.payload_changes_s;
            t
        },
        unordered: {
            // In the design's order the payload changes wherever consecutive poses differ in it.
            let mut t = motion.time(&home, &chosen);
            let changes = offered.as_ref().map_or(0, |p| d.chosen.windows(2).filter(|w| p[w[0]] != p[w[1]]).count());
            t.payload_changes_s = changes as f64 * crate::sim::pose_list::PAYLOAD_CHANGE_S;
            t.total_s += t.payload_changes_s;
            t
        },
        poses,
        candidates: cands,
        design: d,
        seconds: t0.elapsed().as_secs_f64(),
        features: None,
    })
}
