//! The truth file the twin writes beside a dataset (`truth.json`): its one schema, which the twin
//! writes and the calibration, `ik` and Python read, and the link that ties it to the exact
//! dataset it describes.

use crate::dataset::Split;
use crate::error::{Error, Result};
use crate::robot::statics::Contact;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Name of the truth file in a dataset folder.
pub const TRUTH_FILE: &str = "truth.json";

/// What a truth file says, read below the twin: the one schema with the effects as JSON and the
/// tracker's placement.
pub type TruthFile = Truth;

/// A tracker's placement as the truth file states it (the rest of its scenario entry, its noise
/// and decimals, is the twin's business).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TruthTracker {
    /// The base-to-tracker translation `t` of `y = R·p + t`, mm.
    pub translation_mm: [f64; 3],
    /// The base-to-tracker rotation `R = Rx(a)·Ry(b)·Rz(c)`, degrees.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// A 6-D probe's orientation on the flange (intrinsic X-Y-Z, degrees); absent for a reflector.
    #[serde(default)]
    pub probe_rotation_deg: Option<[f64; 3]>,
}
/// Per-pose ground truth.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PoseTruth {
    /// Index of the pose among the sampled poses (acquisition order; rejected poses keep their
    /// number).
    #[serde(default)]
    pub index: usize,
    /// The subset the pose's row belongs to.
    #[serde(default)]
    pub split: Split,
    /// Acquisition time, s from the start of acquisition (unrounded; the row's `t` is rounded to
    /// [`crate::sim::generate::T_DECIMALS`]).
    #[serde(default)]
    pub t_s: f64,
    /// The structure's true temperature rise over ambient, K (drives the thermal scaling).
    #[serde(default)]
    pub delta_t_k: f64,
    /// What the temperature sensor wrote in the `temp` column, °C (absent without a column).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temp_measured_c: Option<f64>,
    /// Commanded (controller) joint angles, degrees.
    #[serde(default)]
    pub q_cmd_deg: Vec<f64>,
    /// Encoder eccentricity, true motor-side minus commanded angle per joint, millidegrees
    /// (absent when the effect is off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eccentricity_mdeg: Option<Vec<f64>>,
    /// Link-side angles the chain sees (commanded + eccentricity + deflection), degrees.
    #[serde(default)]
    pub q_link_deg: Vec<f64>,
    /// Link-side deflection per joint (link side minus motor side), millidegrees.
    #[serde(default)]
    pub deflection_mdeg: Vec<f64>,
    /// Load torque per joint at rest (gravity, payload, cable tension), N·m.
    #[serde(default)]
    pub joint_torque_nm: Vec<f64>,
    /// Backlash flank each joint arrived on (±1), by the approach rule.
    #[serde(default)]
    pub approach_side: Vec<f64>,
    /// Where each joint's transmission came to rest (spring, a flank, held, free).
    #[serde(default)]
    pub contact: Vec<Contact>,
    /// True tool position, base frame, mm.
    #[serde(default)]
    pub tool_mm: [f64; 3],
    /// Distance + length offset, mm (no linearity error, no noise).
    pub length_true_mm: f64,
    /// What a perfect reading would give: true length + linearity error, mm.
    #[serde(default)]
    pub length_noise_free_mm: f64,
    /// The draw-wire's reading, mm: noise, resolution and any glitch run included (the value a
    /// draw-wire dataset holds).
    #[serde(default)]
    pub length_measured_mm: f64,
    /// With a tracker: the reflector's true position in the tracker's frame, mm (no noise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_true_mm: Option<[f64; 3]>,
    /// With a tracker: what it wrote (`x, y, z`), mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_measured_mm: Option<[f64; 3]>,
    /// With a 6-D probe: its true pose in the tracker's frame (`x, y, z` mm, `rx, ry, rz`
    /// degrees, intrinsic X-Y-Z; no noise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_true: Option<[f64; 6]>,
    /// With another instrument than these: its true reading (its dataset columns: mm, and
    /// degrees for angles; no noise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading_true: Option<Vec<f64>>,
    /// ... and what it wrote.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading_measured: Option<Vec<f64>>,
    /// Simulation steps the arm took to settle (0 for the quasi-static model or a rigid arm).
    #[serde(default)]
    pub settle_steps: usize,
    /// Simulated time the arm took to come to rest, s. Longer than the sensor's hold time means
    /// a real reading would have been taken while the arm still moved.
    #[serde(default)]
    pub settle_time_s: f64,
    /// How the simulated acquisition went at this pose (absent for settled / quasi-static datasets).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acquisition: Option<PoseAcquisition>,
}

