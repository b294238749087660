//! A plan verified on the twin, not assumed: for each seed the twin (its true geometry and
//! effects drawn from the seed) measures the planned poses and random feasible sets of several
//! sizes; each set is calibrated alone; each calibrated model's true error is measured on
//! independent test poses.
//!
//! The true error of a model: its tool point at a test pose (its own prediction, with its
//! effects), against the twin's true tool point there, after the rigid registration of the
//! model's base frame to the twin's made on the model's own calibration poses (as an accuracy
//! test registers a robot: no measurement of the arm fixes where it stands in the cell). RMS
//! over the test poses, mm. The test poses are feasible poses drawn from a stream of their own,
//! none of them a row of any calibration.

use super::{candidates, plan, random_set, PlanOptions};
use crate::calib::pipeline::{calibrate, CalibOptions, Method, ModelSpec};
use crate::compensate::{nominal_x, Compensator};
use crate::error::{Error, Result};
use crate::robot::Robot;
use crate::seed::{stream_seed, Stream};
use crate::sim::generate::{generate_at, Silent};
use crate::sim::pose_list::PoseList;
use crate::sim::scenario::Scenario;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// The twin's true tool points (mm) at `poses` (rad; with `payloads`, each measured under its
/// own payload, one payload after the other), `None` where it refused one.
fn true_tool(s: &Scenario, robot: &Robot, poses: &[Vec<f64>], payloads: Option<&[f64]>) -> Result<(crate::dataset::Dataset, Vec<Option<Vector3<f64>>>)> {
    let g = match payloads {
        None => generate_at(s, robot, poses.to_vec(), None, &Silent)?,
        Some(p) => crate::sim::pose_list::generate_pose_list(s, robot, PoseList { q: poses.to_vec(), payload_kg: Some(p.to_vec()) }, &Silent)?,
    };
    let mut out = vec![None; poses.len()];
    for p in &g.truth.poses {
        out[p.index] = Some(Vector3::from(p.tool_mm));
    }
    Ok((g.dataset, out))
}

/// The scenario measuring every pose given it, none held out, no glitch.
fn all_train(s: &Scenario, seed: u64, n: usize) -> Scenario {
    let mut s = s.clone();
    s.seed = seed;
    s.sampling.poses = n;
    s.sampling.test = 0;
    s.glitches = None;
    s
}

/// Test poses (rad) and the twin's true tool points there (mm).
pub type TestSet = (Vec<Vec<f64>>, Vec<Vector3<f64>>);

/// The independent test poses of `seed` (`count` feasible poses from a stream of their own) and
/// the twin's true tool points there (mm); poses the twin refused are left out.
fn test_set(s: &Scenario, robot: &Robot, seed: u64, count: usize) -> Result<TestSet> {
    let test_q = candidates(s, robot, count, stream_seed(seed, Stream::Plan, 1_000_000))?.q;
    let (_, truth) = true_tool(&all_train(s, seed, test_q.len()), robot, &test_q, None)?;
    let test: TestSet = test_q.iter().zip(&truth).filter_map(|(q, t)| t.map(|t| (q.clone(), t))).unzip();
    if test.0.is_empty() {
        return Err(Error::Invalid(format!("seed {seed}: the twin refused every test pose")));
    }
    Ok(test)
}

/// `k` poses drawn at random from the plan's candidate `pool` (seeded by `seed` and `k`): the
/// random feasible set a plan of the same constraints is compared with.
fn random_poses(pool: &[Vec<f64>], k: usize, seed: u64) -> Vec<Vec<f64>> {
    random_set(pool.len(), k, stream_seed(seed, Stream::Plan, 2_000_000 + k as u64)).iter().map(|&i| pool[i].clone()).collect()
}

