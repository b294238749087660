//! Robust estimation for measured data: gross outliers and runs of them are found with a
//! robust scale and kept out, and an optional heavy-tailed loss down-weights what remains.
//!
//! * [`screen`]: rows whose residual is more than `k` robust standard deviations (1.4826·MAD)
//!   from the median residual of a fit on the rows kept so far, iterated with refits until the
//!   set is stable. Flagged rows close together form [`OutlierRun`]s: on a real arm a run is
//!   one disturbed stretch of the acquisition (a bumped cable, a glitch of the reader), not
//!   independent bad luck.
//! * [`reading_steps`]: a run whose rows all sit one constant offset off (the reading jumped and
//!   stayed: a draw-wire slipped on its drum, an encoder lost counts) is a [`ReadingStep`]; its
//!   rows are corrected by the offset and kept, and rows of the same stretch that the fit never
//!   saw are corrected by the same offset.
//! * [`Loss`] and [`irls`]: Huber or Cauchy by iteratively reweighted least squares, the
//!   weights from the residuals over a robust scale re-estimated at every pass.

use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::optim::{LeastSquares, LevenbergMarquardt, NoObserver, Observer, Report};
use crate::stats::{median, robust_scale};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A row kept out of the fit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Outlier {
    /// Data row, 1-based (the first row after the header is 1).
    pub row: usize,
    /// The row's residual (measured minus model) that flagged it, mm: for several values per row,
    /// the one farthest from the median.
    pub residual_mm: f64,
    /// Distance from the median residual in robust standard deviations.
    pub robust_z: f64,
}

/// Outlier rows close together in acquisition order (gaps of at most [`RUN_GAP`] rows).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct OutlierRun {
    /// First and last data row, 1-based.
    pub first_row: usize,
    /// Last data row, 1-based.
    pub last_row: usize,
    /// Median residual of the run, mm.
    pub median_residual_mm: f64,
}

/// A stretch of the acquisition whose readings all sit one constant offset away from the
/// model: the reading jumped and stayed (a draw-wire that slipped on its drum, an encoder that
/// lost counts, a reader re-zeroed), so the rows are good once the offset is taken off. Found by
/// [`reading_steps`]; the offset is estimated from the training rows of the stretch.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ReadingStep {
    /// First and last (training) data row of the stretch, 1-based; the rows between them,
    /// test rows included, carry the offset.
    pub first_row: usize,
    /// Last (training) data row of the stretch, 1-based.
    pub last_row: usize,
    /// Training rows in the stretch.
    pub rows: usize,
    /// The reading's offset, mm (measured minus model): the readings are corrected by it.
    pub offset_mm: f64,
    /// Standard uncertainty of the offset (of the median of the stretch's residuals), mm.
    pub std_mm: f64,
}

impl ReadingStep {
    /// Whether data row `row` (0-based) lies in the stretch.
    pub fn covers(&self, row: usize) -> bool {
        (self.first_row..=self.last_row).contains(&(row + 1))
    }
}

/// The offset (mm) the steps give data row `row` (0-based); 0 outside every step.
pub fn step_offset_mm(steps: &[ReadingStep], row: usize) -> f64 {
    steps.iter().find(|s| s.covers(row)).map_or(0.0, |s| s.offset_mm)
}

/// `data` (row `i` is data row `rows[i]`, 0-based) with each reading in a step corrected by the
/// step's offset.
pub fn apply_steps(data: &Samples, rows: &[usize], steps: &[ReadingStep]) -> Samples {
    debug_assert_eq!(data.dim, 1, "reading steps are a cable encoder's");
    let mut out = data.clone();
    for (l, &row) in out.y.iter_mut().zip(rows) {
        *l -= crate::units::to_m(step_offset_mm(steps, row));
    }
    out
}

