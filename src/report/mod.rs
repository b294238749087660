//! What a calibration or a diagnosis looks like, as plain numbers: the residual of every row
//! before and after, the features to plot it against, the convergence from the starting point,
//! each parameter's change with its uncertainty. The Rerun recordings ([`crate::viz::scenes`])
//! and the self-contained HTML page ([`html`]) draw the same figures from these structs; the
//! pass/fail [`verdict`] judges a result against a user's accuracy limits.

pub mod html;
pub mod svg;
pub mod ticks;
pub mod verdict;

use crate::calib::model::Kind;
use crate::calib::problem::{ReadingFit, Samples};
use crate::calib::run::{CalibOptions, CalibResult};
use crate::dataset::Dataset;
use crate::error::Result;
use crate::robot::kinematics::Frame;

/// A per-row quantity to plot a residual against.
#[derive(Clone, Debug)]
pub struct Feature {
    /// Short name (`q1`, `L`, `t`, `temp`), used in entity paths.
    pub name: String,
    /// Axis title with unit.
    pub label: String,
    pub values: Vec<f64>,
}

/// The joint angles, the measured length and, where every row has them, time and temperature.
pub fn features(data: &Dataset) -> Vec<Feature> {
    let mut f: Vec<Feature> = (0..data.n_joints())
        .map(|j| Feature { name: format!("q{}", j + 1), label: format!("q{} (deg)", j + 1), values: data.rows.iter().map(|r| r.q_deg[j]).collect() })
        .collect();
    f.push(Feature { name: "L".into(), label: "measured length L (mm)".into(), values: data.rows.iter().map(|r| r.l_mm().unwrap_or(f64::NAN)).collect() });
    if data.rows.iter().all(|r| r.t_s.is_some()) {
        f.push(Feature { name: "t".into(), label: "acquisition time t (s)".into(), values: data.rows.iter().map(|r| r.t_s.unwrap_or(f64::NAN)).collect() });
    }
    if data.rows.iter().all(|r| r.temp_c.is_some()) {
        f.push(Feature { name: "temp".into(), label: "temperature (°C)".into(), values: data.rows.iter().map(|r| r.temp_c.unwrap_or(f64::NAN)).collect() });
    }
    f
}

/// Which panel a parameter belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Group {
    /// Kinematic lengths, mm.
    Lengths,
    /// Kinematic angles, degrees.
    Angles,
    /// Draw-wire sensor: exit point, length offset, tool point, mm.
    Sensor,
    /// Non-geometric effects (their own units).
    Effects,
}

impl Group {
    pub const ALL: [Group; 4] = [Group::Lengths, Group::Angles, Group::Sensor, Group::Effects];
    pub fn name(self) -> &'static str {
        match self {
            Group::Lengths => "lengths",
            Group::Angles => "angles",
            Group::Sensor => "sensor",
            Group::Effects => "effects",
        }
    }
    pub fn title(self) -> &'static str {
        match self {
            Group::Lengths => "Lengths (mm)",
            Group::Angles => "Angles (deg)",
            Group::Sensor => "Sensor (mm)",
            Group::Effects => "Effects (own units)",
        }
    }
}

/// One free parameter: its change from the starting point, per iteration and at the end.
#[derive(Clone, Debug)]
pub struct ParamChange {
    pub name: String,
    pub unit: String,
    pub group: Group,
    /// Final value minus starting value (display units).
    pub change: f64,
    /// Standard uncertainty of the final value.
    pub sigma: Option<f64>,
    /// Truth-equivalent value minus starting value (with a truth file).
    pub truth_change: Option<f64>,
    /// Change from the start at iteration 0 (= 0), 1, 2, … (see [`Convergence`]).
    pub history: Vec<f64>,
}

/// Cost and RMS of the training residuals (and of the test rows) from the starting point
/// (iteration 0) through every optimiser iteration.
#[derive(Clone, Debug, Default)]
pub struct Convergence {
    pub train_rms_mm: Vec<f64>,
    pub test_rms_mm: Option<Vec<f64>>,
    /// ½ Σ r² over the training rows, mm².
    pub cost_mm2: Vec<f64>,
}

