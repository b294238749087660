//! `twincal iso9283`: pose accuracy and repeatability (ISO 9283) of measured poses against what a
//! model commands, for one model or several (before and after a calibration).
//!
//! The data are measured positions (a tracker's point or pose) at commanded joint angles; a
//! model's *commanded* position for a row is where it puts the tool at those angles, in the
//! instrument's frame (its placement included: a model registered to these data, e.g. by
//! `calibrate --placement-only`, compares in their frame). Rows whose joint angles agree
//! within 0.01° on every joint are the cycles of one pose (a robot logs the angles it reached, which differ
//! between cycles by thousandths of a degree). Per pose, ISO 9283's
//! * position accuracy AP = |mean attained − commanded| (mm),
//! * position repeatability RP = l̄ + 3·S_l, l the distances of the attained positions from their
//!   mean (mm; poses visited at least twice, over every row: it is the arm's, not a model's),
//! * for 6-D data the orientation error: the angle of the rotation between the measured and the
//!   commanded orientation (degrees; one per row, its mean over the pose's cycles);
//!
//! and between consecutive rows (the order of the program) the distance accuracy
//! AD = | |a₁ − a₂| − |c₁ − c₂| | (mm). When the model was calibrated on these very data, only the
//! rows it held out are judged.

use super::files::{data_inputs, load_dataset};
use super::predict::{predicted_readings, rotation_residual_deg};
use crate::calib::pipeline::CalibResult;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use crate::requests::Reading;
use crate::stats::metrics::ErrorStats;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// An ISO 9283 evaluation as `twincal iso9283` runs it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct Iso9283Job {
    /// Measured poses (dataset folder, CSV or xlsx): q1..qN and a tracker's x, y, z (and rx, ry,
    /// rz), rows with the same joint angles being the cycles of one pose.
    #[cfg_attr(feature = "clap", arg(long))]
    pub data: PathBuf,
    /// Models whose commanded positions are judged, each a result.json (give it twice or more:
    /// before and after a calibration), registered to these data's instrument frame.
    #[cfg_attr(feature = "clap", arg(long, required = true))]
    pub model: Vec<PathBuf>,
    /// How the data are read.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(default)]
    pub reading: Reading,
    /// The evaluation as JSON.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub out: Option<PathBuf>,
    /// Also write the figures as an HTML page: the table, each model's per-pose AP as
    /// histograms on one axis, the warnings.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub report: Option<PathBuf>,
    /// Rows a station the model was not calibrated at is registered on (its first ones; they are
    /// then not judged); 0 refuses such a station.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = crate::calib::pipeline::DEFAULT_REGISTER_ROWS))]
    #[serde(default = "default_register_rows")]
    pub register_rows: usize,
}

fn default_register_rows() -> usize {
    crate::calib::pipeline::DEFAULT_REGISTER_ROWS
}

/// One pose's figures.
#[derive(Clone, Debug, Serialize)]
pub struct PoseFigures {
    /// The rows (0-based, file order) that are its cycles.
    pub rows: Vec<usize>,
    /// Position accuracy, mm.
    pub ap_mm: f64,
    /// Position repeatability, mm (visited at least twice among the judged rows).
    pub rp_mm: Option<f64>,
    /// Mean orientation error over its cycles, degrees (6-D data).
    pub orientation_deg: Option<f64>,
}

/// One model's evaluation.
#[derive(Clone, Debug, Serialize)]
pub struct ModelFigures {
    /// The model file.
    pub model: PathBuf,
    /// Which rows were judged: `all`, or `held out` (the model's own test rows).
    pub rows: String,
    /// Poses judged.
    pub poses: usize,
    /// AP over the poses, mm.
    pub ap_mm: ErrorStats,
    /// RP over the poses visited at least twice among every row of the data, mm (the arm's own,
    /// the same for every model; none when no pose was).
    pub rp_mm: Option<ErrorStats>,
    /// AD over consecutive judged rows, mm.
    pub ad_mm: Option<ErrorStats>,
    /// Orientation error over the poses, degrees (6-D data).
    pub orientation_deg: Option<ErrorStats>,
    /// Per pose.
    pub per_pose: Vec<PoseFigures>,
}

