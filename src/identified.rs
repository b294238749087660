//! The identified twin: a calibrated model (and the effects a diagnosis named) written back as
//! a twin scenario, so that `generate` and `replay` simulate *that* robot.
//!
//! The scenario's robot is the calibrated model exported as a URDF ([`crate::export::urdf::urdf`],
//! inertials carried over from the nominal robot), written beside it; its geometric errors are
//! then zero (they are in the URDF). The instrument's placement, the effect sizes, the reading
//! noise and the logging resolutions are the identified ones; what the data did not determine
//! keeps its nominal value, and the scenario's comments say which.

use crate::calib::effects::EffectKind;
use crate::calib::pipeline::CalibResult;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::measurement::Measurement;
use crate::robot::Robot;
use crate::sim::instrument::{DrawWire, Tracker};
use crate::sim::scenario::{Geometry, Order, Sampling, Scenario};
use crate::sim::twin::tour::{Acquisition, AcquisitionModel};
use std::path::Path;

/// The twin's effect a calibration block of `kind` is, set at a size by
/// [`crate::sim::effects::Effects::set_size`] (a sensor's nonlinearity is the instrument's, not
/// the twin's arm's: `None`).
pub fn twin_effect(kind: EffectKind) -> Option<crate::sim::effects::SizedEffect> {
    use crate::sim::effects::SizedEffect;
    match kind {
        EffectKind::Compliance => Some(SizedEffect::Compliance),
        EffectKind::Backlash => Some(SizedEffect::Backlash),
        EffectKind::Thermal => Some(SizedEffect::Thermal),
        EffectKind::Eccentricity => Some(SizedEffect::Eccentricity),
        EffectKind::Nonlinearity => None,
    }
}
/// Largest noise (µm per coordinate and sample) a twin's tracker takes (`Tracker::validate`).
const MAX_TRACKER_NOISE_UM: f64 = 1000.0;

/// What [`identified_scenario`] writes: the scenario's TOML text and the URDF it names.
pub struct IdentifiedTwin {
    /// The scenario itself.
    pub scenario: Scenario,
    /// The scenario as TOML text, with its header comment.
    pub toml: String,
    /// The URDF text of the identified arm.
    pub urdf: String,
    /// The URDF's file name, beside the scenario.
    pub urdf_file: String,
}

/// The twin scenario of calibration result `r` on `data` (the rows it was identified on, in
/// acquisition order), written as `scenario_path` with its URDF beside it. `nominal` supplies
/// the inertials (and the joint limits) of a nominal model. `how` names the command that
/// identified it, for the header comment.
pub fn identified_scenario(r: &CalibResult, data: &Dataset, nominal: Option<&Robot>, scenario_path: &Path, how: &str) -> Result<IdentifiedTwin> {
    let m = &r.model;
    let stem = scenario_path.file_stem().and_then(|s| s.to_str()).unwrap_or("twin").to_string();
    let urdf_file = format!("{stem}.urdf");
    let urdf = crate::export::urdf::urdf(m, &r.x, nominal, &stem);
    let robot = Robot::from_urdf_str(&urdf, &stem).map_err(|e| Error::Calibration(format!("the exported URDF does not load back: {e}")))?;
    let n = robot.dof();
    let mut notes = header_notes(r, data, nominal.is_some(), how, &urdf_file);

    let sigma = reading_sigma(r, &mut notes);
    let lengths = m.measurement.file_lengths();
    let reading_decimals = crate::calib::fit::floor::logging_decimals(data.rows.iter().flat_map(|row| row.reading_mm.iter().take(lengths).copied()));
    let logged_decimals = crate::calib::fit::floor::logging_decimals(data.rows.iter().flat_map(|row| row.q_deg.iter().copied())).filter(|d| *d < 6);
    if let Some(d) = logged_decimals {
        notes.push(format!("Joint angles logged at {d} decimals of a degree, as the data are."));
    }

    let (sensor, tracker) = instrument(r, data, sigma, reading_decimals, &mut notes)?;

    // `..Default::default()` in `Instruments` has no effect while the tracker is its only key;
    // it leaves any other instrument's key at its default.
    #[allow(clippy::needless_update)]
    let mut scenario = Scenario {
        name: stem.clone(),
        description: format!("identified twin of {}", data.source),
        seed: r.provenance.seed,
        robot: urdf_file.clone(),
        geometry: Geometry::default(),
        effects: Default::default(),
        draw_wire: sensor,
        instruments: crate::sim::instrument::Instruments { tracker, ..Default::default() },
        sampling: Sampling {
            poses: data.rows.len().min(crate::sim::scenario::MAX_POSES),
            test: 0,
            ranges_deg: Some(ranges(data, &robot)),
            limit_margin_deg: 0.0,
            min_tool_z_mm: -1.0e5,
            speed_fraction: 0.2,
            order: Order::Halton,
            angle_decimals: 6,
            logged_decimals,
            sweep_length: 20,
        },
        simulation: Default::default(),
        acquisition: Acquisition { model: AcquisitionModel::QuasiStatic, ..Default::default() },
        glitches: None,
        workspace: None,
        sockets: None,
        planes: None,
    };
    // An acquisition that moves one or two joints at a time is written as sweeps.
    if let Some((len, share)) = sweeps(data) {
        scenario.sampling.order = Order::Sweeps;
        scenario.sampling.sweep_length = len;
        notes.push(format!("{:.0} % of the data's moves turn one or two joints: the twin's tour sweeps, {len} poses a sweep (the median).", share * 100.0));
    }
    write_effects(r, &mut scenario, n, &mut notes)?;
    if let Some((g, note)) = glitches(r, data.rows.len()).filter(|_| scenario.instruments.active().is_none()) {
        scenario.glitches = Some(g);
        notes.push(note);
    } else if !r.screen.outliers.is_empty() {
        notes.push(format!("{} rows the calibration kept out as outliers are not modelled (no [glitches]).", r.screen.outliers.len()));
    }
    scenario.validate(&robot, &scenario_path.display().to_string())?;
    let body = toml::to_string(&scenario).map_err(|e| Error::Invalid(format!("cannot write the scenario: {e}")))?;
    let header: String = notes.iter().map(|l| format!("# {l}\n")).collect();
    Ok(IdentifiedTwin { scenario, toml: format!("{header}\n{body}"), urdf, urdf_file })
}

