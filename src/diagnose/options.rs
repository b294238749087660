//! The diagnosis's options and their defaults.

use crate::calib::effects::inputs::LoadOptions;
use crate::calib::effects::EffectKind;
use crate::calib::run::{CalibOptions, Method, ModelSpec};
use crate::robot::Robot;

/// Settings of a diagnosis.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// The kinematic model the diagnosis starts from.
    pub model: ModelSpec,
    /// Inertial model for joint torques when `model` has none (generic 6R).
    pub inertial: Option<Robot>,
    /// What loads the joints (payload, cable tension), for the torque-driven effects.
    pub loads: LoadOptions,
    /// Cross-validation folds (contiguous blocks of acquisition order).
    pub folds: usize,
    /// Family-wise significance level of one selection step.
    pub alpha: f64,
    /// Smallest relative held-out RMSE gain worth a new effect.
    pub min_gain: f64,
    /// Most effects to add.
    pub max_effects: usize,
    /// Robust outlier threshold, in MAD-based standard deviations.
    pub outlier_k: f64,
    /// Runs of outliers that are one constant offset of the reading are corrected and kept
    /// ([`crate::calib::problem::robust::reading_steps`]).
    pub reading_steps: bool,
    /// Relative singular-value tolerance of the identifiability analysis.
    pub rank_tol: f64,
    /// Seed of the diagnosis's random draws.
    pub seed: u64,
    /// Candidate effects, each a kind and optionally its joint (0-based); empty = every kind on
    /// every joint the data support.
    pub candidates: Vec<(EffectKind, Option<usize>)>,
    /// Share of the kept rows (every k-th in acquisition order) held back as a confirmation set
    /// that selection never sees; 0 = none.
    pub confirm_fraction: f64,
    /// A cause is named only when its size is at least this many standard uncertainties.
    pub min_size_sigmas: f64,
    /// Logging step of the joint angles, degrees (default: from the data's decimals).
    pub angle_step_deg: Option<f64>,
    /// The instrument's stated accuracy, mm per coordinate, for the floor.
    pub instrument_accuracy_mm: Option<f64>,
    /// Weight the fits by the rows' own standard deviations where the data give them
    /// ([`crate::calib::problem::weighting`]).
    pub row_std: bool,
    /// Whether the joint angles' logging error is the fits' noise model where rows share
    /// blocks (`Off`: rows taken as independent).
    pub noise_model: crate::calib::problem::noise_model::NoiseChoice,
    /// Where the instrument's stations come from (resolved by the job before the rows are
    /// diagnosed: [`crate::calib::run::setup::resolve_stations`]).
    pub stations: crate::calib::run::StationSource,
}

/// Default cross-validation folds of a diagnosis.
pub const DEFAULT_FOLDS: usize = 5;

/// Default family-wise significance level of one selection step.
pub const DEFAULT_ALPHA: f64 = 0.01;

/// Default smallest relative held-out gain worth a new effect.
pub const DEFAULT_MIN_GAIN: f64 = 0.02;

/// Default most effects a diagnosis adds.
pub const DEFAULT_MAX_EFFECTS: usize = 4;

/// Default share of the kept rows held back as the confirmation set.
pub const DEFAULT_CONFIRM_FRACTION: f64 = 0.2;

/// Default smallest size of a named cause, in standard uncertainties.
pub const DEFAULT_MIN_SIZE_SIGMAS: f64 = 2.0;

/// The q2 extrapolation check trains on the rows up to this quantile of q2.
pub const EXTRAPOLATION_QUANTILE: f64 = 0.7;

impl DiagnoseOptions {
    /// The options of diagnosing with `model`, every other option at its default.
    pub fn new(model: ModelSpec) -> Self {
        DiagnoseOptions {
            model,
            inertial: None,
            loads: LoadOptions::default(),
            folds: DEFAULT_FOLDS,
            alpha: DEFAULT_ALPHA,
            min_gain: DEFAULT_MIN_GAIN,
            max_effects: DEFAULT_MAX_EFFECTS,
            outlier_k: crate::calib::run::DEFAULT_OUTLIER_K,
            reading_steps: true,
            rank_tol: crate::calib::run::DEFAULT_RANK_TOL,
            seed: 0,
            candidates: Vec::new(),
            confirm_fraction: DEFAULT_CONFIRM_FRACTION,
            min_size_sigmas: DEFAULT_MIN_SIZE_SIGMAS,
            angle_step_deg: None,
            instrument_accuracy_mm: None,
            row_std: true,
            noise_model: crate::calib::problem::noise_model::NoiseChoice::Auto,
            stations: crate::calib::run::StationSource::Auto,
        }
    }
    /// The calibration whose stages the diagnosis starts from: the geometric model with its
    /// instrument placed on every row, LM, no split and no screen (the diagnosis screens the
    /// rows itself, with their inputs).
    pub fn baseline_options(&self) -> CalibOptions {
        let mut o = CalibOptions::new(self.model.clone(), Method::LM);
        o.test_fraction = Some(0.0);
        o.rank_tol = self.rank_tol;
        o.seed = self.seed;
        o.outlier_k = 0.0;
        o.inertial = self.inertial.clone();
        o.loads = self.loads.clone();
        o.row_std = self.row_std;
        o.instrument_accuracy_mm = self.instrument_accuracy_mm;
        o.stations = self.stations;
        o
    }
}
