//! Dataset generation: scenario → sampled poses → twin (rapier) → sensor → dataset + truth.

use crate::dataset::{Dataset, Row, Split};
use crate::error::{Error, Result};
use crate::robot::kinematics::Frame;
use crate::robot::Robot;
use crate::sim::scenario::{halton, stream_seed, Order, Scenario, Stream, HALTON_BASES};
use crate::sim::twin::tour::{Acquired, AcquisitionModel, OnTimeout, Schedule, TourSettings};
use crate::sim::twin::{approach_sides, PoseCommand, RestingPose, Twin};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

pub use crate::units::T_DECIMALS;
/// Decimals of a written per-row standard deviation (`sx, sy, sz`), mm: 1 nm.
pub const STD_DECIMALS: usize = 6;
/// Decimals of the temperature column (mK).
pub const TEMP_DECIMALS: usize = 3;

pub use crate::units::round_decimals;

pub use crate::progress::{Progress, Silent};

pub use crate::dataset::truth::{DrawWireTruth, PoseAcquisition, PoseTruth, Rejected, ToolTruth};

/// Everything true about a generated dataset, as truth.json holds it: the one truth schema
/// ([`crate::dataset::truth::Truth`]) with the twin's own effects and tracker tables.
pub type Truth = crate::dataset::truth::Truth<crate::sim::effects::Effects, crate::sim::instrument::Tracker>;

/// A generated dataset with its truth and the link frames (for recordings).
pub struct Generated {
    /// The dataset as `dataset.csv` holds it.
    pub dataset: Dataset,
    /// Its ground truth, as `truth.json` holds it.
    pub truth: Truth,
    /// Frames of the true arm at rest (base, links, flange), per dataset row.
    pub frames: Vec<Vec<Frame>>,
    /// The twin that generated the dataset.
    pub twin: Twin,
}

impl Generated {
    /// What the user should know of this simulation: readings beyond the range the sensor's
    /// reading polynomial was identified on.
    pub fn warnings(&self) -> Vec<String> {
        let lengths: Vec<f64> = self.dataset.rows.iter().filter_map(|r| r.l_mm()).collect();
        self.twin.draw_wire.polynomial.as_ref().and_then(|p| p.beyond_range(&lengths)).into_iter().collect()
    }
    /// True tool point of dataset row `i`, m.
    pub fn truth_tool(&self, i: usize) -> nalgebra::Vector3<f64> {
        let p = self.truth.poses[i].tool_mm;
        crate::units::to_m(nalgebra::Vector3::new(p[0], p[1], p[2]))
    }
}

/// Builds the twin a scenario describes.
pub fn build_twin(s: &Scenario, robot: &Robot) -> Twin {
    Twin::new(robot.clone(), s.true_params(robot), s.effects.clone(), s.draw_wire.clone(), s.simulation.clone()).with_instruments(s.instruments.clone())
}

/// Length (mm) the nominal arm (no geometric error, no effect) gives at joint angles `q` (rad).
pub fn nominal_length(chain: &crate::robot::kinematics::Chain, sensor: &crate::sim::instrument::DrawWire, q: &[f64]) -> f64 {
    let zero = vec![0.0; chain.n_params()];
    sensor.ideal_length(&chain.point(q, &zero, 1.0, chain.flange(), &sensor.tool_point_m()))
}

/// The commanded pose (rad) at `unit(j)` ∈ [0, 1] of each joint's range (`ranges`, rad), rounded
/// to `decimals` of a degree as the twin commands it (the written angles are the simulated ones).
pub fn commanded_pose(ranges: &[(f64, f64)], unit: impl Fn(usize) -> f64, decimals: usize) -> Vec<f64> {
    (0..ranges.len()).map(|j| ranges[j].0 + unit(j) * (ranges[j].1 - ranges[j].0)).map(|q| round_decimals(q.to_degrees(), decimals).to_radians()).collect()
}

