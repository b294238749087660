//! Stage "set-up": where the instrument stood for each row. A tracker campaign is measured in
//! sessions, and between them the tracker is re-stationed, re-registered or bumped: each station
//! is a placement of its own, the arm the same. The stations come from the rows' `station`
//! column, from declared blocks (`--stations blocks`), and (`--stations auto`, for a tracker)
//! from change points in the residuals of a first fit: a jump of the readings from one row on
//! that a move of the instrument explains. Each found change labels the rows after it as a new
//! station, and the search runs again with the stations found, until no change is left.
//!
//! The test for a change at row k of a station's rows (in file order) compares two fits of the
//! station's own placement parameters, linearised at the first fit: one for all its rows, one
//! for each side of k. Residuals are taken in units of their robust scale (per value group: a
//! pose's positions and axes apart), so that the gain of a split is a χ² with as many degrees
//! of freedom as the station has parameters where nothing moved. A change is kept where its gain
//! is beyond [`CHANGE_PENALTY`] times the degrees of freedom times the log of the values (far
//! beyond what the largest of thousands of χ² draws reaches) *and* it explains at least
//! [`CHANGE_SHARE`] of the station's residual sum of squares: a model's misfit, which a move
//! of the tracker explains only in part, is not taken for one.

use super::options::{CalibOptions, StationSource};
use crate::calib::fit::Samples;
use crate::calib::model::{CalibModel, SetupKind};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::measurement::{FeatureKind, Measurement, MAX_DIM};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Least gain of a change point, in units of `dof × ln(values)` of the standardised residuals.
pub const CHANGE_PENALTY: f64 = 3.0;
/// Least share of a station's residual sum of squares a change point explains.
pub const CHANGE_SHARE: f64 = 0.2;
/// Fewest rows on either side of a change point.
pub const MIN_STATION_ROWS: usize = 10;
/// Most change points searched for (the stations of a file then number at most one more than
/// its declared ones plus this).
pub const MAX_CHANGES: usize = 12;

/// A set-up change a first fit's residuals showed: the kind and the label of the new set-up.
pub type Found = Vec<(SetupKind, String)>;

/// A first fit of every row with the set-ups a dataset names: the model, its parameters and the
/// rows, whose residuals the change-point search reads. The pipeline gives it
/// ([`resolve_stations`](super::resolve_stations)), so that this stage hands the options to no
/// other.
pub type FirstFit<'a> = &'a dyn Fn(&Dataset) -> Result<(CalibModel, Vec<f64>, Samples)>;

/// The data with their stations resolved by `opts.stations`: `None` when the rows' own
/// `station` and `mount` columns (or their absence) stand as they are, else a copy whose rows
/// name their stations and mounts (declared blocks, change points), with the set-ups that
/// change points gave.
pub fn resolve(data: &Dataset, opts: &CalibOptions, fit_all: FirstFit) -> Result<(Option<Dataset>, Found)> {
    match opts.stations {
        StationSource::Declared => Ok((None, Vec::new())),
        StationSource::One => {
            let mut d = data.clone();
            d.rows.iter_mut().for_each(|r| {
                r.station = None;
                r.mount = None;
            });
            Ok((Some(d), Vec::new()))
        }
        StationSource::Blocks => {
            if data.rows.iter().any(|r| r.block.is_none()) {
                return Err(Error::data(&data.source, "--stations blocks takes each declared block as a station, but the file has no block column"));
            }
            Ok((Some(data.blocks_as_stations()), Vec::new()))
        }
        StationSource::Auto => {
            let tracker = matches!(data.measurement(), Some(Measurement::Point | Measurement::Pose));
            if !tracker || opts.free != super::options::FreeParams::All {
                return Ok((None, Vec::new()));
            }
            find_changes(data, fit_all)
        }
    }
}

/// The labels of kind `k` of a dataset's rows.
fn labels_of(data: &Dataset, k: SetupKind) -> crate::dataset::Stations {
    match k {
        SetupKind::Station => data.stations(),
        SetupKind::Mount => data.mounts(),
    }
}

