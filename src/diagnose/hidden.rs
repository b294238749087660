//! Hidden-effect scenarios for the diagnosis tests and benchmark (generator side: this module
//! knows the truth; [`super::diagnose`] never calls it).
//!
//! A scenario is the geometric IRB 120 scenario with one (or more) non-geometric effects drawn
//! from a recorded seed: the cause, the joint, and a size at 1.5–4× what a rigid fit absorbs.
//! "What a rigid fit absorbs" is measured, not guessed: the change of length the effect causes
//! per unit of its parameter is projected onto the rigid model's Jacobian (everything a
//! geometric calibration can explain), and the size is set so that what is left over has an RMS
//! of `factor` × the reading noise.

use crate::calib::effects::inputs::{row_inputs, JointLoads, TorqueModel};
use crate::calib::effects::{EffectBlock, EffectKind, ThermalDrive};
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::dataset::{Dataset, Row};
use crate::error::{Error, Result};
use crate::optim::LeastSquares;
use crate::robot::Robot;
use crate::sim::generate::{acquisition_times, sample_poses};
use crate::sim::scenario::Scenario;
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// The geometric scenario every hidden-effect scenario starts from.
pub const BASE_SCENARIO: &str = include_str!("../../scenarios/irb120_geometric.toml");

/// What was hidden, in the units the diagnosis reports.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Hidden {
    /// The effect hidden.
    pub cause: EffectKind,
    /// 0-based joint of a per-joint effect.
    pub joint: Option<usize>,
    /// Size in the diagnosis report's unit (see [`super::report::Cause::unit`]).
    pub magnitude: f64,
    /// Size in the calibration block's internal unit.
    pub internal: f64,
    /// Multiple of the reading noise left over after a rigid fit.
    pub factor: f64,
}

impl Hidden {
    /// Whether a diagnosed cause names this effect: same kind, same joint.
    pub fn named_by(&self, c: &super::report::Cause) -> bool {
        c.is(self.cause, self.joint)
    }
    /// Whether a diagnosed size is right: within 3 standard uncertainties or within 30 %.
    pub fn sized_by(&self, c: &super::report::Cause) -> bool {
        let e = (c.magnitude - self.magnitude).abs();
        e <= 3.0 * c.uncertainty || e <= 0.3 * self.magnitude.abs()
    }
}

/// The block that represents `kind` on `joint` (thermal blocks driven by temperature).
fn block(kind: EffectKind, joint: Option<usize>, ref_c: f64) -> EffectBlock {
    let thermal = (kind == EffectKind::Thermal).then_some(ThermalDrive::Temperature { ref_c, sensor_lag: false });
    EffectBlock { kind, joint, thermal, range_m: None }
}

/// The hideable causes of an arm with `n` joints: kind and joint (joint-zero drift on the first
/// three, the axes that carry the arm).
pub fn causes(n: usize) -> Vec<(EffectKind, Option<usize>)> {
    let mut v = Vec::new();
    for j in 0..n {
        v.push((EffectKind::Compliance, Some(j)));
        v.push((EffectKind::Backlash, Some(j)));
    }
    v.push((EffectKind::Thermal, None));
    for j in 0..n.min(3) {
        v.push((EffectKind::Thermal, Some(j)));
    }
    for j in 0..n {
        v.push((EffectKind::Eccentricity, Some(j)));
    }
    v
}

/// The scenario's commanded poses as a dataset of q, t and temperature (no lengths), with the
/// temperature the thermal scenarios would give.
fn poses(s: &Scenario, robot: &Robot) -> Result<Dataset> {
    let q = sample_poses(s, robot)?;
    let t = acquisition_times(s, robot, &q);
    // The temperature the thermal scenarios would give (the thermal effect's own warm-up).
    let th = crate::sim::effects::Thermal::warm_up();
    let rows = q
        .iter()
        .zip(&t)
        .map(|(qi, ti)| Row {
            q_deg: qi.iter().map(|v| v.to_degrees()).collect(),
            reading_mm: Vec::new(),
            t_s: Some(*ti),
            temp_c: Some(th.ambient_c + th.delta_t(*ti)),
            split: None,
            std_mm: None,
            ..Default::default()
        })
        .collect();
    Ok(Dataset { rows, source: s.name.clone() })
}

