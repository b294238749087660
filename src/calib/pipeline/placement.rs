//! Pipeline stage "sensor placement": the starting model of a calibration. For an arm with a
//! nominal description, the draw-wire's exit point and length offset by multilateration from the
//! nominal tool points, then exit point, offset and tool point by a sensor-only least-squares fit;
//! for the generic arm, a global search for the whole structure ([`crate::calib::pipeline::generic`]).

use super::generic::SearchReport;
use super::options::{CalibOptions, ModelSpec, Parametrisation};
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::{CalibModel, DrawWireGuess, Placement, SetupKind};
use crate::error::{Error, Result};
use crate::measurement::Measurement;
use crate::optim::{LevenbergMarquardt, NoObserver};

/// The calibration model of `spec` with the sensor at `guess`.
pub fn build_model(spec: &ModelSpec, guess: &DrawWireGuess) -> CalibModel {
    match spec {
        ModelSpec::Nominal { robot, parametrisation } => match parametrisation {
            Parametrisation::Frame => CalibModel::frame(robot, guess),
            Parametrisation::Dh => CalibModel::dh(robot, guess, false),
            Parametrisation::Hayati => CalibModel::dh(robot, guess, true),
        },
        ModelSpec::Generic => CalibModel::generic(6, guess),
    }
}

/// The starting model: nominal geometry and a sensor guess (given, or multilaterated and
/// aligned), or for the generic model a global search from broad bounds. Another instrument
/// than the draw-wire (a tracker's points) is located from the nominal flange points
/// ([`Placing::locate`](crate::measurement::Placing::locate)) and aligned the same way.
/// With several stations or mounts (`labels`: the stations', then the mounts'; the rows'
/// [`RowInputs`](crate::calib::effects::RowInputs) index them), each station is located from its
/// own training rows, each mount of a 6-D probe from its rows at their most common station (a
/// point's target starts at the first mount's), and all are aligned together.
pub fn place_sensor(opts: &CalibOptions, train: &Samples, labels: [&[String]; 2]) -> Result<CalibModel> {
    place(opts, train, labels).map(|(m, _)| m)
}

