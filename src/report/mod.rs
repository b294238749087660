//! What a calibration or a diagnosis looks like, as plain numbers: the residual of every row
//! before and after, the features to plot it against, the convergence from the starting point,
//! each parameter's change with its uncertainty, the arm and the instrument. Residuals are held
//! as the calibration holds them, one per reading value ([`Measurement::dim`] per row: a
//! draw-wire's length, a tracker's x, y, z); [`Residual::of`] turns them into the per-row
//! quantities the figures draw (for a tracker's point also the position error |Δp|). The Rerun
//! recordings (the command line's `viz::scenes`) and the self-contained HTML page ([`html`]) draw the same
//! figures from these structs; the pass/fail [`verdict`] judges a result against a user's
//! accuracy limits.

pub mod artifact;
pub mod html;
pub mod svg;
pub mod ticks;
pub mod verdict;

use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::{Kind, Placement};
use crate::calib::pipeline::CalibResult;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::measurement::Measurement;
use crate::robot::kinematics::Frame;
use nalgebra::Matrix3;

/// A per-row quantity to plot a residual against.
#[derive(Clone, Debug)]
pub struct Feature {
    /// Short name (`q1`, `L`, `x`, `t`, `temp`), used in entity paths.
    pub name: String,
    /// Axis title with unit.
    pub label: String,
    /// Its value per row.
    pub values: Vec<f64>,
}

/// The joint angles, the reading's values (a draw-wire's `L`, a tracker's `x, y, z`) and, where
/// every row has them, time and temperature.
pub fn features(data: &Dataset) -> Vec<Feature> {
    let mut f: Vec<Feature> = (0..data.n_joints())
        .map(|j| Feature { name: format!("q{}", j + 1), label: format!("q{} (deg)", j + 1), values: data.rows.iter().map(|r| r.q_deg[j]).collect() })
        .collect();
    if let Some(m) = data.measurement() {
        for (k, col) in m.def().file_columns().iter().enumerate() {
            let unit = if k < m.file_lengths() { "mm" } else { "deg" };
            let label = if m.dim() == 1 { format!("measured length {col} (mm)") } else { format!("measured {col} ({unit})") };
            f.push(Feature { name: col.to_string(), label, values: data.rows.iter().map(|r| r.reading_mm.get(k).copied().unwrap_or(f64::NAN)).collect() });
        }
    }
    if data.rows.iter().all(|r| r.t_s.is_some()) {
        f.push(Feature { name: "t".into(), label: "acquisition time t (s)".into(), values: data.rows.iter().map(|r| r.t_s.unwrap_or(f64::NAN)).collect() });
    }
    if data.rows.iter().all(|r| r.temp_c.is_some()) {
        f.push(Feature { name: "temp".into(), label: "temperature (°C)".into(), values: data.rows.iter().map(|r| r.temp_c.unwrap_or(f64::NAN)).collect() });
    }
    f
}

/// One per-row quantity the residual figures draw: a value of the reading (the draw-wire's
/// length; a tracker's x, y or z) or, for a reading of several values, the row's position error
/// |Δp| (the Euclidean norm of its residuals).
#[derive(Clone, Debug)]
pub struct Residual {
    /// Short name for entity paths: the reading's column (`L`, `x`, …) or `dp` for |Δp|.
    pub name: String,
    /// What it is in titles: empty for a one-value reading (its residual is *the* residual),
    /// else the column (`x`) or `|Δp|`.
    pub label: String,
    /// A distance (|Δp| ≥ 0) rather than a signed residual.
    pub distance: bool,
    /// Per row, mm.
    pub before_mm: Vec<f64>,
    /// After calibration, per row, mm.
    pub after_mm: Vec<f64>,
}