/// Samples commanded poses (rad) by a Halton sequence over the joint ranges, keeping those the
/// scenario's [`Scenario::cell`] finds feasible: the nominal tool point above `min_tool_z_mm`,
/// the nominal reading inside the sensor range (a tracker's distance range, if given) and the
/// `[workspace]`, if any, kept clear of.
pub fn sample_poses(s: &Scenario, robot: &Robot) -> Result<Vec<Vec<f64>>> {
    let n = robot.dof();
    if n > HALTON_BASES.len() {
        return Err(Error::Invalid(format!("Halton sampling supports up to {} joints", HALTON_BASES.len())));
    }
    let ranges = s.ranges_rad(robot);
    let cell = s.cell(robot);
    let mut fk = cell.work();
    let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(s.seed, Stream::Sampling, 0));
    let start: u64 = rng.random_range(100..10_000);
    let mut out = Vec::with_capacity(s.sampling.poses);
    let mut refused: BTreeMap<crate::sim::workspace::Refusal, usize> = BTreeMap::new();
    let mut i = start;
    let limit = start + 200 * s.sampling.poses as u64 + 10_000;
    while out.len() < s.sampling.poses {
        if i > limit {
            return Err(Error::Scenario {
                path: s.name.clone(),
                msg: format!(
                    "only {} of {} poses are reachable inside the {}, above min_tool_z_mm{} (refused: {})",
                    out.len(),
                    s.sampling.poses,
                    if s.instruments.active().is_some() { "tracker's range" } else { "sensor range" },
                    if s.workspace.is_some() { " and clear of the [workspace]" } else { "" },
                    refused.iter().map(|(r, k)| format!("{} {k}", r.name())).collect::<Vec<_>>().join(", ")
                ),
            });
        }
        // Commanded angles at the dataset's precision: the written angles are the simulated ones.
        let unit = |j: usize| match s.sampling.order {
            Order::Sweeps => {
                // Sweep k from base pose `start + k`: joint k mod n (and on odd sweeps the next
                // one too) steps across its range, the others hold.
                let (len, k) = (s.sampling.sweep_length as u64, (i - start) / s.sampling.sweep_length as u64);
                let step = (i - start) % len;
                let moving = (k as usize % n, if k % 2 == 1 { (k as usize + 1) % n } else { k as usize % n });
                if j == moving.0 || j == moving.1 {
                    // Equal steps, started where the base pose puts the joint within the first.
                    (step as f64 + halton(start + k, HALTON_BASES[j])) / len as f64
                } else {
                    halton(start + k, HALTON_BASES[j])
                }
            }
            _ => halton(i, HALTON_BASES[j]),
        };
        let q = commanded_pose(&ranges, unit, s.sampling.angle_decimals);
        i += 1;
        match cell.check(&q, &mut fk) {
            Ok(()) => out.push(q),
            Err(r) => *refused.entry(r).or_insert(0usize) += 1,
        }
    }
    if s.sampling.order == Order::Shuffled {
        out.shuffle(&mut ChaCha8Rng::seed_from_u64(stream_seed(s.seed, Stream::Sampling, 1)));
    }
    Ok(out)
}

/// Adds the scenario's glitch runs to the readings (and to the truth's measured lengths):
/// returns the dataset rows (0-based) that carry one.
fn add_glitches(s: &Scenario, rows: &mut [Row], truth: &mut [PoseTruth]) -> Vec<usize> {
    let Some(g) = &s.glitches else { return Vec::new() };
    let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(s.seed, Stream::Glitches, 0));
    let n = rows.len();
    let mut hit = Vec::new();
    // Runs in separate slots of the acquisition, so they never overlap.
    let slot = n / g.runs;
    for r in 0..g.runs {
        if slot < g.rows {
            break;
        }
        let first = r * slot + rng.random_range(0..=slot - g.rows);
        if g.kind.in_joints() {
            corrupt_joints(g, &mut rng, rows, first.max(1), s.sampling.written_decimals());
            let run = first.max(1)..(first.max(1) + g.rows).min(n);
            if g.kind == crate::sim::scenario::GlitchKind::JointOffsetAndReading {
                let size = g.size_mm * (1.0 + 0.5 * rng.random::<f64>()) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                for i in run.clone() {
                    let l = round_decimals(rows[i].l_mm().expect("generated rows carry a reading") + size, s.draw_wire.reading_decimals());
                    rows[i].reading_mm = vec![l];
                    truth[i].length_measured_mm = l;
                }
            }
            hit.extend(run);
            continue;
        }
        let mut size = g.size_mm * (1.0 + 0.5 * rng.random::<f64>()) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        for i in first..first + g.rows {
            if g.kind == crate::sim::scenario::GlitchKind::Scatter && i > first {
                size = g.size_mm * (1.0 + 0.5 * rng.random::<f64>()) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            }
            let l = rows[i].l_mm().expect("generated rows carry a reading") + size;
            let l = round_decimals(l, s.draw_wire.reading_decimals());
            rows[i].reading_mm = vec![l];
            truth[i].length_measured_mm = l;
            hit.push(i);
        }
    }
    hit
}