/// [`place_sensor`] with what the generic model's search did (`None` for a nominal arm).
pub fn place(opts: &CalibOptions, train: &Samples, labels: [&[String]; 2]) -> Result<(CalibModel, Option<SearchReport>)> {
    let stations = labels[0];
    let spec = &opts.model;
    let zero_guess = DrawWireGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
    let measurement = train.measurement;
    refuse_cable_options(opts, measurement)?;
    if measurement == Measurement::Length && !matches!(spec, ModelSpec::Nominal { .. }) {
        return generic_cable(opts, train, labels);
    }
    // The arm: the nominal's, or the generic search's on the first station's and mount's rows
    // (whose placement it found with the arm).
    let (m, searched, report) = match spec {
        ModelSpec::Nominal { .. } => (build_model(spec, &zero_guess), None, None),
        ModelSpec::Generic => {
            let rows: Vec<usize> = (0..train.len()).filter(|i| train.inputs[*i].station == 0 && train.inputs[*i].mount == 0).collect();
            let s = super::generic::search(&train.subset(&rows), &search_settings(opts))?;
            let p = s.model.placement(&s.model.nominal);
            (s.model, Some(p), Some(s.report))
        }
    };
    let mut w = m.work();
    let flanges: Vec<_> = train.q.iter().map(|q| m.flange_frame(&m.nominal, q, &mut w)).collect();
    // A point's other stations are located from the target points of the arm as found (a
    // nominal arm's target starts at the flange's origin; a generic arm's is far from it).
    let target = match (&searched, measurement) {
        (Some(p), Measurement::Point) => p.tool,
        _ => nalgebra::Vector3::zeros(),
    };
    let locate = |rows: &[usize], label: String| -> Result<Placement> {
        let pts: Vec<_> = rows.iter().map(|&i| flanges[i].point(&target)).collect();
        let rots: Vec<_> = rows.iter().map(|&i| flanges[i].rot).collect();
        let y: Vec<f64> = rows.iter().flat_map(|&i| train.y[i * train.dim..(i + 1) * train.dim].iter().copied()).collect();
        let (own, tool) = measurement.def().locate(&pts, &rots, &y).ok_or_else(|| not_located(measurement, &label, rows.len()))?;
        Ok(Placement { measurement, own, tool })
    };
    // (The first instrument's rows: a second one beside it is placed after, unless it stands
    // at stations of the same list: faces touched by the ball seated in the sockets.)
    let shared = train.also.filter(|a| measurement.shares_stations_with(*a));
    let own_row = |i: &usize| train.inputs[*i].instrument == 0 || shared.is_some();
    let instrument_at = |s: usize| station_instrument(train, shared, s);
    let rows_of = |kind: SetupKind, s: usize| -> Vec<usize> { (0..train.len()).filter(own_row).filter(|i| kind.of(&train.inputs[*i]) == s).collect() };
    let at = |kind: SetupKind, s: usize| labels[usize::from(kind == SetupKind::Mount)].get(s).map_or(String::new(), |l| format!(" at {} {l}", kind.name()));
    // The first station and mount together: the rows of both.
    let first_rows: Vec<usize> = (0..train.len()).filter(own_row).filter(|i| train.inputs[*i].station == 0 && train.inputs[*i].mount == 0).collect();
    // An artifact's features (each a station) share the target: where the instrument finds it
    // from every station's rows together (a stylus touching several faces), each station is
    // placed about it.
    let artifact = searched.is_none() && measurement.feature().is_some();
    let station_rows = |s: usize| seen_from(&flanges, train, &rows_of(SetupKind::Station, s), instrument_at(s).dim());
    let target = artifact.then(|| measurement.def().locate_target(&(0..stations.len().max(1)).map(station_rows).collect::<Vec<_>>())).flatten();
    let about = |s: usize, tool: &nalgebra::Vector3<f64>| -> Option<Placement> {
        if !artifact {
            return None;
        }
        let (pts, rots, y) = station_rows(s);
        let at = instrument_at(s);
        at.def().locate_about(&pts, &rots, &y, tool).map(|own| Placement { measurement: at, own, tool: *tool })
    };
    let shared_first = target.and_then(|t| about(0, &t));
    let first = match (measurement, &opts.draw_wire_guess) {
        _ if searched.is_some() => searched.clone().expect("searched"),
        _ if shared_first.is_some() => shared_first.expect("placed"),
        (Measurement::Length, Some(g)) => Placement::cable(g.exit_m.into(), g.offset_m, g.tool_m.into()),
        _ => {
            let rows = if first_rows.len() >= 3 { first_rows } else { rows_of(SetupKind::Station, 0) };
            locate(&rows, at(SetupKind::Station, 0))?
        }
    };
    let mut others: [Vec<Vec<f64>>; 2] = [Vec::new(), Vec::new()];
    for s in 1..stations.len().max(1) {
        // A face found about the stylus the first one placed (the target is shared).
        let p = match about(s, &first.tool) {
            Some(p) => p,
            None => locate(&rows_of(SetupKind::Station, s), at(SetupKind::Station, s))?,
        };
        others[0].push(setup_values(&p, SetupKind::Station));
    }
    for s in 1..labels[1].len().max(1) {
        let rows = rows_of(SetupKind::Mount, s);
        // A probe's mount is found with its orientation; a point's target starts at the first's.
        let p = if measurement.def().n_targets() > 1 {
            let mut count = vec![0usize; stations.len().max(1)];
            rows.iter().for_each(|&i| count[train.inputs[i].station] += 1);
            let st = (0..count.len()).max_by_key(|k| (count[*k], usize::MAX - k)).unwrap_or(0);
            let at_st: Vec<usize> = rows.iter().copied().filter(|&i| train.inputs[i].station == st).collect();
            locate(&at_st, at(SetupKind::Mount, s))?
        } else {
            first.clone()
        };
        others[1].push(setup_values(&p, SetupKind::Mount));
    }
    let [st, mo] = others;
    let model = m.with_placement(&first).with_setups((stations.to_vec(), &st), (labels[1].to_vec(), &mo));
    Ok((beside_and_aligned(model, shared, &first, opts, train, stations)?, report))
}

/// The placed model with what stands beside its first instrument (faces at stations of its list
/// sharing its target `first.tool`, or another instrument's placement), its artifact's blocks,
/// aligned on the training rows.
fn beside_and_aligned(
    mut model: CalibModel,
    shared: Option<Measurement>,
    first: &Placement,
    opts: &CalibOptions,
    train: &Samples,
    stations: &[String],
) -> Result<CalibModel> {
    if let Some(a) = shared {
        model = model.with_also(&Placement { measurement: a, own: Vec::new(), tool: first.tool });
        model.set_station_instruments(&train.inputs);
    }
    if model.measurement.feature().is_some() {
        feature_blocks(&mut model, stations, opts, train)?;
    }
    if let Some(p) = place_also(&model, train)? {
        model = model.with_also(&p);
    }
    Ok(align_placement(model, train, opts.rank_tol))
}

/// The instrument of station `s`'s rows of `train`: the second (`shared`, standing at stations
/// of the first's list) where they say so, else the first.
fn station_instrument(train: &Samples, shared: Option<Measurement>, s: usize) -> Measurement {
    match shared {
        Some(a) if (0..train.len()).any(|i| train.inputs[i].station == s && train.inputs[i].instrument == 1) => a,
        _ => train.measurement,
    }
}