/// The scenario's first comments: what it is the twin of, its robot file, and the parameters
/// held at their nominal values.
fn header_notes(r: &CalibResult, data: &Dataset, has_nominal: bool, how: &str, urdf_file: &str) -> Vec<String> {
    let m = &r.model;
    let mut notes: Vec<String> = vec![
        format!("Identified twin of {} ({}; {} model, {} rows).", data.source, how, m.name, data.rows.len()),
        if has_nominal {
            format!("The robot is {urdf_file}: the calibrated geometry (joint zero offsets folded in), the nominal inertials moved into its frames.")
        } else {
            format!("The robot is {urdf_file}: the calibrated geometry; no nominal model, so no inertials: the twin carries no load-driven effect.")
        },
    ];
    let fixed: Vec<&str> = r.parameters.iter().filter(|p| p.fixed).map(|p| p.name.as_str()).collect();
    if !fixed.is_empty() {
        notes.push(format!("Held at their nominal values (not identifiable from these rows, or not fitted): {}.", fixed.join(", ")));
    }

    notes
}

/// The reading noise: the data's, less what the logging steps already give (mm per value).
fn reading_sigma(r: &CalibResult, notes: &mut Vec<String>) -> f64 {
    let floor = r.evaluation.noise_floor.as_ref();
    use crate::calib::fit::floor::FloorKind;
    let part = |kind: FloorKind| floor.map_or(0.0, |f| f.part(kind));
    let (angle_part, reading_part) = (part(FloorKind::AngleResolution), part(FloorKind::ReadingResolution));
    let sigma = (r.solve.noise_estimate_mm.powi(2) - angle_part.powi(2) - reading_part.powi(2)).max(0.0).sqrt();
    notes.push(format!(
        "Reading noise {sigma:.4} mm per value: the data's {:.4} mm less the logging steps' share ({angle_part:.4} mm from the angles, {reading_part:.4} mm from the readings), one sample per reading.",
        r.solve.noise_estimate_mm
    ));
    sigma
}

