//! The floor no model can beat on a dataset, from the data themselves: the spread of repeated
//! configurations, and what the logging resolution of the joint angles and of the reading costs
//! on each reading value (the angle steps propagated through the model's joint Jacobian). Each
//! source is named; the final residual of a fit is never one of them.

use crate::calib::model::CalibModel;
use crate::calib::problem::Samples;
use crate::stats::metrics::Repeatability;
use serde::{Deserialize, Serialize};

/// One contribution to the floor.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FloorSource {
    /// `repeatability`, `angle_resolution` or `reading_resolution`.
    pub source: String,
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
pub struct Instrument {
    /// RMS of the rows' own standard deviations of one coordinate, mm; `None` where the rows give
    /// none.
    pub row_std_mm: Option<f64>,
    /// The accuracy the user states, mm; `None` when not given.
    pub accuracy_mm: Option<f64>,
}

/// The floor of `data` (every row) for the model at `x`: repeatability where configurations
/// repeat, the joint angles' logging step (uniform quantisation, step²/12 per joint, through
/// ∂L/∂q of each row), the reading's step and what the instrument states of itself.
///
/// The reading's own error is counted once: the repeatability where configurations repeat, else
/// the reading's logging step; where the instrument states its uncertainty (rows' standard
/// deviations, a stated accuracy), the largest of these, since each is an estimate of the same
/// error and a stated accuracy includes what repeats do not show.
pub fn noise_floor(
    model: &CalibModel,
    x: &[f64],
    data: &Samples,
    angle_step_deg: Option<Step>,
    length_step_mm: Option<f64>,
    repeat: Option<&Repeatability>,
    instrument: Instrument,
) -> NoiseFloor {
    let mut sources = Vec::new();
    let cols = model.measurement.def().columns().join(", ");
    let dim = model.measurement.dim();
    if let Some(r) = repeat.filter(|r| r.groups > 0) {
        sources.push(FloorSource {
            source: "repeatability".into(),
            rms_mm: r.pooled_std,
            detail: format!("pooled spread of {cols} over {} repeated configurations ({} rows)", r.groups, r.rows),
        });
    }
    if let Some(step) = angle_step_deg.filter(|s| s.value() > 0.0) {
        let var_q = step.value().to_radians().powi(2) / 12.0;
        let mut w = model.work();
        let mut g = vec![0.0; model.chain.n_joints * dim];
        let mut y = vec![0.0; dim];
        // Per reading value: the mean over rows and values.
        let mean_var = data
            .q
            .iter()
            .zip(&data.inputs)
            .map(|(q, inp)| {
                model.readings_grad_q(x, q, inp, &mut w, &mut y, &mut g);
                g.iter().map(|d| crate::units::to_mm(d).powi(2) * var_q).sum::<f64>() / dim as f64
            })
            .sum::<f64>()
            / data.len().max(1) as f64;
        let through = if dim == 1 { format!("d{cols}/dq") } else { format!("d({cols})/dq") };
        sources.push(FloorSource {
            source: "angle_resolution".into(),
            rms_mm: mean_var.sqrt(),
            detail: format!("joint angles logged at {} deg ({}), through the model's {through}", step.value(), step.origin()),
        });
    }
    if let Some(step) = length_step_mm.filter(|s| *s > 0.0) {
        sources.push(FloorSource {
            source: "reading_resolution".into(),
            rms_mm: step / 12f64.sqrt(),
            detail: format!("{cols} logged at {step} mm (from the data's decimals)"),
        });
    }
    if let Some(v) = instrument.row_std_mm.filter(|v| *v > 0.0) {
        sources.push(FloorSource {
            source: "row_std".into(),
            rms_mm: v,
            detail: "RMS of the rows' own standard deviations (sx, sy, sz) per coordinate".into(),
        });
    }
    if let Some(v) = instrument.accuracy_mm.filter(|v| *v > 0.0) {
        sources.push(FloorSource {
            source: "instrument_accuracy".into(),
            rms_mm: v,
            detail: "the instrument's stated accuracy per coordinate, as given".into(),
        });
    }
    let has_repeat = sources.iter().any(|s| s.source == "repeatability");
    let stated = sources.iter().any(|s| s.source == "row_std" || s.source == "instrument_accuracy");
    let reading_side = |s: &FloorSource| matches!(s.source.as_str(), "repeatability" | "reading_resolution" | "row_std" | "instrument_accuracy");
    let total_mm = if stated {
        let reading = sources.iter().filter(|s| reading_side(s)).map(|s| s.rms_mm).fold(0.0, f64::max);
        sources.iter().filter(|s| !reading_side(s)).map(|s| s.rms_mm.powi(2)).sum::<f64>() + reading.powi(2)
    } else {
        sources.iter().filter(|s| !(has_repeat && s.source == "reading_resolution")).map(|s| s.rms_mm.powi(2)).sum::<f64>()
    };
    // An empty sum is -0.0: the floor of no known source is 0.
    let total_mm = (total_mm + 0.0).sqrt();
    NoiseFloor { total_mm, sources }
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
        use crate::calib::model::SensorGuess;
        use crate::robot::Robot;
        let robot = Robot::irb120();
        let m = CalibModel::dh(&robot, &SensorGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.1, tool_m: [0.0, 0.0, 0.05] }, true);
        let q: Vec<Vec<f64>> = (0..50).map(|k| (0..6).map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin()).collect()).collect();
        let data = Samples::new(q, vec![0.5; 50]);
        let none = Instrument::default();
        let f1 = noise_floor(&m, &m.nominal, &data, Some(Step::Detected(0.1)), Some(0.01), None, none);
        let f2 = noise_floor(&m, &m.nominal, &data, Some(Step::Given(0.2)), Some(0.01), None, none);
        let angle = |f: &NoiseFloor| f.sources.iter().find(|s| s.source == "angle_resolution").unwrap().rms_mm;
        // Linear in the step; a 0.1 deg step over a ~0.5 m arm is a few tenths of a millimetre.
        assert!((angle(&f2) / angle(&f1) - 2.0).abs() < 1e-12);
        assert!(angle(&f1) > 0.1 && angle(&f1) < 1.0, "{f1:?}");
        assert!((f1.total_mm - (angle(&f1).powi(2) + 0.01f64.powi(2) / 12.0).sqrt()).abs() < 1e-12);
        // With repeatability, the reading's step is inside it and is not added again.
        let rep = Repeatability { pooled_std: 0.05, groups: 3, rows: 7, max_spread: 0.1 };
        let f3 = noise_floor(&m, &m.nominal, &data, Some(Step::Detected(0.1)), Some(0.01), Some(&rep), none);
        assert!((f3.total_mm - (angle(&f1).powi(2) + 0.05f64.powi(2)).sqrt()).abs() < 1e-12);
        // A stated accuracy larger than the repeats' spread takes its place; rows' standard
        // deviations without repeats take the reading step's.
        let f4 = noise_floor(&m, &m.nominal, &data, None, Some(0.01), Some(&rep), Instrument { row_std_mm: Some(0.02), accuracy_mm: Some(0.08) });
        assert!((f4.total_mm - 0.08).abs() < 1e-12, "{f4:?}");
        let f5 = noise_floor(&m, &m.nominal, &data, None, Some(0.001), None, Instrument { row_std_mm: Some(0.02), accuracy_mm: None });
        assert!((f5.total_mm - 0.02).abs() < 1e-12 && f5.sources.iter().any(|s| s.source == "row_std"), "{f5:?}");
    }
}