/// The values of placement `p` that a set-up of `kind` holds: where the instrument stands (a
/// station), or the target and what goes with the arm (a mount).
fn setup_values(p: &Placement, kind: SetupKind) -> Vec<f64> {
    let (all, n) = (p.values(), p.measurement.def().n_station());
    match kind {
        SetupKind::Station => all[..n].to_vec(),
        SetupKind::Mount => all[n..].to_vec(),
    }
}

/// A draw-wire under the generic model: the search over arm topologies places the sensor with
/// each candidate arm (one set-up, no guess of its placement).
fn generic_cable(opts: &CalibOptions, train: &Samples, labels: [&[String]; 2]) -> Result<(CalibModel, Option<SearchReport>)> {
    if labels[0].len() > 1 || labels[1].len() > 1 {
        return Err(Error::Invalid("the generic model searches one draw-wire set-up; these rows stand at several stations or mounts".into()));
    }
    if opts.draw_wire_guess.is_some() {
        // A fixed guess with no arm around it (the old all-zero D-H chain) started fits far
        // from any real robot.
        return Err(Error::Invalid(
            "--draw-wire-guess applies to a nominal model (irb120 or a URDF); the generic model places its sensor in its own search".into(),
        ));
    }
    super::generic::search(train, &search_settings(opts)).map(|s| (s.model, Some(s.report)))
}

/// Rows `rows` of `train` as an instrument's locating functions take them: the flange's origins
/// and rotations (`flanges`, one per training row) and the readings.
fn seen_from(flanges: &[crate::robot::kinematics::Frame], train: &Samples, rows: &[usize], width: usize) -> crate::measurement::plane::FaceRows {
    let pts = rows.iter().map(|&i| flanges[i].pos).collect();
    let rots = rows.iter().map(|&i| flanges[i].rot).collect();
    let y = rows.iter().flat_map(|&i| train.y[i * train.dim..i * train.dim + width].iter().copied()).collect();
    (pts, rots, y)
}

/// The second instrument of `train`'s rows that say so (a tracker's points beside seated rows),
/// placed from the nominal arm's flange on them; `None` without such rows.
fn place_also(model: &CalibModel, train: &Samples) -> Result<Option<Placement>> {
    let rows: Vec<usize> = (0..train.len()).filter(|&i| train.inputs[i].instrument == 1).collect();
    if rows.is_empty() || model.also.is_some() {
        return Ok(None);
    }
    let m = train.also.unwrap_or(if model.measurement.feature().is_some() { Measurement::Point } else { model.measurement });
    let q: Vec<Vec<f64>> = rows.iter().map(|&i| train.q[i].clone()).collect();
    let y: Vec<f64> = rows.iter().flat_map(|&i| train.row(i).iter().copied()).collect();
    let p = locate_on(model, &model.nominal, m, &q, &y)
        .ok_or_else(|| not_located(m, &format!(" beside the {}", model.measurement.def().describe()), rows.len()))?;
    Ok(Some(p))
}

/// Instrument `m` placed from the flange frames of `model` at `x` at joint angles `q` and its
/// readings `y` there ([`Placing::locate`](crate::measurement::Placing::locate)); `None`
/// when the rows cannot place it.
pub fn locate_on(model: &CalibModel, x: &[f64], m: Measurement, q: &[Vec<f64>], y: &[f64]) -> Option<Placement> {
    let mut w = model.work();
    let flanges: Vec<_> = q.iter().map(|q| model.flange_frame(x, q, &mut w)).collect();
    let pts: Vec<_> = flanges.iter().map(|f| f.pos).collect();
    let rots: Vec<_> = flanges.iter().map(|f| f.rot).collect();
    let (own, tool) = m.def().locate(&pts, &rots, y)?;
    Some(Placement { measurement: m, own, tool })
}

/// The error of an instrument that `rows` rows cannot place (`label`: where).
fn not_located(measurement: Measurement, label: &str, rows: usize) -> Error {
    let what = measurement.def().describe();
    Error::Calibration(match measurement {
        Measurement::Length => format!("cannot locate the cable exit point{label}: need at least 6 well-spread poses"),
        Measurement::Socket => format!(
            "cannot place the socket{label} from the nominal arm: {rows} seated configuration(s); the ball's centre on the flange shows only when the tool turns about it: seat at least {} configurations turned by more than {:.0} deg",
            crate::measurement::socket::MIN_ROWS_PER_SOCKET,
            crate::measurement::socket::MIN_TURN_RAD.to_degrees()
        ),
        Measurement::Plane | Measurement::Indicator => format!(
            "cannot place the face{label} from the nominal arm: {rows} contact(s); a face and the stylus on the flange show only when the tool touches it tilted differently: touch it at least {} times, the tool turned by more than {:.0} deg between them",
            crate::measurement::plane::MIN_ROWS_PER_FACE,
            crate::measurement::socket::MIN_TURN_RAD.to_degrees()
        ),
        _ => format!("cannot place the instrument ({what}){label} from the nominal arm: need at least 3 poses whose points are not on one line"),
    })
}