impl Residual {
    /// The quantities of residuals held per reading value (`m.dim()` per row, row after row):
    /// the one value of a one-value reading; else the position error |Δp| first, then each
    /// value (column) in reading order.
    pub fn of(m: Measurement, before_mm: &[f64], after_mm: &[f64]) -> Vec<Residual> {
        let (dim, cols) = (m.dim(), m.def().columns());
        let value = |k: usize, v: &[f64]| -> Vec<f64> { v.chunks(dim).map(|c| c.get(k).copied().unwrap_or(f64::NAN)).collect() };
        if dim == 1 {
            return vec![Residual {
                name: cols[0].to_string(),
                label: String::new(),
                distance: false,
                before_mm: before_mm.to_vec(),
                after_mm: after_mm.to_vec(),
            }];
        }
        let mut out = vec![Residual {
            name: "dp".into(),
            label: "|Δp|".into(),
            distance: true,
            before_mm: crate::stats::position_errors(before_mm, dim),
            after_mm: crate::stats::position_errors(after_mm, dim),
        }];
        out.extend(cols.iter().enumerate().map(|(k, c)| Residual {
            name: c.to_string(),
            label: c.to_string(),
            distance: false,
            before_mm: value(k, before_mm),
            after_mm: value(k, after_mm),
        }));
        out
    }

    /// Title of its figures: `Residual`, `Residual x`, `Position error |Δp|`.
    pub fn title(&self) -> String {
        match (self.label.is_empty(), self.distance) {
            (true, _) => "Residual".into(),
            (false, true) => format!("Position error {}", self.label),
            (false, false) => format!("Residual {}", self.label),
        }
    }

    /// Its axis title: `residual (mm)`, `residual x (mm)`, `|Δp| (mm)`.
    pub fn axis(&self) -> String {
        match (self.label.is_empty(), self.distance) {
            (true, _) => "residual (mm)".into(),
            (false, true) => format!("{} (mm)", self.label),
            (false, false) => format!("residual {} (mm)", self.label),
        }
    }

    /// Title of its histogram of one side (`before`, `after`): `Residuals before`,
    /// `Residuals x before`, `Position error |Δp| before`.
    pub fn histogram_title(&self, side: &str) -> String {
        match (self.label.is_empty(), self.distance) {
            (true, _) => format!("Residuals {side}"),
            (false, true) => format!("{} {side}", self.title()),
            (false, false) => format!("Residuals {} {side}", self.label),
        }
    }

    /// The range its axes and histograms cover for values up to `vmax` in magnitude: from 0
    /// for a distance, symmetric about 0 for a residual.
    pub fn range(&self, vmax: f64) -> (f64, f64) {
        if self.distance {
            (0.0, vmax)
        } else {
            (-vmax, vmax)
        }
    }
}

/// Which panel a parameter belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Group {
    /// Kinematic lengths, mm.
    Lengths,
    /// Kinematic angles, degrees.
    Angles,
    /// The instrument's placement lengths, mm: the draw-wire sensor's exit point, length offset
    /// and tool point; a laser tracker's translation and the reflector on the flange.
    Placement,
    /// The instrument's placement angles, degrees: a laser tracker's rotation (the draw-wire
    /// has none).
    PlacementAngles,
    /// Non-geometric effects (their own units).
    Effects,
}

impl Group {
    /// Every group, in panel order.
    pub const ALL: [Group; 5] = [Group::Lengths, Group::Angles, Group::Placement, Group::PlacementAngles, Group::Effects];
    /// The group's short name (`lengths`, `angles`, `placement`, `placement_angles`, `effects`).
    pub fn name(self) -> &'static str {
        match self {
            Group::Lengths => "lengths",
            Group::Angles => "angles",
            Group::Placement => "placement",
            Group::PlacementAngles => "placement_angles",
            Group::Effects => "effects",
        }
    }
    /// The panel's title for an instrument of measurement `m` (the instrument's panels are
    /// named for it).
    pub fn title(self, m: Measurement) -> &'static str {
        let (lengths, angles) = m.def().panel_titles();
        match self {
            Group::Lengths => "Lengths (mm)",
            Group::Angles => "Angles (deg)",
            Group::Placement => lengths,
            Group::PlacementAngles => angles,
            Group::Effects => "Effects (own units)",
        }
    }
    /// The panel of parameter `k` of `model`.
    pub fn of(model: &crate::calib::model::CalibModel, k: usize) -> Group {
        let placement = model.setup_range().contains(&k);
        match model.kinds[k] {
            Kind::Effect(_) => Group::Effects,
            Kind::Angle if placement => Group::PlacementAngles,
            _ if placement => Group::Placement,
            Kind::Length => Group::Lengths,
            Kind::Angle => Group::Angles,
        }
    }
}

