//! An artifact's calibration judged as the issue of record asks: on the twin, the ball seated in
//! the artifact's sockets ([`crate::sim::artifact`]) or the probe touching its faces
//! ([`crate::sim::planes`]) and calibrated from those rows alone, then judged on a laser
//! tracker's points of the same arm that no fit saw, after the tracker is registered on other
//! points (an artifact never sees the base frame, so a tracker must be placed before its arm can
//! be compared with it). Beside it: the nominal arm registered the same way, and a tracker
//! calibration of the same arm from as many rows as the artifact gave.

use crate::calib::fit::ReadingFit;
use crate::calib::model::KnownSpacing;
use crate::calib::pipeline::{calibrate, samples, CalibOptions, CalibResult};
use crate::dataset::{Dataset, Split};
use crate::error::{Error, Result};
use crate::robot::Robot;
use crate::sim::scenario::Scenario;
use crate::sim::twin::acquisition::AcquisitionModel;
use serde::Serialize;

/// What one seed of [`check`] measured: the held-out tracker points' position error |Δp| (RMS
/// over the points, mm) under each model.
#[derive(Clone, Debug, Serialize)]
pub struct ArtifactCheck {
    /// The scenario's seed.
    pub seed: u64,
    /// The artifact's rows (seated, touched) its calibration trained on.
    pub artifact_rows: usize,
    /// The artifact's rows' held-out RMSE (per value: a ball's centre about its socket, a
    /// stylus' depth below its face), mm.
    pub artifact_test_rmse_mm: f64,
    /// The nominal arm, the tracker registered on its training points.
    pub nominal_mm: f64,
    /// The arm the artifact calibrated, registered the same way.
    pub artifact_mm: f64,
    /// A tracker calibration of the same arm from as many training rows as the artifact had.
    pub tracker_mm: f64,
    /// Tracker points the registration and the tracker calibration may use, and the points judged.
    pub tracker_rows: (usize, usize),
}

/// The `[sockets]` or `[planes]` scenario `s` at its seed: the artifact's rows calibrated with
/// `opts` (their stated spacings or steps added: the artifact's designed distances, as a user
/// states them), then judged on the scenario's tracker points (the same file without the
/// artifact, acquired quasi-statically).
pub fn check(s: &Scenario, robot: &Robot, opts: &CalibOptions) -> Result<ArtifactCheck> {
    check_stated(s, robot, opts, &[])
}

/// [`check`] with the designed distances stated with standard uncertainties `sd_mm` (in the
/// order the artifact lists them: the sockets' spacings, then the faces' steps; missing or
/// `None`: none stated).
pub fn check_stated(s: &Scenario, robot: &Robot, opts: &CalibOptions, sd_mm: &[Option<f64>]) -> Result<ArtifactCheck> {
    let art = crate::sim::generate::artifact_rows(s, robot).ok_or_else(|| Error::Invalid(format!("scenario {} has no [sockets] or [planes]", s.name)))??;
    let tracker = tracker_points(s, robot)?;
    let spacings = art
        .designed
        .iter()
        .enumerate()
        .map(|(k, (a, b, d))| KnownSpacing { sockets: Some((a.clone(), b.clone())), mm: *d, std_mm: sd_mm.get(k).copied().flatten() })
        .collect();
    let artifact_opts = CalibOptions { spacings, ..opts.clone() };
    let by_artifact = calibrate(&art.dataset, None, &artifact_opts)?;
    let (train, test) = (tracker.train_indices(), tracker.test_indices());
    let nominal_mm = on_tracker(&by_artifact, &by_artifact.model.nominal, &tracker)?;
    let artifact_mm = on_tracker(&by_artifact, &by_artifact.x, &tracker)?;
    // The tracker's own calibration on as many training rows as the sockets had.
    let n = by_artifact.provenance.n_train.min(train.len());
    let rows: Vec<_> =
        tracker.rows.iter().enumerate().filter(|(i, r)| r.split == Some(Split::Test) || train[..n].contains(i)).map(|(_, r)| r.clone()).collect();
    let fewer = Dataset { rows, source: format!("{} tracker", s.name) };
    let by_tracker = calibrate(&fewer, None, &CalibOptions { spacings: Vec::new(), ..opts.clone() })?;
    let tracker_mm = position_rms(&ReadingFit { model: &by_tracker.model, data: &samples(&tracker, &test) }.residuals_mm(&by_tracker.x));
    Ok(ArtifactCheck {
        seed: s.seed,
        artifact_rows: by_artifact.provenance.n_train,
        artifact_test_rmse_mm: by_artifact.evaluation.metrics.test_after.as_ref().map_or(f64::NAN, |m| m.rmse),
        nominal_mm,
        artifact_mm,
        tracker_mm,
        tracker_rows: (train.len(), test.len()),
    })
}