/// The nominal Hayati model of `robot` read by the scenario's instrument placed as it is (its
/// draw-wire, or its tracker).
fn nominal_model(s: &Scenario, robot: &Robot) -> CalibModel {
    let placement = crate::sim::instrument::placement(&s.draw_wire, &s.instruments);
    let (chain, kinds) = crate::calib::model::DhTable::from_robot_hayati(robot).chain(true, true);
    CalibModel { limits: robot.limits(), ..CalibModel::of_chain("hayati", chain, kinds, &placement) }
}

/// The rows of `data` as samples of `model`'s readings: their q (radians), zero readings, no
/// inputs.
fn zero_samples(model: &CalibModel, data: &Dataset) -> Samples {
    let q: Vec<Vec<f64>> = data.rows.iter().map(|r| r.q_deg.iter().map(|d| d.to_radians()).collect()).collect();
    let dim = model.measurement.dim();
    Samples::of(model.measurement, q, vec![0.0; data.rows.len() * dim])
}

/// The scenario's commanded poses ([`poses`]), the [`nominal_model`], and the poses as
/// [`zero_samples`].
fn nominal_at_poses(s: &Scenario, robot: &Robot) -> Result<(Dataset, CalibModel, Samples)> {
    let data = poses(s, robot)?;
    let model = nominal_model(s, robot);
    let samples = zero_samples(&model, &data);
    Ok((data, model, samples))
}

/// The static torques the twin's arm carries at `s`'s poses: the draw-wire's tension where the
/// cable reads, none where another instrument does (a tracker pulls on nothing).
fn twin_torques(s: &Scenario, robot: &Robot) -> TorqueModel {
    let sn = &s.draw_wire;
    let cable = s.instruments.active().is_none();
    let loads = JointLoads { cable_tension_n: if cable { sn.tension_n } else { 0.0 }, ..Default::default() };
    TorqueModel::new(robot, &loads, cable.then(|| sn.exit_point_m()), sn.tool_point_m(), false)
}

/// RMS (mm per reading value) per unit size of the reading change a rigid fit cannot absorb,
/// at the scenario's poses. The size is the block's first parameter, or for eccentricity the
/// amplitude at phase `phase` (A·sin(q + φ) = A cos φ·sin q + A sin φ·cos q).
pub fn unabsorbed_rms(s: &Scenario, robot: &Robot, kind: EffectKind, joint: Option<usize>, phase: f64) -> Result<f64> {
    let (data, model, samples) = nominal_at_poses(s, robot)?;
    unabsorbed_at(&data, model, samples, &twin_torques(s, robot), kind, joint, phase)
}

/// [`unabsorbed_rms`] at the rows `data` (their q as `samples`) of the rigid `model`, the rows'
/// torques from `torque`.
fn unabsorbed_at(
    data: &Dataset,
    mut model: CalibModel,
    mut samples: Samples,
    torque: &TorqueModel,
    kind: EffectKind,
    joint: Option<usize>,
    phase: f64,
) -> Result<f64> {
    let ref_c = data.rows[0].temp_c.unwrap_or(21.0);
    model.add_effect(block(kind, joint, ref_c), 0.0);
    samples.inputs = row_inputs(data, Some(torque));
    let fit = ReadingFit { model: &model, data: &samples };
    let mut j = DMatrix::zeros(samples.y.len(), model.n_params());
    LeastSquares::jacobian(&fit, &model.nominal, &mut j);
    let k = model.effect_params(0).start;
    let mut g = DVector::from_column_slice(j.column(k).as_slice());
    if kind == EffectKind::Eccentricity {
        g = g * phase.cos() + DVector::from_column_slice(j.column(k + 1).as_slice()) * phase.sin();
    }
    let rigid = j.columns(0, model.first_effect()).into_owned();
    let coef = rigid.clone().svd(true, true).solve(&g, 1e-10).map_err(|e| Error::Invalid(format!("projection: {e}")))?;
    let rest = &g - &rigid * coef;
    Ok(rest.norm() / (samples.y.len() as f64).sqrt())
}

