//! The diagnosis's options and their defaults.

use crate::calib::effects::EffectKind;
use crate::calib::pipeline::{CalibOptions, FloorOptions, LoadOptions, Method, ModelSpec, ScreenOptions, SplitOptions, StationSource, DEFAULT_RANK_TOL};

/// Settings of a diagnosis.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// The kinematic model the diagnosis starts from.
    pub model: ModelSpec,
    /// What loads the joints, for the torque-driven effects.
    pub loads: LoadOptions,
    /// Cross-validation folds (contiguous blocks of acquisition order).
    pub folds: usize,
    /// Family-wise significance level of one selection step.
    pub alpha: f64,
    /// Smallest relative held-out RMSE gain worth a new effect.
    pub min_gain: f64,
    /// Most effects to add.
    pub max_effects: usize,
    /// The robust screen of the rows.
    pub screen: ScreenOptions,
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
    /// The data's floor and the rows' weights.
    pub floor: FloorOptions,
    /// Where the instrument's stations come from (resolved by the job before the rows are
    /// diagnosed: [`crate::calib::pipeline::resolve_stations`]).
    pub stations: StationSource,
    /// Known distances between the sockets a ball was seated in ([`CalibOptions::spacings`]).
    pub spacings: Vec<crate::calib::model::KnownSpacing>,
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
            loads: LoadOptions::default(),
            folds: DEFAULT_FOLDS,
            alpha: DEFAULT_ALPHA,
            min_gain: DEFAULT_MIN_GAIN,
            max_effects: DEFAULT_MAX_EFFECTS,
            screen: ScreenOptions::default(),
            rank_tol: DEFAULT_RANK_TOL,
            seed: 0,
            candidates: Vec::new(),
            confirm_fraction: DEFAULT_CONFIRM_FRACTION,
            min_size_sigmas: DEFAULT_MIN_SIZE_SIGMAS,
            floor: FloorOptions::default(),
            stations: StationSource::Auto,
            spacings: Vec::new(),
        }
    }
    /// The calibration whose stages the diagnosis starts from: the geometric model with its
    /// instrument placed on every row, LM, no split and no screen (the diagnosis screens the
    /// rows itself, with their inputs); the loads, the floor and the stations are the
    /// diagnosis's own.
    pub fn baseline_options(&self) -> CalibOptions {
        CalibOptions {
            split: SplitOptions { test_fraction: Some(0.0), ..SplitOptions::default() },
            rank_tol: self.rank_tol,
            seed: self.seed,
            screen: ScreenOptions { outlier_k: 0.0, ..self.screen },
            loads: self.loads.clone(),
            floor: self.floor,
            stations: self.stations,
            spacings: self.spacings.clone(),
            ..CalibOptions::new(self.model.clone(), Method::LM)
        }
    }
}