/// The evaluation of every model.
#[derive(Clone, Debug, Serialize)]
pub struct Iso9283 {
    /// See [`crate::output::SCHEMA_VERSION`].
    pub schema_version: u32,
    /// The data.
    pub data: String,
    /// Rows read.
    pub n_rows: usize,
    /// One per model, in the order given.
    pub models: Vec<ModelFigures>,
    /// What the reader should know.
    pub warnings: Vec<String>,
}

/// Joint angles (degrees) within this of each other on every joint are one pose's cycles.
pub const SAME_POSE_DEG: f64 = 0.01;

/// The poses of `rows`: rows whose joint angles agree within [`SAME_POSE_DEG`] on every joint
/// (linked in a chain, as the repeatability floor groups them; never split by a rounding
/// boundary), in first-visit order.
fn poses(data: &Dataset, rows: &[usize]) -> Vec<Vec<usize>> {
    let q: Vec<&[f64]> = data.rows.iter().map(|r| r.q_deg.as_slice()).collect();
    crate::stats::metrics::configuration_groups(&q, rows, SAME_POSE_DEG)
}

fn mean(v: &[Vector3<f64>]) -> Vector3<f64> {
    v.iter().sum::<Vector3<f64>>() / v.len().max(1) as f64
}

/// ISO 9283's figures of one model: `measured[i]` and `commanded[i]` the row's position (mm) and,
/// for 6-D data, its angles (degrees, in `euler`).
pub fn figures(
    data: &Dataset,
    judged: &[usize],
    measured: &[Vec<f64>],
    commanded: &[Vec<f64>],
    euler: crate::measurement::Euler,
) -> (Vec<PoseFigures>, Option<ErrorStats>) {
    let pos = |v: &[f64]| Vector3::new(v[0], v[1], v[2]);
    let per_pose: Vec<PoseFigures> = poses(data, judged)
        .into_iter()
        .map(|rows| {
            let attained: Vec<Vector3<f64>> = rows.iter().map(|&i| pos(&measured[i])).collect();
            let c = mean(&rows.iter().map(|&i| pos(&commanded[i])).collect::<Vec<_>>());
            let a = mean(&attained);
            let rp_mm = (rows.len() >= 2).then(|| {
                let l: Vec<f64> = attained.iter().map(|p| (p - a).norm()).collect();
                let lm = l.iter().sum::<f64>() / l.len() as f64;
                let sl = (l.iter().map(|x| (x - lm).powi(2)).sum::<f64>() / (l.len() - 1) as f64).sqrt();
                lm + 3.0 * sl
            });
            let orientation_deg = (measured[rows[0]].len() >= 6).then(|| {
                rows.iter()
                    .map(|&i| {
                        let r = rotation_residual_deg(&measured[i][3..6], &commanded[i][3..6], euler);
                        Vector3::from(r).norm()
                    })
                    .sum::<f64>()
                    / rows.len() as f64
            });
            PoseFigures { ap_mm: (a - c).norm(), rp_mm, orientation_deg, rows }
        })
        .collect();
    let ad: Vec<f64> = judged
        .windows(2)
        .filter(|w| w[1] == w[0] + 1)
        .map(|w| ((pos(&measured[w[0]]) - pos(&measured[w[1]])).norm() - (pos(&commanded[w[0]]) - pos(&commanded[w[1]])).norm()).abs())
        .collect();
    (per_pose, (!ad.is_empty()).then(|| ErrorStats::of(&ad)))
}

/// A mean AP beyond this (mm) says the model is not of these data's arm and instrument: a
/// nominal model is off by a few mm, a calibrated one by far less.
const OTHER_ARM_AP_MM: f64 = 100.0;

