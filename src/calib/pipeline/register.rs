//! A calibrated model on rows measured from stations (or with target mounts) it was not
//! calibrated at: the tracker re-stationed after the calibration, a probe re-mounted, or a file
//! that names another station. Each new set-up's placement is registered on its first rows (the
//! arm and every other parameter held as calibrated), and the rest of its rows are then
//! predicted as unseen.

use super::result::{CalibResult, ParamReport};
use super::setup::{label_mut, label_of};
use crate::calib::effects::RowInputs;
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::{CalibModel, Placement, SetupKind};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::optim::{LevenbergMarquardt, NoObserver};
use serde::{Deserialize, Serialize};

/// Rows a new set-up is registered on by default (`--register-rows`): four times what a
/// tracker's six placement parameters need, few enough to leave most of a session unseen.
pub const DEFAULT_REGISTER_ROWS: usize = 12;

/// The label a new set-up takes when the rows name none.
pub const UNNAMED_SETUP: &str = "new";

/// The label the model's first set-up of a kind takes when it had none and another is added.
pub const CALIBRATED_SETUP: &str = "calibration";

/// A station or a mount registered on some of its rows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Registration {
    /// A station or a mount.
    pub kind: SetupKind,
    /// Its label (the rows', or [`UNNAMED_SETUP`]).
    pub label: String,
    /// The data rows (1-based) its placement was fitted on: not unseen.
    pub rows: Vec<usize>,
    /// The registration rows' RMS residual after it, mm per value.
    pub rms_mm: f64,
}

impl Registration {
    /// What a command prints of it.
    pub fn line(&self) -> String {
        format!(
            "{} {}: not one the model was calibrated at; its placement registered on rows {}-{} ({} rows, RMS {:.4} mm), its other rows predicted unseen",
            self.kind.name(),
            self.label,
            self.rows.first().copied().unwrap_or(0),
            self.rows.last().copied().unwrap_or(0),
            self.rows.len(),
            self.rms_mm
        )
    }
}

impl CalibResult {
    /// Each row's set-up of kind `k` as this model numbers them (by label); `None` for a row
    /// whose set-up the model does not know (a label it was not calibrated at, or none where it
    /// knows several).
    pub fn setup_of_rows(&self, data: &Dataset, k: SetupKind) -> Vec<Option<usize>> {
        let known = self.model.setups(k);
        data.rows
            .iter()
            .map(|r| match (label_of(r, k), known.len()) {
                (None, 0 | 1) => Some(0),
                (None, _) => None,
                (Some(l), _) => known.iter().position(|x| *x == l),
            })
            .collect()
    }

    /// Every row's inputs for this model: [`row_inputs`](crate::calib::effects::inputs::row_inputs)
    /// with the stations and mounts numbered as the model numbers them (one it does not know
    /// reads its first: register it first, [`Self::at_stations`]).
    pub fn row_inputs(&self, data: &Dataset) -> Vec<RowInputs> {
        let mut inputs = crate::calib::effects::inputs::row_inputs(data, self.torque_model.as_ref());
        let (st, mo) = (self.setup_of_rows(data, SetupKind::Station), self.setup_of_rows(data, SetupKind::Mount));
        for ((inp, s), m) in inputs.iter_mut().zip(st).zip(mo) {
            inp.station = s.unwrap_or(0);
            inp.mount = m.unwrap_or(0);
        }
        inputs
    }

