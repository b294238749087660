//! What went wrong in a run of outlier rows: hypotheses tested against the rows themselves.
//!
//! A run of rows far off the model is a fault of the acquisition, not of the model, and there
//! is more than one kind: the reading jumped (a reading step, see
//! [`crate::calib::fit::robust::reading_steps`]), one joint's logged angle is wrong over the run (an
//! offset, the wrong sign, a value the controller stopped updating, two joints in each other's
//! columns), or the instrument was moved. Each hypothesis is a correction of the run's rows
//! with few or no free numbers; the model (fitted on the kept rows) predicts the corrected
//! rows, and the hypothesis that leaves them like the kept rows with the lowest BIC is named,
//! with its evidence, when it stands clear of the runner-up. Otherwise the run is unexplained
//! (a jumble). The rows stay out of the fits either way; the report says why they are off.

use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::optim::{LevenbergMarquardt, NoObserver};
use serde::{Deserialize, Serialize};

/// What a joint's reading did over a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointFault {
    /// It jumped by an offset and stayed.
    Offset,
    /// Its sign flipped.
    Sign,
    /// It stopped updating (the first row's value held).
    Stale,
    /// Two joints' columns traded places.
    Swap,
}

/// What a run's rows show ([`RunFault::cause`]): a hypothesis named, or none (in files, its
/// name: `joint_sign`, `joint_sign+reading_offset`, `reading_offset`, `ambiguous`, ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum FaultKind {
    /// A joint's reading fault, with the instrument's reading jumping at the same time or not.
    Joint {
        /// What the joint's reading did.
        fault: JointFault,
        /// Whether the instrument's reading jumped by an offset too.
        with_reading: bool,
    },
    /// The instrument's reading jumped by an offset and stayed.
    ReadingOffset,
    /// The instrument moved (its placement refitted on the run).
    InstrumentMoved,
    /// Two hypotheses leave the rows like the kept rows: the rows cannot tell them apart.
    Ambiguous,
    /// No hypothesis leaves the rows like the kept rows (as a hypothesis: the rows as logged).
    Unexplained,
}

impl FaultKind {
    /// Every kind, in the order the names list them.
    pub const ALL: [FaultKind; 12] = [
        FaultKind::Joint { fault: JointFault::Offset, with_reading: false },
        FaultKind::Joint { fault: JointFault::Sign, with_reading: false },
        FaultKind::Joint { fault: JointFault::Stale, with_reading: false },
        FaultKind::Joint { fault: JointFault::Swap, with_reading: false },
        FaultKind::Joint { fault: JointFault::Offset, with_reading: true },
        FaultKind::Joint { fault: JointFault::Sign, with_reading: true },
        FaultKind::Joint { fault: JointFault::Stale, with_reading: true },
        FaultKind::Joint { fault: JointFault::Swap, with_reading: true },
        FaultKind::ReadingOffset,
        FaultKind::InstrumentMoved,
        FaultKind::Ambiguous,
        FaultKind::Unexplained,
    ];
    /// Its name in files and messages.
    pub fn name(self) -> &'static str {
        use JointFault::*;
        match self {
            FaultKind::Joint { fault: Offset, with_reading: false } => "joint_offset",
            FaultKind::Joint { fault: Sign, with_reading: false } => "joint_sign",
            FaultKind::Joint { fault: Stale, with_reading: false } => "joint_stale",
            FaultKind::Joint { fault: Swap, with_reading: false } => "joint_swap",
            FaultKind::Joint { fault: Offset, with_reading: true } => "joint_offset+reading_offset",
            FaultKind::Joint { fault: Sign, with_reading: true } => "joint_sign+reading_offset",
            FaultKind::Joint { fault: Stale, with_reading: true } => "joint_stale+reading_offset",
            FaultKind::Joint { fault: Swap, with_reading: true } => "joint_swap+reading_offset",
            FaultKind::ReadingOffset => "reading_offset",
            FaultKind::InstrumentMoved => "instrument_moved",
            FaultKind::Ambiguous => "ambiguous",
            FaultKind::Unexplained => "unexplained",
        }
    }
    /// The same joint fault with the instrument's reading jumping too (`None` for a kind that
    /// is no joint fault).
    pub fn with_reading(self) -> Option<FaultKind> {
        match self {
            FaultKind::Joint { fault, .. } => Some(FaultKind::Joint { fault, with_reading: true }),
            _ => None,
        }
    }
    /// Whether it names a cause (neither `ambiguous` nor `unexplained`).
    pub fn is_named(self) -> bool {
        !matches!(self, FaultKind::Ambiguous | FaultKind::Unexplained)
    }
}