impl PoseTruth {
    /// The noise-free reading of an instrument other than the cable, as the model reads it
    /// (values, mm), when this pose holds one of `measurement`'s dimension.
    pub fn instrument_reading_mm(&self, measurement: crate::measurement::Measurement) -> Option<Vec<f64>> {
        // A probe's truth also holds its point, which a pose file read as points compares to.
        let candidates = [self.reading_true.as_deref(), self.pose_true.as_ref().map(|v| &v[..]), self.point_true_mm.as_ref().map(|v| &v[..])];
        let file = candidates.into_iter().flatten().find(|v| v.len() == measurement.file_dim())?;
        Some(measurement.values_of_file(file))
    }

    /// What a perfect instrument reading `measurement` would give at this pose, model values
    /// (mm): the cable's true length with its linearity error, or another instrument's
    /// noise-free reading.
    pub fn noise_free_reading_mm(&self, measurement: crate::measurement::Measurement) -> Option<Vec<f64>> {
        match measurement {
            crate::measurement::Measurement::Length => Some(vec![self.length_noise_free_mm]),
            m => self.instrument_reading_mm(m),
        }
    }
}

/// The true placement of an instrument that has no table of its own in truth.json.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstrumentTruth {
    /// What it reads.
    pub measurement: crate::measurement::Measurement,
    /// Its own placement parameters (the measurement's `placement_names` but the target's), m
    /// and rad.
    pub own: Vec<f64>,
}

/// Per pose of a simulated acquisition (`acquisition.model = "simulated"`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PoseAcquisition {
    /// Duration of the move to this pose, s.
    pub move_s: f64,
    /// When the stability gate opened, s after arrival; `null`: still closed when the hold ended.
    pub gate_s: Option<f64>,
    /// The readings were taken with the gate closed (`on_timeout = "read"`).
    pub read_with_gate_closed: bool,
    /// What the transient adds to L: the window's mean noise-free length minus that of the arm at
    /// rest on the flanks it ends on, mm. With a tracker: the distance of the window's mean tool
    /// point from the arm at rest, mm.
    pub transient_mm: f64,
    /// From when on the transient could no longer reach 1 nm at the tool by the readings (its
    /// amplitude decaying at the slowest modelled rate), s after arrival; `null`: it still could.
    pub negligible_s: Option<f64>,
    /// The flank the load/approach rule predicts per joint (±1); `contact` is what the motion gave.
    pub rule_side: Vec<f64>,
}

/// A sampled pose that gave no dataset row, and why.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Rejected {
    /// Index of the pose among the sampled poses.
    pub index: usize,
    /// Commanded joint angles, degrees.
    pub q_cmd_deg: Vec<f64>,
    /// Why the pose was rejected (settling failed, reading out of range, stability gate still
    /// closed).
    pub reason: String,
}