/// The scenario's tracker points of the same arm (the file without its artifact, acquired
/// quasi-statically).
fn tracker_points(s: &Scenario, robot: &Robot) -> Result<Dataset> {
    if s.instruments.tracker.is_none() {
        return Err(Error::Invalid(format!("scenario {} has no [tracker] to judge the artifact's calibration on", s.name)));
    }
    let mut ts = Scenario { sockets: None, planes: None, ..s.clone() };
    ts.acquisition.model = AcquisitionModel::QuasiStatic;
    Ok(crate::sim::generate::generate(&ts, robot, &crate::progress::Silent)?.dataset)
}

/// The arm of `r` at `x` judged on `tracker`'s test points (|Δp| RMS, mm), the tracker
/// registered on its training points (an artifact never sees the base frame).
fn on_tracker(r: &CalibResult, x: &[f64], tracker: &Dataset) -> Result<f64> {
    let (train, test) = (tracker.train_indices(), tracker.test_indices());
    let (model, xr) = crate::calib::pipeline::register::under_instrument(&r.model, x, tracker, &train)?;
    Ok(position_rms(&ReadingFit { model: &model, data: &samples(tracker, &test) }.residuals_mm(&xr)))
}

/// RMS over points of the position error |Δp| of residuals `r` (mm, x, y, z per point).
fn position_rms(r: &[f64]) -> f64 {
    let sq: Vec<f64> = r.chunks(3).map(|c| c.iter().map(|v| v * v).sum::<f64>()).collect();
    (sq.iter().sum::<f64>() / sq.len().max(1) as f64).sqrt()
}

/// One placement of the artifact that a calibration on another placement never saw, judged as
/// the published ball-in-socket work judges it: each socket's scatter (RMS distance of the
/// predicted ball centres of its rows from their mean) and the error of the distance between
/// the sockets' means against the stated spacing.
#[derive(Clone, Debug, Serialize)]
pub struct PlacementCheck {
    /// The scenario's seed.
    pub seed: u64,
    /// The placement the calibration trained on.
    pub trained_on: String,
    /// The placement judged.
    pub judged: String,
    /// `nominal` (the nominal arm, the ball placed on the training rows) or `twincal`.
    pub model: String,
    /// Each socket's scatter, mm, by socket label.
    pub scatter_mm: Vec<(String, f64)>,
    /// |distance between the first two sockets' means − the stated spacing|, mm.
    pub spacing_error_mm: f64,
}

/// The `[sockets]` scenario `s` at its seed, calibrated with `opts` on each placement alone and
/// judged on every other one ([`PlacementCheck`]), beside the nominal arm.
pub fn held_out_placements(s: &Scenario, robot: &Robot, opts: &CalibOptions) -> Result<Vec<PlacementCheck>> {
    let art = s.sockets.as_ref().ok_or_else(|| Error::Invalid(format!("scenario {} has no [sockets]", s.name)))?;
    let twin = crate::sim::generate::build_twin(s, robot);
    let (seated, truth) = crate::sim::artifact::seat(&twin, robot, art, s.sampling.written_decimals(), s.seed)?;
    let (a, b, stated) = truth.designed_spacings_mm.first().cloned().ok_or_else(|| Error::Invalid("the artifact needs two sockets".into()))?;
    let spacings = vec![KnownSpacing { sockets: Some((a.clone(), b.clone())), mm: stated, std_mm: None }];
    let placements: Vec<String> = (1..=art.placements.len()).map(|k| format!("p{k}")).collect();
    let mut out = Vec::new();
    for p in &placements {
        // Every row of the placement trains (the judged ones are the other placements').
        let rows =
            seated.rows.iter().filter(|r| r.station.as_deref() == Some(p)).map(|r| crate::dataset::Row { split: Some(Split::Train), ..r.clone() }).collect();
        let train = Dataset { rows, source: format!("{} {p}", s.name) };
        let r = calibrate(&train, None, &CalibOptions { spacings: spacings.clone(), ..opts.clone() })?;
        for q in placements.iter().filter(|q| *q != p) {
            for (name, x) in [("nominal", &r.model.nominal), ("twincal", &r.x)] {
                let mut w = r.model.work();
                let mut centres = |sock: &str| -> Vec<nalgebra::Vector3<f64>> {
                    seated
                        .rows
                        .iter()
                        .filter(|row| row.station.as_deref() == Some(q) && row.socket() == Some(sock))
                        .map(|row| crate::units::to_mm(r.model.tool_point(x, &row.q_deg.iter().map(|d| d.to_radians()).collect::<Vec<_>>(), &mut w)))
                        .collect()
                };
                let (ca, cb) = (centres(&a), centres(&b));
                let mean = |c: &[nalgebra::Vector3<f64>]| c.iter().sum::<nalgebra::Vector3<f64>>() / c.len().max(1) as f64;
                let scatter = |c: &[nalgebra::Vector3<f64>]| (c.iter().map(|v| (v - mean(c)).norm_squared()).sum::<f64>() / c.len().max(1) as f64).sqrt();
                out.push(PlacementCheck {
                    seed: s.seed,
                    trained_on: p.clone(),
                    judged: q.clone(),
                    model: name.into(),
                    scatter_mm: vec![(a.clone(), scatter(&ca)), (b.clone(), scatter(&cb))],
                    spacing_error_mm: ((mean(&ca) - mean(&cb)).norm() - stated).abs(),
                });
            }
        }
    }
    Ok(out)
}