/// `data` (rows not seen by the fit; row `i` is data row `rows[i]`, 0-based) with each reading
/// corrected by the offset of the nearest row in acquisition order among the fit's rows `seen`
/// (ascending): inside a step that is the step's offset, and a row between two steps, or between
/// a step and clean rows, takes the side it is nearer to (the mean of both on a tie). A step is
/// one stretch of time, so its nearest neighbours in time are the best guess of a row's offset.
pub fn apply_steps_nearest(data: &Samples, rows: &[usize], seen: &[usize], steps: &[ReadingStep]) -> Samples {
    let mut out = data.clone();
    if steps.is_empty() || seen.is_empty() {
        return out;
    }
    debug_assert_eq!(data.dim, 1, "reading steps are a cable encoder's");
    for (l, &row) in out.y.iter_mut().zip(rows) {
        let at = seen.partition_point(|&d| d < row);
        let before = at.checked_sub(1).map(|i| seen[i]);
        let after = seen.get(at).copied();
        let off = match (before, after) {
            (Some(b), Some(a)) if row - b == a - row => 0.5 * (step_offset_mm(steps, b) + step_offset_mm(steps, a)),
            (Some(b), Some(a)) => step_offset_mm(steps, if row - b < a - row { b } else { a }),
            (Some(n), None) | (None, Some(n)) => step_offset_mm(steps, n),
            (None, None) => 0.0,
        };
        *l -= crate::units::to_m(off);
    }
    out
}

/// Fewest training rows of a reading step: fewer cannot tell a constant offset from a jumble.
pub const MIN_STEP_ROWS: usize = 4;
/// A step's offset is at least this many robust standard deviations (smaller shifts are left
/// to the noise).
pub const STEP_MIN_SIGMAS: f64 = 4.0;
/// Within a step the residuals scatter no more than this many times the robust scale of the
/// other rows: the offset is constant, not a disturbed stretch.
pub const STEP_MAX_SPREAD: f64 = 2.0;
/// Penalty of a change point in the segmentation, in robust variances times ln(window length):
/// the largest chance gain of one split over white noise is about 2·ln(n) variances.
pub const STEP_PENALTY: f64 = 8.0;

/// Reading steps among the residuals `r` (mm; sample `i` is data row `rows[i]`, 0-based,
/// ascending) of a fit whose good rows have median `med` and robust scale `scale`: each run of
/// rows beyond `k`·scale ([`runs`], at least [`MIN_STEP_ROWS`] rows) and a few rows either
/// side are cut into constant pieces by binary segmentation (penalty [`STEP_PENALTY`]); a piece
/// is a step when it has at least [`MIN_STEP_ROWS`] rows, an offset beyond [`STEP_MIN_SIGMAS`],
/// and the window holds no disturbed piece (a row beyond `k`·scale of its piece's offset, or an
/// offset piece whose spread exceeds [`STEP_MAX_SPREAD`]).
pub fn reading_steps(r: &[f64], rows: &[usize], med: f64, scale: f64, k: f64) -> Vec<ReadingStep> {
    if !(scale > 0.0) || k <= 0.0 {
        return Vec::new();
    }
    let flagged: Vec<Outlier> =
        (0..r.len()).filter(|&i| !((r[i] - med).abs() <= k * scale)).map(|i| Outlier { row: rows[i] + 1, residual_mm: r[i], robust_z: 0.0 }).collect();
    // Windows in sample indices around each long enough run, merged where they overlap.
    let mut windows: Vec<(usize, usize)> = Vec::new();
    for run in runs(&flagged) {
        let members = flagged.iter().filter(|o| (run.first_row..=run.last_row).contains(&o.row)).count();
        if members < MIN_STEP_ROWS {
            continue;
        }
        let first = rows.partition_point(|&d| d + 1 < run.first_row);
        let last = rows.partition_point(|&d| d < run.last_row);
        let (lo, hi) = (first.saturating_sub(MIN_STEP_ROWS + 1), (last + MIN_STEP_ROWS + 1).min(r.len()));
        match windows.last_mut() {
            Some(w) if lo <= w.1 => w.1 = w.1.max(hi),
            _ => windows.push((lo, hi)),
        }
    }
    let d: Vec<f64> = r.iter().map(|v| v - med).collect();
    let mut steps = Vec::new();
    for (lo, hi) in windows {
        let penalty = STEP_PENALTY * scale * scale * ((hi - lo) as f64).ln();
        let mut pieces = Vec::new();
        segment(&d, lo, hi, penalty, &mut pieces);
        // Per piece: offset, spread, and whether it is disturbed (not one offset).
        let stats: Vec<(f64, f64, bool)> = pieces
            .iter()
            .map(|&(a, b)| {
                let piece = &d[a..b];
                let (off, spread) = robust_scale(piece);
                let off_piece = off.abs() > STEP_MIN_SIGMAS * scale;
                let disturbed = (off_piece && spread > STEP_MAX_SPREAD * scale) || piece.iter().any(|v| (v - off).abs() > k * scale);
                (off, spread, disturbed)
            })
            .collect();
        // A constant piece in a stretch that also holds a disturbed piece is a lull in a
        // disturbed stretch, not a step: such a stretch stays outliers as a whole.
        if stats.iter().any(|s| s.2) {
            continue;
        }
        for (p, &(a, b)) in pieces.iter().enumerate() {
            let (off, spread, _) = stats[p];
            if b - a >= MIN_STEP_ROWS && off.abs() > STEP_MIN_SIGMAS * scale {
                let std_mm = 1.2533 * spread.max(scale) / ((b - a) as f64).sqrt();
                steps.push(ReadingStep { first_row: rows[a] + 1, last_row: rows[b - 1] + 1, rows: b - a, offset_mm: off, std_mm });
            }
        }
    }
    steps
}