/// The arm drawn at one row: frame poses (mm) and the tool point.
#[derive(Clone, Debug)]
pub struct ArmPose {
    pub row: usize,
    pub frames: Vec<Frame>,
    pub tool_mm: [f64; 3],
}

/// Everything the calibration figures show.
#[derive(Clone, Debug)]
pub struct CalibFigures {
    pub title: String,
    /// Per row: used for training (else held out).
    pub train: Vec<bool>,
    /// Measured minus predicted length, mm: the starting model and the calibrated one.
    pub before_mm: Vec<f64>,
    pub after_mm: Vec<f64>,
    /// Tool point of every row, calibrated model, mm.
    pub tool_mm: Vec<[f64; 3]>,
    /// Calibrated cable exit point, mm.
    pub exit_mm: [f64; 3],
    pub arm: Option<ArmPose>,
    pub features: Vec<Feature>,
    pub params: Vec<ParamChange>,
    pub convergence: Convergence,
}

fn mm3(v: &nalgebra::Vector3<f64>) -> [f64; 3] {
    [v.x * 1e3, v.y * 1e3, v.z * 1e3]
}

/// The calibrated tool point of every row of `s` and the calibrated cable exit point, mm.
fn tool_points_and_exit(r: &CalibResult, s: &Samples) -> (Vec<[f64; 3]>, [f64; 3]) {
    let mut w = r.model.work();
    let tool_mm = (0..s.len()).map(|i| mm3(&r.model.tool_point_with(&r.x, &s.q[i], &s.inputs[i], &mut w))).collect();
    (tool_mm, mm3(&r.model.placement(&r.x).exit().unwrap_or_else(nalgebra::Vector3::zeros)))
}

/// Every row of `data` as samples with the model's per-row inputs (torques, flanks, time).
fn all_samples(r: &CalibResult, data: &Dataset) -> Samples {
    let all: Vec<usize> = (0..data.rows.len()).collect();
    let mut s = crate::calib::run::samples(data, &all);
    s.inputs = crate::calib::inputs::row_inputs(data, r.torque_model.as_ref());
    s
}

use crate::calib::stats::rms;

/// The arm of model `x` at row `row` (frames in mm).
fn arm_pose(r: &CalibResult, x: &[f64], s: &Samples, row: usize) -> Option<ArmPose> {
    let q = s.q.get(row)?;
    let chain = &r.model.chain;
    let mut fk = crate::robot::kinematics::FkWork::new(chain);
    chain.forward(q, &x[..r.model.n_chain()], 1.0, &mut fk);
    let frames: Vec<Frame> = (0..chain.n_frames())
        .map(|f| {
            let fr = chain.frame(&fk, f);
            Frame { rot: fr.rot, pos: fr.pos * 1e3 }
        })
        .collect();
    let mut w = r.model.work();
    Some(ArmPose { row, frames, tool_mm: mm3(&r.model.tool_point_with(x, q, &s.inputs[row], &mut w)) })
}

/// Measured minus predicted length (mm) of every row, every effect and corrector included.
pub fn residuals_after(r: &CalibResult, data: &Dataset) -> Vec<f64> {
    data.rows.iter().zip(r.predict_rows(data)).map(|(row, p)| row.l_mm().unwrap_or(f64::NAN) - p).collect()
}