/// The identified tracker's moves: each station after the first where the data's rows stand,
/// from its first row on (replay reads the rows in order, one pose a row). None where the
/// stations' rows interleave (a note says the twin stands at the first), and a note where the
/// target had several mounts (the twin keeps the first).
fn tracker_moves(r: &CalibResult, data: &Dataset, notes: &mut Vec<String>) -> Vec<crate::sim::instrument::tracker::TrackerMove> {
    use crate::calib::model::SetupKind;
    let m = &r.model;
    if m.n_setups(SetupKind::Mount) > 1 {
        notes.push(format!("The target sat on {} mounts; the twin's sits on the first ({}).", m.n_setups(SetupKind::Mount), m.mounts[0]));
    }
    if m.n_stations() < 2 {
        return Vec::new();
    }
    // Each station's rows, as the result reports them (found stations name no row of the file).
    let parts = r.setup.as_ref().map(|u| u.stations.as_slice()).unwrap_or_default();
    let firsts: Vec<usize> = parts.iter().map(|p| p.first_row.saturating_sub(1)).collect();
    // Contiguous and in order: each station's rows one stretch, after the one before.
    let ordered = parts.len() == m.n_stations()
        && parts.iter().all(|p| p.rows > 0 && p.last_row + 1 == p.first_row + p.rows)
        && parts.windows(2).all(|w| w[1].first_row == w[0].last_row + 1)
        && parts.last().is_some_and(|p| p.last_row == data.rows.len());
    if !ordered {
        notes.push(format!("The tracker stood at {} stations whose rows interleave: the twin stands at the first ({}).", m.n_stations(), m.stations[0]));
        return Vec::new();
    }
    notes.push(format!("The tracker stood at {} stations, each from its first row on: {}.", m.n_stations(), m.stations.join(", ")));
    (1..m.n_stations())
        .map(|s| {
            let o = m.placement_at(&r.x, s, 0).own;
            crate::sim::instrument::tracker::TrackerMove {
                from_pose: firsts[s],
                translation_mm: [crate::units::to_mm(o[0]), crate::units::to_mm(o[1]), crate::units::to_mm(o[2])],
                rotation_deg: [o[3].to_degrees(), o[4].to_degrees(), o[5].to_degrees()],
            }
        })
        .collect()
}

/// The instrument of the twin: a draw-wire sensor at the identified placement (a length
/// reading), or a tracker (a point or a pose) with a placeholder draw-wire section.
fn instrument(r: &CalibResult, data: &Dataset, sigma: f64, reading_decimals: Option<usize>, notes: &mut Vec<String>) -> Result<(DrawWire, Option<Tracker>)> {
    let m = &r.model;
    let p = m.placement(&r.x);
    let mm = |v: nalgebra::Vector3<f64>| [crate::units::to_mm(v.x), crate::units::to_mm(v.y), crate::units::to_mm(v.z)];
    let tension = r.torque_model.as_ref().and_then(|t| t.cable).map_or(0.0, |c| c.2);
    let max_reading = data.rows.iter().filter_map(|row| row.reading_mm.first()).fold(0.0_f64, |a, v| a.max(v.abs()));
    let mut sensor = DrawWire {
        exit_point_mm: [0.0; 3],
        tool_point_mm: mm(p.tool),
        length_offset_mm: 0.0,
        noise_std_mm: 0.0,
        resolution_mm: 0.0,
        linearity_pct_fs: 0.0,
        range_mm: [0.0, (2.0 * max_reading).max(3000.0)],
        tension_n: 0.0,
        hold_s: 2.0,
        samples: 1,
        rate_hz: 1000.0,
        polynomial: None,
        noise_t_dof: None,
    };
    let tracker = match p.exit() {
        Some(exit) => {
            sensor.exit_point_mm = mm(exit);
            sensor.length_offset_mm = crate::units::to_mm(p.own[3]);
            sensor.noise_std_mm = sigma;
            if let Some((nu, k, n)) = heavy_tails(r, data) {
                sensor.noise_t_dof = Some(nu);
                notes.push(format!(
                    "The residuals of the {n} rows that are not glitches have an excess kurtosis of {k:.2} (a Gaussian's is 0 ± {:.2}): Student-t noise of {nu:.1} degrees of freedom, which has it.",
                    (24.0 / n as f64).sqrt()
                ));
            }
            sensor.resolution_mm = reading_decimals.map_or(0.0, |k| 10f64.powi(-(k as i32)));
            sensor.tension_n = tension;
            None
        }
        None if matches!(m.measurement, Measurement::Point | Measurement::Pose) => {
            let o = &p.own;
            let probe = (m.measurement == Measurement::Pose).then(|| probe_noise(r, o, data, notes));
            Some(Tracker {
                translation_mm: [crate::units::to_mm(o[0]), crate::units::to_mm(o[1]), crate::units::to_mm(o[2])],
                rotation_deg: [o[3].to_degrees(), o[4].to_degrees(), o[5].to_degrees()],
                noise_um: {
                    let um = probe.map_or(sigma, |(_, _, pos)| pos) * 1e3;
                    if um > MAX_TRACKER_NOISE_UM {
                        notes.push(format!("The data's noise ({um:.0} µm) is beyond a tracker's {MAX_TRACKER_NOISE_UM} µm: the twin's is cut there (the residuals are the model's error, not the tracker's)."));
                    }
                    um.min(MAX_TRACKER_NOISE_UM)
                },
                noise_um_per_m: 0.0,
                decimals: reading_decimals.unwrap_or(4).min(crate::sim::instrument::tracker::MAX_DECIMALS),
                probe_rotation_deg: probe.map(|(r, _, _)| r),
                orientation_noise_urad: probe.map_or(0.0, |(_, u, _)| u),
                angle_decimals: 6,
                write_std: data.rows.iter().any(|row| row.std_mm.is_some()),
                moves: tracker_moves(r, data, notes),
                write_station: false,
            })
        }
        None => {
            return Err(Error::Invalid(format!(
                "an identified twin reads with a draw-wire or a tracker; it has no twin instrument for a {} yet",
                m.measurement.def().describe()
            )))
        }
    };
    Ok((sensor, tracker))
}