/// Binary segmentation of `d[lo..hi]` into pieces of constant mean: the split that removes the
/// most squared deviation is kept while it removes more than `penalty`, and both sides hold at
/// least [`MIN_STEP_ROWS`] rows.
fn segment(d: &[f64], lo: usize, hi: usize, penalty: f64, out: &mut Vec<(usize, usize)>) {
    let n = hi - lo;
    let mut best: Option<(f64, usize)> = None;
    if n >= 2 * MIN_STEP_ROWS {
        let (total, total2) = d[lo..hi].iter().fold((0.0, 0.0), |(s, s2), v| (s + v, s2 + v * v));
        let sse = |s: f64, s2: f64, m: usize| s2 - s * s / m as f64;
        let whole = sse(total, total2, n);
        let (mut s, mut s2) = (0.0, 0.0);
        for c in 1..n {
            let v = d[lo + c - 1];
            s += v;
            s2 += v * v;
            if c < MIN_STEP_ROWS || n - c < MIN_STEP_ROWS {
                continue;
            }
            let gain = whole - sse(s, s2, c) - sse(total - s, total2 - s2, n - c);
            if best.is_none_or(|(g, _)| gain > g) {
                best = Some((gain, c));
            }
        }
    }
    match best {
        Some((gain, c)) if gain > penalty => {
            segment(d, lo, lo + c, penalty, out);
            segment(d, lo + c, hi, penalty, out);
        }
        _ => out.push((lo, hi)),
    }
}

/// What [`screen`] found.
#[derive(Clone, Debug)]
pub struct Screen {
    /// Indices (into the screened samples) of the rows kept.
    pub keep: Vec<usize>,
    /// The rows flagged, with their residuals.
    pub outliers: Vec<Outlier>,
    /// Runs of at least two outlier rows close together ([`runs`]).
    pub runs: Vec<OutlierRun>,
    /// Stretches whose readings are offset by a constant ([`reading_steps`]); their rows are
    /// kept, corrected.
    pub steps: Vec<ReadingStep>,
    /// The screened samples with the steps' readings corrected.
    pub corrected: Samples,
    /// The fit on the kept rows.
    pub x: Vec<f64>,
    /// Robust standard deviation of the kept rows' residuals (1.4826·MAD), mm, never below the
    /// rule's `min_scale_mm`; and their median.
    pub scale_mm: f64,
    /// Median of the kept rows' residuals, mm.
    pub median_mm: f64,
    /// The rule the rows were screened by.
    pub rule: ScreenRule,
}

/// How [`screen`] flags rows: a row whose residual is more than `k` robust standard deviations
/// from the kept rows' median is an outlier, the scale never taken below `min_scale_mm`, the
/// spread the data's known noise alone puts on a reading (the joint angles' logging resolution
/// through the model). Where the angles' rounding is shared by the rows of a sweep, most rows of
/// a sweep sit together and the residuals' median absolute deviation can fall far below that
/// noise (0.03 mm against 0.24 mm on a twin acquisition logged at 0.1°): whole sweeps, and the
/// rows a backlash flank shifts, were then taken for outliers. `steps`: look for reading steps
/// (a cable's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenRule {
    /// Threshold, robust standard deviations from the median.
    pub k: f64,
    /// Whether to look for reading steps.
    pub steps: bool,
    /// Floor of the robust scale, mm.
    pub min_scale_mm: f64,
}

