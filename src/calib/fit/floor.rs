//! The floor no model can beat on a dataset, from the data themselves: the spread of repeated
//! configurations, and what the logging resolution of the joint angles and of the reading costs
//! on each reading value (the angle steps propagated through the model's joint Jacobian). Each
//! source is named; the final residual of a fit is never one of them.

use crate::calib::fit::Samples;
use crate::calib::model::CalibModel;
use crate::stats::metrics::Repeatability;
use serde::{Deserialize, Serialize};

/// What a contribution to the floor is.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FloorKind {
    /// The spread of repeated configurations.
    Repeatability,
    /// The joint angles' logging step through the model's joint Jacobian.
    AngleResolution,
    /// The reading's logging step.
    ReadingResolution,
    /// The rows' own standard deviations (`sx, sy, sz`).
    RowStd,
    /// The instrument's accuracy as the user states it.
    InstrumentAccuracy,
}

impl FloorKind {
    /// Its name in reports (`angle_resolution`).
    pub fn name(self) -> &'static str {
        match self {
            FloorKind::Repeatability => "repeatability",
            FloorKind::AngleResolution => "angle_resolution",
            FloorKind::ReadingResolution => "reading_resolution",
            FloorKind::RowStd => "row_std",
            FloorKind::InstrumentAccuracy => "instrument_accuracy",
        }
    }
    /// Whether it is the reading's own error (not the angles' logging): one estimate of it is
    /// counted, never several added.
    pub fn reading_side(self) -> bool {
        self != FloorKind::AngleResolution
    }
    /// Whether the data or the instrument measure it (not a logging step's lower bound).
    pub fn measured(self) -> bool {
        matches!(self, FloorKind::Repeatability | FloorKind::RowStd | FloorKind::InstrumentAccuracy)
    }
}

impl std::fmt::Display for FloorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One contribution to the floor.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FloorSource {
    /// What it is.
    pub source: FloorKind,
    /// RMS contribution to one reading value (L, or one coordinate of a point), mm.
    pub rms_mm: f64,
    /// How the contribution was found (step sizes, rows, configurations), in words.
    pub detail: String,
}

/// The data's own floor: its sources and their combination.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct NoiseFloor {
    /// Root sum of squares of the independent sources, mm (the reading resolution is inside
    /// the repeatability where there is one, so it is then not added again).
    pub total_mm: f64,
    /// Each source, named.
    pub sources: Vec<FloorSource>,
    /// Where a reading's values are of different kinds (a 6-D pose's position and its axes at
    /// the lever), the floor of each kind apart, from the sources that reach it: the gain of a
    /// cause is judged on each. Empty for one kind of value.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub by_group: Vec<GroupFloor>,
}

/// A kind of reading value with a floor of its own.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ValueKind {
    /// A pose's position (value group 0).
    Position,
    /// A pose's axes at the lever (value group 1).
    Orientation,
}

impl ValueKind {
    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            ValueKind::Position => "position",
            ValueKind::Orientation => "orientation",
        }
    }
}

/// The floor of one kind of reading value (a pose's position, or its axes).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GroupFloor {
    /// Which kind.
    pub group: ValueKind,
    /// Combined like [`NoiseFloor::total_mm`], over this kind's values, mm.
    pub total_mm: f64,
    /// Whether a source the data or the instrument measure reaches it (else it is a logging
    /// step's lower bound).
    pub measured: bool,
}

impl NoiseFloor {
    /// The RMS of the source of `kind`, if it is one (0 otherwise).
    pub fn part(&self, kind: FloorKind) -> f64 {
        self.sources.iter().find(|s| s.source == kind).map_or(0.0, |s| s.rms_mm)
    }
    /// Whether a source of `kind` is one.
    pub fn has(&self, kind: FloorKind) -> bool {
        self.sources.iter().any(|s| s.source == kind)
    }
    /// The floor of the value group `g` (the whole floor for one kind of value).
    pub fn of_group(&self, g: usize) -> f64 {
        self.by_group.get(g).map_or(self.total_mm, |f| f.total_mm)
    }
    /// Whether a source the data or the instrument measure is one (repeats, the rows' own
    /// standard deviations, a stated accuracy), not only logging steps' lower bounds.
    pub fn is_measured(&self) -> bool {
        self.sources.iter().any(|s| s.source.measured())
    }
}