/// A row's label of kind `k`.
pub fn label_of(r: &crate::dataset::Row, k: SetupKind) -> Option<String> {
    match (k, &r.feature) {
        // A seated ball's station is its socket at its placement (a probe's, its face).
        (SetupKind::Station, Some(f)) => Some(crate::dataset::feature_station(r.station.as_deref(), &f.label)),
        (SetupKind::Station, None) => r.station.clone(),
        (SetupKind::Mount, _) => r.mount.clone(),
    }
}

/// A row's label of kind `k`, to set.
pub(super) fn label_mut(r: &mut crate::dataset::Row, k: SetupKind) -> &mut Option<String> {
    match k {
        SetupKind::Station => &mut r.station,
        SetupKind::Mount => &mut r.mount,
    }
}

/// The change-point search of [`resolve`]: a first fit with the set-ups so far, the best change
/// point over every set-up's rows, until none is left.
fn find_changes(data: &Dataset, fit_all: FirstFit) -> Result<(Option<Dataset>, Found)> {
    let mut labelled = data.clone();
    let mut found = Vec::new();
    for _ in 0..MAX_CHANGES {
        let (model, x, all) = fit_all(&labelled)?;
        let Some(change) = best_change(&model, &x, &all) else { break };
        for kind in change.kinds {
            let declared = data.rows.iter().all(|r| label_of(r, kind).is_some());
            let label = new_label(&labelled, kind, change.row, declared);
            let old = label_of(&labelled.rows[change.row], kind);
            for r in labelled.rows[change.row..].iter_mut().filter(|r| label_of(r, kind) == old) {
                *label_mut(r, kind) = Some(label.clone());
            }
            // The first set-up of a file that names none is `1`.
            for r in labelled.rows.iter_mut().filter(|r| label_of(r, kind).is_none()) {
                *label_mut(r, kind) = Some("1".into());
            }
            found.push((kind, label));
        }
    }
    Ok(if found.is_empty() { (None, found) } else { (Some(labelled), found) })
}

/// A label for a new set-up of kind `kind` split off at row `row` of `data`: `N` (the next
/// number) where the file names none of the kind, `A.k` for the k-th part of a declared `A`.
fn new_label(data: &Dataset, kind: SetupKind, row: usize, declared: bool) -> String {
    let st = labels_of(data, kind);
    if !declared {
        return (st.len() + 1).to_string();
    }
    let base = st.labels[st.of_row[row]].split('.').next().unwrap_or_default().to_string();
    (2..).map(|k| format!("{base}.{k}")).find(|l| !st.labels.contains(l)).unwrap_or(base)
}

/// Each row's standardised residuals and the Jacobian of its prediction with respect to its
/// station's and its mount's own parameters (same units; `ns + nm` columns), row after row.
fn standardised(model: &CalibModel, x: &[f64], all: &Samples) -> (Vec<f64>, Vec<f64>) {
    let (d, n) = (all.dim, model.n_params());
    let nc = model.n_chain();
    let cols_of = |inp: &crate::calib::effects::RowInputs| -> Vec<usize> {
        SetupKind::ALL
            .iter()
            .flat_map(|&k| {
                let s = k.of(inp);
                let params = model.setup_params(k);
                match s {
                    0 => params.map(|p| nc + p).collect::<Vec<_>>(),
                    _ => model.setup_block(k, s).collect(),
                }
            })
            .collect()
    };
    let np = model.measurement.n_placement();
    let (mut r, mut j) = (vec![0.0; all.len() * d], vec![0.0; all.len() * d * np]);
    let mut w = model.work();
    let (mut y, mut g) = ([0.0; MAX_DIM], vec![0.0; d * n]);
    for i in 0..all.len() {
        model.readings_grad(x, &all.q[i], &all.inputs[i], &mut w, &mut y[..d], &mut g);
        let cols = cols_of(&all.inputs[i]);
        for c in 0..d {
            r[i * d + c] = crate::units::to_mm(all.y[i * d + c] - y[c]);
            for (k, col) in cols.iter().enumerate() {
                j[(i * d + c) * np + k] = crate::units::to_mm(g[c * n + col]);
            }
        }
    }
    // Each value group on its own robust scale.
    let groups = model.measurement.def().value_groups();
    let group = |c: usize| groups.get(c).copied().unwrap_or(0);
    for gi in 0..model.measurement.n_value_groups() {
        let vals: Vec<f64> = r.iter().enumerate().filter(|(k, _)| group(k % d) == gi).map(|(_, v)| *v).collect();
        let scale = crate::stats::robust_scale(&vals).1.max(1e-9);
        for (k, v) in r.iter_mut().enumerate().filter(|(k, _)| group(k % d) == gi) {
            *v /= scale;
            j[k * np..(k + 1) * np].iter_mut().for_each(|e| *e /= scale);
        }
    }
    (r, j)
}

