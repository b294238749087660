//! The truth file the twin writes beside a dataset, as far as calibration needs it.

use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::Path;

/// What a truth file says, as far as calibration needs it.
#[derive(Clone, Debug, Deserialize)]
pub struct TruthFile {
    /// True geometric deviations by name: mm for `.dx/.dy/.dz`, degrees otherwise.
    #[serde(default)]
    pub parameters: std::collections::BTreeMap<String, f64>,
    pub sensor: TruthSensor,
    pub tool: TruthTool,
    pub noise_std_mm: f64,
    pub poses: Vec<TruthPose>,
}
#[derive(Clone, Debug, Deserialize)]
pub struct TruthSensor {
    pub exit_point_mm: [f64; 3],
    pub length_offset_mm: f64,
}
#[derive(Clone, Debug, Deserialize)]
pub struct TruthTool {
    pub point_mm: [f64; 3],
}
#[derive(Clone, Debug, Deserialize)]
pub struct TruthPose {
    pub length_true_mm: f64,
}

impl TruthFile {
    /// `DIR/truth.json` next to a dataset folder or file, if present.
    pub fn find(data: &Path) -> Result<Option<TruthFile>> {
        let dir = if data.is_dir() { data.to_path_buf() } else { data.parent().map(|p| p.to_path_buf()).unwrap_or_default() };
        let p = dir.join("truth.json");
        if !p.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
        serde_json::from_str(&text).map(Some).map_err(|e| Error::data(p.display(), format!("malformed truth file: {e}")))
    }
}