/// The true error (RMS over the test poses, mm) of the model calibrated on the twin's readings at
/// `poses`; `test` holds the test poses and the twin's true tool points there.
pub fn true_error(s: &Scenario, robot: &Robot, opts: &CalibOptions, poses: &[Vec<f64>], payloads: Option<&[f64]>, test: &TestSet) -> Result<f64> {
    let (data, truth) = true_tool(&all_train(s, s.seed, poses.len()), robot, poses, payloads)?;
    error_of(&data, &truth, opts, test)
}

/// [`true_error`] of the twin's readings `data` already taken, with its true tool points
/// `truth` at the poses (`None` where it refused one).
fn error_of(data: &crate::dataset::Dataset, truth: &[Option<Vector3<f64>>], opts: &CalibOptions, test: &TestSet) -> Result<f64> {
    let r = calibrate(data, None, opts)?;
    let x_nom = nominal_x(&r);
    let c = Compensator::new(&r, &x_nom, r.torque_model.clone(), 0.001, 0.001)?;
    // The registration on the calibration's own rows, each predicted under its own payload (the
    // rows are the poses the twin measured, in order).
    let reg_true: Vec<Vector3<f64>> = truth.iter().flatten().copied().collect();
    let inputs = crate::calib::effects::inputs::row_inputs(data, r.torque_model.as_ref());
    let mut w = r.model.work();
    let predicted: Vec<Vector3<f64>> = data
        .rows
        .iter()
        .zip(&inputs)
        .map(|(row, inp)| crate::units::to_mm(r.model.tool_point_with(&r.x, &row.q_deg.iter().map(|d| d.to_radians()).collect::<Vec<_>>(), inp, &mut w)))
        .collect();
    if predicted.len() != reg_true.len() {
        return Err(Error::Invalid(format!("{} rows for {} measured poses", predicted.len(), reg_true.len())));
    }
    let (rot, tr) = crate::ik::rigid_fit(&reg_true, &predicted);
    let sq: Vec<f64> = test.0.iter().zip(&test.1).map(|(q, t)| (rot * t + tr - c.predicted(q)).norm_squared()).collect();
    Ok((sq.iter().sum::<f64>() / sq.len().max(1) as f64).sqrt())
}

/// One seed's comparison at one N.
#[derive(Clone, Debug, Serialize)]
pub struct SeedRow {
    /// The scenario's seed (the twin's truth and the pool).
    pub seed: u64,
    /// The planned poses' true error, mm.
    pub planned_mm: f64,
    /// Random feasible sets' true errors, mm, one per size in [`Comparison::random_sizes`].
    pub random_mm: Vec<f64>,
    /// The random feasible poses the plan is worth, predicted by its mean prediction variance
    /// ([`super::bound::Ceiling::plan_worth`]).
    pub predicted_plan_worth: Option<usize>,
    /// The most random feasible poses any set of N poses of the pool is worth, predicted
    /// ([`super::bound::Ceiling::best_worth`]).
    pub predicted_best_worth: Option<usize>,
}

/// Planned against random at one N, over the seeds.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Poses planned.
    pub n: usize,
    /// The sizes of the random sets compared.
    pub random_sizes: Vec<usize>,
    /// Per seed.
    pub seeds: Vec<SeedRow>,
    /// Median over the seeds of the planned error, mm.
    pub planned_median_mm: f64,
    /// Median over the seeds of each random size's error, mm.
    pub random_median_mm: Vec<f64>,
    /// The fewest random poses (of the sizes tried) whose median error is at most the plan's;
    /// `None` when no size tried reaches it.
    pub random_poses_to_match: Option<usize>,
    /// Median over the seeds of [`SeedRow::predicted_plan_worth`] (a seed beyond the search
    /// counts as more than any; `None` when the median is beyond it).
    pub predicted_plan_worth: Option<f64>,
    /// Median over the seeds of [`SeedRow::predicted_best_worth`].
    pub predicted_best_worth: Option<f64>,
}