/// A joint fault of `g` (see [`crate::sim::scenario::Glitches`]) in the logged angles of rows
/// `first..first + g.rows` (`first` ≥ 1: a stale joint repeats the row before).
fn corrupt_joints(g: &crate::sim::scenario::Glitches, rng: &mut ChaCha8Rng, rows: &mut [Row], first: usize, decimals: usize) {
    use crate::sim::scenario::GlitchKind;
    let n = rows[0].q_deg.len();
    let run = first..(first + g.rows).min(rows.len());
    let drawn = g.joint.map_or_else(|| rng.random_range(0..n), |j| j - 1);
    // Over the run: the joint furthest from zero, and the one that moves most.
    let span = |j: usize| rows[run.clone()].iter().fold((f64::MAX, f64::MIN), |(lo, hi), r| (lo.min(r.q_deg[j]), hi.max(r.q_deg[j])));
    let furthest = (0..n).max_by(|&a, &b| {
        let m = |j: usize| rows[run.clone()].iter().map(|r| r.q_deg[j].abs()).fold(f64::MAX, f64::min);
        m(a).total_cmp(&m(b))
    });
    let moving = (0..n).max_by(|&a, &b| (span(a).1 - span(a).0).total_cmp(&(span(b).1 - span(b).0)));
    match g.kind {
        GlitchKind::JointOffset | GlitchKind::JointOffsetAndReading => {
            let size = g.size_deg.unwrap_or(1.0) * (1.0 + 0.5 * rng.random::<f64>()) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            rows[run].iter_mut().for_each(|r| r.q_deg[drawn] = round_decimals(r.q_deg[drawn] + size, decimals));
        }
        GlitchKind::JointSign => {
            let j = g.joint.map(|j| j - 1).or(furthest).unwrap_or(drawn);
            rows[run].iter_mut().for_each(|r| r.q_deg[j] = -r.q_deg[j]);
        }
        GlitchKind::JointStale => {
            let j = g.joint.map(|j| j - 1).or(moving).unwrap_or(drawn);
            let stale = rows[first - 1].q_deg[j];
            rows[run].iter_mut().for_each(|r| r.q_deg[j] = stale);
        }
        GlitchKind::JointSwap => {
            let j = drawn.min(n.saturating_sub(2));
            rows[run].iter_mut().for_each(|r| r.q_deg.swap(j, j + 1));
        }
        GlitchKind::Offset | GlitchKind::Scatter => {}
    }
}

pub use crate::dataset::split::stratified_split;

/// Most robot time (s) one run simulates: a day. A slower acquisition (a tiny `speed_fraction`, a
/// joint with a tiny speed limit) would keep the simulation busy for as long, so it is refused.
pub const MAX_ROBOT_TIME_S: f64 = 86_400.0;

/// Refuses an acquisition whose last reading (`times`, s) comes after [`MAX_ROBOT_TIME_S`]
/// (the twin's own schedule; measured times, as `replay` gives them, are the data's).
pub fn check_robot_time(s: &Scenario, times: &[f64]) -> Result<()> {
    let end = times.iter().copied().fold(0.0, f64::max);
    if end > MAX_ROBOT_TIME_S || !end.is_finite() {
        return Err(Error::Scenario {
            path: s.name.clone(),
            msg: format!(
                "the acquisition would take {:.1} h of robot time ({} poses at sampling.speed_fraction = {}), more than the {} h a run \
                 simulates; raise speed_fraction (or check the URDF's joint velocity limits)",
                end / 3600.0,
                times.len(),
                s.sampling.speed_fraction,
                MAX_ROBOT_TIME_S / 3600.0
            ),
        });
    }
    Ok(())
}

/// Acquisition time of each pose: move at `speed_fraction` of the joint speed limits, hold still,
/// then sample. The time recorded is the middle of the sampling window.
pub fn acquisition_times(s: &Scenario, robot: &Robot, poses: &[Vec<f64>]) -> Vec<f64> {
    let mut t = 0.0;
    let mut prev = vec![0.0; robot.dof()];
    poses
        .iter()
        .map(|q| {
            let move_s =
                q.iter().zip(&prev).zip(&robot.joints).map(|((a, b), j)| (a - b).abs() / (s.sampling.speed_fraction * j.speed_limit())).fold(0.0, f64::max);
            prev = q.clone();
            let at = t + move_s + s.draw_wire.hold_s + 0.5 * s.draw_wire.window_s();
            t += move_s + s.draw_wire.hold_s + s.draw_wire.window_s();
            at
        })
        .collect()
}

/// Ambient temperature written when the thermal effect is off, °C.
pub const DEFAULT_AMBIENT_C: f64 = 20.0;