/// A change point: the first data row after it and what changed there.
struct Change {
    row: usize,
    kinds: Vec<SetupKind>,
}

/// The best change point of any set-up's rows (the rows of one station and one mount, in file
/// order), of the hypothesis (the station moved, the mount changed, or both) that its gain
/// beyond its penalty favours most.
fn best_change(model: &CalibModel, x: &[f64], all: &Samples) -> Option<Change> {
    let (r, j) = standardised(model, x, all);
    let d = all.dim;
    let ns = model.n_station_params();
    let np = model.measurement.n_placement();
    let ln = ((all.len() * d) as f64).ln();
    let hypotheses: [(Vec<SetupKind>, std::ops::Range<usize>); 3] =
        [(vec![SetupKind::Station], 0..ns), (vec![SetupKind::Mount], ns..np), (vec![SetupKind::Station, SetupKind::Mount], 0..np)];
    let mut best: Option<(f64, usize, usize)> = None;
    let mut pairs: Vec<(usize, usize)> = all.inputs.iter().map(|i| (i.station, i.mount)).collect();
    pairs.sort_unstable();
    pairs.dedup();
    for (st, mo) in pairs {
        let rows: Vec<usize> = (0..all.len()).filter(|i| (all.inputs[*i].station, all.inputs[*i].mount) == (st, mo)).collect();
        if rows.len() < 2 * MIN_STATION_ROWS {
            continue;
        }
        let sums = PrefixSums::new(&rows, &r, &j, d, np);
        for (h, (_, cols)) in hypotheses.iter().enumerate() {
            if cols.is_empty() {
                continue;
            }
            let whole = sums.rss(0, rows.len(), cols.clone());
            let threshold = CHANGE_PENALTY * cols.len() as f64 * ln;
            for k in MIN_STATION_ROWS..=rows.len() - MIN_STATION_ROWS {
                let gain = whole - sums.rss(0, k, cols.clone()) - sums.rss(k, rows.len(), cols.clone());
                let score = gain - threshold;
                if score > 0.0 && gain > CHANGE_SHARE * whole && best.is_none_or(|b| score > b.0) {
                    best = Some((score, h, rows[k]));
                }
            }
        }
    }
    best.map(|(_, h, row)| Change { row, kinds: hypotheses[h].0.clone() })
}

/// Running sums over a set-up's rows of JᵀJ, Jᵀr and rᵀr: the residual sum of squares of any
/// stretch after a fit of some of the set-up's parameters to it, in O(n³) for n of them.
struct PrefixSums {
    ata: Vec<DMatrix<f64>>,
    atb: Vec<DVector<f64>>,
    btb: Vec<f64>,
}

impl PrefixSums {
    fn new(rows: &[usize], r: &[f64], j: &[f64], d: usize, np: usize) -> PrefixSums {
        let mut out = PrefixSums { ata: vec![DMatrix::zeros(np, np)], atb: vec![DVector::zeros(np)], btb: vec![0.0] };
        for &i in rows {
            let (mut a, mut b, mut e) =
                (out.ata.last().cloned().unwrap_or_default(), out.atb.last().cloned().unwrap_or_default(), *out.btb.last().unwrap_or(&0.0));
            for c in 0..d {
                let v = i * d + c;
                let jr = &j[v * np..(v + 1) * np];
                for p in 0..np {
                    b[p] += jr[p] * r[v];
                    for q in 0..np {
                        a[(p, q)] += jr[p] * jr[q];
                    }
                }
                e += r[v] * r[v];
            }
            out.ata.push(a);
            out.atb.push(b);
            out.btb.push(e);
        }
        out
    }