/// Seated rows and a few tracker points of the same arm in one fit, judged on tracker points
/// neither fit saw: what a handful of points beside the sockets (faces) adds.
#[derive(Clone, Debug, Serialize)]
pub struct MixedCheck {
    /// The scenario's seed.
    pub seed: u64,
    /// Tracker points beside the artifact's rows.
    pub points: usize,
    /// The artifact alone, judged as [`check`] judges them (|Δp| RMS, mm).
    pub artifact_mm: f64,
    /// The artifact and the points in one fit: the held-out tracker points' |Δp| RMS, mm.
    pub mixed_mm: f64,
    /// The first placement's spacing as the mixed fit found it, and as the artifact was made
    /// (at its temperature), mm.
    pub spacing_fitted_mm: f64,
    /// See `spacing_fitted_mm`.
    pub spacing_made_mm: f64,
}

/// The `[sockets]` or `[planes]` scenario `s` at its seed: its artifact's rows with the first
/// `points` training points of its tracker (the same arm) in one file, calibrated with `opts`
/// and judged on the tracker's test points; beside the artifact alone ([`check`]).
pub fn mixed(s: &Scenario, robot: &Robot, opts: &CalibOptions, points: usize) -> Result<MixedCheck> {
    let art = crate::sim::generate::artifact_rows(s, robot).ok_or_else(|| Error::Invalid(format!("scenario {} has no [sockets] or [planes]", s.name)))??;
    let alone = check(s, robot, opts)?;
    let seated = &art.dataset;
    let tracker = tracker_points(s, robot)?;
    let beside: Vec<_> = tracker.rows.iter().filter(|r| r.split == Some(Split::Train)).take(points).cloned().collect();
    let judged: Vec<_> = tracker.rows.iter().filter(|r| r.split == Some(Split::Test)).cloned().collect();
    let train: Vec<_> = seated.rows.iter().map(|r| crate::dataset::Row { split: Some(Split::Train), ..r.clone() }).chain(beside).collect();
    let n_train = train.len();
    let both = Dataset { rows: train.into_iter().chain(judged).collect(), source: format!("{} sockets and points", s.name) };
    let spacings: Vec<KnownSpacing> =
        art.designed.iter().map(|(a, b, d)| KnownSpacing { sockets: Some((a.clone(), b.clone())), mm: *d, std_mm: None }).collect();
    let r = calibrate(&both, None, &CalibOptions { spacings, ..opts.clone() })?;
    let test: Vec<usize> = (n_train..both.rows.len()).collect();
    let mixed_mm = position_rms(&ReadingFit { model: &r.model, data: &samples(&both, &test) }.residuals_mm(&r.x));
    // (The samples of `both` number its rows as the model does: the same dataset.)
    Ok(MixedCheck {
        seed: s.seed,
        points,
        artifact_mm: alone.artifact_mm,
        mixed_mm,
        spacing_fitted_mm: if r.model.spacings.is_empty() { f64::NAN } else { r.model.spacing_mm(&r.x, 0) },
        spacing_made_mm: art.made.first().map_or(f64::NAN, |s| s.2),
    })
}

/// An artifact's plan verified by seating on the twin: the planned seatings and random sets of
/// as many, each made on the true arm, calibrated alone and judged on the tracker's points no fit
/// saw (|Δp| RMS, mm).
#[derive(Clone, Debug, Serialize)]
pub struct PlanCheck {
    /// The scenario's seed (the true arm and the candidates).
    pub seed: u64,
    /// Seatings planned.
    pub n: usize,
    /// The arm calibrated on the planned seatings.
    pub planned_mm: f64,
    /// The arm calibrated on each random set of `n` of the plan's candidates.
    pub random_mm: Vec<f64>,
    /// Planned seatings the true arm could not make within its joint limits (skipped).
    pub planned_skipped: usize,
    /// The same over every random set.
    pub random_skipped: usize,
}