/// The `temp` column of pose `i` acquired at `t` s, at the dataset's precision: the temperature
/// sensor's reading (ambient + offset + the structure's rise through the sensor's lag + seeded
/// Gaussian noise, see [`crate::sim::effects::Thermal`]); `None` when `temp_column = false`. Without
/// the thermal effect the column holds the constant [`DEFAULT_AMBIENT_C`].
pub fn measured_temp(s: &Scenario, i: usize, t: f64) -> Option<f64> {
    let Some(th) = &s.effects.thermal else {
        return Some(DEFAULT_AMBIENT_C);
    };
    if !th.temp_column {
        return None;
    }
    let mut v = th.sensed_temp_c(t);
    if th.temp_noise_k > 0.0 {
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(s.seed, Stream::TempNoise, i as u64));
        v += th.temp_noise_k * rng.sample::<f64, _>(rand_distr::StandardNormal);
    }
    Some(round_decimals(v, TEMP_DECIMALS))
}

/// What the twin gave for one pose.
pub enum Outcome {
    /// At rest (settled in rapier, or the quasi-static model).
    Rest(RestingPose),
    /// Read during a simulated acquisition.
    Acquired(Acquired),
}

/// Every pose through the scenario's acquisition model, in order; results do not depend on the
/// number of threads.
/// `read_at`: the simulated tour reads at these times (a replayed acquisition's) instead of its
/// own schedule's.
pub fn acquire_all(
    s: &Scenario,
    twin: &Twin,
    poses: &[Vec<f64>],
    sides: &[Vec<f64>],
    times: &[f64],
    read_at: Option<&[f64]>,
    progress: &dyn Progress,
) -> Vec<Result<Outcome>> {
    let cmd = |i: usize| PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: times[i] };
    let what = match s.acquisition.model {
        AcquisitionModel::Settled => "settling poses",
        AcquisitionModel::QuasiStatic => "quasi-static poses",
        AcquisitionModel::Simulated => "simulating the tour",
    };
    progress.start(poses.len() as u64, what);
    let out = match s.acquisition.model {
        AcquisitionModel::Settled => (0..poses.len())
            .into_par_iter()
            .map(|i| {
                let r = twin.simulate(&cmd(i)).map(Outcome::Rest);
                progress.inc(1);
                r
            })
            .collect(),
        AcquisitionModel::QuasiStatic => (0..poses.len())
            .map(|i| {
                progress.inc(1);
                Ok(Outcome::Rest(twin.quasi_static(&cmd(i))))
            })
            .collect(),
        AcquisitionModel::Simulated => {
            let settings = TourSettings { seed: s.seed, speed_fraction: s.sampling.speed_fraction };
            crate::sim::twin::tour::acquire(twin, &s.acquisition, settings, &vec![0.0; twin.chain.n_joints], poses, read_at, progress)
                .into_iter()
                .map(|r| r.map(Outcome::Acquired))
                .collect()
        }
    };
    progress.finish();
    out
}

/// Refuses a scenario with an artifact (`[sockets]`, `[planes]`): its acquisition is the ball
/// seated in the sockets or the probe touching the faces ([`artifact_rows`], what `twincal
/// generate` runs), not the instrument's tour.
pub fn refuse_artifact(s: &Scenario) -> Result<()> {
    let what = if s.sockets.is_some() {
        "seats a ball in sockets ([sockets])"
    } else if s.planes.is_some() {
        "touches a block's faces ([planes])"
    } else {
        return Ok(());
    };
    Err(Error::Invalid(format!("scenario {} {what}: its rows come from the artifact (twincal generate writes them), not from the instrument's tour", s.name)))
}