/// An artifact's residual blocks: the stated spacings between the sockets (steps between the
/// faces) of each placement (`stations`), and the arm pulled toward its nominal by the
/// documented tolerances (the published objective's pull: a ball on the last axis leaves the
/// wrist's links nearly free).
fn feature_blocks(model: &mut CalibModel, stations: &[String], opts: &CalibOptions, train: &Samples) -> Result<()> {
    use crate::measurement::FeatureKind;
    let kind = model.measurement.feature().unwrap_or(FeatureKind::Socket);
    // Faces beside sockets: which stations are faces (their rows read by the second instrument).
    let shared = model.also.is_some_and(|a| model.shares_stations_with(a));
    let face: Vec<bool> = (0..stations.len().max(1))
        .map(|s| kind == FeatureKind::Plane || (shared && (0..train.len()).any(|i| train.inputs[i].station == s && train.inputs[i].instrument == 1)))
        .collect();
    model.spacings = if shared {
        crate::calib::model::resolve_mixed_spacings(stations, &face, &opts.spacings)?
    } else {
        crate::calib::model::resolve_spacings(stations, &opts.spacings, kind)?
    };
    {
        // A step is taken at the middle of its second face's contacts as the start puts them.
        let mut w = model.work();
        for k in 0..model.spacings.len() {
            if !face[model.spacings[k].b] {
                continue;
            }
            let rows: Vec<usize> =
                (0..train.len()).filter(|&i| train.inputs[i].station == model.spacings[k].b && (shared || train.inputs[i].instrument == 0)).collect();
            let sum = rows.iter().map(|&i| model.tool_point(&model.nominal, &train.q[i], &mut w)).sum::<nalgebra::Vector3<f64>>();
            model.spacings[k].at = Some((sum / rows.len().max(1) as f64).into());
        }
    }
    let std = opts.tolerances.prior_std(model);
    model.pulls = (0..model.n_chain()).map(|k| crate::calib::model::Pull { k, to: model.nominal[k], std: std[k] }).collect();
    Ok(())
}

/// Refuses a draw-wire's options (a guess of its placement, its cable's pull) on another
/// instrument's rows.
fn refuse_cable_options(opts: &CalibOptions, measurement: Measurement) -> Result<()> {
    let what = measurement.def().describe();
    if measurement.feature().is_none() && !opts.spacings.is_empty() {
        return Err(Error::Invalid(format!("--spacing-mm states the distance between an artifact's sockets or faces; these rows hold a {what}")));
    }
    if measurement.feature().is_none() && opts.loads.joints.preload_n != 0.0 {
        return Err(Error::Invalid(format!("--preload-n is the force pressing a ball into its socket or a probe onto a face; these rows hold a {what}")));
    }
    if measurement != Measurement::Length {
        if opts.draw_wire_guess.is_some() {
            return Err(Error::Invalid(format!("--draw-wire-guess places a draw-wire; these rows hold a {what}, whose placement is found from the data")));
        }
        if opts.loads.joints.cable_tension_n != 0.0 {
            return Err(Error::Invalid(format!("--cable-tension-n is a draw-wire's pull on the tool; these rows hold a {what}: no cable pulls")));
        }
    }
    Ok(())
}

/// The generic search's settings of a calibration's options.
fn search_settings(opts: &CalibOptions) -> super::generic::SearchSettings {
    super::generic::SearchSettings { effort: opts.effort, seed: opts.seed, rank_tol: opts.rank_tol }
}

/// Aligns the instrument alone (its own placement and the tool point) to the nominal robot, so
/// that every method starts from "nominal kinematics, best-fitting instrument" and the
/// identifiability analysis sees a realistic tool point (a tool point on the last axis would
/// hide that axis' direction).
///
/// Placement parameters the rows do not determine (a probe's origin on the flange where its
/// orientation hardly changes) stay where the start put them: the identifiability analysis of
/// the placement alone holds them.
fn align_placement(mut model: CalibModel, train: &Samples, rank_tol: f64) -> CalibModel {
    let nc = model.n_chain();
    let fit = ReadingFit { model: &model, data: train };
    let id = crate::calib::fit::identify::identify(&fit, &model.nominal, rank_tol);
    let fixed: Vec<bool> = (0..model.n_params()).map(|k| k < nc || id.fixed_mask[k]).collect();
    let lm = LevenbergMarquardt::budget(200);
    let x = lm.minimize(&fit, &model.nominal, &fixed, &mut NoObserver).x;
    if x.iter().all(|v| v.is_finite()) {
        model.nominal = x;
    }
    model
}