/// One free parameter: its change from the starting point, per iteration and at the end.
#[derive(Clone, Debug)]
pub struct ParamChange {
    /// Parameter name.
    pub name: String,
    /// Display unit of the change.
    pub unit: String,
    /// The panel it is drawn in.
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
    /// RMS of the training residuals per iteration, mm.
    pub train_rms_mm: Vec<f64>,
    /// RMS of the test residuals per iteration, mm (absent without test rows).
    pub test_rms_mm: Option<Vec<f64>>,
    /// ½ Σ r² over the training rows, mm².
    pub cost_mm2: Vec<f64>,
}

/// The arm drawn at one row: frame poses (mm) and the tool point.
#[derive(Clone, Debug)]
pub struct ArmPose {
    /// Dataset row (0-based).
    pub row: usize,
    /// Frames of the arm (base, links, flange), positions in mm.
    pub frames: Vec<Frame>,
    /// Tool point, base frame, mm.
    pub tool_mm: [f64; 3],
}

/// Where the calibrated instrument sits in the base frame, to draw it with its line to the
/// target: the draw-wire's cable exit point (the wire runs to the tool point), or a laser
/// tracker's origin and axes (its line of sight runs to the reflector).
#[derive(Clone, Debug, PartialEq)]
pub struct InstrumentPose {
    /// What the instrument reads.
    pub measurement: Measurement,
    /// The cable exit point, or the tracker's origin, base frame, mm.
    pub origin_mm: [f64; 3],
    /// The instrument's own axes in the base frame (columns: its x, y, z), for an instrument
    /// with a frame (a tracker reads in its own); `None` for the cable exit, a point.
    pub axes: Option<Matrix3<f64>>,
}

impl InstrumentPose {
    /// The pose of the instrument placed at `p` ([`Placing::frame`](crate::measurement::Placing::frame)).
    pub fn of(p: &Placement) -> InstrumentPose {
        let f = p.measurement.def().frame(&p.own);
        InstrumentPose { measurement: p.measurement, origin_mm: mm3(&f.origin), axes: f.axes }
    }
}

/// Everything the calibration figures show.
#[derive(Clone, Debug)]
pub struct CalibFigures {
    /// Figure title: method, model and data.
    pub title: String,
    /// Per row: used for training (else held out, or a training outlier kept out).
    pub train: Vec<bool>,
    /// Per row: a held-out (test) row.
    pub test: Vec<bool>,
    /// What the rows read.
    pub measurement: Measurement,
    /// Measured minus predicted reading, mm, one per reading value (row after row): the
    /// starting model and the calibrated one.
    pub before_mm: Vec<f64>,
    /// Measured minus predicted reading after calibration, mm, in the same order.
    pub after_mm: Vec<f64>,
    /// Tool point of every row, calibrated model, mm.
    pub tool_mm: Vec<[f64; 3]>,
    /// The calibrated instrument.
    pub instrument: InstrumentPose,
    /// The calibrated arm at the first row.
    pub arm: Option<ArmPose>,
    /// The artifact the rows read, if any.
    pub artifact: Option<artifact::ArtifactFigure>,
    /// The per-row quantities to plot residuals against.
    pub features: Vec<Feature>,
    /// Every free parameter's change from the starting point.
    pub params: Vec<ParamChange>,
    /// Cost and RMS per iteration.
    pub convergence: Convergence,
}

fn mm3(v: &nalgebra::Vector3<f64>) -> [f64; 3] {
    [crate::units::to_mm(v.x), crate::units::to_mm(v.y), crate::units::to_mm(v.z)]
}

/// The calibrated tool point of every row of `s` (mm) and the calibrated instrument.
fn tool_points_and_instrument(r: &CalibResult, s: &Samples) -> (Vec<[f64; 3]>, InstrumentPose) {
    let mut w = r.model.work();
    let tool_mm = (0..s.len()).map(|i| mm3(&r.model.tool_point_with(&r.x, &s.q[i], &s.inputs[i], &mut w))).collect();
    (tool_mm, InstrumentPose::of(&r.model.placement(&r.x)))
}