/// What the study runs.
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Plan sizes.
    pub ns: Vec<usize>,
    /// Random set sizes, as multiples of N (rounded to whole poses).
    pub multiples: Vec<f64>,
    /// Seeds.
    pub seeds: Vec<u64>,
    /// Test poses per seed.
    pub test_poses: usize,
    /// The plan's options (its `n` and `seed` are set per run).
    pub plan: PlanOptions,
}

/// Plans and random sets compared on the twin of `s` (see the module docs).
pub fn study(s: &Scenario, robot: &Robot, o: &StudyOptions) -> Result<Vec<Comparison>> {
    let calib = CalibOptions::new(ModelSpec::nominal(robot.clone(), o.plan.parametrisation), Method::LM);
    let mut out = Vec::new();
    for &n in &o.ns {
        let sizes: Vec<usize> = o.multiples.iter().map(|m| (m * n as f64).round().max(1.0) as usize).collect();
        let mut rows = Vec::new();
        for &seed in &o.seeds {
            let s = all_train(s, seed, n);
            let test = test_set(&s, robot, seed, o.test_poses)?;
            let p = plan(&s, robot, &PlanOptions { n, seed, ..o.plan.clone() })?;
            let planned_mm = true_error(&s, robot, &calib, &p.poses, p.payload_kg.as_deref(), &test)?;
            let random_mm =
                sizes.iter().map(|&k| true_error(&s, robot, &calib, &random_poses(&p.candidates.q, k, seed), None, &test)).collect::<Result<Vec<f64>>>()?;
            let ce = p.ceiling.as_ref();
            rows.push(SeedRow {
                seed,
                planned_mm,
                random_mm,
                predicted_plan_worth: ce.and_then(|c| c.plan_worth),
                predicted_best_worth: ce.and_then(|c| c.best_worth),
            });
        }
        let med = |f: &dyn Fn(&SeedRow) -> f64| crate::stats::median(&rows.iter().map(f).collect::<Vec<f64>>());
        let planned_median_mm = med(&|r| r.planned_mm);
        let random_median_mm: Vec<f64> = (0..sizes.len()).map(|k| med(&|r| r.random_mm[k])).collect();
        let random_poses_to_match = sizes.iter().zip(&random_median_mm).find(|(_, e)| **e <= planned_median_mm).map(|(k, _)| *k);
        // A seed whose search passed 8 N counts as beyond it (an infinite worth): the median
        // is then beyond 8 N when half the seeds are.
        let worth = |f: &dyn Fn(&SeedRow) -> Option<usize>| {
            let v: Vec<f64> = rows.iter().map(|r| f(r).map_or(f64::INFINITY, |k| k as f64)).collect();
            Some(crate::stats::median(&v)).filter(|m| m.is_finite())
        };
        let (predicted_plan_worth, predicted_best_worth) = (worth(&|r| r.predicted_plan_worth), worth(&|r| r.predicted_best_worth));
        out.push(Comparison {
            n,
            random_sizes: sizes,
            seeds: rows,
            planned_median_mm,
            random_median_mm,
            random_poses_to_match,
            predicted_plan_worth,
            predicted_best_worth,
        });
    }
    Ok(out)
}

/// What a diagnosis and an extended calibration make of one set of poses with an effect hidden
/// in the twin.
#[derive(Clone, Debug, Serialize)]
pub struct EffectCheck {
    /// The joints (1-based) `diagnose` named the effect on, with its size and standard
    /// uncertainty in the diagnosis's unit.
    pub named: Vec<(usize, f64, f64)>,
    /// The other causes `diagnose` named (`kind[jJ]`): what the set made it see that is not there.
    pub others: Vec<String>,
    /// The true error (mm, as [`true_error`]) of the calibration that fits the effect.
    pub true_error_mm: f64,
}