    /// This model with every station and mount of `data` it does not know registered on its
    /// first `rows` rows, and the data with those set-ups named (rows without a label where the
    /// model knows several become [`UNNAMED_SETUP`]); `None` where it knows them all. `rows` =
    /// 0 refuses an unknown set-up.
    pub fn at_stations(&self, data: &Dataset, rows: usize) -> Result<Option<(CalibResult, Dataset, Vec<Registration>)>> {
        let of_row = SetupKind::ALL.map(|k| self.setup_of_rows(data, k));
        if of_row.iter().all(|v| v.iter().all(Option::is_some)) {
            return Ok(None);
        }
        let mut named = data.clone();
        let mut unknown: Vec<(SetupKind, String)> = Vec::new();
        for (k, of) in SetupKind::ALL.into_iter().zip(&of_row) {
            for (r, s) in named.rows.iter_mut().zip(of) {
                let slot = label_mut(r, k);
                if s.is_none() {
                    let label = slot.get_or_insert_with(|| UNNAMED_SETUP.into()).clone();
                    if !unknown.contains(&(k, label.clone())) {
                        unknown.push((k, label));
                    }
                }
            }
        }
        if rows == 0 {
            let list: Vec<String> = unknown.iter().map(|(k, l)| format!("{} {l}", k.name())).collect();
            return Err(Error::data(
                &data.source,
                format!("the rows stand at {} the model was not calibrated at: register each on its first rows (--register-rows N) or name a known one in a station (mount) column", list.join(", ")),
            ));
        }
        let mut out = self.clone();
        let registrations = out.register(&named, &unknown, rows)?;
        // Rows of the set-ups the model was calibrated at, named as it now names them.
        for (k, of) in SetupKind::ALL.into_iter().zip(&of_row) {
            for (r, s) in named.rows.iter_mut().zip(of) {
                let slot = label_mut(r, k);
                if *s == Some(0) && slot.is_none() {
                    *slot = out.model.setups(k).first().cloned();
                }
            }
        }
        Ok(Some((out, named, registrations)))
    }

    /// Adds the set-ups `unknown` to this model, their placements fitted together on the first
    /// `rows` rows of each (everything else held).
    fn register(&mut self, data: &Dataset, unknown: &[(SetupKind, String)], rows: usize) -> Result<Vec<Registration>> {
        let m = self.model.measurement;
        let groups: Vec<Vec<usize>> = unknown
            .iter()
            .map(|(k, l)| data.rows.iter().enumerate().filter(|(_, r)| label_of(r, *k).as_deref() == Some(l.as_str())).map(|(i, _)| i).take(rows).collect())
            .collect();
        let (model, x) = self.with_new_setups(data, unknown, &groups)?;
        // Every registration row with its set-ups as the extended model numbers them.
        let extended = CalibResult { model: model.clone(), x: x.clone(), ..self.clone() };
        let all: Vec<usize> = {
            let mut v: Vec<usize> = groups.iter().flatten().copied().collect();
            v.sort_unstable();
            v.dedup();
            v
        };
        let inputs = extended.row_inputs(data);
        let mut sub = super::split::samples(data, &all);
        sub.inputs = all.iter().map(|&i| inputs[i].clone()).collect();
        let free: Vec<std::ops::Range<usize>> =
            unknown.iter().map(|(k, l)| model.setup_block(*k, model.setups(*k).iter().position(|x| x == l).unwrap_or(0).max(1))).collect();
        let fixed: Vec<bool> = (0..x.len()).map(|k| !free.iter().any(|r| r.contains(&k))).collect();
        let fit = ReadingFit { model: &model, data: &Samples { w: None, gls: None, ..sub } };
        let x = LevenbergMarquardt::budget(200).minimize(&fit, &x, &fixed, &mut NoObserver).x;
        let r = fit.residuals_mm(&x);
        let d = m.dim();
        let rms_of = |idx: &[usize]| {
            let sq: Vec<f64> = idx.iter().filter_map(|i| all.iter().position(|a| a == i)).flat_map(|p| r[p * d..(p + 1) * d].iter().map(|v| v * v)).collect();
            (sq.iter().sum::<f64>() / sq.len().max(1) as f64).sqrt()
        };
        if r.iter().any(|v| !v.is_finite()) {
            return Err(Error::Calibration("the registration of a new station or mount diverged".into()));
        }
        // The parameter report follows the model's parameters (inserted in their order).
        let mut free = free;
        free.sort_by_key(|r| r.start);
        for range in &free {
            for k in range.clone() {
                let dsp = model.kinds[k].display();
                self.parameters.insert(
                    k,
                    ParamReport {
                        name: model.names[k].clone(),
                        unit: model.kinds[k].unit().into(),
                        nominal: model.nominal[k] * dsp,
                        value: x[k] * dsp,
                        std_uncertainty: None,
                        fixed: false,
                        truth: None,
                        error: None,
                        z: None,
                    },
                );
            }
        }
        self.model = model;
        self.x = x;
        Ok(unknown
            .iter()
            .zip(&groups)
            .map(|((k, l), idx)| Registration { kind: *k, label: l.clone(), rows: idx.iter().map(|i| i + 1).collect(), rms_mm: rms_of(idx) })
            .collect())
    }