/// The base scenario with `seed` (no hidden effect).
pub fn clean(seed: u64) -> Result<(Scenario, Robot)> {
    let mut s = Scenario::from_toml(BASE_SCENARIO, "scenarios/irb120_geometric.toml (embedded)")?;
    s.seed = seed;
    s.sampling.poses = 400;
    s.sampling.test = 0;
    let robot = s.load_robot(None)?;
    Ok((s, robot))
}

/// A scenario with `n` different causes drawn from `seed`, each at 1.5–4× what a rigid fit
/// absorbs, among the causes that stay plausible at that size.
pub fn hidden(seed: u64, n: usize) -> Result<(Scenario, Robot, Vec<Hidden>)> {
    let (s, robot) = clean(seed)?;
    let sigma = s.draw_wire.noise_std_mm / (s.draw_wire.samples as f64).sqrt();
    hide_in(s, robot, seed, n, sigma, 1.5..4.0, false)
}

/// Poses per sweep, glitch runs, rows per run and their size (mm) of [`realistic`] acquisitions.
pub const REALISTIC_SWEEP: usize = 20;
/// Glitch runs, rows per run and their size (mm) of [`realistic`] acquisitions.
pub const REALISTIC_GLITCHES: (usize, usize, f64) = (3, 8, 2.0);

/// The clean scenario of `seed` acquired as measured data are: in sweeps of
/// [`REALISTIC_SWEEP`] poses (one or two joints move, the others hold), the joint angles logged
/// at `decimals` decimals of a degree (1: 0.1°, 2: 0.01°; the arm stands at the commanded angle),
/// and [`REALISTIC_GLITCHES`] runs of disturbed readings.
pub fn realistic(seed: u64, decimals: usize) -> Result<(Scenario, Robot)> {
    let (mut s, robot) = clean(seed)?;
    s.sampling.order = crate::sim::scenario::Order::Sweeps;
    s.sampling.sweep_length = REALISTIC_SWEEP;
    s.sampling.logged_decimals = Some(decimals);
    let (runs, rows, size_mm) = REALISTIC_GLITCHES;
    s.glitches = Some(crate::sim::scenario::Glitches { runs, rows, size_mm, kind: Default::default(), joint: None, size_deg: None });
    s.name = format!("realistic-{seed}-{decimals}");
    Ok((s, robot))
}

/// RMS (mm) of what logging the joint angles at `step_deg` costs one reading at the scenario's
/// poses (uniform quantisation through the nominal model's joint Jacobian): the floor an effect
/// of realistic data must rise above.
pub fn logging_floor_mm(s: &Scenario, robot: &Robot, step_deg: f64) -> Result<f64> {
    let (_, model, samples) = nominal_at_poses(s, robot)?;
    let step = crate::calib::fit::floor::Step::Given(step_deg);
    let f = crate::calib::fit::floor::noise_floor(
        &model,
        &model.nominal,
        &samples,
        crate::calib::fit::floor::FloorInputs { angle_step: Some(step), reading_step_mm: None, repeat: None, instrument: Default::default() },
    );
    Ok(f.total_mm)
}

/// A [`realistic`] scenario with one cause drawn from `seed` at `factors` times the data's
/// floor (the averaged reading noise and the angle logging together) left over after a rigid
/// fit: above the floor (1.5–4×) a diagnosis must name it, far below it (0.05–0.2×) it must
/// not. Also returns the floor, mm.
pub fn hidden_realistic(seed: u64, decimals: usize, factors: std::ops::Range<f64>) -> Result<(Scenario, Robot, Vec<Hidden>, f64)> {
    let (s, robot) = realistic(seed, decimals)?;
    let noise = s.draw_wire.noise_std_mm / (s.draw_wire.samples as f64).sqrt();
    let floor = logging_floor_mm(&s, &robot, 10f64.powi(-(decimals as i32)))?;
    let sigma = (noise * noise + floor * floor).sqrt();
    let (mut s, robot, h) = hide_in(s, robot, seed, 1, sigma, factors, true)?;
    s.name = format!("hidden-{seed}-realistic-{decimals}");
    Ok((s, robot, h, sigma))
}

