//! A calibrated model on rows measured from stations it was not calibrated at: the tracker
//! re-stationed after the calibration, or a file that names another station. Each new station's
//! placement is registered on its first rows (the arm, the target and every other parameter held
//! as calibrated), and the rest of its rows are then predicted as unseen.

use super::result::CalibResult;
use crate::calib::effects::RowInputs;
use crate::calib::problem::{ReadingFit, Samples};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::optim::{LevenbergMarquardt, NoObserver};
use serde::{Deserialize, Serialize};

/// Rows a new station is registered on by default (`--register-rows`): four times what a
/// tracker's six placement parameters need, few enough to leave most of a session unseen.
pub const DEFAULT_REGISTER_ROWS: usize = 12;

/// The label a new station takes when the rows name none.
pub const UNNAMED_STATION: &str = "new";

/// A station registered on some of its rows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Registration {
    /// The station's label (the rows', or [`UNNAMED_STATION`]).
    pub label: String,
    /// The data rows (1-based) its placement was fitted on: not unseen.
    pub rows: Vec<usize>,
    /// The rows' RMS residual after the registration, mm per value.
    pub rms_mm: f64,
}

impl Registration {
    /// What a command prints of it.
    pub fn line(&self) -> String {
        format!(
            "station {}: not one the model was calibrated at; its placement registered on rows {}-{} ({} rows, RMS {:.4} mm), its other rows predicted unseen",
            self.label,
            self.rows.first().copied().unwrap_or(0),
            self.rows.last().copied().unwrap_or(0),
            self.rows.len(),
            self.rms_mm
        )
    }
}

impl CalibResult {
    /// Each row's station as this model numbers them (by label); `None` for a row whose station
    /// the model does not know (a label it was not calibrated at, or none where it knows
    /// several).
    pub fn station_of_rows(&self, data: &Dataset) -> Vec<Option<usize>> {
        let known = &self.model.stations;
        data.rows
            .iter()
            .map(|r| match (r.station.as_deref(), known.len()) {
                (None, 0 | 1) => Some(0),
                (None, _) => None,
                (Some(l), _) => known.iter().position(|k| k == l),
            })
            .collect()
    }

    /// Every row's inputs for this model: [`row_inputs`](crate::calib::effects::inputs::row_inputs)
    /// with the stations numbered as the model numbers them (a station it does not know reads
    /// its first: register it first, [`Self::at_stations`]).
    pub fn row_inputs(&self, data: &Dataset) -> Vec<RowInputs> {
        let mut inputs = crate::calib::effects::inputs::row_inputs(data, self.torque_model.as_ref());
        for (inp, s) in inputs.iter_mut().zip(self.station_of_rows(data)) {
            inp.station = s.unwrap_or(0);
        }
        inputs
    }

    /// This model with every station of `data` it does not know registered on the station's
    /// first `rows` rows, and the data with those stations named (rows without a label where
    /// the model knows several stations become [`UNNAMED_STATION`]); `None` where it knows
    /// them all. `rows` = 0 refuses an unknown station.
    pub fn at_stations(&self, data: &Dataset, rows: usize) -> Result<Option<(CalibResult, Dataset, Vec<Registration>)>> {
        let of_row = self.station_of_rows(data);
        if of_row.iter().all(Option::is_some) {
            return Ok(None);
        }
        let mut named = data.clone();
        for (r, s) in named.rows.iter_mut().zip(&of_row) {
            if s.is_none() && r.station.is_none() {
                r.station = Some(UNNAMED_STATION.into());
            }
        }
        let mut unknown: Vec<String> = Vec::new();
        for (r, _) in named.rows.iter().zip(&of_row).filter(|(_, s)| s.is_none()) {
            if let Some(l) = r.station.as_ref().filter(|l| !unknown.contains(l)) {
                unknown.push(l.clone());
            }
        }
        if rows == 0 {
            return Err(Error::data(
                &data.source,
                format!(
                    "the rows stand at station(s) {} the model was not calibrated at ({}): register each on its first rows (--register-rows N) or name a known station in a station column",
                    unknown.join(", "),
                    if self.model.stations.is_empty() { "one unnamed station".to_string() } else { self.model.stations.join(", ") }
                ),
            ));
        }
        let mut out = self.clone();
        let mut registrations = Vec::new();
        for label in &unknown {
            let idx: Vec<usize> = named.rows.iter().enumerate().filter(|(_, r)| r.station.as_deref() == Some(label)).map(|(i, _)| i).take(rows).collect();
            registrations.push(out.register(&named, label, &idx)?);
        }
        // Rows of the station the model was calibrated at, named as it now names it.
        for (r, s) in named.rows.iter_mut().zip(&of_row) {
            if *s == Some(0) && r.station.is_none() {
                r.station = out.model.stations.first().cloned();
            }
        }
        Ok(Some((out, named, registrations)))
    }

