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
use super::placement::place_sensor;
use super::result::{SetupReport, StationOrigin, StationReport};
use super::split::samples;
use crate::calib::model::CalibModel;
use crate::calib::problem::identify::identify;
use crate::calib::problem::{ReadingFit, Samples};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::measurement::{Measurement, MAX_DIM};
use crate::optim::{LevenbergMarquardt, NoObserver};
use nalgebra::{DMatrix, DVector};

/// Least gain of a change point, in units of `dof × ln(values)` of the standardised residuals.
pub const CHANGE_PENALTY: f64 = 3.0;
/// Least share of a station's residual sum of squares a change point explains.
pub const CHANGE_SHARE: f64 = 0.2;
/// Fewest rows on either side of a change point.
pub const MIN_STATION_ROWS: usize = 10;
/// Most change points searched for (the stations of a file then number at most one more than
/// its declared ones plus this).
pub const MAX_CHANGES: usize = 12;

/// The data with their stations resolved by `opts.stations`: `None` when the rows' own
/// `station` column (or its absence) stands as it is, else a copy whose rows name their
/// stations (declared blocks, change points), with the labels that change points gave.
pub fn resolve_stations(data: &Dataset, opts: &CalibOptions) -> Result<(Option<Dataset>, Vec<String>)> {
    match opts.stations {
        StationSource::Declared => Ok((None, Vec::new())),
        StationSource::One => {
            let mut d = data.clone();
            d.rows.iter_mut().for_each(|r| r.station = None);
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
            if !tracker || !matches!(opts.model, super::options::ModelSpec::Nominal { .. }) || opts.placement_only {
                return Ok((None, Vec::new()));
            }
            find_changes(data, opts)
        }
    }
}

/// The change-point search of [`resolve_stations`]: a first fit with the stations so far, the
/// best change point over every station's rows, until none is left.
fn find_changes(data: &Dataset, opts: &CalibOptions) -> Result<(Option<Dataset>, Vec<String>)> {
    let mut labelled = data.clone();
    let declared = data.rows.iter().all(|r| r.station.is_some());
    let mut found = Vec::new();
    for _ in 0..MAX_CHANGES {
        let (model, x, all) = first_fit(&labelled, opts)?;
        let Some((station, row)) = best_change(&model, &x, &all) else { break };
        let label = new_label(&labelled, station, declared);
        let old = labelled.rows[row].station.clone();
        for r in labelled.rows[row..].iter_mut().filter(|r| r.station == old) {
            r.station = Some(label.clone());
        }
        if !declared && labelled.rows[0].station.is_none() {
            // The first station of a file without stations is `1`.
            for r in labelled.rows.iter_mut().filter(|r| r.station.is_none()) {
                r.station = Some("1".into());
            }
        }
        found.push(label);
    }
    Ok(if found.is_empty() { (None, found) } else { (Some(labelled), found) })
}

/// A label for a new station split off station `s` of `data`: `N` (the next number) for a
/// file without stations, `A.k` for the k-th part of a declared station `A`.
fn new_label(data: &Dataset, s: usize, declared: bool) -> String {
    let st = data.stations();
    if !declared {
        return (st.len() + 1).to_string();
    }
    let base = st.labels[s].split('.').next().unwrap_or_default().to_string();
    (2..).map(|k| format!("{base}.{k}")).find(|l| !st.labels.contains(l)).unwrap_or(base)
}

/// The geometric model fitted to every row with the stations `data` names (no screen): what the
/// change-point search reads the residuals of.
fn first_fit(data: &Dataset, opts: &CalibOptions) -> Result<(CalibModel, Vec<f64>, Samples)> {
    let all = samples(data, &(0..data.rows.len()).collect::<Vec<_>>());
    let model = place_sensor(opts, &all, &data.stations().labels)?;
    let fit = ReadingFit { model: &model, data: &all };
    let id = identify(&fit, &model.nominal, opts.rank_tol);
    let x = LevenbergMarquardt::budget(100).minimize(&fit, &model.nominal, &id.fixed_mask, &mut NoObserver).x;
    Ok((model, x, all))
}