impl CalibFigures {
    /// The figures of calibration `r` of `data` run with `opts` (for the train / test split).
    pub fn new(r: &CalibResult, data: &Dataset, opts: &CalibOptions) -> Result<CalibFigures> {
        let (mut train_idx, test_idx) = crate::calib::run::split_rows(data, opts.test_fraction, opts.seed)?;
        // Readings in a reading step are shown corrected, as the calibration took them (test
        // rows by their nearest training row).
        let all: Vec<usize> = (0..data.rows.len()).collect();
        let raw = all_samples(r, data);
        let s = crate::calib::robust::apply_steps_nearest(&raw, &all, &train_idx, &r.reading_steps);
        // The calibration kept its training outliers out: so do its figures.
        train_idx.retain(|i| !r.outliers.iter().any(|o| o.row == i + 1));
        let mut train = vec![false; data.rows.len()];
        for &i in &train_idx {
            train[i] = true;
        }
        let x0 = &r.model.nominal;
        let before_mm = ReadingFit { model: &r.model, data: &s }.residuals_mm(x0);
        let after_mm: Vec<f64> = residuals_after(r, data).iter().zip(raw.y.iter().zip(&s.y)).map(|(v, (a, b))| v - (a - b) * 1e3).collect();
        let (tool_mm, exit_mm) = tool_points_and_exit(r, &s);

        // Convergence: the start, then every iteration the optimiser reported.
        let to_internal = |xs: &[f64]| -> Vec<f64> { xs.iter().enumerate().map(|(k, v)| v / r.model.kinds[k].display()).collect() };
        let mut xs: Vec<Vec<f64>> = vec![x0.clone()];
        xs.extend(r.history.iter().filter(|h| h.len() == x0.len()).map(|h| to_internal(h)));
        let (tr, te) = (s.subset(&train_idx), s.subset(&test_idx));
        let (ftr, fte) = (ReadingFit { model: &r.model, data: &tr }, ReadingFit { model: &r.model, data: &te });
        let mut conv = Convergence::default();
        let mut test = Vec::new();
        for x in &xs {
            let rt = ftr.residuals_mm(x);
            conv.train_rms_mm.push(rms(&rt));
            conv.cost_mm2.push(0.5 * rt.iter().map(|v| v * v).sum::<f64>());
            if !te.is_empty() {
                test.push(rms(&fte.residuals_mm(x)));
            }
        }
        conv.test_rms_mm = (!te.is_empty()).then_some(test);

        let params = r
            .parameters
            .iter()
            .enumerate()
            .filter(|(_, p)| !p.fixed)
            .map(|(k, p)| {
                let group = match r.model.kinds[k] {
                    Kind::Effect(_) => Group::Effects,
                    _ if r.model.placement_range().contains(&k) => Group::Sensor,
                    Kind::Length => Group::Lengths,
                    Kind::Angle => Group::Angles,
                };
                let d = r.model.kinds[k].display();
                ParamChange {
                    name: p.name.clone(),
                    unit: p.unit.clone(),
                    group,
                    change: p.value - p.nominal,
                    sigma: p.std_uncertainty,
                    truth_change: p.truth.map(|t| t - p.nominal),
                    history: xs.iter().map(|x| x[k] * d - p.nominal).collect(),
                }
            })
            .collect();
        Ok(CalibFigures {
            title: format!("{} / {} on {}", r.method.name(), r.model_name, r.data),
            train,
            before_mm,
            after_mm,
            tool_mm,
            exit_mm,
            arm: arm_pose(r, &r.x, &s, 0),
            features: features(data),
            params,
            convergence: conv,
        })
    }
}

/// One diagnosed cause: the residual against the length change the cause predicts.
#[derive(Clone, Debug)]
pub struct CauseEvidence {
    /// The cause's one-line summary.
    pub title: String,
    /// Length change the cause predicts on each row (the final model with and without it), mm.
    pub contribution_mm: Vec<f64>,
    /// Residual without this cause (final residual + its contribution), mm.
    pub without_mm: Vec<f64>,
    /// Residual of the final model, mm.
    pub with_mm: Vec<f64>,
}

/// Everything the diagnosis figures show.
#[derive(Clone, Debug)]
pub struct DiagnosisFigures {
    pub title: String,
    /// Residual of the final model's geometry with every named cause removed, mm.
    pub before_mm: Vec<f64>,
    /// Residual of the final (extended) model, mm.
    pub after_mm: Vec<f64>,
    pub tool_mm: Vec<[f64; 3]>,
    pub exit_mm: [f64; 3],
    pub arm: Option<ArmPose>,
    pub features: Vec<Feature>,
    pub causes: Vec<CauseEvidence>,
    /// Held-out RMSE after step 0 (geometric), 1, … (mm).
    pub heldout_rmse_mm: Vec<f64>,
    /// Rows the diagnosis kept out as outliers (0-based).
    pub outliers: Vec<usize>,
}