/// The fit of the outlier screen: the identifiable parameters of `model` on `data` from `x`,
/// with the Cauchy loss. A least-squares fit bends towards a run of bad rows until none of them
/// stands out (on RobotCali a disturbed stretch of ~80 rows 4 mm off left the median absolute
/// deviation at 1.2 mm and no row beyond six of it); the Cauchy fit follows the good rows.
/// Its tolerances are 1e-6: the screen needs residuals to a small share of their scale, not the
/// last digits (on HSR the passes take 64–83 iterations instead of 129–140; RobotCali's test
/// RMSE moves by under 0.002 mm).
/// (A short cut — the least-squares fit alone when none of its rows is beyond 4.5 of its robust
/// scale — was tried: on RobotCali the later passes then took it with a disturbed stretch still
/// in, and the screen let it through.)
pub fn screen_fit(model: &CalibModel, data: &Samples, x: &[f64], rank_tol: f64) -> Vec<f64> {
    let fit = ReadingFit { model, data };
    let fixed = crate::calib::fit::identify::identify(&fit, x, rank_tol).fixed_mask;
    let lm = LevenbergMarquardt::budget(200).tolerances(1e-6, 1e-6);
    irls(&lm, &fit, x, &fixed, Loss::Cauchy, &mut NoObserver).x
}

/// The value of a row's residuals (one per reading value) farthest from `med`: what judges the
/// row against a robust scale (a row is out when any of its values is). NaN for an empty row.
pub fn farthest_from(values: &[f64], med: f64) -> f64 {
    values.iter().copied().fold(f64::NAN, |far, v| if far.is_nan() || (v - med).abs() > (far - med).abs() { v } else { far })
}

/// Passes of the screen at most: the set of kept rows settles in two or three.
const SCREEN_PASSES: usize = 6;

/// Screens `data` (whose row `i` is data row `rows[i]`, 0-based, ascending) for outliers of the
/// model fitted from `x0`; `refit` fits the model to a subset from a start (see [`screen_fit`]).
/// With `steps`, runs of outliers that are one constant offset ([`reading_steps`]) are
/// corrected and kept instead. See the module docs.
pub fn screen(model: &CalibModel, x0: &[f64], data: &Samples, rows: &[usize], rule: ScreenRule, refit: &dyn Fn(&Samples, &[f64]) -> Vec<f64>) -> Screen {
    let ScreenRule { k, steps, min_scale_mm } = rule;
    let n = data.len();
    // A row of several values (a tracker's point) is one observation: its values share the
    // robust scale, and the row is out when any of them is. Reading steps are a cable encoder's.
    let d = data.dim.max(1);
    let steps = steps && d == 1;
    // Each instrument on its own robust scale (a touch probe's micrometres beside a printed
    // socket's seating), over the values its rows hold.
    let farthest = |r: &[f64], i: usize, med: f64| farthest_from(&r[i * d..i * d + data.width(i)], med);
    let mut by_instrument = [(f64::NAN, f64::NAN); 2];
    let mut keep: Vec<usize> = (0..n).collect();
    let mut x = x0.to_vec();
    let mut flagged: Vec<usize> = Vec::new();
    let mut found: Vec<ReadingStep> = Vec::new();
    let mut corrected = data.clone();
    let (mut scale, mut med) = (f64::NAN, 0.0);
    let mut r = Vec::new();
    let groups = model.measurement.def().value_groups();
    for _ in 0..SCREEN_PASSES {
        x = refit(&corrected.subset(&keep), &x);
        r = ReadingFit { model, data: &corrected }.residuals_mm(&x);
        equalise_groups(&mut r, d, groups, &keep);
        for (g, stat) in by_instrument.iter_mut().enumerate() {
            let kept_r = data.values_of(&r, g, keep.iter().copied());
            *stat = if kept_r.is_empty() { (f64::NAN, f64::NAN) } else { robust_scale(&kept_r) };
            stat.1 = stat.1.max(min_scale_mm);
        }
        (med, scale) = by_instrument[0];
        if by_instrument[0].1.is_nan() {
            (med, scale) = by_instrument[1];
        }
        if !(scale > 0.0) || k <= 0.0 {
            flagged.clear();
            break;
        }
        let new_steps = if steps {
            let raw = ReadingFit { model, data }.residuals_mm(&x);
            let s = reading_steps(&raw, rows, med, scale, k);
            corrected = apply_steps(data, rows, &s);
            r = ReadingFit { model, data: &corrected }.residuals_mm(&x);
            s
        } else {
            Vec::new()
        };
        let of = |i: usize| by_instrument[data.instrument(i)];
        flagged = (0..n).filter(|&i| !((farthest(&r, i, of(i).0) - of(i).0).abs() <= k * of(i).1)).collect();
        let new_keep: Vec<usize> = (0..n).filter(|i| flagged.binary_search(i).is_err()).collect();
        let settled = new_keep == keep && new_steps == found;
        keep = new_keep;
        found = new_steps;
        if settled {
            break;
        }
    }
    let outliers: Vec<Outlier> = flagged
        .iter()
        .map(|&i| {
            let (med, scale) = by_instrument[data.instrument(i)];
            let v = farthest(&r, i, med);
            Outlier { row: rows[i] + 1, residual_mm: v, robust_z: (v - med) / scale }
        })
        .collect();
    Screen { runs: runs(&outliers), keep, outliers, steps: found, corrected, x, scale_mm: scale, median_mm: med, rule }
}