impl Iso9283Job {
    /// Reads the data and every model, evaluates each, writes `--out` when given.
    pub fn run(&self) -> Result<Iso9283> {
        let mut inputs: Vec<(&str, PathBuf)> = data_inputs(&self.data).into_iter().map(|p| ("--data", p)).collect();
        inputs.extend(self.model.iter().map(|m| ("--model", m.clone())));
        let outs: Vec<(&str, &std::path::Path)> =
            self.out.iter().map(|p| ("--out", p.as_path())).chain(self.report.iter().map(|p| ("--report", p.as_path()))).collect();
        check_outputs(&inputs, &outs)?;
        if self.model.is_empty() {
            return Err(Error::Invalid("iso9283 needs at least one --model".into()));
        }
        let data = load_dataset(&self.data, &self.reading, true)?;
        let euler = self.reading.euler;
        let m = data.measurement().ok_or_else(|| Error::data(&data.source, "no readings"))?;
        if m.file_lengths() < 3 {
            return Err(Error::data(&data.source, format!("ISO 9283 judges positions: these rows hold a {}, not a tracker's x, y, z", m.def().describe())));
        }
        let measured: Vec<Vec<f64>> = data.rows.iter().map(|r| r.reading_mm.clone()).collect();
        let sha = crate::dataset::truth::file_sha256(&data_inputs(&self.data)[0]).ok();
        let mut warnings = Vec::new();
        let mut models = Vec::new();
        for path in &self.model {
            let r = CalibResult::load(path)?;
            let p = predicted_readings(&r, &data, euler, &format!("the model {}", path.display()), self.register_rows)?;
            warnings.extend(p.warnings.iter().cloned());
            let d = r.model.measurement.file_dim();
            let commanded: Vec<Vec<f64>> = p.values.chunks(d).map(<[f64]>::to_vec).collect();
            let own = sha.is_some() && r.provenance.data_sha256 == sha && !r.provenance.test_rows.is_empty();
            if let Some(row) = r.provenance.test_rows.iter().find(|i| **i >= data.rows.len()).filter(|_| own) {
                return Err(Error::model(
                    path.display(),
                    format!("provenance.test_rows names row {}, past the {} rows of {} (edited result file?)", row + 1, data.rows.len(), data.source),
                ));
            }
            let registration = p.registration_rows();
            let judged: Vec<usize> = if own { r.provenance.test_rows.clone() } else { (0..data.rows.len()).collect() };
            let judged: Vec<usize> = judged.into_iter().filter(|i| !registration.contains(i)).collect();
            let (per_pose, ad_mm) = figures(&data, &judged, &measured, &commanded, euler);
            let all: Vec<usize> = (0..data.rows.len()).collect();
            let rp: Vec<f64> = figures(&data, &all, &measured, &commanded, euler).0.iter().filter_map(|p| p.rp_mm).collect();
            let orient: Vec<f64> = per_pose.iter().filter_map(|p| p.orientation_deg).collect();
            let ap = ErrorStats::of(&per_pose.iter().map(|p| p.ap_mm).collect::<Vec<_>>());
            if ap.mean > OTHER_ARM_AP_MM {
                warnings.push(format!(
                    "the model {} misses these poses by {:.1} mm on average: a model of another arm, or of the instrument where it stood before it moved?",
                    path.display(),
                    ap.mean
                ));
            }
            models.push(ModelFigures {
                model: path.clone(),
                rows: if own { "held out".into() } else { "all".into() },
                poses: per_pose.len(),
                ap_mm: ap,
                rp_mm: (!rp.is_empty()).then(|| ErrorStats::of(&rp)),
                ad_mm,
                orientation_deg: (!orient.is_empty()).then(|| ErrorStats::of(&orient)),
                per_pose,
            });
        }
        if models.iter().any(|m| m.rows != models[0].rows) {
            warnings.push("the models are judged on different rows (each calibrated on these data on the rows it held out, the others on every row): compare them on rows judged alike".into());
        }
        let out = Iso9283 { schema_version: crate::output::schema_version(), data: data.source.clone(), n_rows: data.rows.len(), models, warnings };
        let mut outputs = OutputSet::new();
        if let Some(p) = &self.out {
            outputs.write_json(p, &out)?;
        }
        if let Some(p) = &self.report {
            outputs.write(p, iso9283_page(&out).as_bytes())?;
        }
        outputs.commit()?;
        Ok(out)
    }
}