impl std::fmt::Display for FaultKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl From<FaultKind> for String {
    fn from(k: FaultKind) -> String {
        k.name().to_string()
    }
}

impl TryFrom<String> for FaultKind {
    type Error = String;
    fn try_from(s: String) -> std::result::Result<FaultKind, String> {
        FaultKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown run fault '{s}' (one of {})", FaultKind::ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")))
    }
}

/// A named run fault: the hypothesis, its joints, its size, and how well it and its runner-up
/// explain the run.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunFault {
    /// First and last data row of the run, 1-based.
    pub first_row: usize,
    /// Last data row of the run, 1-based.
    pub last_row: usize,
    /// `joint_offset`, `joint_sign`, `joint_stale`, `joint_swap`, each also with
    /// `+reading_offset` (the reading jumped at the same time), `instrument_moved`,
    /// `reading_offset`; `ambiguous` when the best and the runner-up both leave the rows like
    /// the kept rows; `unexplained` when no hypothesis does. A combined cause competes with the
    /// others by its evidence against its extra freedom (BIC); its own parts are no rivals.
    pub cause: FaultKind,
    /// The joints concerned, 1-based.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<usize>,
    /// An offset's size (degrees for a joint, mm for the reading), where the cause has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// The reading's offset (mm) of a joint fault with a reading jump (`joint_*+reading_offset`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading_offset_mm: Option<f64>,
    /// RMS residual of the run's rows as logged, and corrected by the cause, mm.
    pub rms_as_logged_mm: f64,
    /// RMS residual of the run's rows corrected by the cause, mm.
    pub rms_corrected_mm: f64,
    /// The runner-up hypothesis and its corrected RMS.
    pub runner_up: String,
    /// The runner-up's corrected RMS, mm.
    pub runner_up_rms_mm: f64,
    /// One line of evidence.
    pub evidence: String,
}

/// A corrected run explains it when its RMS is at most this many robust standard deviations of
/// the kept rows ...
pub const EXPLAINED_SIGMAS: f64 = 4.0;
/// ... and the runner-up's residual sum of squares is at least this many times the named one's
/// and its RMS above [`RUNNER_UP_SIGMAS`] robust standard deviations (else both explain the
/// rows: `ambiguous`).
pub const CLEAR_RATIO: f64 = 4.0;
/// ... above which the runner-up no longer explains the rows too (robust standard deviations of the
/// kept rows).
pub const RUNNER_UP_SIGMAS: f64 = 2.0;
/// An offset of a whole run within this many of the kept rows' robust standard deviations is
/// taken for an error its rows share (a sweep's logging rounding), not a jump of the reading.
pub const SHARED_SIGMAS: f64 = 3.0;
/// A part of a combined fault is named instead of the whole where the χ² test of what it leaves
/// of the run at the kept rows' noise has at least this p-value (the rows are like the kept
/// rows with it alone).
pub const PART_FIT_ALPHA: f64 = 0.01;
/// ... or the runner-up has more free numbers than the named one and, weighed by what each
/// explains in units of the kept rows' noise against its free numbers, its BIC is at least this
/// much worse (strong evidence): seven numbers of an instrument refitted to a run of twenty rows
/// fit them below the noise, by their freedom alone.
pub const FREER_RIVAL_BIC: f64 = 6.0;
/// Largest joint offset tried, degrees.
pub const MAX_OFFSET_DEG: f64 = 20.0;

struct Hypothesis {
    cause: FaultKind,
    joints: Vec<usize>,
    value: Option<f64>,
    /// The reading's offset (mm) a combined hypothesis adds to its joint fault.
    reading: Option<f64>,
    params: usize,
    rss: f64,
    /// What it leaves of the run around the run's mean, and that mean (mm): the part of the rss
    /// a shared error of the run's rows may hold (0 and `rss` where the hypothesis fits the
    /// reading's offset itself).
    centred: f64,
    mean: f64,
}

