//! A diagnosis as a user asks for it: `twincal diagnose`'s options but `--data` and the files it
//! writes, Python's `twincal.diagnose` keyword arguments.

use super::groups::{Artifact, Floor, Loads, ModelChoice, Reading, SetUp};
use crate::calib::effects::EffectChoice;
use crate::calib::pipeline::SplitBy;
use crate::dataset::ReadOptions;
use crate::diagnose::{DiagnoseOptions, DEFAULT_ALPHA, DEFAULT_FOLDS};
use crate::error::{Error, Result};
use crate::report::verdict::Limit;
use serde::{Deserialize, Serialize};

/// The options of a diagnosis (the field docs are `twincal diagnose --help`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct DiagnoseRequest {
    /// How the data are read.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub reading: Reading,
    /// Where the instrument stood.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub setup: SetUp,
    /// The model fitted.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub model: ModelChoice,
    /// What loads the joints.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub loads: Loads,
    /// The artifact a ball was seated in (a probe touched).
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub artifact: Artifact,
    /// Candidate effects (default: every kind the data support).
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ','))]
    pub candidates: Vec<EffectChoice>,
    /// Cross-validation folds (contiguous blocks of acquisition order).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, default_value_t = DEFAULT_FOLDS))]
    pub folds: usize,
    /// Family-wise significance level of each selection step.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = DEFAULT_ALPHA, allow_negative_numbers = true))]
    pub alpha: f64,
    /// Seed of the hold-out split (--test-fraction) and of the diagnosis' random draws.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, default_value_t = 0))]
    pub seed: u64,
    /// Accuracy limit for the verdict in --out: the final cross-validated held-out RMSE, mm.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub max_test_rmse_mm: Option<f64>,
    /// The data's floor and the rows' weights.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub floor: Floor,
    /// Diagnose on the other rows only: hold out this fraction of the rows (the split
    /// `calibrate --test-fraction` draws with the same --seed), never seen, so that `replay`
    /// can measure the identified twin on them.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub test_fraction: Option<f64>,
    /// How --test-fraction draws its rows: blocks (whole sweeps, pauses, declared blocks),
    /// rows (stratified by the reading) or time (the last rows: a drift judged on later rows).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = SplitBy::default()))]
    pub split_by: SplitBy,
}

impl Default for DiagnoseRequest {
    fn default() -> Self {
        DiagnoseRequest {
            reading: Reading::default(),
            setup: SetUp::default(),
            artifact: Artifact::default(),
            model: ModelChoice::default(),
            loads: Loads::default(),
            candidates: Vec::new(),
            folds: DEFAULT_FOLDS,
            alpha: DEFAULT_ALPHA,
            seed: 0,
            max_test_rmse_mm: None,
            floor: Floor::default(),
            test_fraction: None,
            split_by: SplitBy::default(),
        }
    }
}

impl DiagnoseRequest {
    /// Every option checked and resolved into the diagnosis' options and the verdict's limit
    /// (reads no data; reads --robot's URDF).
    pub fn options(&self) -> Result<(DiagnoseOptions, Limit)> {
        let a = self;
        super::calibrate::check_test_fraction(a.test_fraction)?;
        let limit = Limit { flag: "--max-test-rmse-mm", value: a.max_test_rmse_mm };
        limit.validate()?;
        if !(a.alpha > 0.0 && a.alpha < 0.5) {
            return Err(Error::Invalid(format!("--alpha must be in (0, 0.5), got {}", a.alpha)));
        }
        let model = a.model.spec()?;
        let loads = a.loads.resolve()?;
        if let Some(path) = &a.loads.robot {
            crate::calib::pipeline::check_inertial(&model, loads.inertial.as_ref(), &path.display().to_string())?;
        }
        let opts = DiagnoseOptions {
            loads,
            folds: a.folds,
            alpha: a.alpha,
            seed: a.seed,
            floor: a.floor.resolve()?,
            candidates: a.candidates.iter().map(|c| c.pair()).collect(),
            stations: a.setup.stations,
            spacings: a.artifact.spacing_mm.clone(),
            ..DiagnoseOptions::new(model)
        };
        Ok((opts, limit))
    }

    /// How the data are read (`--angles`, `--measurement`, `--euler`).
    pub fn load_options(&self) -> ReadOptions {
        self.reading.load_options(true)
    }
}