/// A 6-D probe's orientation on the flange (degrees), its orientation noise (µrad per axis) and
/// its position noise (mm per coordinate), from the residuals: a rotation of σ per axis moves
/// an axis tip at the lever by lever·σ·√(2/3) per coordinate, RMS. `o`: the identified
/// placement's own parameters.
fn probe_noise(r: &CalibResult, o: &[f64], data: &Dataset, notes: &mut Vec<String>) -> ([f64; 3], f64, f64) {
    let m = &r.model;
    let predicted = r.predict_rows(data);
    let d = m.measurement.dim();
    let res: Vec<Vec<f64>> =
        data.rows.iter().zip(predicted.chunks(d)).filter_map(|(row, p)| Some(row.values_mm()?.iter().zip(p).map(|(a, b)| a - b).collect())).collect();
    let part = |k: std::ops::Range<usize>| crate::stats::robust_scale(&res.iter().flat_map(|v| v[k.clone()].to_vec()).collect::<Vec<_>>()).1;
    let (pos_sd, sd) = (part(0..3), part(3..d));
    let urad = sd / (crate::measurement::pose::LEVER_MM * (2.0f64 / 3.0).sqrt()) * 1e6;
    notes.push(format!(
        "Orientation noise {urad:.0} µrad per axis: the probe axes' residuals ({sd:.4} mm robust sd at the {} mm lever).",
        crate::measurement::pose::LEVER_MM
    ));
    notes.push(format!("Position noise {pos_sd:.4} mm per coordinate: the position residuals' robust sd (a pose's noise above is over all nine values)."));
    ([o[6].to_degrees(), o[7].to_degrees(), o[8].to_degrees()], urad.min(10_000.0), pos_sd)
}