/// The tracker scenario every hidden tracker-effect scenario starts from: the IRB 120's
/// reflector read in 3-D by a laser tracker 2.5 m away, the rows' own standard deviations
/// written as `sx, sy, sz`.
pub const TRACKER_SCENARIO: &str = include_str!("../../scenarios/irb120_tracker.toml");

/// Rows of a hidden tracker-effect scenario: each its own pose, measured once (no repeats, no
/// sweeps): independent rows.
pub const TRACKER_POSES: usize = 400;

/// The tracker scenario with `seed` and no hidden effect: [`TRACKER_POSES`] rows, every row
/// with its `sx, sy, sz`.
pub fn clean_tracker(seed: u64) -> Result<(Scenario, Robot)> {
    let mut s = Scenario::from_toml(TRACKER_SCENARIO, "scenarios/irb120_tracker.toml (embedded)")?;
    s.seed = seed;
    s.sampling.poses = TRACKER_POSES;
    s.sampling.test = 0;
    let tracker = s.instruments.tracker.as_mut().ok_or_else(|| Error::Invalid("the tracker scenario has no [tracker]".into()))?;
    tracker.write_std = true;
    s.name = format!("tracker-{seed}");
    let robot = s.load_robot(None)?;
    Ok((s, robot))
}

/// RMS over the scenario's poses of one row's standard deviation per coordinate (mm): the
/// tracker's `a + b·distance` per sample, averaged over the sensor's samples, at the nominal
/// arm's reflector.
pub fn tracker_row_noise_mm(s: &Scenario, robot: &Robot) -> Result<f64> {
    let tracker = s.instruments.tracker.as_ref().ok_or_else(|| Error::Invalid(format!("{} has no [tracker]", s.name)))?;
    let (_, model, samples) = nominal_at_poses(s, robot)?;
    let mut w = model.work();
    let mut y = vec![0.0; model.measurement.dim()];
    let per_sample = |d_m: f64| (tracker.noise_um + tracker.noise_um_per_m * d_m) * 1e-3 / (s.draw_wire.samples.max(1) as f64).sqrt();
    let ms = samples
        .q
        .iter()
        .zip(&samples.inputs)
        .map(|(q, inp)| {
            model.readings(&model.nominal, q, inp, &mut w, &mut y);
            per_sample(y.iter().map(|v| v * v).sum::<f64>().sqrt()).powi(2)
        })
        .sum::<f64>()
        / samples.len().max(1) as f64;
    Ok(ms.sqrt())
}

/// A [`clean_tracker`] scenario with one cause drawn from `seed` whose reading change a rigid
/// fit (arm and tracker placement) cannot absorb is `factors` times one row's noise per
/// coordinate (RMS): at half the noise, an effect a row cannot show but hundreds of independent
/// rows do. Also returns that noise, mm.
pub fn hidden_tracker(seed: u64, factors: std::ops::Range<f64>) -> Result<(Scenario, Robot, Vec<Hidden>, f64)> {
    let (s, robot) = clean_tracker(seed)?;
    let sigma = tracker_row_noise_mm(&s, &robot)?;
    let (mut s, robot, h) = hide_in(s, robot, seed, 1, sigma, factors, true)?;
    s.name = format!("hidden-{seed}-tracker");
    Ok((s, robot, h, sigma))
}

/// The warm-up of [`hidden_warm_up`]: expansion coefficient range (ppm/K, steel to aluminium),
/// the structure's rise (K), its time constant (s) and the temperature sensor's lag behind it
/// as a share of that time constant.
pub const WARM_UP_ALPHA_PPM: std::ops::Range<f64> = 12.0..25.0;
/// See [`WARM_UP_ALPHA_PPM`].
pub const WARM_UP_RISE_K: std::ops::Range<f64> = 4.0..10.0;
/// See [`WARM_UP_ALPHA_PPM`].
pub const WARM_UP_TAU_S: std::ops::Range<f64> = 600.0..1200.0;
/// See [`WARM_UP_ALPHA_PPM`].
pub const WARM_UP_LAG_SHARE: std::ops::Range<f64> = 0.2..0.5;
/// Noise of one temperature reading in [`hidden_warm_up`], K.
pub const WARM_UP_TEMP_NOISE_K: f64 = 0.01;