/// The draw-wire sensor's settings, as the truth file records them (see
/// [`crate::sim::instrument::DrawWire`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DrawWireTruth {
    /// Cable exit point in the base frame, mm.
    pub exit_point_mm: [f64; 3],
    /// Added to the geometric distance, mm.
    pub length_offset_mm: f64,
    /// Standard deviation of one raw sample, mm.
    #[serde(default)]
    pub noise_std_mm: f64,
    /// Standard deviation of a written reading: `noise_std_mm` / √`samples`, mm.
    #[serde(default)]
    pub averaged_noise_std_mm: f64,
    /// Quantisation step of one raw sample, mm (0 = none).
    #[serde(default)]
    pub resolution_mm: f64,
    /// Amplitude of the linearity error, % of full scale (range width).
    #[serde(default)]
    pub linearity_pct_fs: f64,
    /// Valid reading range [min, max], mm.
    #[serde(default)]
    pub range_mm: [f64; 2],
    /// Cable tension acting on the tool, N.
    #[serde(default)]
    pub tension_n: f64,
    /// Raw samples averaged per reading.
    #[serde(default)]
    pub samples: usize,
    /// Hold time before sampling, s.
    #[serde(default)]
    pub hold_s: f64,
    /// Sampling rate, Hz.
    #[serde(default)]
    pub rate_hz: f64,
}

/// The tool point the instrument reads, as the truth file records it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ToolTruth {
    /// Cable attachment point (or reflector) in the flange frame, mm.
    pub point_mm: [f64; 3],
}

/// truth.json, the one truth schema: everything true about a generated dataset. The twin writes
/// it (`sim::generate::Truth`, with its own `Effects` and `Tracker` as `E` and `T`); a reader
/// below the twin (the calibration's truth comparison, `ik`, Python) reads it with the effects as
/// JSON and the tracker's placement ([`TruthFile`]). What a reader needs is required; what only
/// the twin's own files hold defaults when absent, so hand-written truths stay readable.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Truth<E = serde_json::Value, T = TruthTracker> {
    /// See [`crate::output::SCHEMA_VERSION`].
    #[serde(default = "crate::output::schema_version")]
    pub schema_version: u32,
    /// The dataset this truth belongs to (written first by the twin's writer; absent in files
    /// written before twincal recorded it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<DatasetLink>,
    /// The scenario's `name`.
    #[serde(default)]
    pub scenario: String,
    /// The seed the dataset was generated with.
    #[serde(default)]
    pub seed: u64,
    /// Name of the robot.
    #[serde(default)]
    pub robot: String,
    /// The robot's URDF text, for a robot other than the embedded IRB 120: the truth file then
    /// holds everything needed to rebuild the twin (`ik` validates against it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_urdf: Option<String>,
    /// Unit of each kind of value in the file, by name.
    #[serde(default)]
    pub units: BTreeMap<String, String>,
    /// True geometric deviations: mm for dx/dy/dz, degrees for rx/ry/rz/dtheta.
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
    /// The twin's effects and their true settings.
    #[serde(default)]
    pub effects: E,
    /// The draw-wire sensor.
    #[serde(rename = "sensor")]
    pub draw_wire: DrawWireTruth,
    /// The tracker that wrote `x, y, z` (absent for a draw-wire dataset).
    #[serde(default = "Option::default", skip_serializing_if = "Option::is_none")]
    pub tracker: Option<T>,
    /// The placement of another instrument than the cable and the tracker, which have their
    /// own tables.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instrument: Option<InstrumentTruth>,
    /// The tool point.
    pub tool: ToolTruth,
    /// Standard deviation of one written reading value, mm: the averaged cable noise, or for a
    /// tracker the RMS over the poses of one coordinate's averaged noise.
    pub noise_std_mm: f64,
    /// Ground truth of each dataset row, in file order.
    pub poses: Vec<PoseTruth>,
    /// Sampled poses that gave no row.
    #[serde(default)]
    pub rejected: Vec<Rejected>,
    /// Dataset rows (0-based, in file order) whose reading carries a glitch run's offset.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub glitch_rows: Vec<usize>,
}