impl Hypothesis {
    /// A hypothesis that leaves the run's residuals `r` with `params` free numbers.
    fn leaving(cause: FaultKind, joints: Vec<usize>, value: Option<f64>, params: usize, r: &[f64]) -> Hypothesis {
        let (mean, centred) = less_offset(r);
        Hypothesis { cause, joints, value, reading: None, params, rss: rss(r), centred, mean }
    }
    /// A hypothesis that fits the reading's offset besides (`reading`, mm), leaving `left` (mm²).
    fn with_offset(cause: FaultKind, joints: Vec<usize>, value: Option<f64>, reading: f64, params: usize, left: f64) -> Hypothesis {
        Hypothesis { cause, joints, value, reading: Some(reading), params, rss: left, centred: left, mean: 0.0 }
    }
}

/// What the run's residuals `r` leave after one reading offset: the offset (their mean) and
/// the sum of squares around it.
fn less_offset(r: &[f64]) -> (f64, f64) {
    let mean = r.iter().sum::<f64>() / r.len().max(1) as f64;
    (mean, r.iter().map(|v| (v - mean).powi(2)).sum())
}

/// The run's joint angles `q` with joint `j` turned by `d` (rad).
fn offset_joint(q: &[Vec<f64>], j: usize, d: f64) -> Vec<Vec<f64>> {
    q.iter().map(|q| q.iter().enumerate().map(|(k, v)| if k == j { v + d } else { *v }).collect()).collect()
}

/// Whether `a` is `b` with fewer freedoms (no fault at all, a single fault inside a combined
/// one): not a rival explanation of the rows but a part of it.
fn nested_in(a: &Hypothesis, b: &Hypothesis) -> bool {
    a.cause == FaultKind::Unexplained
        || (b.reading.is_some()
            && a.reading.is_none()
            && (a.cause == FaultKind::ReadingOffset || (a.cause.with_reading() == Some(b.cause) && a.joints == b.joints)))
}

/// The run's residuals (mm, unweighted) with joint angles `q` (rad) for its rows.
fn residuals(model: &CalibModel, x: &[f64], run: &Samples, q: &[Vec<f64>]) -> Vec<f64> {
    let data = Samples { q: q.to_vec(), ..run.unweighted() };
    ReadingFit { model, data: &data }.residuals_mm(x)
}

