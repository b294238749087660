//! A plan for an artifact (`[sockets]` or `[planes]` in the scenario): which seated
//! configurations (touches) to record, at which of the artifact's placements and features,
//! before the arm is touched. The candidates are the artifact's own acquisition on the nominal
//! arm (no deviation, no effect: the plan never sees the truth), many per feature of every
//! placement the scenario offers — the tool turned about the ball, tilted on a face, a 7-joint
//! arm's elbow swept through its null space. The calibration model is placed on them as a
//! calibration places it (each socket or face a station, the stated spacings), and the design
//! chooses among them as [`super::plan`] chooses poses: the same criteria, the same bound, the
//! same comparison with random sets. The tour keeps each placement's rows together (the
//! artifact is moved once per placement).

use super::{bound, criterion, design, median_indices, pool_design, random_set, tour, Candidates, Indices, Model, Plan, PlanOptions, RANDOM_SETS};
use crate::calib::pipeline::{placement::place_sensor, samples, CalibOptions, Method, ModelSpec};
use crate::error::{Error, Result};
use crate::robot::Robot;
use crate::seed::{stream_seed, Stream};
use crate::sim::scenario::Scenario;

/// Most candidates drawn per feature of each placement.
pub const MAX_PER_FEATURE: usize = 400;

/// Scenario `s` with its artifact acquired `per_feature` times per feature of each placement,
/// every row a training row: the pool's acquisition (on the nominal arm, the candidates; on the
/// true arm with the same seed, the same draws as measured).
pub fn with_per_feature(s: &Scenario, per_feature: usize) -> Scenario {
    let mut out = s.clone();
    if let Some(a) = out.sockets.as_mut() {
        a.per_socket = per_feature;
        a.test_fraction = 0.0;
    }
    if let Some(a) = out.planes.as_mut() {
        a.per_face = per_feature;
        a.test_fraction = 0.0;
    }
    out
}

/// Configurations drawn per feature of each placement for about `candidates` in all.
pub fn per_feature(s: &Scenario, candidates: usize) -> Result<usize> {
    let (placements, features) = match (&s.sockets, &s.planes) {
        (Some(a), _) => (a.placements.len(), a.layout_mm.len()),
        (_, Some(a)) => (a.placements.len(), a.faces.len()),
        _ => return Err(Error::Invalid(format!("scenario {} has no artifact", s.name))),
    };
    Ok(candidates.div_ceil((placements * features).max(1)).clamp(crate::measurement::plane::MIN_ROWS_PER_FACE, MAX_PER_FEATURE))
}

/// The scenario's artifact seated `per_feature` times per feature on the nominal arm, with seed
/// `seed`: the candidates.
pub(crate) fn nominal_candidates(s: &Scenario, robot: &Robot, per_feature: usize, seed: u64) -> Result<crate::dataset::Dataset> {
    let nominal = Scenario { geometry: Default::default(), effects: Default::default(), seed, ..with_per_feature(s, per_feature) };
    let rows = crate::sim::generate::artifact_rows(&nominal, robot).ok_or_else(|| Error::Invalid(format!("scenario {} has no artifact", s.name)))??;
    Ok(rows.dataset)
}