/// Each row's standardised residuals and the Jacobian of its prediction with respect to its
/// station's own parameters (same units), row after row: `dim` values and `dim × ns` entries.
fn standardised(model: &CalibModel, x: &[f64], all: &Samples) -> (Vec<f64>, Vec<f64>) {
    let (d, n, ns) = (all.dim, model.n_params(), model.n_station_params());
    let nc = model.n_chain();
    let (mut r, mut j) = (vec![0.0; all.len() * d], vec![0.0; all.len() * d * ns]);
    let mut w = model.work();
    let (mut y, mut g) = ([0.0; MAX_DIM], vec![0.0; d * n]);
    for i in 0..all.len() {
        model.readings_grad_with(x, &all.q[i], &all.inputs[i], &mut w, &mut y[..d], &mut g);
        let s = all.inputs[i].station;
        let first = if s == 0 { nc } else { model.station_range(s).start };
        for c in 0..d {
            r[i * d + c] = crate::units::to_mm(all.y[i * d + c] - y[c]);
            for k in 0..ns {
                j[(i * d + c) * ns + k] = crate::units::to_mm(g[c * n + first + k]);
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
            j[k * ns..(k + 1) * ns].iter_mut().for_each(|e| *e /= scale);
        }
    }
    (r, j)
}

/// The best change point of any station's rows: (station, first data row of the new station).
fn best_change(model: &CalibModel, x: &[f64], all: &Samples) -> Option<(usize, usize)> {
    let (r, j) = standardised(model, x, all);
    let (d, ns) = (all.dim, model.n_station_params());
    let values = (all.len() * d) as f64;
    let threshold = CHANGE_PENALTY * ns as f64 * values.ln();
    let mut best: Option<(f64, usize, usize)> = None;
    for s in 0..model.n_stations() {
        let rows: Vec<usize> = (0..all.len()).filter(|i| all.inputs[*i].station == s).collect();
        if rows.len() < 2 * MIN_STATION_ROWS {
            continue;
        }
        let sums = PrefixSums::new(&rows, &r, &j, d, ns);
        let whole = sums.rss(0, rows.len());
        for k in MIN_STATION_ROWS..=rows.len() - MIN_STATION_ROWS {
            let gain = whole - sums.rss(0, k) - sums.rss(k, rows.len());
            if gain > threshold && gain > CHANGE_SHARE * whole && best.is_none_or(|b| gain > b.0) {
                best = Some((gain, s, rows[k]));
            }
        }
    }
    best.map(|(_, s, row)| (s, row))
}

/// Running sums over a station's rows of JᵀJ, Jᵀr and rᵀr: the residual sum of squares of any
/// stretch after a fit of the station's parameters to it, in O(ns³).
struct PrefixSums {
    ata: Vec<DMatrix<f64>>,
    atb: Vec<DVector<f64>>,
    btb: Vec<f64>,
}

impl PrefixSums {
    fn new(rows: &[usize], r: &[f64], j: &[f64], d: usize, ns: usize) -> PrefixSums {
        let mut out = PrefixSums { ata: vec![DMatrix::zeros(ns, ns)], atb: vec![DVector::zeros(ns)], btb: vec![0.0] };
        for &i in rows {
            let (mut a, mut b, mut e) =
                (out.ata.last().cloned().unwrap_or_default(), out.atb.last().cloned().unwrap_or_default(), *out.btb.last().unwrap_or(&0.0));
            for c in 0..d {
                let v = i * d + c;
                let jr = &j[v * ns..(v + 1) * ns];
                for p in 0..ns {
                    b[p] += jr[p] * r[v];
                    for q in 0..ns {
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

    /// The residual sum of squares of rows `from..to` (of the station's) after their own fit.
    fn rss(&self, from: usize, to: usize) -> f64 {
        let a = &self.ata[to] - &self.ata[from];
        let b = &self.atb[to] - &self.atb[from];
        let e = self.btb[to] - self.btb[from];
        let explained = a.svd(true, true).solve(&b, 1e-10).map_or(0.0, |z| b.dot(&z));
        (e - explained).max(0.0)
    }
}

/// The stations of a fitted model on `data` (labelled as the model's stations), as the result
/// reports them: rows, origin and where each stood relative to the first.
pub fn setup_report(model: &CalibModel, x: &[f64], data: &Dataset, source: StationSource, found: &[String]) -> Option<SetupReport> {
    if model.n_stations() < 2 {
        return None;
    }
    let st = data.stations();
    let def = model.measurement.def();
    let first = def.frame(&model.station_placement(x, 0).own);
    let stations = (0..model.n_stations())
        .map(|s| {
            let rows = st.rows(s);
            let frame = def.frame(&model.station_placement(x, s).own);
            let turn_deg = match (first.axes, frame.axes) {
                (Some(a), Some(b)) => nalgebra::Rotation3::from_matrix_unchecked(a.transpose() * b).angle().to_degrees(),
                _ => 0.0,
            };
            let label = model.stations[s].clone();
            StationReport {
                origin: if found.contains(&label) || (s == 0 && found.iter().any(|f| !f.contains('.'))) {
                    StationOrigin::ChangePoint
                } else {
                    StationOrigin::Declared
                },
                label,
                rows: rows.len(),
                first_row: rows.first().map_or(0, |r| r + 1),
                last_row: rows.last().map_or(0, |r| r + 1),
                shift_mm: crate::units::to_mm((frame.origin - first.origin).norm()),
                turn_deg,
            }
        })
        .collect();
    Some(SetupReport { source, stations })
}