/// Combines the sources' contributions (kind, RMS mm): the reading's own error counted once
/// (see [`noise_floor`]), the angles' logging added to it.
fn combine(parts: &[(FloorKind, f64)]) -> f64 {
    let has_repeat = parts.iter().any(|p| p.0 == FloorKind::Repeatability);
    let stated = parts.iter().any(|p| matches!(p.0, FloorKind::RowStd | FloorKind::InstrumentAccuracy));
    let total = if stated {
        let reading = parts.iter().filter(|p| p.0.reading_side()).map(|p| p.1).fold(0.0, f64::max);
        parts.iter().filter(|p| !p.0.reading_side()).map(|p| p.1 * p.1).sum::<f64>() + reading * reading
    } else {
        parts.iter().filter(|p| !(has_repeat && p.0 == FloorKind::ReadingResolution)).map(|p| p.1 * p.1).sum::<f64>()
    };
    // An empty sum is -0.0: the floor of no known source is 0.
    (total + 0.0).sqrt()
}

/// Where a logging step came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Read from the decimals of the data.
    Detected(f64),
    /// Given by the user.
    Given(f64),
}

impl Step {
    /// The step, however it was found.
    pub fn value(self) -> f64 {
        match self {
            Step::Detected(v) | Step::Given(v) => v,
        }
    }
    fn origin(self) -> &'static str {
        match self {
            Step::Detected(_) => "from the data's decimals",
            Step::Given(_) => "as given",
        }
    }
}

pub use crate::dataset::logging::{logging_decimals, logging_step};

/// What the instrument says of itself: the RMS of the rows' own standard deviations (a
/// tracker's `sx, sy, sz`) and the accuracy the user states (`--instrument-accuracy-mm`), each a
/// standard uncertainty of one position coordinate, mm.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InstrumentNoise {
    /// RMS of the rows' own standard deviations of one coordinate, mm; `None` where the rows give
    /// none.
    pub row_std_mm: Option<f64>,
    /// The accuracy the user states, mm; `None` when not given.
    pub accuracy_mm: Option<f64>,
}

/// What a floor is made of, as the data give it: the joint angles' logging step, the readings'
/// logging step (mm), the repeatability where configurations repeat, and what the instrument
/// states of itself.
#[derive(Clone, Copy, Debug, Default)]
pub struct FloorInputs<'a> {
    /// The joint angles' logging step, degrees (given or detected).
    pub angle_step: Option<Step>,
    /// The readings' logging step, mm.
    pub reading_step_mm: Option<f64>,
    /// The repeatability of repeated configurations.
    pub repeat: Option<&'a Repeatability>,
    /// The rows' own standard deviations and the stated accuracy.
    pub instrument: InstrumentNoise,
}