/// A warm-up the temperature sensor lags: the [`clean_tracker`] scenario of `seed` with the
/// whole arm's thermal expansion, the structure warming by a rise over a time constant and the
/// `temp` column read by a sensor that lags it (with a reading noise of
/// [`WARM_UP_TEMP_NOISE_K`]), each drawn from the seed within the [`WARM_UP_ALPHA_PPM`] ranges.
/// Returns the scenario, the arm, what was hidden (its size in ppm/K; `factor` is the lag over
/// the time constant) and one row's noise, mm.
pub fn hidden_warm_up(seed: u64) -> Result<(Scenario, Robot, Hidden, f64)> {
    let (mut s, robot) = clean_tracker(seed)?;
    let sigma = tracker_row_noise_mm(&s, &robot)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5741_524d_5550);
    let alpha = rng.random_range(WARM_UP_ALPHA_PPM) * 1e-6;
    let tau = rng.random_range(WARM_UP_TAU_S);
    let share = rng.random_range(WARM_UP_LAG_SHARE);
    let thermal = crate::sim::effects::Thermal {
        temp_lag_s: share * tau,
        temp_noise_k: WARM_UP_TEMP_NOISE_K,
        ..crate::sim::effects::Thermal::new(alpha, rng.random_range(WARM_UP_RISE_K), tau, 20.0)
    };
    s.effects.thermal = Some(thermal);
    s.name = format!("warm-up-{seed}");
    let h = Hidden { cause: EffectKind::Thermal, joint: None, magnitude: alpha * 1e6, internal: alpha, factor: share };
    Ok((s, robot, h, sigma))
}

/// The payloads of [`hidden_payload_runs`], kg: none, half and the IRB 120's rated 3 kg.
pub const PAYLOAD_RUNS_KG: [f64; 3] = [0.0, 1.5, 3.0];
/// Poses of each payload run (the same poses in every run).
pub const PAYLOAD_RUN_POSES: usize = 120;
/// The payload's centre of mass in the flange frame, mm (as a user states it).
pub const PAYLOAD_COM_MM: [f64; 3] = [150.0, 0.0, 100.0];
/// What a rigid fit leaves of the hidden compliance in the unloaded run alone, at most, as a
/// multiple of one row's noise: below what [`super`]'s gain test can name on that run's rows.
pub const UNLOADED_FACTOR: f64 = 0.3;