impl TruthFile {
    /// The true placement of the instrument that wrote the dataset (m, rad): the tracker's
    /// when there is one, else the draw-wire's.
    pub fn placement(&self) -> crate::measurement::Placement {
        use crate::measurement::Placement;
        use nalgebra::Vector3;
        let mm = |v: [f64; 3]| crate::units::to_m(Vector3::from(v));
        let tool = mm(self.tool.point_mm);
        if let Some(i) = &self.instrument {
            return Placement { measurement: i.measurement, own: i.own.clone(), tool };
        }
        match &self.tracker {
            Some(t) => Placement::tracker(t.translation_mm, t.rotation_deg, t.probe_rotation_deg, tool),
            None => Placement::cable(mm(self.draw_wire.exit_point_mm), crate::units::to_m(self.draw_wire.length_offset_mm), tool),
        }
    }

    /// Pose `i`'s noise-free reading, m, in `measurement`'s order; `None` when the file does not
    /// hold that kind of reading.
    pub fn true_reading(&self, i: usize, measurement: crate::measurement::Measurement) -> Option<Vec<f64>> {
        let p = self.poses.get(i)?;
        let values = match measurement {
            crate::measurement::Measurement::Length if self.tracker.is_none() && self.instrument.is_none() => vec![p.length_true_mm],
            crate::measurement::Measurement::Length => return None,
            _ => p.instrument_reading_mm(measurement)?,
        };
        Some(values.iter().map(crate::units::to_m).collect())
    }
}

/// The dataset file a truth file was written with: its name, the SHA-256 of its exact bytes
/// (lower-case hex) and its number of data rows.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DatasetLink {
    /// The dataset's file name (`dataset.csv`).
    pub file: String,
    /// SHA-256 of the file's exact bytes, lower-case hex.
    pub sha256: String,
    /// Number of data rows.
    pub rows: usize,
}

impl DatasetLink {
    /// The link of a dataset file called `file` with contents `bytes` and `rows` data rows.
    pub fn of(file: &str, bytes: &[u8], rows: usize) -> DatasetLink {
        DatasetLink { file: file.to_string(), sha256: sha256_hex(bytes), rows }
    }
}

/// SHA-256 of `bytes`, lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of a file's bytes, lower-case hex; an unreadable file is an error naming it.
pub fn file_sha256(path: &Path) -> Result<String> {
    Ok(sha256_hex(&std::fs::read(path).map_err(|e| Error::io(path, e))?))
}

/// The file a dataset path reads: `DIR/dataset.csv` for a folder, the file itself otherwise
/// (without an xlsx `#Sheet` suffix).
pub fn dataset_file(data: &Path) -> PathBuf {
    if data.is_dir() {
        return data.join(crate::dataset::DATASET_FILE);
    }
    if !data.exists() {
        let s = data.to_string_lossy();
        if let Some((file, _sheet)) = s.rsplit_once('#') {
            return PathBuf::from(file);
        }
    }
    data.to_path_buf()
}

/// The truth file that belongs beside a dataset path: `DIR/truth.json` in a dataset folder, or
/// in the folder of a dataset file.
pub fn truth_file(data: &Path) -> PathBuf {
    let dir = if data.is_dir() { data.to_path_buf() } else { dataset_file(data).parent().map(Path::to_path_buf).unwrap_or_default() };
    dir.join(TRUTH_FILE)
}

impl TruthFile {
    /// `DIR/truth.json` next to a dataset folder or file, if present and if it belongs to that
    /// dataset. A truth file whose dataset fingerprint does not match the dataset file's bytes
    /// (the dataset was edited, regenerated or replaced, or an interrupted write left an old
    /// truth file behind) is refused with an error. A truth file without a fingerprint (written
    /// by twincal before it recorded one) cannot be checked: it is ignored with a warning on
    /// stderr.
    pub fn find(data: &Path) -> Result<Option<TruthFile>> {
        let file = dataset_file(data);
        let p = truth_file(data);
        if !p.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
        let truth = TruthFile::parse(&text, &p.display().to_string())?;
        if truth.dataset.is_none() {
            eprintln!(
                "warning: {} has no dataset fingerprint (written by an older twincal), so it cannot be matched to {}; \
                 it is ignored (regenerate the dataset to compare against the truth)",
                p.display(),
                file.display()
            );
            return Ok(None);
        }
        let bytes = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
        let fix = format!("delete {} or regenerate the folder with `twincal generate`", p.display());
        truth.check_belongs(&bytes, &file.display().to_string(), &p.display().to_string(), &fix)?;
        Ok(Some(truth))
    }