/// Residuals of values in other groups than the first ([`Block::value_groups`]: a pose's
/// axes beside its position) put on the first group's robust scale, over the rows `keep`: each
/// value's distance from its group's median, in its group's robust standard deviations, is the
/// same after. A measurement of one group is left as it is.
///
/// [`Block::value_groups`]: crate::measurement::Block::value_groups
pub fn equalise_groups(r: &mut [f64], d: usize, groups: &[usize], keep: &[usize]) {
    if groups.iter().all(|g| *g == 0) {
        return;
    }
    let stats = group_scales(r, d, groups, keep);
    let (med0, scale0) = stats[0];
    for (g, &(med, scale)) in stats.iter().enumerate().skip(1) {
        if !(scale > 0.0 && scale0 > 0.0) {
            continue;
        }
        for (k, _) in groups.iter().enumerate().filter(|(_, gk)| **gk == g) {
            for row in r.chunks_mut(d) {
                row[k] = med0 + (row[k] - med) * scale0 / scale;
            }
        }
    }
}

/// The robust scale ([`robust_scale`]: median and robust standard deviation) of each value
/// group's residuals over the rows `rows` of `r` (`d` values a row; `groups` as
/// [`Block::value_groups`] gives them, empty for one group), in group order.
///
/// [`Block::value_groups`]: crate::measurement::Block::value_groups
pub fn group_scales(r: &[f64], d: usize, groups: &[usize], rows: &[usize]) -> Vec<(f64, f64)> {
    let group = |k: usize| groups.get(k).copied().unwrap_or(0);
    let n_groups = groups.iter().max().map_or(1, |g| g + 1);
    (0..n_groups)
        .map(|g| robust_scale(&rows.iter().flat_map(|&i| (0..d).filter(move |&k| group(k) == g).map(move |k| r[i * d + k])).collect::<Vec<f64>>()))
        .collect()
}

/// Most data rows between two outliers of one run: rows held out for testing, or a row of the
/// stretch that happens to read close, do not end it.
pub const RUN_GAP: usize = 3;

/// Runs of at least two outliers at most [`RUN_GAP`] data rows apart.
pub fn runs(outliers: &[Outlier]) -> Vec<OutlierRun> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < outliers.len() {
        let mut j = i;
        while j + 1 < outliers.len() && outliers[j + 1].row <= outliers[j].row + 1 + RUN_GAP {
            j += 1;
        }
        if j > i {
            let res: Vec<f64> = outliers[i..=j].iter().map(|o| o.residual_mm).collect();
            out.push(OutlierRun { first_row: outliers[i].row, last_row: outliers[j].row, median_residual_mm: median(&res) });
        }
        i = j + 1;
    }
    out
}

/// The loss a least-squares fit minimises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Loss {
    /// Squared residuals.
    #[default]
    #[serde(alias = "squared")]
    #[cfg_attr(feature = "clap", value(alias = "squared"))]
    L2,
    /// Quadratic within 1.345 robust standard deviations, linear beyond (95 % efficient on
    /// Gaussian noise).
    Huber,
    /// log(1 + (r/c)²) with c = 2.385 robust standard deviations: far residuals count for
    /// almost nothing.
    Cauchy,
}