/// A compliance the unloaded arm hides and payload runs reveal: the [`clean_tracker`] scenario
/// of `seed` (its reflector's `sx, sy, sz` written) measured at [`PAYLOAD_RUN_POSES`] poses
/// under each payload of [`PAYLOAD_RUNS_KG`] in turn, with a joint compliance drawn from the
/// seed (shoulder, elbow or wrist pitch) sized so that what a rigid fit leaves of it over the
/// runs is `factors` × one row's noise, but over the unloaded run at most [`UNLOADED_FACTOR`]
/// × that noise, and never beyond its plausible size. Returns the scenario, the arm, the pose list to measure, what was hidden (its
/// `factor` over the runs) and the noise, mm.
pub fn hidden_payload_runs(seed: u64, factors: std::ops::Range<f64>) -> Result<(Scenario, Robot, crate::sim::pose_list::PoseList, Hidden, f64)> {
    let (mut s, robot) = clean_tracker(seed)?;
    s.sampling.poses = PAYLOAD_RUN_POSES;
    s.effects.payload = Some(crate::sim::effects::Payload { mass_kg: 0.0, com_mm: PAYLOAD_COM_MM });
    let sigma = tracker_row_noise_mm(&s, &robot)?;
    let poses = crate::sim::generate::sample_poses(&s, &robot)?;
    let list = crate::sim::pose_list::PoseList {
        q: PAYLOAD_RUNS_KG.iter().flat_map(|_| poses.iter().cloned()).collect(),
        payload_kg: Some(PAYLOAD_RUNS_KG.iter().flat_map(|m| vec![*m; poses.len()]).collect()),
    };
    let rows = |payload: Option<f64>| -> Dataset {
        let per_run = list.q.iter().zip(list.payload_kg.iter().flatten()).filter(|(_, m)| payload.is_none_or(|p| p == **m));
        Dataset {
            rows: per_run.map(|(q, m)| Row { q_deg: q.iter().map(|v| v.to_degrees()).collect(), payload_kg: Some(*m), ..Default::default() }).collect(),
            source: s.name.clone(),
        }
    };
    let loads = JointLoads { payload: Some(crate::robot::statics::Payload { mass_kg: 0.0, com_mm: PAYLOAD_COM_MM }), ..Default::default() };
    let torque = TorqueModel::new(&robot, &loads, None, s.draw_wire.tool_point_m(), false);
    let model = nominal_model(&s, &robot);
    let unabsorbed = |data: &Dataset, joint: usize| -> Result<f64> {
        unabsorbed_at(data, model.clone(), zero_samples(&model, data), &torque, EffectKind::Compliance, Some(joint), 0.0)
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5041_594c_4f41);
    let joint = [1usize, 2, 4][rng.random_range(0..3)];
    let (over_runs, unloaded) = (unabsorbed(&rows(None), joint)?, unabsorbed(&rows(Some(0.0)), joint)?);
    let wanted = rng.random_range(factors.clone()) * sigma / over_runs;
    let kind = EffectKind::Compliance;
    let size = wanted.min(UNLOADED_FACTOR * sigma / unloaded.max(f64::MIN_POSITIVE)).min(kind.def().plausible(Some(joint)));
    s.effects.set_size(crate::sim::effects::SizedEffect::Compliance, robot.dof(), Some(joint), size, 0.0).map_err(Error::Invalid)?;
    s.name = format!("hidden-{seed}-payload-runs");
    let hidden =
        Hidden { cause: kind, joint: Some(joint), magnitude: kind.def().reported(Some(joint), size), internal: size, factor: size * over_runs / sigma };
    Ok((s, robot, list, hidden, sigma))
}

/// `s` with `n` different causes drawn from `seed`, each at `factors` × `sigma` (mm) left over
/// after a rigid fit, among the causes that stay plausible at the largest such size (`clamp`:
/// at the smallest, the factor then drawn up to the plausible size).
fn hide_in(
    mut s: Scenario,
    robot: Robot,
    seed: u64,
    n: usize,
    sigma: f64,
    factors: std::ops::Range<f64>,
    clamp: bool,
) -> Result<(Scenario, Robot, Vec<Hidden>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4849_4444_454e);
    let mut pool: Vec<(EffectKind, Option<usize>, f64, f64)> = Vec::new();
    for (kind, joint) in causes(robot.dof()) {
        let phase = if kind == EffectKind::Eccentricity { rng.random_range(-std::f64::consts::PI..std::f64::consts::PI) } else { 0.0 };
        let a = unabsorbed_rms(&s, &robot, kind, joint, phase)?;
        let needed = if clamp { factors.start } else { factors.end };
        if a > 0.0 && needed * sigma / a <= kind.def().plausible(joint) {
            pool.push((kind, joint, a, phase));
        }
    }
    if pool.is_empty() {
        return Err(Error::Invalid(format!("no cause can hide at {:.2}x {sigma:.4} mm within its plausible size", factors.start)));
    }
    let mut out = Vec::new();
    while out.len() < n && !pool.is_empty() {
        let (kind, joint, a, phase) = pool.remove(rng.random_range(0..pool.len()));
        let top = if clamp { factors.end.min(kind.def().plausible(joint) * a / sigma) } else { factors.end };
        let factor = if top > factors.start { rng.random_range(factors.start..top) } else { factors.start };
        let v = factor * sigma / a;
        let twin = crate::identified::twin_effect(kind).ok_or_else(|| Error::Invalid(format!("the twin cannot take a '{}' at a given size", kind.name())))?;
        s.effects.set_size(twin, robot.dof(), joint, v, phase).map_err(Error::Invalid)?;
        out.push(Hidden { cause: kind, joint, magnitude: kind.def().reported(joint, v), internal: v, factor });
    }
    s.name = format!("hidden-{seed}");
    Ok((s, robot, out))
}