/// The effects, each at its identified size where the twin takes it, and the payload; notes
/// say what is left out and why.
fn write_effects(r: &CalibResult, scenario: &mut Scenario, n: usize, notes: &mut Vec<String>) -> Result<()> {
    let m = &r.model;
    let mut written = Vec::new();
    for (b, block) in m.effects.iter().enumerate() {
        let k = m.effect_params(b).start;
        let label = block.label();
        match block.kind {
            EffectKind::Nonlinearity => match block.range_m {
                Some([lo, hi]) if m.measurement == Measurement::Length => {
                    scenario.draw_wire.polynomial = Some(crate::sim::instrument::drawwire::ReadingPolynomial {
                        range_mm: [crate::units::to_mm(lo), crate::units::to_mm(hi)],
                        legendre_mm: [crate::units::to_mm(r.x[k]), crate::units::to_mm(r.x[k + 1]), crate::units::to_mm(r.x[k + 2])],
                    });
                    notes.push(format!(
                        "{label}: identified on readings of {:.1} to {:.1} mm; beyond them the twin holds its end values (the data say nothing there).",
                        crate::units::to_mm(lo),
                        crate::units::to_mm(hi)
                    ));
                    written.push(label);
                }
                _ => notes.push(format!("{label}: identified without its reading range; left out.")),
            },
            // A block the data could not show is not carried: not identifiable, or every
            // parameter within two standard uncertainties of zero.
            _ if !shown_by_the_data(r.parameters.get(m.effect_params(b)).unwrap_or_default(), notes, &label) => {}
            // Every other effect: the size the block says the twin takes, which the twin may
            // still refuse (beyond its range); either way the note names why it is left out.
            kind => match kind.def().twin_size(block, &r.x, k).and_then(|(size, phase)| {
                twin_effect(kind)
                    .ok_or_else(|| format!("the twin cannot take a '{}' at a given size", kind.name()))
                    .and_then(|t| scenario.effects.set_size(t, n, block.joint, size, phase))
            }) {
                Ok(()) => written.push(label),
                Err(why) => notes.push(format!("{label}: {why}, left out.")),
            },
        }
    }
    if let Some(c) = &r.corrector {
        notes.push(format!(
            "The calibration's learned corrector ({}) is no physical effect the twin simulates: left out, the twin reads what its geometry and effects give.",
            c.name()
        ));
    }
    if let Some((mass, com)) = r.torque_model.as_ref().and_then(|t| t.payload) {
        scenario.effects.payload = Some(crate::sim::effects::Payload { mass_kg: mass, com_mm: com.map(crate::units::to_mm) });
    }
    if !written.is_empty() {
        notes.push(format!("Effects at their identified sizes: {}.", written.join(", ")));
    }
    Ok(())
}

/// Smallest |value| / standard uncertainty of a block's largest parameter for the twin to carry
/// it: within two standard uncertainties of zero the data do not tell it from no effect.
pub const MIN_CARRIED_Z: f64 = 2.0;

/// Whether the data showed the block whose parameter reports are `params` (the result's
/// `parameters` over the block's range): identifiable, with a parameter at least
/// [`MIN_CARRIED_Z`] standard uncertainties from zero; else a note says why it is left out.
fn shown_by_the_data(params: &[crate::calib::pipeline::ParamReport], notes: &mut Vec<String>, label: &str) -> bool {
    if params.is_empty() {
        return true;
    }
    if params.iter().all(|p| p.fixed) {
        notes.push(format!("{label}: not identifiable from these data, left out."));
        return false;
    }
    let z = params.iter().filter(|p| !p.fixed).map(|p| p.std_uncertainty.filter(|s| *s > 0.0).map_or(f64::INFINITY, |s| p.value.abs() / s)).fold(0.0, f64::max);
    if z < MIN_CARRIED_Z {
        let shown: Vec<String> =
            params.iter().map(|p| format!("{} = {:.4} ± {:.4} {}", p.name, p.value, p.std_uncertainty.unwrap_or(f64::NAN), p.unit)).collect();
        notes.push(format!("{label}: {} is not told from zero by these data (|z| = {z:.2} < {MIN_CARRIED_Z}), left out.", shown.join(", ")));
        return false;
    }
    true
}

/// Each joint's range over the data (degrees), widened to at least 1° and kept inside the
/// robot's limits.
fn ranges(data: &Dataset, robot: &Robot) -> Vec<[f64; 2]> {
    (0..robot.dof())
        .map(|j| {
            let (lo, hi) = data.rows.iter().map(|r| r.q_deg[j]).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            let mid = 0.5 * (lo + hi);
            let half = (0.5 * (hi - lo)).max(0.5);
            let (l, u) = (robot.joints[j].lower.to_degrees(), robot.joints[j].upper.to_degrees());
            [(mid - half).max(l), (mid + half).min(u)]
        })
        .collect()
}