    /// This model's parameters with the set-ups `unknown` added, each started where the
    /// calibrated arm's flange on its rows `groups` places it (a point's target: the calibrated
    /// one).
    fn with_new_setups(&self, data: &Dataset, unknown: &[(SetupKind, String)], groups: &[Vec<usize>]) -> Result<(crate::calib::model::CalibModel, Vec<f64>)> {
        let m = self.model.measurement;
        let what = m.def().describe();
        let mut model = self.model.clone();
        let mut x = self.x.clone();
        // The rows' inputs for the flange (their torques and flanks; no set-up moves the flange).
        let inputs = self.row_inputs(data);
        for ((k, label), idx) in unknown.iter().zip(groups) {
            let n = model.setup_params(*k).len();
            if idx.len() * m.dim() < 2 * n || idx.len() < 3 {
                return Err(Error::data(
                    &data.source,
                    format!(
                        "{} {label}: {} rows are too few to register a {what}'s placement (at least 3, and twice as many values as its {n} parameters)",
                        k.name(),
                        idx.len()
                    ),
                ));
            }
            // The start: the instrument located from the calibrated arm's flange on these rows
            // (a point's target: the calibrated one).
            let sub = super::split::samples(data, idx);
            let mut w = model.work();
            let (pts, rots): (Vec<_>, Vec<_>) = idx
                .iter()
                .zip(&sub.q)
                .map(|(&i, q)| {
                    let f = model.flange_frame_with(&x, q, &inputs[i], &mut w);
                    (f.pos, f.rot)
                })
                .unzip();
            let (own, tool) = m.def().locate(&pts, &rots, &sub.y).ok_or_else(|| {
                Error::data(
                    &data.source,
                    format!("{} {label}: cannot place the {what} from rows {}-{} (points on one line?)", k.name(), idx[0] + 1, idx[idx.len() - 1] + 1),
                )
            })?;
            let located = crate::measurement::Placement { measurement: m, own, tool };
            let from = match (k, m.def().n_targets() > 1) {
                (SetupKind::Mount, false) => model.placement(&x),
                _ => located,
            };
            let start = from.values()[model.setup_params(*k)].to_vec();
            model.add_setup(*k, &mut x, label, &start, CALIBRATED_SETUP);
        }
        Ok((model, x))
    }
}

/// The arm of `model` at `x` (its chain held as calibrated) read by the instrument of `data`'s
/// rows: that instrument placed from the calibrated flange on `rows` (where it stands and its
/// target on the flange, both fitted; nothing of the arm). How a calibration by one kind of
/// data is judged on another: a ball-in-socket calibration, which never sees the base frame,
/// on a tracker's points once the tracker is registered. The model must have no effect block.
pub fn under_instrument(model: &CalibModel, x: &[f64], data: &Dataset, rows: &[usize]) -> Result<(CalibModel, Vec<f64>)> {
    let m = data.measurement().ok_or_else(|| Error::data(&data.source, "the rows hold no reading to register an instrument on"))?;
    if !model.effects.is_empty() {
        return Err(Error::Invalid("a model with effect blocks is registered under its own instrument only".into()));
    }
    let nc = model.n_chain();
    let zero = Placement { measurement: m, own: vec![0.0; m.target_index()], tool: nalgebra::Vector3::zeros() };
    let mut other = model.clone().with_placement(&zero);
    other.nominal[..nc].copy_from_slice(&x[..nc]);
    let sub = super::split::samples(data, rows);
    let located = super::placement::locate_on(&other, &other.nominal, m, &sub.q, &sub.y)
        .ok_or_else(|| Error::Calibration(format!("cannot place the {} from the calibrated arm on {} rows", m.def().describe(), rows.len())))?;
    let mut start = other.nominal.clone();
    other.set_placement(&mut start, &located);
    let fixed: Vec<bool> = (0..start.len()).map(|k| k < nc).collect();
    let fit = ReadingFit { model: &other, data: &Samples { w: None, gls: None, ..sub } };
    let x = LevenbergMarquardt::budget(200).minimize(&fit, &start, &fixed, &mut NoObserver).x;
    if x.iter().any(|v| !v.is_finite()) {
        return Err(Error::Calibration("the instrument's registration diverged".into()));
    }
    Ok((other, x))
}