impl DiagnosisFigures {
    pub fn new(d: &crate::diagnose::Diagnosis, r: &CalibResult, data: &Dataset) -> DiagnosisFigures {
        let all: Vec<usize> = (0..data.rows.len()).collect();
        let s = crate::calib::robust::apply_steps(&all_samples(r, data), &all, &d.reading_steps);
        let fit = ReadingFit { model: &r.model, data: &s };
        let after_mm = fit.residuals_mm(&r.x);
        let first = r.model.first_effect();
        let mut x_geo = r.x.clone();
        x_geo[first..].copy_from_slice(&r.model.nominal[first..]);
        let before_mm = fit.residuals_mm(&x_geo);
        let mut causes = Vec::new();
        for (b, block) in r.model.effects.iter().enumerate() {
            let mut x_without = r.x.clone();
            for k in r.model.effect_params(b) {
                x_without[k] = r.model.nominal[k];
            }
            let without_mm = fit.residuals_mm(&x_without);
            let contribution_mm: Vec<f64> = without_mm.iter().zip(&after_mm).map(|(w, a)| w - a).collect();
            let title = d
                .causes
                .iter()
                .find(|c| c.cause == block.kind.name() && c.joint == block.joint.map(|j| j + 1))
                .map(|c| c.summary())
                .unwrap_or_else(|| block.label());
            causes.push(CauseEvidence { title, contribution_mm, without_mm, with_mm: after_mm.clone() });
        }
        let (tool_mm, exit_mm) = tool_points_and_exit(r, &s);
        let mut heldout: Vec<f64> = d.steps.iter().map(|s| s.heldout_rmse_before_mm).collect();
        heldout.push(d.final_heldout_rmse_mm);
        heldout.truncate(d.causes.len() + 1);
        DiagnosisFigures {
            title: format!("diagnosis of {}", d.data),
            before_mm,
            after_mm,
            tool_mm,
            exit_mm,
            arm: arm_pose(r, &r.x, &s, 0),
            features: features(data),
            causes,
            heldout_rmse_mm: heldout,
            outliers: d.outliers.iter().map(|o| o.row.saturating_sub(1)).collect(),
        }
    }
}

/// Largest |value| of the finite values (a small positive floor so colour scales never divide
/// by zero).
pub fn max_abs(values: &[f64]) -> f64 {
    values.iter().filter(|v| v.is_finite()).fold(0.0f64, |m, v| m.max(v.abs())).max(1e-9)
}

/// Histogram of `values` in `bins` equal bins over `[lo, hi]`; returns `(edges, counts)` with
/// `edges.len() == bins + 1` and `counts.len() == bins`.
///
/// Like numpy: bins are half-open `[e_i, e_{i+1})` except the last, which includes `hi`; values
/// outside `[lo, hi]` and `NaN`s are not counted. If `bins == 0`, or `lo < hi` does not hold with
/// both finite, every count is zero (and with `bins == 0` both vectors are empty).
pub fn histogram(values: &[f64], bins: usize, lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    if bins == 0 {
        return (Vec::new(), Vec::new());
    }
    let edges: Vec<f64> = (0..=bins).map(|i| if i == bins { hi } else { lo + (hi - lo) * i as f64 / bins as f64 }).collect();
    let mut counts = vec![0.0; bins];
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return (edges, counts);
    }
    let width = (hi - lo) / bins as f64;
    for &v in values {
        if !(lo..=hi).contains(&v) {
            continue; // also skips NaN
        }
        let mut i = (((v - lo) / width).floor() as usize).min(bins - 1);
        // Guard against rounding placing v one bin off its edges.
        if v < edges[i] && i > 0 {
            i -= 1;
        } else if i + 1 < bins && v >= edges[i + 1] {
            i += 1;
        }
        counts[i] += 1.0;
    }
    (edges, counts)
}