/// The glitches a calibration found (reading steps, runs of outliers, lone outliers) as the
/// twin's `[glitches]`: as many runs per row as the training rows had, of the median run's
/// length and the median size (the twin draws each run's size as size × (1 + U(0, 0.5))),
/// offsets when reading steps are the most, scattered rows otherwise. With a note saying so.
fn glitches(r: &CalibResult, rows: usize) -> Option<(crate::sim::scenario::Glitches, String)> {
    use crate::sim::scenario::{GlitchKind, Glitches};
    let in_runs = |row: usize| r.screen.outlier_runs.iter().any(|u| (u.first_row..=u.last_row).contains(&row));
    let lone = r.screen.outliers.iter().filter(|o| !in_runs(o.row)).count();
    let mut lengths: Vec<f64> = r.screen.reading_steps.iter().map(|s| (s.last_row + 1 - s.first_row) as f64).collect();
    lengths.extend(r.screen.outlier_runs.iter().map(|u| (u.last_row + 1 - u.first_row) as f64));
    lengths.extend(std::iter::repeat_n(1.0, lone));
    let mut sizes: Vec<f64> = r.screen.reading_steps.iter().map(|s| s.offset_mm.abs()).collect();
    sizes.extend(r.screen.outlier_runs.iter().map(|u| u.median_residual_mm.abs()));
    sizes.extend(r.screen.outliers.iter().filter(|o| !in_runs(o.row)).map(|o| o.residual_mm.abs()));
    if lengths.is_empty() || r.provenance.n_train == 0 {
        return None;
    }
    let found = lengths.len();
    let len = crate::stats::median(&lengths).round().max(1.0) as usize;
    let size = crate::stats::median(&sizes) / 1.25;
    let runs = ((found as f64 * rows as f64 / r.provenance.n_train as f64).round() as usize).max(1).min(rows / 4 / len);
    let kind = if r.screen.reading_steps.len() * 2 >= found { GlitchKind::Offset } else { GlitchKind::Scatter };
    (runs > 0 && size > 0.0).then(|| {
        let note = format!(
            "Glitches as the calibration found them in its {} training rows ({} reading steps, {} outlier runs, {lone} lone outliers): {runs} runs of {len} rows, {size:.3} mm x (1 + U(0, 0.5)), {} (placed from the seed, not at the data's rows).",
            r.provenance.n_train,
            r.screen.reading_steps.len(),
            r.screen.outlier_runs.len(),
            if kind == GlitchKind::Offset { "constant offsets" } else { "scattered" }
        );
        (Glitches { runs, rows: len, size_mm: size, kind, joint: None, size_deg: None }, note)
    })
}

/// Heavy tails in the model's residuals over `data` (rows beyond 6 robust standard deviations,
/// glitches, left out): (Student-t degrees of freedom with the same excess kurtosis, the
/// excess kurtosis, the rows) when it exceeds three of its standard errors (√(24/n)), else
/// `None` (Gaussian).
fn heavy_tails(r: &CalibResult, data: &Dataset) -> Option<(f64, f64, usize)> {
    let predicted = r.predict_rows(data);
    let res: Vec<f64> = data.rows.iter().zip(&predicted).filter_map(|(row, p)| Some(row.values_mm()?.first()? - p)).filter(|v| v.is_finite()).collect();
    let (med, scale) = crate::stats::robust_scale(&res);
    let kept: Vec<f64> = res.iter().copied().filter(|v| (v - med).abs() <= crate::calib::pipeline::DEFAULT_OUTLIER_K * scale).collect();
    let n = kept.len();
    if n < 50 {
        return None;
    }
    let mean = kept.iter().sum::<f64>() / n as f64;
    let m2 = kept.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
    let m4 = kept.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / n as f64;
    let k = m4 / (m2 * m2) - 3.0;
    (k > 3.0 * (24.0 / n as f64).sqrt()).then(|| ((4.0 + 6.0 / k).clamp(4.5, 100.0), k, n))
}

/// Sweeps in the acquisition order: when most moves between consecutive rows turn one or two
/// joints, (the median length of the runs of such moves + 1, clamped to 2..=1000; the share of
/// such moves).
fn sweeps(data: &Dataset) -> Option<(usize, f64)> {
    let moves: Vec<bool> = data
        .rows
        .windows(2)
        .map(|w| {
            let turned = w[0].q_deg.iter().zip(&w[1].q_deg).filter(|(a, b)| (*a - *b).abs() > 1e-9).count();
            (1..=2).contains(&turned)
        })
        .collect();
    let share = moves.iter().filter(|m| **m).count() as f64 / moves.len().max(1) as f64;
    if share <= 0.5 {
        return None;
    }
    let mut runs = Vec::new();
    let mut run = 0usize;
    for m in moves.iter().chain([&false]) {
        if *m {
            run += 1;
        } else if run > 0 {
            runs.push((run + 1) as f64);
            run = 0;
        }
    }
    Some(((crate::stats::median(&runs).round() as usize).clamp(2, 1000), share))
}
