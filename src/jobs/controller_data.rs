//! `twincal controller-data`: what a controller that takes no new kinematic model can be given
//! of a calibration ([`crate::controller::ControllerData`]), as RAPID, KRL or URScript data.

use crate::calib::run::CalibResult;
use crate::controller::{ControllerData, Language};
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A controller data file as `twincal controller-data` writes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct ControllerDataJob {
    /// A result.json of `calibrate --controller-subset`.
    #[cfg_attr(feature = "clap", arg(long))]
    pub model: PathBuf,
    /// rapid (a module of tooldata, wobjdata and the joint offsets), krl (a data list of FRAMEs
    /// for TOOL_DATA and BASE_DATA, and the offsets) or urscript (set_tcp and the instrument's
    /// frame).
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    pub format: Language,
    /// The tool's mass, kg, where the calibration states no payload (RAPID's tooldata needs one).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    #[serde(default)]
    pub tool_mass_kg: Option<f64>,
    /// The file to write (.mod, .dat or .script); its stem names the module or data list.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
}

/// What `controller-data` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct ControllerDataSummary {
    /// The file written.
    pub out: PathBuf,
    /// The joint zero offsets, degrees.
    pub joint_offsets_deg: Vec<(String, f64)>,
    /// The tool point in the flange frame, mm.
    pub tool_mm: [f64; 3],
}

impl ControllerDataJob {
    /// Reads the calibration and writes the file, whole or not at all.
    pub fn run(&self) -> Result<ControllerDataSummary> {
        check_outputs(&[("--model", self.model.clone())], &[("--out", self.out.as_path())])?;
        if let Some(m) = self.tool_mass_kg.filter(|m| !(m.is_finite() && *m > 0.0 && *m <= crate::dataset::MAX_PAYLOAD_KG)) {
            return Err(Error::Invalid(format!("--tool-mass-kg must be in (0, {}] kg, got {m}", crate::dataset::MAX_PAYLOAD_KG)));
        }
        let want = self.format.data_extension();
        let name = self.out.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        if self.out.extension().and_then(|e| e.to_str()) != Some(want) {
            return Err(Error::Invalid(format!("--out {}: a {} data file is a .{want}", self.out.display(), self.format.name())));
        }
        let r = CalibResult::load(&self.model)?;
        let data = ControllerData::of(&r)?;
        let file = data.write(self.format, name, self.tool_mass_kg, &self.model.display().to_string())?;
        let mut outputs = OutputSet::new();
        outputs.write(&self.out, file.text.as_bytes())?;
        outputs.commit()?;
        Ok(ControllerDataSummary { out: self.out.clone(), joint_offsets_deg: data.joint_offsets_deg, tool_mm: data.tool_mm.into() })
    }
}