/// Every row of `data` as samples with the model's per-row inputs (torques, flanks, time).
fn all_samples(r: &CalibResult, data: &Dataset) -> Samples {
    let all: Vec<usize> = (0..data.rows.len()).collect();
    let mut s = crate::calib::pipeline::samples(data, &all);
    s.inputs = crate::calib::effects::inputs::row_inputs(data, r.torque_model.as_ref());
    s
}

use crate::stats::rms;

/// The arm of model `x` at row `row` (frames in mm).
fn arm_pose(r: &CalibResult, x: &[f64], s: &Samples, row: usize) -> Option<ArmPose> {
    let q = s.q.get(row)?;
    let chain = &r.model.chain;
    let mut fk = crate::robot::kinematics::FkWork::new(chain);
    chain.forward(q, &x[..r.model.n_chain()], 1.0, &mut fk);
    let frames: Vec<Frame> = (0..chain.n_frames())
        .map(|f| {
            let fr = chain.frame(&fk, f);
            Frame { rot: fr.rot, pos: crate::units::to_mm(fr.pos) }
        })
        .collect();
    let mut w = r.model.work();
    Some(ArmPose { row, frames, tool_mm: mm3(&r.model.tool_point_with(x, q, &s.inputs[row], &mut w)) })
}

/// Measured minus predicted reading (mm) of every row, every effect and corrector included:
/// one per reading value, row after row (NaN where a row lacks a value).
pub fn residuals_after(r: &CalibResult, data: &Dataset) -> Vec<f64> {
    let dim = r.model.measurement.dim();
    let predicted = r.predict_rows(data);
    data.rows
        .iter()
        .zip(predicted.chunks(dim))
        .flat_map(|(row, p)| {
            let y = row.values_mm().filter(|v| v.len() == dim);
            p.iter().enumerate().map(move |(k, p)| y.as_ref().map_or(f64::NAN, |y| y[k] - p))
        })
        .collect()
}

impl CalibFigures {
    /// The figures of calibration `r` of `data`, split into training and test rows as the
    /// result records (its `test_rows`).
    pub fn new(r: &CalibResult, data: &Dataset) -> Result<CalibFigures> {
        let n = data.rows.len();
        if let Some(&bad) = r.provenance.test_rows.iter().find(|&&i| i >= n) {
            return Err(Error::Invalid(format!("the result's test row {} is beyond these data's {n} rows (a result of other data?)", bad + 1)));
        }
        let test_idx = r.provenance.test_rows.clone();
        let mut in_test = vec![false; n];
        test_idx.iter().for_each(|&i| in_test[i] = true);
        let mut train_idx: Vec<usize> = (0..n).filter(|&i| !in_test[i]).collect();
        // Readings in a reading step are shown corrected, as the calibration took them (test
        // rows by their nearest training row).
        let all: Vec<usize> = (0..data.rows.len()).collect();
        let raw = all_samples(r, data);
        let s = crate::calib::fit::robust::apply_steps_nearest(&raw, &all, &train_idx, &r.screen.reading_steps);
        // The calibration kept its training outliers out: so do its figures.
        train_idx.retain(|i| !r.screen.outliers.iter().any(|o| o.row == i + 1));
        let mut train = vec![false; data.rows.len()];
        for &i in &train_idx {
            train[i] = true;
        }
        let mut held_out = vec![false; data.rows.len()];
        for &i in &test_idx {
            held_out[i] = true;
        }
        let x0 = &r.model.nominal;
        let before_mm = ReadingFit { model: &r.model, data: &s }.residuals_mm(x0);
        let after_mm: Vec<f64> = residuals_after(r, data).iter().zip(raw.y.iter().zip(&s.y)).map(|(v, (a, b))| v - crate::units::to_mm(a - b)).collect();
        let (tool_mm, instrument) = tool_points_and_instrument(r, &s);

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
                let group = Group::of(&r.model, k);
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
            title: format!("{} / {} on {}", r.provenance.method, r.provenance.model_name, r.provenance.data),
            train,
            test: held_out,
            measurement: r.model.measurement,
            before_mm,
            artifact: r.artifact.as_ref().map(|a| artifact::ArtifactFigure::new(a, data, &after_mm, r.model.measurement.dim(), &tool_mm)),
            after_mm,
            tool_mm,
            instrument,
            arm: arm_pose(r, &r.x, &s, 0),
            features: features(data),
            params,
            convergence: conv,
        })
    }

    /// The per-row residual quantities to draw ([`Residual::of`]).
    pub fn residuals(&self) -> Vec<Residual> {
        Residual::of(self.measurement, &self.before_mm, &self.after_mm)
    }
}