/// The rows a scenario's artifact gives and what a user states of it.
pub struct ArtifactRows {
    /// The rows: joint angles at each feature, labelled, in acquisition order.
    pub dataset: crate::dataset::Dataset,
    /// The truth, as written beside the dataset: each file's name and its value (the sockets'
    /// and the faces' where the ball is seated and touches both).
    pub truths: Vec<(&'static str, serde_json::Value)>,
    /// The designed distances between features (sockets' spacings, faces' steps) a user
    /// states, mm.
    pub designed: Vec<(String, String, f64)>,
    /// The same as made, at the artifact's temperature, mm.
    pub made: Vec<(String, String, f64)>,
    /// Configurations out of reach, redrawn.
    pub unreachable: usize,
    /// What the rows are, for messages ("a ball seated in 2 sockets").
    pub what: String,
}

/// The rows of scenario `s`'s artifact on the twin of `robot`: the ball seated in the sockets
/// (`[sockets]`), the probe on the faces (`[planes]`), or both in one acquisition (the same ball
/// seated, then touching: the faces' rows after the sockets', their times after); `None`
/// without one.
pub fn artifact_rows(s: &Scenario, robot: &Robot) -> Option<Result<ArtifactRows>> {
    let twin = build_twin(s, robot);
    let decimals = s.sampling.written_decimals();
    let seated = s.sockets.as_ref().map(|art| {
        crate::sim::artifact::seat(&twin, robot, art, decimals, s.seed).map(|(dataset, t)| ArtifactRows {
            truths: vec![(crate::sim::artifact::SOCKETS_TRUTH_FILE, serde_json::to_value(&t).unwrap_or(serde_json::Value::Null))],
            designed: t.designed_spacings_mm.clone(),
            made: t.spacings_mm.clone(),
            unreachable: t.unreachable,
            what: format!("a ball seated in {} sockets at {} placements", art.layout_mm.len(), art.placements.len()),
            dataset,
        })
    });
    let touched = s.planes.as_ref().map(|art| {
        let seed = if s.sockets.is_some() { s.seed ^ FACES_BESIDE_SEED } else { s.seed };
        crate::sim::planes::touch(&twin, robot, art, decimals, seed).map(|(dataset, t)| ArtifactRows {
            truths: vec![(crate::sim::planes::PLANES_TRUTH_FILE, serde_json::to_value(&t).unwrap_or(serde_json::Value::Null))],
            designed: t.designed_steps_mm.clone(),
            made: t.steps_mm.clone(),
            unreachable: t.unreachable,
            what: format!(
                "a {} touching {} faces at {} placements",
                if art.indicator { "dial indicator" } else { "probe" },
                art.faces.len(),
                art.placements.len()
            ),
            dataset,
        })
    });
    match (seated, touched) {
        (Some(a), Some(b)) => {
            let step = s.sockets.as_ref().map_or(0.0, |k| k.step_s);
            Some(a.and_then(|a| b.map(|b| beside(a, b, step))))
        }
        (a, b) => a.or(b),
    }
}

/// What the faces' stream of the twin's randomness is apart from the sockets' where one ball is
/// seated and touches both (the faces alone keep the scenario's seed).
const FACES_BESIDE_SEED: u64 = 0x9e37_79b9_7f4a_7c15;

/// Faces' rows `b` after seated rows `a`: one acquisition, the faces' times after the last seat
/// (`step_s` later).
fn beside(a: ArtifactRows, b: ArtifactRows, step_s: f64) -> ArtifactRows {
    let last = a.dataset.rows.iter().filter_map(|r| r.t_s).fold(0.0, f64::max);
    let mut rows = a.dataset.rows;
    rows.extend(b.dataset.rows.into_iter().map(|mut r| {
        r.t_s = r.t_s.map(|t| t + last + step_s);
        r
    }));
    ArtifactRows {
        dataset: crate::dataset::Dataset { rows, source: a.dataset.source },
        truths: a.truths.into_iter().chain(b.truths).collect(),
        designed: a.designed.into_iter().chain(b.designed).collect(),
        made: a.made.into_iter().chain(b.made).collect(),
        unreachable: a.unreachable + b.unreachable,
        what: format!("{}, then {}", a.what, b.what.replacen("a ", "the same ball as a ", 1)),
    }
}

/// Runs a scenario end to end. Poses are simulated in parallel; results do not depend on the
/// number of threads.
pub fn generate(s: &Scenario, robot: &Robot, progress: &dyn Progress) -> Result<Generated> {
    let poses = sample_poses(s, robot)?;
    generate_at(s, robot, poses, None, progress)
}

/// [`generate`] at given commanded poses (rad, in acquisition order) instead of the scenario's
/// sampled ones, read at the given times (s) where there are some (a replay of a measured
/// acquisition, see `twincal replay`), else at the scenario's acquisition times.
pub fn generate_at(s: &Scenario, robot: &Robot, poses: Vec<Vec<f64>>, given_times: Option<Vec<f64>>, progress: &dyn Progress) -> Result<Generated> {
    refuse_artifact(s)?;
    let twin = build_twin(s, robot);
    let home = vec![0.0; robot.dof()];
    // With given times the simulated tour waits at rest before each move to read at them (or
    // reads as soon as it can); the rows carry the times it read at.
    let schedule = (s.acquisition.model == AcquisitionModel::Simulated).then(|| Schedule::new(robot, &s.timing(), &home, &poses, given_times.as_deref()));
    let read_at: Option<Vec<f64>> = given_times.clone().filter(|_| schedule.is_some());
    // Measured times span what the acquisition spanned (a series of days replays); only the
    // twin's own schedule is held to a day of robot time.
    let own_schedule = given_times.is_none();
    let times = match (given_times, &schedule) {
        (_, Some(sc)) => sc.read_t.clone(),
        (Some(t), None) => t,
        (None, None) => acquisition_times(s, robot, &poses),
    };
    if own_schedule {
        check_robot_time(s, &times)?;
    }
    let sides = approach_sides(&vec![0.0; robot.dof()], &poses);
    let chain = &twin.chain;
    let nominal_lengths: Vec<f64> = poses.iter().map(|q| nominal_length(chain, &s.draw_wire, q)).collect();
    let split = stratified_split(&nominal_lengths, s.sampling.test, s.seed);

    let results = acquire_all(s, &twin, &poses, &sides, &times, read_at.as_deref(), progress);
    let tour = Tour { s, twin: &twin, poses: &poses, sides: &sides, times: &times, split: &split, schedule: schedule.as_ref() };
    let mut rows = Vec::new();
    let mut truth_poses = Vec::new();
    let mut frames = Vec::new();
    let mut rejected = Vec::new();
    let mut point_var = Vec::new();
    for (i, r) in results.into_iter().enumerate() {
        match tour.pose_output(i, r) {
            Ok(o) => {
                rows.push(o.row);
                truth_poses.push(o.truth);
                frames.push(o.frames);
                point_var.extend(o.point_var);
            }
            Err(reason) => rejected.push(Rejected { index: i, q_cmd_deg: degrees(&poses[i]), reason }),
        }
    }
    if rows.is_empty() {
        return Err(Error::Sensor(format!("every pose was rejected; first reason: {}", rejected.first().map(|r| r.reason.as_str()).unwrap_or("?"))));
    }
    let glitch_rows = add_glitches(s, &mut rows, &mut truth_poses);
    let truth = truth_file(s, robot, &twin, &point_var, truth_poses, rejected, glitch_rows);
    Ok(Generated { dataset: Dataset { rows, source: s.name.clone() }, truth, frames, twin })
}

/// What the tour of one run shares across its poses.
struct Tour<'a> {
    s: &'a Scenario,
    twin: &'a Twin,
    /// Commanded poses, rad.
    poses: &'a [Vec<f64>],
    sides: &'a [Vec<f64>],
    times: &'a [f64],
    split: &'a [Split],
    schedule: Option<&'a Schedule>,
}