/// The floor of `data` (every row) for the model at `x`: repeatability where configurations
/// repeat, the joint angles' logging step (uniform quantisation, step²/12 per joint, through
/// ∂L/∂q of each row), the reading's step and what the instrument states of itself.
///
/// The reading's own error is counted once: the repeatability where configurations repeat, else
/// the reading's logging step; where the instrument states its uncertainty (rows' standard
/// deviations, a stated accuracy), the largest of these, since each is an estimate of the same
/// error and a stated accuracy includes what repeats do not show.
pub fn noise_floor(model: &CalibModel, x: &[f64], data: &Samples, inputs: FloorInputs) -> NoiseFloor {
    let FloorInputs { angle_step: angle_step_deg, reading_step_mm: length_step_mm, repeat, instrument } = inputs;
    let mut sources = Vec::new();
    let cols = model.measurement.def().columns().join(", ");
    let dim = model.measurement.dim();
    if let Some(r) = repeat.filter(|r| r.groups > 0) {
        sources.push(FloorSource {
            source: FloorKind::Repeatability,
            rms_mm: r.pooled_std,
            detail: format!("pooled spread of {cols} over {} repeated configurations ({} rows)", r.groups, r.rows),
        });
    }
    // The angles' logging step per reading value (mean square over the rows).
    let angle_var = angle_step_deg.filter(|s| s.value() > 0.0).map(|step| angle_variance(model, x, data, step.value()));
    if let (Some(step), Some(var)) = (angle_step_deg, &angle_var) {
        let through = if dim == 1 { format!("d{cols}/dq") } else { format!("d({cols})/dq") };
        sources.push(FloorSource {
            source: FloorKind::AngleResolution,
            rms_mm: (var.iter().sum::<f64>() / dim as f64).sqrt(),
            detail: format!("joint angles logged at {} deg ({}), through the model's {through}", step.value(), step.origin()),
        });
    }
    if let Some(step) = length_step_mm.filter(|s| *s > 0.0) {
        sources.push(FloorSource {
            source: FloorKind::ReadingResolution,
            rms_mm: step / 12f64.sqrt(),
            detail: format!("{cols} logged at {step} mm (from the data's decimals)"),
        });
    }
    if let Some(v) = instrument.row_std_mm.filter(|v| *v > 0.0) {
        sources.push(FloorSource {
            source: FloorKind::RowStd,
            rms_mm: v,
            detail: "RMS of the rows' own standard deviations (sx, sy, sz) per coordinate".into(),
        });
    }
    if let Some(v) = instrument.accuracy_mm.filter(|v| *v > 0.0) {
        sources.push(FloorSource {
            source: FloorKind::InstrumentAccuracy,
            rms_mm: v,
            detail: "the instrument's stated accuracy per coordinate, as given".into(),
        });
    }
    let parts: Vec<(FloorKind, f64)> = sources.iter().map(|s| (s.source, s.rms_mm)).collect();
    let total_mm = combine(&parts);
    let by_group = group_floors(model, &parts, repeat, angle_var.as_deref());
    NoiseFloor { total_mm, sources, by_group }
}

/// Mean over the rows of each reading value's variance (mm²) from the joint angles' uniform
/// quantisation at `step_deg` (step²/12 per joint, through ∂value/∂q).
fn angle_variance(model: &CalibModel, x: &[f64], data: &Samples, step_deg: f64) -> Vec<f64> {
    let dim = model.measurement.dim();
    let var_q = step_deg.to_radians().powi(2) / 12.0;
    let n = model.chain.n_joints;
    let mut w = model.work();
    let mut g = vec![0.0; n * dim];
    let mut y = vec![0.0; dim];
    let mut var = vec![0.0; dim];
    for (q, inp) in data.q.iter().zip(&data.inputs) {
        model.readings_grad_q(x, q, inp, &mut w, &mut y, &mut g);
        // `g` is row-major, `n` joint derivatives per value.
        for (c, v) in var.iter_mut().enumerate() {
            *v += g[c * n..(c + 1) * n].iter().map(|d| crate::units::to_mm(d).powi(2) * var_q).sum::<f64>();
        }
    }
    var.iter_mut().for_each(|v| *v /= data.len().max(1) as f64);
    var
}