/// One diagnosed cause: the residual against the reading change the cause predicts (one point
/// per reading value: a tracker's row gives three).
#[derive(Clone, Debug)]
pub struct CauseEvidence {
    /// The cause's one-line summary.
    pub title: String,
    /// Reading change the cause predicts on each reading value (the final model with and
    /// without it), mm, row after row.
    pub contribution_mm: Vec<f64>,
    /// Residual without this cause (final residual + its contribution), mm.
    pub without_mm: Vec<f64>,
    /// Residual of the final model, mm.
    pub with_mm: Vec<f64>,
}

/// Everything the diagnosis figures show.
#[derive(Clone, Debug)]
pub struct DiagnosisFigures {
    /// Figure title (`diagnosis of <data>`).
    pub title: String,
    /// What the rows read.
    pub measurement: Measurement,
    /// Residual of the final model's geometry with every named cause removed, mm, one per
    /// reading value (row after row).
    pub before_mm: Vec<f64>,
    /// Residual of the final (extended) model, mm, one per reading value.
    pub after_mm: Vec<f64>,
    /// Tool point of every row, final model, mm.
    pub tool_mm: Vec<[f64; 3]>,
    /// The final model's instrument.
    pub instrument: InstrumentPose,
    /// The final model's arm at the first row.
    pub arm: Option<ArmPose>,
    /// The artifact the rows read, if any.
    pub artifact: Option<artifact::ArtifactFigure>,
    /// The per-row quantities to plot residuals against.
    pub features: Vec<Feature>,
    /// Each effect block of the final model, with the residual it explains.
    pub causes: Vec<CauseEvidence>,
    /// Held-out RMSE after step 0 (geometric), 1, … (mm).
    pub heldout_rmse_mm: Vec<f64>,
    /// Rows the diagnosis kept out as outliers (0-based).
    pub outliers: Vec<usize>,
}