fn rss(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// The offset (rad) of joint `j` that best explains the run and its sum of squares: a grid of
/// 0.1° steps over ±[`MAX_OFFSET_DEG`], then golden-section search around the best point.
/// With `reading`, the reading's offset is fitted with it (the mean residual at each offset).
fn best_offset(model: &CalibModel, x: &[f64], run: &Samples, j: usize, reading: bool) -> (f64, f64) {
    let cost = |d: f64| {
        let r = residuals(model, x, run, &offset_joint(&run.q, j, d));
        if reading {
            less_offset(&r).1
        } else {
            rss(&r)
        }
    };
    let step = 0.1f64.to_radians();
    let n = (MAX_OFFSET_DEG / 0.1) as i64;
    let (mut best, mut best_cost) = (0.0, cost(0.0));
    for k in -n..=n {
        let d = k as f64 * step;
        let c = cost(d);
        if c < best_cost {
            (best, best_cost) = (d, c);
        }
    }
    let (mut a, mut b) = (best - step, best + step);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..40 {
        let (c, d) = (b - g * (b - a), a + g * (b - a));
        if cost(c) < cost(d) {
            b = d;
        } else {
            a = c;
        }
    }
    let d = 0.5 * (a + b);
    (d, cost(d).min(best_cost))
}

/// Every hypothesis for the run's rows `rows` (indices into `all`, consecutive; `all` in
/// acquisition order, readings as logged, unweighted): the reading's offset, each joint's
/// faults alone and each with a reading offset besides (a cable re-hooked after the fault), the
/// instrument moved.
fn hypotheses(model: &CalibModel, x: &[f64], all: &Samples, rows: &[usize]) -> Vec<Hypothesis> {
    let run = all.subset(rows);
    let nj = model.chain.n_joints;
    let mut out = Vec::new();
    let r = residuals(model, x, &run, &run.q);
    out.push(Hypothesis::leaving(FaultKind::Unexplained, vec![], None, 0, &r));
    // The reading jumped: one offset.
    let (mean, left) = less_offset(&r);
    out.push(Hypothesis { reading: None, ..Hypothesis::with_offset(FaultKind::ReadingOffset, vec![], Some(mean), mean, 1, left) });
    // A joint fault whose rows read `q`, alone and with the reading's offset.
    let mut joint_fault = |fault: JointFault, joints: Vec<usize>, q: &[Vec<f64>]| {
        let r = residuals(model, x, &run, q);
        let (mean, left) = less_offset(&r);
        out.push(Hypothesis::with_offset(FaultKind::Joint { fault, with_reading: true }, joints.clone(), None, mean, 1, left));
        out.push(Hypothesis::leaving(FaultKind::Joint { fault, with_reading: false }, joints, None, 0, &r));
    };
    for j in 0..nj {
        let flipped: Vec<Vec<f64>> = run.q.iter().map(|q| q.iter().enumerate().map(|(k, v)| if k == j { -v } else { *v }).collect()).collect();
        joint_fault(JointFault::Sign, vec![j + 1], &flipped);
        if let Some(q) = stale_angles(all, &run, rows, j, &|q| rss(&residuals(model, x, &run, q))) {
            joint_fault(JointFault::Stale, vec![j + 1], &q);
        }
        for k in j + 1..nj {
            let swapped: Vec<Vec<f64>> = run
                .q
                .iter()
                .map(|q| {
                    let mut q = q.clone();
                    q.swap(j, k);
                    q
                })
                .collect();
            joint_fault(JointFault::Swap, vec![j + 1, k + 1], &swapped);
        }
    }
    // An offset at the edge of the search is no fit of one (the run wants more than a joint's
    // offset can give): not a hypothesis.
    let inside = |d: f64| d.to_degrees().abs() < MAX_OFFSET_DEG - 0.1;
    for j in 0..nj {
        let (d, _) = best_offset(model, x, &run, j, false);
        if inside(d) {
            out.push(Hypothesis::leaving(
                FaultKind::Joint { fault: JointFault::Offset, with_reading: false },
                vec![j + 1],
                Some(d.to_degrees()),
                1,
                &residuals(model, x, &run, &offset_joint(&run.q, j, d)),
            ));
        }
        let (d, c) = best_offset(model, x, &run, j, true);
        if inside(d) {
            let mean = less_offset(&residuals(model, x, &run, &offset_joint(&run.q, j, d))).0;
            out.push(Hypothesis::with_offset(
                FaultKind::Joint { fault: JointFault::Offset, with_reading: true },
                vec![j + 1],
                Some(d.to_degrees()),
                mean,
                2,
                c,
            ));
        }
    }
    // The instrument moved: its placement refitted on the run's rows.
    let placement = model.setup_range();
    if run.y.len() > 2 * placement.len() {
        let fixed: Vec<bool> = (0..x.len()).map(|k| !placement.contains(&k)).collect();
        let plain = run.unweighted();
        let fit = ReadingFit { model, data: &plain };
        let xm = LevenbergMarquardt::budget(50).minimize(&fit, x, &fixed, &mut NoObserver).x;
        out.push(Hypothesis::leaving(FaultKind::InstrumentMoved, vec![], None, placement.len(), &fit.residuals_mm(&xm)));
    }
    out
}

/// A stale joint `j`: logged constant over the run (`rows` of `all`, as `run`) while it moved
/// on. Its true angles are taken on the line between the rows either side of the run, or
/// continuing the steps of the two rows before it (a sweep that ends within the run); the one
/// `cost` prefers. `None` where the joint is not constant over the run or nothing moves it.
fn stale_angles(all: &Samples, run: &Samples, rows: &[usize], j: usize, cost: &dyn Fn(&[Vec<f64>]) -> f64) -> Option<Vec<Vec<f64>>> {
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    if !(run.q.iter().all(|q| q[j] == run.q[0][j]) && first > 1) {
        return None;
    }
    let a = all.q[first - 1][j];
    let steps = [(last + 1 < all.len()).then(|| (all.q[last + 1][j] - a) / (rows.len() as f64 + 1.0)), Some(all.q[first - 1][j] - all.q[first - 2][j])];
    steps
        .into_iter()
        .flatten()
        .filter(|d| d.abs() > 1e-9)
        .map(|d| -> Vec<Vec<f64>> {
            run.q.iter().enumerate().map(|(k, q)| q.iter().enumerate().map(|(i, v)| if i == j { a + d * (k as f64 + 1.0) } else { *v }).collect()).collect()
        })
        .min_by(|p, q| cost(p).total_cmp(&cost(q)))
}

/// Names what went wrong in each run of outlier rows (`runs`: first and last row, 0-based,
/// inclusive) of `all` (in acquisition order, readings as logged) against `model` at `x`, with
/// the kept rows' robust scale `scale_mm`.
pub fn explain_runs(model: &CalibModel, x: &[f64], all: &Samples, runs: &[(usize, usize)], scale_mm: f64) -> Vec<RunFault> {
    runs.iter()
        .map(|&(first, last)| {
            let rows: Vec<usize> = (first..=last).collect();
            let mut h = hypotheses(model, x, all, &rows);
            let n = (rows.len() * all.dim) as f64;
            // The noise is known: the kept rows' scatter. A hypothesis is weighed by what it
            // explains in units of that noise against its free numbers (a fit below the noise
            // earns nothing more). The run's rows share errors (a sweep's logging rounding, up
            // to the kept rows' scatter on every row alike): an offset of the whole run within
            // [`SHARED_SIGMAS`] of that scatter is such a shared error, not a jump of the
            // reading, so it costs no hypothesis anything and earns none a free number.
            let shared = |h: &Hypothesis| h.reading.is_none() && h.mean.abs() <= SHARED_SIGMAS * scale_mm;
            let bic = |h: &Hypothesis| {
                if scale_mm > 0.0 {
                    let left = if shared(h) { h.centred } else { h.rss };
                    left / (scale_mm * scale_mm) + h.params as f64 * n.ln()
                } else {
                    n * (h.rss / n).max(1e-30).ln() + h.params as f64 * n.ln()
                }
            };
            h.sort_by(|a, b| bic(a).total_cmp(&bic(b)));
            let rms = |h: &Hypothesis| (h.rss / n).sqrt();
            let logged = h.iter().find(|h| h.cause == FaultKind::Unexplained).map_or(f64::NAN, rms);
            // A combined fault only where none of its parts alone leaves the rows like the kept
            // rows (with a few rows, a joint's free offset beside a reading jump fits their
            // noise): a part is named where what it leaves is consistent with the kept rows'
            // scatter (the χ² test at [`PART_FIT_ALPHA`]).
            let like_kept = |o: &Hypothesis| {
                let dof = (n - o.params as f64).max(1.0);
                let left = if shared(o) { o.centred } else { o.rss };
                scale_mm > 0.0 && crate::stats::f_survival(left / (scale_mm * scale_mm) / dof, dof, 1e9) >= PART_FIT_ALPHA
            };
            let fits_alone = |o: &Hypothesis| o.cause != FaultKind::Unexplained && rms(o) <= EXPLAINED_SIGMAS * scale_mm && nested_in(o, &h[0]) && like_kept(o);
            let best = h.iter().find(|o| fits_alone(o)).unwrap_or(&h[0]);
            // The runner-up: the best hypothesis of another kind or other joints.
            let runner = h.iter().skip(1).find(|o| (o.cause != best.cause || o.joints != best.joints) && !nested_in(o, best) && !nested_in(best, o));
            let clear = runner.is_none_or(|o| {
                (o.rss >= CLEAR_RATIO * best.rss && rms(o) > RUNNER_UP_SIGMAS * scale_mm) || (o.params > best.params && bic(o) - bic(best) >= FREER_RIVAL_BIC)
            });
            let fits = best.cause != FaultKind::Unexplained && rms(best) <= EXPLAINED_SIGMAS * scale_mm;
            let explained = fits && clear;
            let (runner_up, runner_up_rms_mm) = runner.map_or((String::new(), f64::NAN), |o| (label(o), rms(o)));
            let weighed = weighed_note(best, runner, &bic, shared(best), scale_mm);
            let evidence = if explained {
                format!(
                    "{}: the run's rows {:.3} mm RMS as logged, {:.3} mm so corrected (kept rows' robust sd {:.3} mm); next best {} at {:.3} mm{weighed}",
                    label(best),
                    logged,
                    rms(best),
                    scale_mm,
                    runner_up,
                    runner_up_rms_mm
                )
            } else if fits {
                format!(
                    "{} ({:.3} mm) or {} ({:.3} mm): both leave the rows like the kept rows (robust sd {:.3} mm; as logged {:.3} mm), these rows cannot tell them apart",
                    label(best),
                    rms(best),
                    runner_up,
                    runner_up_rms_mm,
                    scale_mm,
                    logged
                )
            } else {
                format!(
                    "no hypothesis leaves the rows within {EXPLAINED_SIGMAS} robust sd ({:.3} mm): best {} at {:.3} mm, then {} at {:.3} mm (as logged {:.3} mm)",
                    EXPLAINED_SIGMAS * scale_mm,
                    label(best),
                    rms(best),
                    runner_up,
                    runner_up_rms_mm,
                    logged
                )
            };
            RunFault {
                first_row: first + 1,
                last_row: last + 1,
                cause: if explained {
                    best.cause
                } else if fits {
                    FaultKind::Ambiguous
                } else {
                    FaultKind::Unexplained
                },
                joints: if explained { best.joints.clone() } else { vec![] },
                value: if explained { best.value } else { None },
                reading_offset_mm: if explained { best.reading } else { None },
                rms_as_logged_mm: logged,
                rms_corrected_mm: if explained { rms(best) } else { logged },
                runner_up,
                runner_up_rms_mm,
                evidence,
            }
        })
        .collect()
}

/// What the evidence line adds: how a freer runner-up that fits the rows closer is weighed
/// (`bic`), and the offset the named hypothesis leaves on every row where it is the rows' shared
/// error (`shared`).
fn weighed_note(best: &Hypothesis, runner: Option<&Hypothesis>, bic: &dyn Fn(&Hypothesis) -> f64, shared: bool, scale_mm: f64) -> String {
    let weighed = runner.filter(|o| o.params > best.params && o.rss < best.rss).map_or(String::new(), |o| {
        format!(" with {} free numbers against {}: weighed by the kept rows' noise, its BIC is {:.1} worse", o.params, best.params, bic(o) - bic(best))
    });
    let shared_note = (shared && best.mean.abs() > 0.5 * scale_mm).then(|| {
        format!(
            "; the {:+.3} mm it leaves on every row alike is within {SHARED_SIGMAS} robust sd, an error the rows of one run share (a sweep's rounding), not a jump of the reading",
            best.mean
        )
    });
    weighed + shared_note.as_deref().unwrap_or("")
}

fn label(h: &Hypothesis) -> String {
    let joints = h.joints.iter().map(|j| format!("j{j}")).collect::<Vec<_>>().join("<->");
    let mut value = match (h.cause, h.value) {
        (FaultKind::Joint { fault: JointFault::Offset, .. }, Some(v)) => format!(" {v:+.3} deg"),
        (FaultKind::ReadingOffset, Some(v)) => format!(" {v:+.3} mm"),
        _ => String::new(),
    };
    if let Some(r) = h.reading {
        value += &format!(", reading {r:+.3} mm");
    }
    if joints.is_empty() {
        format!("{}{value}", h.cause)
    } else {
        format!("{} {joints}{value}", h.cause)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_kinds_are_written_by_their_names_and_read_back() {
        for k in FaultKind::ALL {
            let json = serde_json::to_string(&k).unwrap();
            assert_eq!(json, format!("\"{}\"", k.name()));
            assert_eq!(serde_json::from_str::<FaultKind>(&json).unwrap(), k);
            assert_eq!(k.with_reading().is_some(), matches!(k, FaultKind::Joint { .. }), "{k}");
        }
        let names: std::collections::BTreeSet<&str> = FaultKind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(names.len(), FaultKind::ALL.len());
        let e = serde_json::from_str::<FaultKind>("\"joint_wobble\"").unwrap_err().to_string();
        assert!(e.contains("unknown run fault 'joint_wobble'") && e.contains("joint_sign+reading_offset"), "{e}");
    }
}