/// The floor of each kind of reading value where a reading holds several (a 6-D pose's position
/// and its axes): the repeatability and the angles' logging over that kind's values; the
/// reading's logging step, the rows' standard deviations and a stated accuracy describe the
/// position only. Empty for one kind.
fn group_floors(model: &CalibModel, parts: &[(FloorKind, f64)], repeat: Option<&Repeatability>, angle_var: Option<&[f64]>) -> Vec<GroupFloor> {
    let value_groups = model.measurement.def().value_groups();
    let n_groups = model.measurement.n_value_groups();
    if n_groups < 2 {
        return Vec::new();
    }
    let mean_over = |v: &[f64], g: usize, sq: bool| {
        let vals: Vec<f64> = v.iter().zip(value_groups).filter(|(_, k)| **k == g).map(|(x, _)| if sq { x * x } else { *x }).collect();
        vals.iter().sum::<f64>() / vals.len().max(1) as f64
    };
    (0..n_groups)
        .map(|g| {
            let group_parts: Vec<(FloorKind, f64)> = parts
                .iter()
                .filter_map(|&(kind, rms)| match kind {
                    FloorKind::Repeatability => {
                        let per = repeat.map(|r| r.per_value_std.as_slice()).unwrap_or_default();
                        Some((kind, if per.len() == value_groups.len() { mean_over(per, g, true).sqrt() } else { rms }))
                    }
                    FloorKind::AngleResolution => angle_var.map(|v| (kind, mean_over(v, g, false).sqrt())),
                    _ => (g == 0).then_some((kind, rms)),
                })
                .collect();
            GroupFloor {
                group: if g == 0 { ValueKind::Position } else { ValueKind::Orientation },
                total_mm: combine(&group_parts),
                measured: group_parts.iter().any(|p| p.0.measured() && p.1 > 0.0),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logging_steps_from_decimals() {
        assert_eq!(logging_step([-74.5, 33.9, 80.0, -0.1].into_iter()), Some(0.1));
        assert_eq!(logging_step([65.122, 65.125, -181.904].into_iter()), Some(0.001));
        assert_eq!(logging_step([3.0, -7.0].into_iter()), Some(1.0));
        assert_eq!(logging_step([0.123_456_7].into_iter()), None);
        assert_eq!(logging_step([f64::NAN].into_iter()), None);
    }

    #[test]
    fn angle_quantisation_propagates_through_the_joint_jacobian() {
        use crate::calib::model::DrawWireGuess;
        use crate::robot::Robot;
        let robot = Robot::irb120();
        let m = CalibModel::dh(&robot, &DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.1, tool_m: [0.0, 0.0, 0.05] }, true);
        let q: Vec<Vec<f64>> = (0..50).map(|k| (0..6).map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin()).collect()).collect();
        let data = Samples::new(q, vec![0.5; 50]);
        let none = InstrumentNoise::default();
        let f1 = noise_floor(
            &m,
            &m.nominal,
            &data,
            FloorInputs { angle_step: Some(Step::Detected(0.1)), reading_step_mm: Some(0.01), repeat: None, instrument: none },
        );
        let f2 =
            noise_floor(&m, &m.nominal, &data, FloorInputs { angle_step: Some(Step::Given(0.2)), reading_step_mm: Some(0.01), repeat: None, instrument: none });
        let angle = |f: &NoiseFloor| f.sources.iter().find(|s| s.source == FloorKind::AngleResolution).unwrap().rms_mm;
        // Linear in the step; a 0.1 deg step over a ~0.5 m arm is a few tenths of a millimetre.
        assert!((angle(&f2) / angle(&f1) - 2.0).abs() < 1e-12);
        assert!(angle(&f1) > 0.1 && angle(&f1) < 1.0, "{f1:?}");
        assert!((f1.total_mm - (angle(&f1).powi(2) + 0.01f64.powi(2) / 12.0).sqrt()).abs() < 1e-12);
        // With repeatability, the reading's step is inside it and is not added again.
        let rep = Repeatability { pooled_std: 0.05, groups: 3, rows: 7, max_spread: 0.1, per_value_std: Vec::new() };
        let f3 = noise_floor(
            &m,
            &m.nominal,
            &data,
            FloorInputs { angle_step: Some(Step::Detected(0.1)), reading_step_mm: Some(0.01), repeat: Some(&rep), instrument: none },
        );
        assert!((f3.total_mm - (angle(&f1).powi(2) + 0.05f64.powi(2)).sqrt()).abs() < 1e-12);
        // A stated accuracy larger than the repeats' spread takes its place; rows' standard
        // deviations without repeats take the reading step's.
        let f4 = noise_floor(
            &m,
            &m.nominal,
            &data,
            FloorInputs {
                angle_step: None,
                reading_step_mm: Some(0.01),
                repeat: Some(&rep),
                instrument: InstrumentNoise { row_std_mm: Some(0.02), accuracy_mm: Some(0.08) },
            },
        );
        assert!((f4.total_mm - 0.08).abs() < 1e-12, "{f4:?}");
        let f5 = noise_floor(
            &m,
            &m.nominal,
            &data,
            FloorInputs {
                angle_step: None,
                reading_step_mm: Some(0.001),
                repeat: None,
                instrument: InstrumentNoise { row_std_mm: Some(0.02), accuracy_mm: None },
            },
        );
        assert!((f5.total_mm - 0.02).abs() < 1e-12 && f5.sources.iter().any(|s| s.source == FloorKind::RowStd), "{f5:?}");
    }

    #[test]
    fn a_poses_position_and_orientation_have_floors_of_their_own() {
        use crate::calib::model::{DhTable, Placement};
        use crate::robot::Robot;
        let robot = Robot::irb120();
        let (chain, kinds) = DhTable::from_robot_hayati(&robot).chain(true, true);
        let probe = Placement::tracker([2000.0, 0.0, 300.0], [0.0, 0.0, 40.0], Some([0.0, 0.0, -90.0]), nalgebra::Vector3::new(0.0, 0.05, 0.1));
        let m = CalibModel::of_chain("hayati", chain, kinds, &probe);
        assert_eq!(m.measurement.dim(), 9);
        let q: Vec<Vec<f64>> = (0..40).map(|k| (0..6).map(|j| ((k * 5 + j * 3) as f64 * 0.41).sin()).collect()).collect();
        let data = Samples::readings(q, vec![0.0; 40 * 9], 9);
        // Repeats spread 0.02 mm on the origin and 0.001 mm on the axes' tips; the rows state 0.03 mm.
        let per_value_std = [0.02, 0.02, 0.02, 0.001, 0.001, 0.001, 0.001, 0.001, 0.001].to_vec();
        let rep = Repeatability { pooled_std: 0.0116, groups: 5, rows: 10, max_spread: 0.05, per_value_std };
        let f = noise_floor(
            &m,
            &m.nominal,
            &data,
            FloorInputs {
                angle_step: Some(Step::Given(1e-4)),
                reading_step_mm: Some(1e-4),
                repeat: Some(&rep),
                instrument: InstrumentNoise { row_std_mm: Some(0.03), accuracy_mm: None },
            },
        );
        let [pos, ori] = f.by_group.as_slice() else { panic!("{f:?}") };
        // The position: the largest estimate of the reading's error (the rows' 0.03 mm) and the
        // angles' logging; the orientation: its repeats alone (the rows' sx, sy, sz are positions').
        let angle_pos = f.by_group[0].total_mm.powi(2) - 0.03f64.powi(2);
        assert!(pos.group == ValueKind::Position && pos.measured && (pos.total_mm - 0.03).abs() < 1e-3 && angle_pos > 0.0, "{pos:?}");
        assert!(ori.group == ValueKind::Orientation && ori.measured && (ori.total_mm - 0.001).abs() < 2e-4, "{ori:?}");
        assert_eq!(f.of_group(1), ori.total_mm);
        // Without repeats the orientation's floor is the angles' logging only: not measured.
        let f = noise_floor(
            &m,
            &m.nominal,
            &data,
            FloorInputs {
                angle_step: Some(Step::Given(1e-4)),
                reading_step_mm: None,
                repeat: None,
                instrument: InstrumentNoise { row_std_mm: Some(0.03), accuracy_mm: None },
            },
        );
        assert!(!f.by_group[1].measured && f.by_group[1].total_mm < 1e-3, "{f:?}");
        // A point reading has one kind of value: no groups.
        let (chain, kinds) = DhTable::from_robot_hayati(&robot).chain(true, true);
        let point = Placement::tracker([2000.0, 0.0, 300.0], [0.0, 0.0, 40.0], None, nalgebra::Vector3::new(0.0, 0.05, 0.1));
        let m = CalibModel::of_chain("hayati", chain, kinds, &point);
        let data = Samples::readings(data.q.clone(), vec![0.0; 40 * 3], 3);
        assert!(noise_floor(
            &m,
            &m.nominal,
            &data,
            FloorInputs { angle_step: Some(Step::Given(1e-4)), reading_step_mm: None, repeat: Some(&rep), instrument: InstrumentNoise::default() }
        )
        .by_group
        .is_empty());
    }
}