impl Loss {
    /// The loss's name in files and options (`l2`, `huber`, `cauchy`).
    pub fn name(self) -> &'static str {
        match self {
            Loss::L2 => "l2",
            Loss::Huber => "huber",
            Loss::Cauchy => "cauchy",
        }
    }
    /// IRLS weight of a residual `u` in robust standard deviations.
    fn weight(self, u: f64) -> f64 {
        match self {
            Loss::L2 => 1.0,
            Loss::Huber => {
                let c = 1.345;
                if u.abs() <= c {
                    1.0
                } else {
                    c / u.abs()
                }
            }
            Loss::Cauchy => {
                let c = 2.385;
                1.0 / (1.0 + (u / c).powi(2))
            }
        }
    }
}

/// A least-squares problem with each residual scaled by the square root of its weight.
struct Weighted<'a, P: LeastSquares> {
    inner: &'a P,
    sqrt_w: Vec<f64>,
}

impl<P: LeastSquares> LeastSquares for Weighted<'_, P> {
    fn n_params(&self) -> usize {
        self.inner.n_params()
    }
    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        self.inner.residuals(x, r);
        r.iter_mut().zip(&self.sqrt_w).for_each(|(v, w)| *v *= w);
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        self.inner.jacobian(x, j);
        for (i, w) in self.sqrt_w.iter().enumerate() {
            j.row_mut(i).scale_mut(*w);
        }
    }
}

/// Passes of [`irls`]: the weights settle in a few.
const IRLS_PASSES: usize = 6;