    /// The residual sum of squares of rows `from..to` (of the set-up's) after their own fit of
    /// the parameters `cols`.
    fn rss(&self, from: usize, to: usize, cols: std::ops::Range<usize>) -> f64 {
        let n = cols.len();
        let a = (&self.ata[to] - &self.ata[from]).view((cols.start, cols.start), (n, n)).into_owned();
        let b = (&self.atb[to] - &self.atb[from]).rows(cols.start, n).into_owned();
        let e = self.btb[to] - self.btb[from];
        let explained = a.svd(true, true).solve(&b, 1e-10).map_or(0.0, |z| b.dot(&z));
        (e - explained).max(0.0)
    }
}

/// The set-ups of a fitted model on `data` (labelled as the model's), as the result reports
/// them: rows, origin and where each stood (a station) or sat (a mount) relative to the first.
/// `found`: the set-ups change points gave.
pub fn setup_report(model: &CalibModel, x: &[f64], data: &Dataset, source: StationSource, found: &[(SetupKind, String)]) -> Option<SetupReport> {
    if model.n_stations() < 2 && model.n_setups(SetupKind::Mount) < 2 {
        return None;
    }
    let def = model.measurement.def();
    let seated_model = model.measurement.feature().is_some();
    let parts = |kind: SetupKind| -> Vec<SetupPart> {
        if model.n_setups(kind) < 2 {
            return Vec::new();
        }
        let st = labels_of(data, kind);
        let at = |s: usize| match kind {
            SetupKind::Station => model.placement_at(x, s, 0),
            SetupKind::Mount => model.placement_at(x, 0, s),
        };
        let first = at(0);
        let auto = found.iter().any(|(k, l)| *k == kind && !l.contains('.'));
        (0..model.n_setups(kind))
            .map(|s| {
                let p = at(s);
                let (shift_mm, turn) = match kind {
                    SetupKind::Station => {
                        let (a, b) = (def.frame(&first.own), def.frame(&p.own));
                        let turn = a.axes.zip(b.axes).map(|(a, b)| a.transpose() * b);
                        (crate::units::to_mm((b.origin - a.origin).norm()), turn)
                    }
                    SetupKind::Mount => {
                        (crate::units::to_mm((p.tool - first.tool).norm()), Some(def.target_rotation(&first.own).transpose() * def.target_rotation(&p.own)))
                    }
                };
                let label = model.setups(kind)[s].clone();
                let mut rows = st.labels.iter().position(|l| *l == label).map(|k| st.rows(k)).unwrap_or_default();
                // (A tracker's points beside seated rows stand at no socket.)
                if seated_model {
                    rows.retain(|&i| data.rows[i].feature.is_some());
                }
                let changed = found.iter().any(|(k, l)| *k == kind && *l == label) || (s == 0 && auto);
                SetupPart {
                    origin: if changed { StationOrigin::ChangePoint } else { StationOrigin::Declared },
                    label,
                    rows: rows.len(),
                    first_row: rows.first().map_or(0, |r| r + 1),
                    last_row: rows.last().map_or(0, |r| r + 1),
                    shift_mm,
                    turn_deg: turn.map_or(0.0, |m| nalgebra::Rotation3::from_matrix_unchecked(m).angle().to_degrees()),
                    after_pause_s: rows.first().filter(|_| s > 0).and_then(|&r| crate::dataset::blocks::pause_before(data, r)),
                }
            })
            .collect()
    };
    // (Sockets and faces in one list are features, neither kind alone: the artifact's report
    // says which is which.)
    let feature = model.measurement.feature().filter(|_| !model.also.is_some_and(|m| model.shares_stations_with(m)));
    Some(SetupReport { source, stations: parts(SetupKind::Station), mounts: parts(SetupKind::Mount), feature })
}