/// The plan of `opts.n` configurations among about `opts.candidates` for the scenario's
/// artifact (see the module).
pub fn plan(s: &Scenario, robot: &Robot, opts: &PlanOptions) -> Result<Plan> {
    let t0 = std::time::Instant::now();
    let crit = criterion(&opts.criterion)?;
    if opts.calibrated.is_some() || !opts.effects.is_empty() || !opts.payloads.is_empty() {
        return Err(Error::Invalid("an artifact's plan designs for the geometry: not with --model, --effects or --payloads".into()));
    }
    let data = nominal_candidates(s, robot, per_feature(s, opts.candidates)?, opts.seed)?;
    if data.rows.len() < opts.n {
        return Err(Error::Invalid(format!("{} candidate configurations for {} asked: ask for fewer", data.rows.len(), opts.n)));
    }
    // The distances the user states, as designed (the artifact's drawing, not as made).
    let designed = match (&s.sockets, &s.planes) {
        (Some(a), _) => a.designed_spacings_mm(),
        (_, Some(a)) => a.designed_steps_mm(),
        _ => Vec::new(),
    };
    let copts = CalibOptions {
        spacings: designed.iter().map(|(a, b, d)| crate::calib::model::KnownSpacing { sockets: Some((a.clone(), b.clone())), mm: *d, std_mm: None }).collect(),
        ..CalibOptions::new(ModelSpec::nominal(robot.clone(), opts.parametrisation), Method::LM)
    };
    let all = samples(&data, &(0..data.rows.len()).collect::<Vec<_>>());
    let placed = place_sensor(&copts, &all, [&data.stations().labels, &data.mounts().labels])?;
    let model = Model { x: placed.nominal.clone(), stations: all.inputs.iter().map(|i| i.station).collect(), model: placed, torque: None };
    let prob = pool_design(&model, &all.q, None);
    let mut d = design::design(&prob.pool, opts.n, crit, opts.max_sweeps);
    let labels: Vec<String> =
        data.rows.iter().map(|r| crate::calib::pipeline::setup::label_of(r, crate::calib::model::SetupKind::Station).unwrap_or_default()).collect();
    let short_note = full_features(&prob.pool, &mut d, &data, &labels, crit);
    // The tour: placement after placement (the artifact moved once each), each ordered.
    let motion = tour::Motion::new(robot, s.sampling.speed_fraction, s.acquisition.ramp_s, s.draw_wire.hold_s + s.draw_wire.window_s());
    let home = vec![0.0; robot.dof()];
    let mut order: Vec<String> = Vec::new();
    data.rows.iter().filter_map(|r| r.station.clone()).for_each(|p| {
        if !order.contains(&p) {
            order.push(p)
        }
    });
    let mut toured = Vec::with_capacity(d.chosen.len());
    for p in &order {
        let group: Vec<usize> = d.chosen.iter().copied().filter(|&c| data.rows[c].station.as_ref() == Some(p)).collect();
        let qs: Vec<Vec<f64>> = group.iter().map(|&c| all.q[c].clone()).collect();
        toured.extend(motion.order(&home, &qs).into_iter().map(|i| group[i]));
    }
    let poses: Vec<Vec<f64>> = toured.iter().map(|&c| all.q[c].clone()).collect();
    let chosen: Vec<Vec<f64>> = d.chosen.iter().map(|&c| all.q[c].clone()).collect();
    let indices = Indices::of(&prob.pool, &d.chosen);
    let (ceiling, ceiling_note) = match bound::ceiling(&prob.pool, &d.chosen, indices.i_prediction_variance, opts.seed) {
        Ok(c) => (Some(c), None),
        Err(why) => (None, Some(why)),
    };
    let sets: Vec<Vec<usize>> = (0..RANDOM_SETS).map(|k| random_set(all.len(), opts.n, stream_seed(opts.seed, Stream::Plan, 1 + k as u64))).collect();
    let mut warnings = Vec::new();
    warnings.extend(short_note);
    let used: std::collections::BTreeSet<&str> = toured.iter().filter_map(|&c| data.rows[c].station.as_deref()).collect();
    if used.len() < order.len() {
        warnings.push(format!(
            "the design uses {} of the {} placements offered ({}): the others add nothing the chosen ones do not see",
            used.len(),
            order.len(),
            used.iter().copied().collect::<Vec<_>>().join(", ")
        ));
    }
    Ok(Plan {
        scenario: s.name.clone(),
        robot: robot.name.clone(),
        measurement: model.model.measurement.name().to_string(),
        parametrisation: opts.parametrisation.name().to_string(),
        criterion: crit.name().to_string(),
        criterion_describe: crit.describe().to_string(),
        seed: opts.seed,
        identifiable: prob.identifiable.clone(),
        fixed: prob.fixed.clone(),
        poses_deg: poses.iter().map(|q| q.iter().map(|v| crate::units::round_decimals(v.to_degrees(), s.sampling.angle_decimals)).collect()).collect(),
        payload_kg: None,
        indices,
        ceiling,
        ceiling_note,
        warnings,
        random_median: median_indices(&prob.pool, &sets),
        tour: motion.time(&home, &poses),
        unordered: motion.time(&home, &chosen),
        features: Some(toured.iter().map(|&c| labels[c].clone()).collect()),
        poses,
        candidates: Candidates { q: all.q.clone(), drawn: all.len(), refused: Default::default() },
        design: d,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Every socket (face) the design `d` seats in seated as often as a calibration needs to place
/// it ([`design::with_full_groups`], the candidates grouped by their `labels`); the warning
/// naming those that were held too few, if any.
fn full_features(
    pool: &super::design::Pool,
    d: &mut super::design::Design,
    data: &crate::dataset::Dataset,
    labels: &[String],
    crit: &dyn super::design::Criterion,
) -> Option<String> {
    let mut names: Vec<&String> = labels.iter().collect();
    names.sort_unstable();
    names.dedup();
    let group: Vec<usize> = labels.iter().map(|l| names.binary_search(&l).expect("every label is listed")).collect();
    let mut min = vec![crate::measurement::socket::MIN_ROWS_PER_SOCKET; names.len()];
    for (row, &g) in data.rows.iter().zip(&group) {
        if row.feature.as_ref().is_some_and(|f| f.kind == crate::measurement::FeatureKind::Plane) {
            min[g] = crate::measurement::plane::MIN_ROWS_PER_FACE;
        }
    }
    let short = design::with_full_groups(pool, d, &group, &min, crit);
    (!short.is_empty()).then(|| {
        let said: Vec<String> = short.iter().map(|(g, k)| format!("{} ({k} of {})", names[*g], min[*g])).collect();
        format!("the design held fewer rows than a calibration needs to place a socket (face) at {}: those rows went to the others", said.join(", "))
    })
}