/// How a tracker moved between two sessions of a campaign, as the benchmark hides it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackerMove {
    /// Set up again elsewhere: metres away and tens of degrees turned.
    Restationed,
    /// Registered again on its reference marks: a millimetre or two, a twentieth of a degree.
    Reregistered,
    /// A tripod leg knocked: a fifth of a millimetre, a hundredth of a degree.
    Bumped,
}

/// A tracker moved at row `from` (0-based): the readings from there on turned by `turn` about
/// the tracker's origin, then shifted by `shift_mm`.
#[derive(Clone, Copy, Debug)]
pub struct MovedTracker {
    /// The kind of move.
    pub kind: TrackerMove,
    /// The first row the tracker read from its new place.
    pub from: usize,
    /// The readings' turn.
    pub turn: nalgebra::Rotation3<f64>,
    /// The readings' shift after the turn, mm.
    pub shift_mm: nalgebra::Vector3<f64>,
}

impl MovedTracker {
    /// How far the tracker's origin moved, mm (the inverse of the readings' move).
    pub fn origin_shift_mm(&self) -> f64 {
        (self.turn.inverse() * -self.shift_mm).norm()
    }
    /// How far its axes turned, degrees.
    pub fn turn_deg(&self) -> f64 {
        self.turn.angle().to_degrees()
    }
    /// `data` as the moved tracker read it: rows `from..` moved (a 6-D reading's orientation
    /// turned with it).
    pub fn apply(&self, data: &Dataset) -> Dataset {
        let mut d = data.clone();
        for r in &mut d.rows[self.from..] {
            let p = self.turn * nalgebra::Vector3::new(r.reading_mm[0], r.reading_mm[1], r.reading_mm[2]) + self.shift_mm;
            r.reading_mm[..3].copy_from_slice(p.as_slice());
            if r.reading_mm.len() == 6 {
                let o = self.turn.matrix() * crate::measurement::Euler::XYZ.matrix([r.reading_mm[3], r.reading_mm[4], r.reading_mm[5]].map(f64::to_radians));
                r.reading_mm[3..].copy_from_slice(&crate::measurement::Euler::XYZ.angles(&o).map(f64::to_degrees));
            }
        }
        d
    }
}

/// A clean tracker scenario ([`clean_tracker`]) whose tracker moves once, between 30 % and
/// 70 % of the rows: re-stationed, re-registered or bumped by turns of the seed, each sized from
/// the seed within its kind's range.
pub fn moved_tracker(seed: u64) -> Result<(Scenario, Robot, MovedTracker)> {
    let (mut s, robot) = clean_tracker(seed)?;
    s.name = format!("tracker-moved-{seed}");
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4d4f_5645_4420);
    let kind = [TrackerMove::Restationed, TrackerMove::Reregistered, TrackerMove::Bumped][(seed % 3) as usize];
    let (turn_deg, shift_mm): (std::ops::Range<f64>, std::ops::Range<f64>) = match kind {
        TrackerMove::Restationed => (15.0..40.0, 300.0..1500.0),
        TrackerMove::Reregistered => (0.02..0.1, 0.5..3.0),
        TrackerMove::Bumped => (0.005..0.02, 0.1..0.3),
    };
    let axis = nalgebra::Unit::new_normalize(nalgebra::Vector3::new(rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2), 1.0));
    let turn = nalgebra::Rotation3::from_axis_angle(&axis, rng.random_range(turn_deg).to_radians() * if rng.random_bool(0.5) { 1.0 } else { -1.0 });
    let direction =
        nalgebra::Unit::new_normalize(nalgebra::Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-0.3..0.3)));
    let shift_mm = direction.into_inner() * rng.random_range(shift_mm);
    let from = rng.random_range(TRACKER_POSES * 3 / 10..TRACKER_POSES * 7 / 10);
    Ok((s, robot, MovedTracker { kind, from, turn, shift_mm }))
}