/// The evaluation as a Markdown table, a row per model.
pub fn iso9283_table(e: &Iso9283) -> String {
    let mut out = format!("# ISO 9283 on {} ({} rows)\n\n| model | rows | poses | AP mean | AP max | RP mean | AD mean | orientation mean (deg) |\n|---|---|---|---|---|---|---|---|\n", e.data, e.n_rows);
    for m in &e.models {
        let opt = |s: &Option<ErrorStats>, f: fn(&ErrorStats) -> f64, d: usize| s.as_ref().map_or("–".to_string(), |s| format!("{:.d$}", f(s)));
        out.push_str(&format!(
            "| {} | {} | {} | {:.4} | {:.4} | {} | {} | {} |\n",
            m.model.display(),
            m.rows,
            m.poses,
            m.ap_mm.mean,
            m.ap_mm.max,
            opt(&m.rp_mm, |s| s.mean, 4),
            opt(&m.ad_mm, |s| s.mean, 4),
            opt(&m.orientation_deg, |s| s.mean, 5)
        ));
    }
    out
}

/// Colours of the models' histograms, in the order given (the first, grey: the one before).
const MODEL_COLOURS: [&str; 5] = ["#9a9a9a", "#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd"];

/// The figures as an HTML page (`iso9283 --report`).
pub fn iso9283_page(e: &Iso9283) -> String {
    use crate::report::svg::{esc, histograms};
    let mut b = String::new();
    b.push_str(&format!(
        "<p class=\"note\">{} ({} rows). AP: the distance from the mean attained position of a pose's cycles to its commanded position (the model's prediction); \
         RP: the spread of a pose's cycles (the arm's own, the same for every model); AD: the error of the distance between consecutive rows; \
         poses are rows whose joint angles agree within 0.01°. A model calibrated on these data is judged on the rows it held out.</p>\n",
        esc(&e.data),
        e.n_rows
    ));
    b.push_str("<table><tr><th>model</th><th>rows</th><th>poses</th><th>AP mean (mm)</th><th>AP max (mm)</th><th>RP mean (mm)</th><th>AD mean (mm)</th><th>orientation mean (deg)</th></tr>");
    let opt = |s: &Option<ErrorStats>, d: usize| s.as_ref().map_or("–".to_string(), |s| format!("{:.d$}", s.mean));
    for m in &e.models {
        b.push_str(&format!(
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>{:.4}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&m.model.display().to_string()),
            esc(&m.rows),
            m.poses,
            m.ap_mm.mean,
            m.ap_mm.max,
            opt(&m.rp_mm, 4),
            opt(&m.ad_mm, 4),
            opt(&m.orientation_deg, 5)
        ));
    }
    b.push_str("</table>\n");
    let top = e.models.iter().flat_map(|m| m.per_pose.iter().map(|p| p.ap_mm)).fold(0.0f64, f64::max).max(1e-6);
    let hists: Vec<(String, String, Vec<f64>, Vec<f64>)> = e
        .models
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let (edges, counts) = crate::report::histogram(&m.per_pose.iter().map(|p| p.ap_mm).collect::<Vec<_>>(), 30, 0.0, top);
            let name = m.model.file_name().map_or_else(|| m.model.display().to_string(), |f| f.to_string_lossy().into_owned());
            (name, MODEL_COLOURS[k % MODEL_COLOURS.len()].to_string(), edges, counts)
        })
        .collect();
    b.push_str("<h2>Position accuracy per pose</h2>\n");
    b.push_str(&histograms("AP per pose, every model", "AP (mm)", &hists));
    if !e.warnings.is_empty() {
        b.push_str("<h2>Warnings</h2><ul>");
        e.warnings.iter().for_each(|w| b.push_str(&format!("<li>{}</li>", esc(w))));
        b.push_str("</ul>\n");
    }
    crate::report::html::page("ISO 9283 pose accuracy and repeatability", &b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two cycles 0.0002° apart that straddle a 0.01° rounding boundary are one pose (rounding
    /// made them two, and two poses without RP); poses 0.05° apart stay two.
    #[test]
    fn cycles_are_grouped_by_tolerance_not_by_rounding() {
        let mut data = Dataset::default();
        for a in [10.00499, 10.00519, 10.06, 10.00505] {
            data.rows.push(crate::dataset::Row { q_deg: vec![a, -20.0, 30.0, 0.0, 45.0, 0.0], reading_mm: vec![0.0; 3], ..Default::default() });
        }
        assert_eq!(poses(&data, &[0, 1, 2, 3]), vec![vec![0, 1, 3], vec![2]]);
    }

    #[test]
    fn ap_rp_and_ad_follow_their_definitions() {
        // Two poses: the first visited three times around (10, 0, 0) mm, commanded at (10.3, 0, 0);
        // the second once at (0, 20, 0), commanded at (0, 20.4, 0).
        let mut data = Dataset::default();
        let q = |a: f64| vec![a, 0.0, 0.0, 0.0, 0.0, 0.0];
        for (qq, y) in [(q(1.0), [9.9, 0.0, 0.0]), (q(1.003), [10.1, 0.0, 0.0]), (q(2.0), [0.0, 20.0, 0.0]), (q(0.998), [10.0, 0.0, 0.0])] {
            data.rows.push(crate::dataset::Row { q_deg: qq, reading_mm: y.to_vec(), ..Default::default() });
        }
        let measured: Vec<Vec<f64>> = data.rows.iter().map(|r| r.reading_mm.clone()).collect();
        let commanded = vec![vec![10.3, 0.0, 0.0], vec![10.3, 0.0, 0.0], vec![0.0, 20.4, 0.0], vec![10.3, 0.0, 0.0]];
        let (p, ad) = figures(&data, &[0, 1, 2, 3], &measured, &commanded, crate::measurement::Euler::XYZ);
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].rows, [0, 1, 3]);
        assert!((p[0].ap_mm - 0.3).abs() < 1e-12 && (p[1].ap_mm - 0.4).abs() < 1e-12);
        // l = 0.1, 0.1, 0: mean 1/15, S_l = sqrt(((1/30)² · 2 + (1/15)²) / 2).
        let (lm, sl) = (0.2 / 3.0, ((2.0 * (0.1f64 - 0.2 / 3.0).powi(2) + (0.2f64 / 3.0).powi(2)) / 2.0).sqrt());
        assert!((p[0].rp_mm.unwrap() - (lm + 3.0 * sl)).abs() < 1e-12);
        assert!(p[1].rp_mm.is_none());
        // Consecutive rows: |a1 − a2| − |c1 − c2| per pair.
        let d = |a: [f64; 3], b: [f64; 3]| Vector3::from(a).metric_distance(&Vector3::from(b));
        let expect = [
            (d([9.9, 0.0, 0.0], [10.1, 0.0, 0.0]) - 0.0).abs(),
            (d([10.1, 0.0, 0.0], [0.0, 20.0, 0.0]) - d([10.3, 0.0, 0.0], [0.0, 20.4, 0.0])).abs(),
            (d([0.0, 20.0, 0.0], [10.0, 0.0, 0.0]) - d([0.0, 20.4, 0.0], [10.3, 0.0, 0.0])).abs(),
        ];
        assert!((ad.unwrap().mean - expect.iter().sum::<f64>() / 3.0).abs() < 1e-12);
    }
}