/// What one pose gave: its dataset row, its truth, the arm's frames, and the tracker's variance
/// per coordinate (when a tracker read it).
struct PoseOutput {
    row: Row,
    truth: PoseTruth,
    frames: Vec<Frame>,
    point_var: Option<f64>,
}

impl Tour<'_> {
    /// Pose `i`'s row and truth from what the twin gave for it (`r`), or why it is rejected.
    fn pose_output(&self, i: usize, r: Result<Outcome>) -> std::result::Result<PoseOutput, String> {
        let s = self.s;
        let (rest, series, acq) = match r {
            Ok(Outcome::Rest(r)) => (r, None, None),
            Ok(Outcome::Acquired(a)) => {
                let closed = a.gate_s.is_none();
                if closed && s.acquisition.on_timeout == OnTimeout::Reject {
                    return Err(format!(
                        "stability gate still closed when the {} s hold ended (readings differed by {} mm or more between {} s windows)",
                        s.draw_wire.hold_s, s.acquisition.gate_mm, s.acquisition.gate_window_s
                    ));
                }
                let pa = PoseAcquisition {
                    move_s: self.schedule.map(|sc| sc.moves[i].duration).unwrap_or(0.0),
                    gate_s: a.gate_s,
                    read_with_gate_closed: closed,
                    transient_mm: a.transient_mm,
                    negligible_s: a.negligible_s,
                    rule_side: a.rule_sides.clone(),
                };
                (a.rest, Some(a.lengths), Some(pa))
            }
            Err(e) => return Err(e.to_string()),
        };
        let (l_true, noise_free, reading) = cable_reading(s, i, &rest, series.as_deref())?;
        let time = self.times[i];
        let dt = self.twin.effects.thermal.as_ref().map(|th| th.delta_t(time)).unwrap_or(0.0);
        let temp = measured_temp(s, i, time);
        let other = instrument_reading(s, i, &rest);
        let reading_mm = other.as_ref().map_or_else(|| vec![reading], |r| r.read.clone());
        let row = Row {
            q_deg: self.poses[i].iter().map(|v| round_decimals(v.to_degrees(), s.sampling.written_decimals())).collect(),
            reading_mm,
            t_s: Some(round_decimals(time, T_DECIMALS)),
            temp_c: temp,
            split: Some(self.split[i]),
            std_mm: other.as_ref().filter(|r| r.write_std).map(|r| [round_decimals(r.std_mm, STD_DECIMALS); 3]),
            block: None,
            payload_kg: None,
            station: s.instruments.active().map(|ins| ins.station(i)).filter(|(_, written)| *written).map(|(k, _)| (k + 1).to_string()),
            mount: None,
            feature: None,
        };
        let mut truth = PoseTruth {
            index: i,
            split: self.split[i],
            t_s: time,
            delta_t_k: dt,
            temp_measured_c: temp,
            q_cmd_deg: degrees(&self.poses[i]),
            eccentricity_mdeg: s.effects.eccentricity.as_ref().map(|_| rest.eccentricity.iter().map(|e| e.to_degrees() * 1e3).collect()),
            q_link_deg: degrees(&rest.q_link),
            deflection_mdeg: rest.deflection.iter().map(|d| d.to_degrees() * 1e3).collect(),
            joint_torque_nm: rest.torque.clone(),
            approach_side: self.sides[i].clone(),
            contact: rest.contact.clone(),
            tool_mm: [crate::units::to_mm(rest.tool.x), crate::units::to_mm(rest.tool.y), crate::units::to_mm(rest.tool.z)],
            length_true_mm: l_true,
            length_noise_free_mm: noise_free,
            length_measured_mm: reading,
            point_true_mm: None,
            point_measured_mm: None,
            pose_true: None,
            reading_true: None,
            reading_measured: None,
            settle_steps: rest.steps,
            settle_time_s: match &acq {
                Some(a) => a.negligible_s.unwrap_or(s.draw_wire.hold_s + s.draw_wire.window_s()),
                None => rest.steps as f64 * s.simulation.dt_s,
            },
            acquisition: acq,
        };
        if let (Some(i), Some(r)) = (s.instruments.active(), &other) {
            i.record(r, &mut truth);
        }
        Ok(PoseOutput { row, truth, frames: rest.frames, point_var: other.map(|r| r.std_mm * r.std_mm) })
    }
}