    /// A truth file's text (`label` names it in errors).
    pub fn parse(text: &str, label: &str) -> Result<TruthFile> {
        let t: TruthFile = serde_json::from_str(text).map_err(|e| Error::data(label, format!("malformed truth file: {e}")))?;
        crate::output::check_schema(t.schema_version, "a truth file").map_err(|e| Error::data(label, e))?;
        Ok(t)
    }

    /// Refuses this truth unless it was written for exactly these dataset bytes (`data` and
    /// `label` name the dataset and the truth in the error, `fix` says what to do about it).
    pub fn check_belongs(&self, bytes: &[u8], data: &str, label: &str, fix: &str) -> Result<()> {
        let Some(link) = &self.dataset else {
            return Err(Error::data(label, "has no dataset fingerprint (written by an older twincal): regenerate the dataset"));
        };
        let sha = sha256_hex(bytes);
        if sha != link.sha256 {
            return Err(Error::data(
                label,
                format!(
                    "this truth file does not belong to {data}: it was written with a {} of {} rows and SHA-256 {}, \
                     the data have SHA-256 {} (edited, replaced or half-written?); {fix}",
                    link.file,
                    link.rows,
                    &link.sha256[..link.sha256.len().min(12)],
                    &sha[..12],
                ),
            ));
        }
        if self.poses.len() != link.rows {
            return Err(Error::data(label, format!("lists {} poses for a dataset of {} rows (edited truth file?)", self.poses.len(), link.rows)));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sha256_matches_the_standard_vector() {
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }

    #[test]
    fn truth_is_matched_to_its_dataset_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let csv = "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,300\n";
        std::fs::write(dir.path().join("dataset.csv"), csv).unwrap();
        let truth = |link: Option<DatasetLink>| {
            let mut v = serde_json::json!({
                "sensor": {"exit_point_mm": [0.0, 0.0, 0.0], "length_offset_mm": 0.0},
                "tool": {"point_mm": [0.0, 0.0, 0.0]}, "noise_std_mm": 0.01,
                "poses": [{"length_true_mm": 300.0}]
            });
            if let Some(l) = link {
                v["dataset"] = serde_json::to_value(l).unwrap();
            }
            std::fs::write(dir.path().join(TRUTH_FILE), v.to_string()).unwrap();
        };
        truth(Some(DatasetLink::of("dataset.csv", csv.as_bytes(), 1)));
        assert!(TruthFile::find(dir.path()).unwrap().is_some());
        assert!(TruthFile::find(&dir.path().join("dataset.csv")).unwrap().is_some());
        // One changed byte in the dataset: refused, by folder and by file.
        std::fs::write(dir.path().join("dataset.csv"), csv.replace("300", "301")).unwrap();
        for p in [dir.path().to_path_buf(), dir.path().join("dataset.csv")] {
            let e = TruthFile::find(&p).unwrap_err().to_string();
            assert!(e.contains("does not belong to") && e.contains("delete"), "{e}");
        }
        // An older truth file without a link is ignored.
        truth(None);
        assert!(TruthFile::find(dir.path()).unwrap().is_none());
        // No truth file at all.
        std::fs::remove_file(dir.path().join(TRUTH_FILE)).unwrap();
        assert!(TruthFile::find(dir.path()).unwrap().is_none());
    }
}
