//! The truth file the twin writes beside a dataset, as far as calibration needs it, and the link
//! that ties it to the exact dataset it describes.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Name of the truth file in a dataset folder.
pub const TRUTH_FILE: &str = "truth.json";

/// What a truth file says, as far as calibration needs it.
#[derive(Clone, Debug, Deserialize)]
pub struct TruthFile {
    /// See [`crate::io::SCHEMA_VERSION`].
    #[serde(default = "crate::io::schema_version")]
    pub schema_version: u32,
    /// True geometric deviations by name: mm for `.dx/.dy/.dz`, degrees otherwise.
    #[serde(default)]
    pub parameters: std::collections::BTreeMap<String, f64>,
    /// The dataset this truth belongs to (absent in files written before twincal recorded it).
    #[serde(default)]
    pub dataset: Option<DatasetLink>,
    /// The draw-wire sensor's true placement.
    pub sensor: TruthSensor,
    /// The tracker that wrote `x, y, z` (a tracker dataset), as its scenario gave it.
    #[serde(default)]
    pub tracker: Option<TruthTracker>,
    /// The true tool point (cable attachment or reflector) on the flange.
    pub tool: TruthTool,
    /// Standard deviation of one written reading value, mm.
    pub noise_std_mm: f64,
    /// Ground truth of each dataset row, in file order.
    pub poses: Vec<TruthPose>,
}
/// A tracker's placement as the truth file states it (the rest of its scenario entry, its noise
/// and decimals, is the twin's business).
#[derive(Clone, Debug, Deserialize)]
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
/// The draw-wire sensor as the truth file states it.
#[derive(Clone, Debug, Deserialize)]
pub struct TruthSensor {
    /// Cable exit point in the base frame, mm.
    pub exit_point_mm: [f64; 3],
    /// Added to the geometric distance, mm.
    pub length_offset_mm: f64,
}
/// The tool point as the truth file states it.
#[derive(Clone, Debug, Deserialize)]
pub struct TruthTool {
    /// Cable attachment point (or reflector) in the flange frame, mm.
    pub point_mm: [f64; 3],
}
/// One row's truth, as far as calibration needs it.
#[derive(Clone, Debug, Deserialize)]
pub struct TruthPose {
    /// True cable length: distance plus length offset, mm (no linearity error, no noise).
    pub length_true_mm: f64,
    /// The commanded joint angles, degrees, before the controller logged them (rounded): the
    /// angles the true arm stood at.
    #[serde(default)]
    pub q_cmd_deg: Option<Vec<f64>>,
    /// A tracker's noise-free reading, mm.
    #[serde(default)]
    pub point_true_mm: Option<[f64; 3]>,
    /// A 6-D probe's noise-free pose (`x, y, z` mm, `rx, ry, rz` degrees, intrinsic X-Y-Z).
    #[serde(default)]
    pub pose_true: Option<[f64; 6]>,
}

impl TruthFile {
    /// The true placement of the instrument that wrote the dataset (m, rad): the tracker's
    /// when there is one, else the draw-wire's.
    pub fn placement(&self) -> crate::measurement::Placement {
        use crate::measurement::Placement;
        use nalgebra::Vector3;
        let mm = |v: [f64; 3]| Vector3::from(v) * 1e-3;
        let tool = mm(self.tool.point_mm);
        match &self.tracker {
            Some(t) => Placement::tracker(t.translation_mm, t.rotation_deg, t.probe_rotation_deg, tool),
            None => Placement::cable(mm(self.sensor.exit_point_mm), self.sensor.length_offset_mm * 1e-3, tool),
        }
    }

    /// Pose `i`'s noise-free reading, m, in `measurement`'s order; `None` when the file does not
    /// hold that kind of reading.
    pub fn true_reading(&self, i: usize, measurement: crate::measurement::Measurement) -> Option<Vec<f64>> {
        let p = self.poses.get(i)?;
        match (measurement, p.point_true_mm) {
            (crate::measurement::Measurement::Length, _) if self.tracker.is_none() => Some(vec![p.length_true_mm * 1e-3]),
            (crate::measurement::Measurement::Point, Some(v)) => Some(v.iter().map(|c| c * 1e-3).collect()),
            (crate::measurement::Measurement::Pose, _) => Some(measurement.values_of_file(&p.pose_true?).iter().map(|c| c * 1e-3).collect()),
            _ => None,
        }
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

/// The file a dataset path reads: `DIR/dataset.csv` for a folder, the file itself otherwise
/// (without an xlsx `#Sheet` suffix).
fn dataset_file(data: &Path) -> PathBuf {
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

impl TruthFile {
    /// `DIR/truth.json` next to a dataset folder or file, if present and if it belongs to that
    /// dataset. A truth file whose dataset fingerprint does not match the dataset file's bytes
    /// (the dataset was edited, regenerated or replaced, or an interrupted write left an old
    /// truth file behind) is refused with an error. A truth file without a fingerprint (written
    /// by twincal before it recorded one) cannot be checked: it is ignored with a warning on
    /// stderr.
    pub fn find(data: &Path) -> Result<Option<TruthFile>> {
        let file = dataset_file(data);
        let dir = if data.is_dir() { data.to_path_buf() } else { file.parent().map(|p| p.to_path_buf()).unwrap_or_default() };
        let p = dir.join(TRUTH_FILE);
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
        crate::io::check_schema(t.schema_version, "a truth file").map_err(|e| Error::data(label, e))?;
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