/// The draw-wire's reading of pose `i`, mm: the true length (the window's mean noise-free
/// length, constant for an arm at rest), with the sensor's linearity error, and as read (noise,
/// resolution, at its meaning's precision: see `DrawWire::reading_decimals`); or why it failed.
fn cable_reading(s: &Scenario, i: usize, rest: &RestingPose, series: Option<&[f64]>) -> std::result::Result<(f64, f64, f64), String> {
    let l_true = match series {
        Some(l) => l.iter().sum::<f64>() / l.len().max(1) as f64,
        None => s.draw_wire.ideal_length(&rest.tool),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(s.seed, Stream::Noise, i as u64));
    let read = match series {
        Some(l) => s.draw_wire.read_series(l, &mut rng),
        None => s.draw_wire.read(l_true, &mut rng),
    };
    let noise_free = match series {
        Some(l) => l.iter().map(|v| v + s.draw_wire.linearity_error(*v)).sum::<f64>() / l.len().max(1) as f64,
        None => l_true + s.draw_wire.linearity_error(l_true),
    };
    let reading = read.map_err(|e| e.to_string())?;
    Ok((l_true, noise_free, round_decimals(reading, s.draw_wire.reading_decimals())))
}

/// The reading of pose `i`'s tool point by the instrument that reads instead of the cable (a
/// tracker), from its own noise stream; the flange's orientation is the twin's resting frame's.
fn instrument_reading(s: &Scenario, i: usize, rest: &RestingPose) -> Option<crate::sim::instrument::TwinReading> {
    let instrument = s.instruments.active()?;
    let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(s.seed, Stream::TrackerNoise, i as u64));
    Some(instrument.reading_at(i, &rest.tool, &rest.frames[rest.frames.len() - 1].rot, s.draw_wire.samples, &mut rng))
}

/// Angles in degrees.
fn degrees(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x.to_degrees()).collect()
}