impl DiagnosisFigures {
    /// The figures of diagnosis `d`, whose final model is `r`, on `data`.
    pub fn new(d: &crate::diagnose::Diagnosis, r: &CalibResult, data: &Dataset) -> DiagnosisFigures {
        let all: Vec<usize> = (0..data.rows.len()).collect();
        // Reading steps are a cable encoder's: only one-value readings have any.
        let raw = all_samples(r, data);
        let s = if d.reading_steps.is_empty() { raw } else { crate::calib::fit::robust::apply_steps(&raw, &all, &d.reading_steps) };
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
            let title = d.causes.iter().find(|c| c.is(block.kind, block.joint)).map(|c| c.summary()).unwrap_or_else(|| block.label());
            causes.push(CauseEvidence { title, contribution_mm, without_mm, with_mm: after_mm.clone() });
        }
        let (tool_mm, instrument) = tool_points_and_instrument(r, &s);
        let mut heldout: Vec<f64> = d.steps.iter().map(|s| s.heldout_rmse_before_mm).collect();
        heldout.push(d.final_heldout_rmse_mm);
        heldout.truncate(d.causes.len() + 1);
        DiagnosisFigures {
            title: format!("diagnosis of {}", d.data),
            measurement: r.model.measurement,
            before_mm,
            artifact: r.artifact.as_ref().map(|a| artifact::ArtifactFigure::new(a, data, &after_mm, r.model.measurement.dim(), &tool_mm)),
            after_mm,
            tool_mm,
            instrument,
            arm: arm_pose(r, &r.x, &s, 0),
            features: features(data),
            causes,
            heldout_rmse_mm: heldout,
            outliers: d.outliers.iter().map(|o| o.row.saturating_sub(1)).collect(),
        }
    }

    /// The per-row residual quantities to draw ([`Residual::of`]).
    pub fn residuals(&self) -> Vec<Residual> {
        Residual::of(self.measurement, &self.before_mm, &self.after_mm)
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

/// What a replay's report and recording show (`twincal replay --report / --rrd`), over the
/// replayed rows.
pub struct ReplayFigures {
    /// Figure title.
    pub title: String,
    /// What the rows read.
    pub measurement: Measurement,
    /// Which rows are judged, in words.
    pub judged_on: String,
    /// (label, stats) lines of the summary table.
    pub stats: Vec<(String, Option<crate::stats::metrics::ErrorStats>)>,
    /// One line on the twin's own noise and a Kolmogorov–Smirnov test of the judged residuals
    /// against it.
    pub ks_line: String,
    /// Per replayed row: a judged (held-out) row.
    pub judged: Vec<bool>,
    /// The twin's reading − its noise-free reading, and measured − the twin's noise-free
    /// reading, mm, one per value, row after row.
    pub noise_mm: Vec<f64>,
    /// Measured reading minus the twin's noise-free reading, mm (see `noise_mm`).
    pub residual_mm: Vec<f64>,
    /// The twin's tool point per replayed row, base frame, mm.
    pub tools_mm: Vec<[f64; 3]>,
    /// The twin's instrument.
    pub instrument: InstrumentPose,
    /// The replayed rows' joint angles, readings, time and temperature.
    pub features: Vec<Feature>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn a_tracker_reads_its_origin_as_zero_and_its_axes_as_unit_points() {
        let p = Placement { measurement: Measurement::Point, own: vec![2.5, -0.4, 0.3, 0.02, -0.015, 0.7], tool: Vector3::zeros() };
        let pose = InstrumentPose::of(&p);
        let axes = pose.axes.expect("a tracker has axes");
        let origin = Vector3::from(pose.origin_mm) * 1e-3;
        let mut y = [0.0; 3];
        Measurement::Point.reading(&p.own, &origin, &mut y);
        assert!(y.iter().all(|v| v.abs() < 1e-12), "the origin reads {y:?}");
        for k in 0..3 {
            Measurement::Point.reading(&p.own, &(origin + axes.column(k)), &mut y);
            for (i, v) in y.iter().enumerate() {
                assert!((v - if i == k { 1.0 } else { 0.0 }).abs() < 1e-12, "axis {k} reads {y:?}");
            }
        }
        // The cable exit is a point: the placement's exit, in mm.
        let cable = InstrumentPose::of(&Placement::cable(Vector3::new(0.8, 0.3, 0.05), 0.12, Vector3::zeros()));
        assert_eq!((cable.origin_mm, cable.axes), ([800.0, 300.0, 50.0], None));
    }

    #[test]
    fn residuals_per_row_are_the_value_or_the_position_error_and_each_coordinate() {
        let one = Residual::of(Measurement::Length, &[0.1, -0.2], &[0.01, 0.02]);
        assert_eq!(one.len(), 1);
        assert_eq!((one[0].name.as_str(), one[0].title(), one[0].axis(), one[0].distance), ("L", "Residual".into(), "residual (mm)".into(), false));
        assert_eq!((one[0].before_mm.clone(), one[0].after_mm.clone()), (vec![0.1, -0.2], vec![0.01, 0.02]));
        let before = [3.0, 4.0, 0.0, -1.0, 2.0, -2.0];
        let after = [0.0, 0.0, 0.5, f64::NAN, 0.0, 0.0];
        let r = Residual::of(Measurement::Point, &before, &after);
        let names: Vec<&str> = r.iter().map(|q| q.name.as_str()).collect();
        assert_eq!(names, ["dp", "x", "y", "z"]);
        assert_eq!(r[0].before_mm, vec![5.0, 3.0]);
        assert_eq!(r[0].after_mm[0], 0.5);
        assert!(r[0].after_mm[1].is_nan(), "a missing value leaves the row's |Δp| unknown");
        assert_eq!((r[2].before_mm.clone(), r[3].before_mm.clone()), (vec![4.0, 2.0], vec![0.0, -2.0]));
        assert_eq!((r[0].title(), r[0].axis(), r[0].range(2.0)), ("Position error |Δp|".into(), "|Δp| (mm)".into(), (0.0, 2.0)));
        assert_eq!((r[1].title(), r[1].histogram_title("after"), r[1].range(2.0)), ("Residual x".into(), "Residuals x after".into(), (-2.0, 2.0)));
    }
}