/// Minimises `loss` by iteratively reweighted least squares: LM on the weighted problem, the
/// weights recomputed from the residuals (over their robust scale) before each pass. With
/// [`Loss::L2`] it is one plain LM run. The report's cost is the plain least-squares cost at the
/// solution; iterations and evaluations add up over the passes.
pub fn irls<P: LeastSquares>(lm: &LevenbergMarquardt, p: &P, x0: &[f64], fixed: &[bool], loss: Loss, obs: &mut dyn Observer) -> Report {
    if loss == Loss::L2 {
        return lm.minimize(p, x0, fixed, obs);
    }
    let mut r = vec![0.0; p.n_residuals()];
    let mut x = x0.to_vec();
    let (mut iterations, mut evaluations) = (0, 0);
    let mut last = None;
    for pass in 0..IRLS_PASSES {
        p.residuals(&x, &mut r);
        let (med, scale) = robust_scale(&r);

        // The first pass is plain least squares: weights from the start's residuals (far from
        // any fit) would only cost passes.
        let sqrt_w: Vec<f64> = r.iter().map(|v| if scale > 0.0 && pass > 0 { loss.weight((v - med) / scale).sqrt() } else { 1.0 }).collect();
        let wp = Weighted { inner: p, sqrt_w };
        let rep = if pass + 1 == IRLS_PASSES { lm.minimize(&wp, &x, fixed, obs) } else { lm.minimize(&wp, &x, fixed, &mut NoObserver) };
        iterations += rep.iterations;
        evaluations += rep.evaluations;
        // Weights that no longer move the fit (LM done within its first steps) have settled.
        let settled = rep.iterations <= 3;
        x = rep.x.clone();
        last = Some(rep);
        if settled {
            break;
        }
    }
    let mut rep = last.expect("at least one pass");
    rep.cost = p.cost(&x);
    rep.iterations = iterations;
    rep.evaluations = evaluations;
    rep.reason = format!("{} ({} loss by IRLS)", rep.reason, loss.name());
    rep
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = a + b·t with a few gross outliers.
    struct Line {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl LeastSquares for Line {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn residuals(&self, x: &[f64], r: &mut [f64]) {
            for i in 0..self.t.len() {
                r[i] = self.y[i] - x[0] - x[1] * self.t[i];
            }
        }
    }

    #[test]
    fn robust_losses_resist_gross_outliers() {
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
        let mut y: Vec<f64> = t.iter().enumerate().map(|(i, t)| 1.0 + 0.5 * t + 0.01 * (((i * 37) % 17) as f64 - 8.0) / 8.0).collect();
        for i in [10, 11, 12, 50, 77] {
            y[i] += 5.0;
        }
        let p = Line { t, y };
        let lm = LevenbergMarquardt::default();
        let l2 = irls(&lm, &p, &[0.0, 0.0], &[], Loss::L2, &mut NoObserver);
        assert!((l2.x[0] - 1.0).abs() > 0.1, "plain least squares is pulled by the outliers: {:?}", l2.x);
        for loss in [Loss::Huber, Loss::Cauchy] {
            let rep = irls(&lm, &p, &[0.0, 0.0], &[], loss, &mut NoObserver);
            let tol = if loss == Loss::Cauchy { 0.005 } else { 0.05 };
            assert!((rep.x[0] - 1.0).abs() < tol && (rep.x[1] - 0.5).abs() < tol, "{loss:?}: {:?}", rep.x);
            assert!(rep.reason.contains(loss.name()));
        }
    }

    /// Residuals of 200 rows (every other data row: the rest are test rows), unit-scale noise,
    /// with rows 40..70 reading 8 too high then 60..70 12 too high (a slipping reading), and
    /// rows 120..135 scattered ±8 (a disturbed stretch).
    fn slipping(seed: u64) -> (Vec<f64>, Vec<usize>) {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let r = (0..200)
            .map(|i| {
                let noise: f64 = (0..12).map(|_| rng.random::<f64>()).sum::<f64>() - 6.0;
                noise
                    + match i {
                        40..60 => 8.0,
                        60..70 => 12.0,
                        120..135 => 8.0 * if rng.random_bool(0.5) { 1.0 } else { -1.0 } * (1.0 + rng.random::<f64>()),
                        _ => 0.0,
                    }
            })
            .collect();
        (r, (0..200).map(|i| 2 * i).collect())
    }

    #[test]
    fn reading_steps_are_constant_offsets_and_a_disturbed_stretch_is_not_one() {
        for seed in 0..20 {
            let (r, rows) = slipping(seed);
            let steps = reading_steps(&r, &rows, 0.0, 1.0, 6.0);
            assert_eq!(steps.len(), 2, "seed {seed}: {steps:?}");
            let (a, b) = (&steps[0], &steps[1]);
            // Data rows are 1-based: sample 40 is data row 80 (0-based), 81 (1-based).
            assert!(a.first_row.abs_diff(81) <= 4 && b.last_row.abs_diff(139) <= 4, "seed {seed}: {steps:?}");
            assert!((a.offset_mm - 8.0).abs() < 4.0 * a.std_mm && (b.offset_mm - 12.0).abs() < 4.0 * b.std_mm, "seed {seed}: {steps:?}");
            assert!(steps.iter().all(|s| s.last_row < 200), "the scattered stretch is no step: {steps:?}");
            // Test rows take the offset of their nearest training row.
            let test = Samples::new(vec![vec![0.0; 6]; 3], vec![0.0; 3]);
            let corrected = apply_steps_nearest(&test, &[101, 135, 300], &rows, &steps);
            assert!((corrected.y[0] + a.offset_mm * 1e-3).abs() < 1e-12 && (corrected.y[1] + b.offset_mm * 1e-3).abs() < 1e-12);
            assert_eq!(corrected.y[2], 0.0);
        }
        let (r, rows) = slipping(0);
        assert!(reading_steps(&r, &rows, 0.0, 1.0, 0.0).is_empty(), "no screen, no steps");
        let clean: Vec<f64> = r.iter().enumerate().map(|(i, v)| if (40..70).contains(&i) || (120..135).contains(&i) { 0.0 } else { *v }).collect();
        assert!(reading_steps(&clean, &rows, 0.0, 1.0, 6.0).is_empty());
    }

    #[test]
    fn runs_group_nearby_rows() {
        let o = |row, r| Outlier { row, residual_mm: r, robust_z: 10.0 };
        let found = runs(&[o(1, 1.0), o(7, 5.0), o(8, 7.0), o(9, 6.0), o(20, 1.0), o(24, 2.0), o(25, 4.0), o(40, 1.0)]);
        assert_eq!(
            found,
            vec![OutlierRun { first_row: 7, last_row: 9, median_residual_mm: 6.0 }, OutlierRun { first_row: 20, last_row: 25, median_residual_mm: 2.0 }]
        );
    }
}