/// The truth file of a run: the scenario's true parameters (in the file's units), effects,
/// instrument, and each pose's truth.
fn truth_file(
    s: &Scenario,
    robot: &Robot,
    twin: &Twin,
    point_var: &[f64],
    truth_poses: Vec<PoseTruth>,
    rejected: Vec<Rejected>,
    glitch_rows: Vec<usize>,
) -> Truth {
    let names = robot.param_names();
    let parameters = names.iter().zip(robot.param_kinds()).zip(&twin.params).map(|((n, kind), v)| (n.clone(), kind.to_file(*v))).collect();
    let sn = &s.draw_wire;
    let averaged = sn.noise_std_mm / (sn.samples as f64).sqrt();
    let units = BTreeMap::from(
        [
            ("parameters", "mm for <joint>.dx/dy/dz, degrees for <joint>.rx/ry/rz/dtheta"),
            ("angles", "degrees, controller convention"),
            ("lengths", "mm"),
            ("time", "s from the start of acquisition"),
            ("deflection_mdeg", "millidegrees, link side minus motor side"),
            ("eccentricity_mdeg", "millidegrees, true motor side minus commanded (encoder) angle"),
            ("temperature", "°C for temp_measured_c, K for delta_t_k (the structure's true rise)"),
        ]
        .map(|(k, v)| (k.to_string(), v.to_string())),
    );
    Truth {
        schema_version: crate::output::SCHEMA_VERSION,
        dataset: None,
        scenario: s.name.clone(),
        seed: s.seed,
        robot: robot.name.clone(),
        robot_urdf: (!robot.is_embedded()).then(|| robot.urdf.clone()),
        units,
        parameters,
        effects: s.effects.clone(),
        draw_wire: DrawWireTruth {
            exit_point_mm: sn.exit_point_mm,
            length_offset_mm: sn.length_offset_mm,
            noise_std_mm: sn.noise_std_mm,
            averaged_noise_std_mm: averaged,
            resolution_mm: sn.resolution_mm,
            linearity_pct_fs: sn.linearity_pct_fs,
            range_mm: sn.range_mm,
            tension_n: sn.tension_n,
            samples: sn.samples,
            hold_s: sn.hold_s,
            rate_hz: sn.rate_hz,
        },
        tracker: s.instruments.tracker.clone(),
        instrument: s
            .instruments
            .active()
            .filter(|i| !i.own_truth_table())
            .map(|i| crate::dataset::truth::InstrumentTruth { measurement: i.measurement(), own: i.placement(sn.tool_point_m()).own }),
        tool: ToolTruth { point_mm: sn.tool_point_mm },
        noise_std_mm: if s.instruments.active().is_some() { (point_var.iter().sum::<f64>() / point_var.len().max(1) as f64).sqrt() } else { averaged },
        poses: truth_poses,
        rejected,
        glitch_rows,
    }
}

/// Stages `dataset.csv` and `truth.json` of `dir` in `outputs` (renamed into place, in that order,
/// by `outputs.commit()`). truth.json starts with a `dataset` link (file name, SHA-256 of the
/// exact dataset.csv bytes, row count) that [`crate::dataset::truth::TruthFile::find`] checks, so a
/// truth file is never trusted beside a dataset it does not describe.
pub fn stage_outputs(g: &Generated, dir: &std::path::Path, outputs: &mut crate::output::OutputSet) -> Result<()> {
    let (csv, truth) = output_texts(g)?;
    outputs.write(&dir.join(crate::dataset::DATASET_FILE), csv.as_bytes())?;
    outputs.write(&dir.join(crate::dataset::truth::TRUTH_FILE), truth.as_bytes())
}

/// The texts of `dataset.csv` and `truth.json` as [`stage_outputs`] writes them.
pub fn output_texts(g: &Generated) -> Result<(String, String)> {
    use crate::dataset::truth::DatasetLink;
    /// truth.json as written: the dataset link first, then the truth.
    #[derive(Serialize)]
    struct TruthOut<'a> {
        dataset: DatasetLink,
        #[serde(flatten)]
        truth: &'a Truth,
    }
    let csv = g.dataset.to_csv_string();
    let link = DatasetLink::of(crate::dataset::DATASET_FILE, csv.as_bytes(), g.dataset.rows.len());
    let truth = serde_json::to_string_pretty(&TruthOut { dataset: link, truth: &g.truth })
        .map_err(|e| Error::Invalid(format!("cannot serialise {}: {e}", crate::dataset::truth::TRUTH_FILE)))?;
    Ok((csv, truth))
}

/// Writes `dataset.csv` and `truth.json` into `dir`, both or neither (see [`stage_outputs`]).
pub fn write_outputs(g: &Generated, dir: &std::path::Path) -> Result<()> {
    let mut outputs = crate::output::OutputSet::new();
    stage_outputs(g, dir, &mut outputs)?;
    outputs.commit()
}