/// One seed of the hidden-effect comparison.
#[derive(Clone, Debug, Serialize)]
pub struct HiddenRow {
    /// The seed.
    pub seed: u64,
    /// The planned poses (the plan includes the effect's parameters).
    pub planned: EffectCheck,
    /// A random feasible set of the same size, at the scenario's payload.
    pub random: EffectCheck,
    /// With payloads to choose from: the same random set, each pose under a payload drawn at
    /// random from them, measured one payload after the other.
    pub random_payloads: Option<EffectCheck>,
}

/// Diagnoses and calibrates the twin's readings at `poses`, for the effect `kind`.
fn effect_check(
    s: &Scenario,
    robot: &Robot,
    kind: crate::calib::effects::EffectKind,
    loads: &crate::calib::effects::inputs::JointLoads,
    poses: &[Vec<f64>],
    payloads: Option<&[f64]>,
    test: &TestSet,
) -> Result<EffectCheck> {
    let spec = ModelSpec::nominal(robot.clone(), crate::calib::model::Parametrisation::Hayati);
    // One acquisition serves the diagnosis and the calibration.
    let (data, truth) = true_tool(&all_train(s, s.seed, poses.len()), robot, poses, payloads)?;
    let mut d = crate::diagnose::DiagnoseOptions::new(spec.clone());
    d.loads.joints = loads.clone();
    d.seed = s.seed;
    let (diag, _) = crate::diagnose::diagnose(&data, &d, &|_| {})?;
    let named = diag.causes.iter().filter(|c| c.cause == kind).map(|c| (c.joint.unwrap_or(0), c.magnitude, c.uncertainty)).collect();
    let others = diag.causes.iter().filter(|c| c.cause != kind).map(|c| c.label()).collect();
    let mut calib = CalibOptions::new(spec, Method::LM);
    calib.effects = vec![(kind, None)];
    calib.loads.joints = loads.clone();
    Ok(EffectCheck { named, others, true_error_mm: error_of(&data, &truth, &calib, test)? })
}

/// With an effect hidden in the twin of `s` (its scenario holds it; the plan and the
/// calibration are told only its kind, as an engineer suspecting it would be): per seed, a
/// plan of `n` poses that includes the effect's parameters against a random feasible set of
/// `n`, each diagnosed (does it name the effect, on which joints, how big?) and calibrated with
/// the effect (true error on independent test poses).
pub fn hidden_effect(s: &Scenario, robot: &Robot, n: usize, seeds: &[u64], test_poses: usize, o: &PlanOptions) -> Result<Vec<HiddenRow>> {
    let [(kind, _)] = o.effects[..] else {
        return Err(Error::Invalid("the hidden-effect comparison plans for exactly one effect kind".into()));
    };
    let mut rows = Vec::new();
    for &seed in seeds {
        let s = all_train(s, seed, n);
        let test = test_set(&s, robot, seed, test_poses)?;
        let p = plan(&s, robot, &PlanOptions { n, seed, ..o.clone() })?;
        let random = random_poses(&p.candidates.q, n, seed);
        let drawn: Option<Vec<f64>> = (!o.payloads.is_empty()).then(|| {
            let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, Stream::Plan, 1000));
            (0..n).map(|_| o.payloads[rng.random_range(0..o.payloads.len())]).collect()
        });
        rows.push(HiddenRow {
            seed,
            planned: effect_check(&s, robot, kind, &o.loads, &p.poses, p.payload_kg.as_deref(), &test)?,
            random: effect_check(&s, robot, kind, &o.loads, &random, None, &test)?,
            random_payloads: drawn
                .map(|d| {
                    // Measured as the plan is: one payload after the other (in --payloads' order).
                    let mut order: Vec<usize> = (0..n).collect();
                    order.sort_by_key(|&i| o.payloads.iter().position(|m| *m == d[i]));
                    let (q, m): (Vec<Vec<f64>>, Vec<f64>) = order.iter().map(|&i| (random[i].clone(), d[i])).unzip();
                    effect_check(&s, robot, kind, &o.loads, &q, Some(&m), &test)
                })
                .transpose()?,
        });
    }
    Ok(rows)
}