/// The plan `opts` of the `[sockets]` scenario `s` verified by seating on the twin (the true arm
/// of seed `opts.seed`): the planned seatings made as an operator makes them
/// ([`crate::sim::artifact::seat_planned`]: the arm jogged to the planned joints, the ball pushed
/// into its socket), and `random` random sets of as many of the plan's candidates made the same
/// way ([`spread_set`]: as an engineer seats without a plan, as many in each socket); each
/// calibrated with `copts` (the designed spacings stated) and judged on the tracker points
/// ([`check`]'s).
pub fn plan_check(s: &Scenario, robot: &Robot, opts: &crate::plan::PlanOptions, copts: &CalibOptions, random: usize) -> Result<PlanCheck> {
    let art = s.sockets.as_ref().ok_or_else(|| Error::Invalid(format!("scenario {}: a plan is verified by seating on the twin for [sockets]", s.name)))?;
    let plan = crate::plan::artifact::plan(s, robot, opts)?;
    let candidates = crate::plan::artifact::nominal_candidates(s, robot, crate::plan::artifact::per_feature(s, opts.candidates)?, opts.seed)?;
    let seating = |i: usize| -> Result<crate::sim::artifact::PlannedSeating> {
        let row = &candidates.rows[i];
        let pi = row.station.as_deref().and_then(crate::sim::artifact::placement_index);
        let k = row.feature.as_ref().and_then(|f| (0..art.layout_mm.len()).find(|&k| art.label(k) == f.label));
        match (pi, k) {
            (Some(pi), Some(k)) => Ok((pi, k, plan.candidates.q[i].clone())),
            _ => Err(Error::Invalid(format!("candidate {} names no placement and socket of the artifact", i + 1))),
        }
    };
    let truth = Scenario { seed: opts.seed, ..s.clone() };
    let twin = crate::sim::generate::build_twin(&truth, robot);
    let tracker = tracker_points(&truth, robot)?;
    let spacings: Vec<KnownSpacing> =
        art.designed_spacings_mm().into_iter().map(|(a, b, d)| KnownSpacing { sockets: Some((a, b)), mm: d, std_mm: None }).collect();
    let copts = CalibOptions { spacings, ..copts.clone() };
    let judged = |set: &[usize]| -> Result<(f64, usize)> {
        let planned = set.iter().map(|&i| seating(i)).collect::<Result<Vec<_>>>()?;
        let (data, skipped) = crate::sim::artifact::seat_planned(&twin, robot, art, truth.sampling.written_decimals(), truth.seed, &planned)?;
        let r = calibrate(&data, None, &copts)?;
        Ok((on_tracker(&r, &r.x, &tracker)?, skipped.len()))
    };
    let n = plan.design.chosen.len();
    let (planned_mm, planned_skipped) = judged(&plan.design.chosen)?;
    let random: Vec<(f64, usize)> = (0..random)
        .map(|k| judged(&spread_set(&candidates, n, crate::seed::stream_seed(opts.seed, crate::seed::Stream::Plan, 3_000_000 + k as u64))))
        .collect::<Result<_>>()?;
    Ok(PlanCheck {
        seed: opts.seed,
        n,
        planned_mm,
        random_mm: random.iter().map(|r| r.0).collect(),
        planned_skipped,
        random_skipped: random.iter().map(|r| r.1).sum(),
    })
}

/// `n` rows of `data` drawn at random as evenly over its stations (each socket or face at each
/// placement) as `n` allows: each station's rows shuffled (seed `seed`), then taken a station at
/// a time in turn.
pub fn spread_set(data: &Dataset, n: usize, seed: u64) -> Vec<usize> {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let mut groups: std::collections::BTreeMap<String, Vec<usize>> = std::collections::BTreeMap::new();
    for (i, r) in data.rows.iter().enumerate() {
        let label = crate::calib::pipeline::setup::label_of(r, crate::calib::model::SetupKind::Station).unwrap_or_default();
        groups.entry(label).or_default().push(i);
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut groups: Vec<Vec<usize>> = groups.into_values().collect();
    groups.iter_mut().for_each(|g| g.shuffle(&mut rng));
    let mut out = Vec::with_capacity(n);
    for k in 0.. {
        let before = out.len();
        out.extend(groups.iter().filter_map(|g| g.get(k)).take(n - out.len()));
        if out.len() == n || out.len() == before {
            break;
        }
    }
    out.sort_unstable();
    out
}