/// How a station came to be.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StationOrigin {
    /// Named in the file (`station` column, or a declared block with `--stations blocks`).
    Declared,
    /// Found: a change point in the residuals of a first fit.
    ChangePoint,
}

/// One station of the instrument, or one mount of its target, in a calibration's result: its
/// rows and where it stood (sat) relative to the first.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetupPart {
    /// Its label (the file's, or `A.2` for the second part of a declared station `A` that a
    /// change point split, `2` for the second part of a file without stations).
    pub label: String,
    /// Declared or found.
    pub origin: StationOrigin,
    /// Its number of rows.
    pub rows: usize,
    /// Its first and last data rows (1-based).
    pub first_row: usize,
    /// See `first_row`.
    pub last_row: usize,
    /// How far its origin sits from the first's, mm (a mount: its target on the flange; 0 for
    /// the first).
    pub shift_mm: f64,
    /// How far its axes are turned from the first's, degrees (a mount: a 6-D probe's
    /// orientation on the flange; a draw-wire's station and a point's mount, which have no
    /// axes: 0).
    pub turn_deg: f64,
    /// The pause in `t` before its first row, s, where the rows read one there (a found change
    /// that a break between sessions explains).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub after_pause_s: Option<f64>,
}

impl SetupReport {
    /// What a summary prints of the set-ups: a line for the stations and one for the mounts
    /// where there are several, then one per station or mount with its rows and where it stood
    /// relative to the first.
    pub fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        let stood = match self.feature {
            Some(FeatureKind::Socket) => ("socket", "the ball was seated in"),
            Some(FeatureKind::Plane) => ("face", "the probe touched"),
            None if self.stations.iter().any(|s| s.label.contains('/')) => ("feature", "the ball stood at"),
            None => ("station", "the instrument stood at"),
        };
        for (what, parts, verb) in [(stood.0, &self.stations, stood.1), ("mount", &self.mounts, "the target sat on")] {
            if parts.is_empty() {
                continue;
            }
            let found = parts.iter().filter(|s| s.origin == StationOrigin::ChangePoint).count();
            let how = match (found, parts.len() - found) {
                (0, _) => "as declared".to_string(),
                (_, 0) => "found as change points in the residuals of a first fit".to_string(),
                (f, d) => format!("{d} declared, {f} found as change points in the residuals of a first fit"),
            };
            if what == "feature" {
                // Sockets and faces: shifts between a socket's centre and a face's angles mean
                // nothing; the artifact's report lists each.
                out.push(format!("set-up: {verb} {} features ({how}), sockets and faces, each with its own placement, the arm shared", parts.len()));
                continue;
            }
            out.push(format!("set-up: {verb} {} {what}s ({how}), each with its own placement, the arm shared:", parts.len()));
            for (k, s) in parts.iter().enumerate() {
                let at =
                    if k == 0 { "the reference".to_string() } else { format!("{:.3} mm and {:.4}° from {what} {}", s.shift_mm, s.turn_deg, parts[0].label) };
                let pause = s.after_pause_s.map_or(String::new(), |p| format!(", after a pause of {} in t", crate::units::duration(p)));
                out.push(format!("  {what} {}: rows {}-{} ({} rows), {at}{pause}", s.label, s.first_row, s.last_row, s.rows));
            }
        }
        out
    }
}

/// The stations of a calibration's rows, as its result reports them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SetupReport {
    /// Where the stations came from (`--stations`).
    pub source: super::options::StationSource,
    /// Every station, in the order of its first row (none where the instrument stood at one).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stations: Vec<SetupPart>,
    /// Every mount of the target, in the order of its first row (none where it sat on one).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mounts: Vec<SetupPart>,
    /// The artifact's features the stations are (the sockets a ball was seated in, the faces a
    /// probe touched), if they are.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feature: Option<FeatureKind>,
}