    /// Adds station `label` to this model, its placement fitted on data rows `idx` (everything
    /// else held).
    fn register(&mut self, data: &Dataset, label: &str, idx: &[usize]) -> Result<Registration> {
        let m = self.model.measurement;
        let what = m.def().describe();
        if idx.len() * m.dim() < 2 * m.def().n_station() || idx.len() < 3 {
            return Err(Error::data(
                &data.source,
                format!(
                    "station {label}: {} rows are too few to register a {what}'s placement (at least 3, and twice as many values as its {} parameters)",
                    idx.len(),
                    m.def().n_station()
                ),
            ));
        }
        let inputs = self.row_inputs(data);
        let mut sub = super::split::samples(data, idx);
        sub.inputs = idx.iter().map(|&i| inputs[i].clone()).collect();
        // The start: the instrument located from the calibrated arm's flange on these rows.
        let mut w = self.model.work();
        let frames: Vec<_> = sub.q.iter().zip(&sub.inputs).map(|(q, inp)| self.model.flange_frame_with(&self.x, q, inp, &mut w)).collect();
        let (pts, rots): (Vec<_>, Vec<_>) = frames.iter().map(|f| (f.pos, f.rot)).unzip();
        let (own, _) = m.def().locate(&pts, &rots, &sub.y).ok_or_else(|| {
            Error::data(
                &data.source,
                format!("station {label}: cannot place the {what} from rows {}-{} (points on one line?)", idx[0] + 1, idx[idx.len() - 1] + 1),
            )
        })?;
        let first = "calibration";
        let mut x = self.x.clone();
        let mut model = self.model.clone();
        let s = model.add_station(&mut x, label, &own[..m.def().n_station()], first);
        sub.inputs.iter_mut().for_each(|inp| inp.station = s);
        let range = model.station_range(s);
        let fixed: Vec<bool> = (0..x.len()).map(|k| !range.contains(&k)).collect();
        let fit = ReadingFit { model: &model, data: &Samples { w: None, gls: None, ..sub } };
        let x = LevenbergMarquardt::budget(200).minimize(&fit, &x, &fixed, &mut NoObserver).x;
        let r = fit.residuals_mm(&x);
        let rms_mm = (r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64).sqrt();
        if !rms_mm.is_finite() {
            return Err(Error::Calibration(format!("station {label}: the registration diverged")));
        }
        // The parameter report follows the model's parameters.
        let at = range.start;
        for k in (range.start..range.end).rev() {
            let d = model.kinds[k].display();
            self.parameters.insert(
                at,
                super::result::ParamReport {
                    name: model.names[k].clone(),
                    unit: model.kinds[k].unit().into(),
                    nominal: model.nominal[k] * d,
                    value: x[k] * d,
                    std_uncertainty: None,
                    fixed: false,
                    truth: None,
                    error: None,
                    z: None,
                },
            );
        }
        self.model = model;
        self.x = x;
        Ok(Registration { label: label.to_string(), rows: idx.iter().map(|i| i + 1).collect(), rms_mm })
    }
}
