//! What a diagnosis reports (`diagnosed.json`): the evidence, the selection's steps, the causes
//! with their sizes, the baseline and the final model's held-out error.

use crate::calib::effects::EffectKind;
pub use crate::calib::fit::gls::NoiseModel;
pub use crate::calib::fit::robust::{Outlier, OutlierRun};
use crate::dataset::blocks::Structure;
use serde::{Deserialize, Serialize};

/// How strongly the baseline residual follows a per-row feature.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Evidence {
    /// The feature's name: `torque_j2`, `sign(torque_j2)`, `backlash_side_j2`, `sin(q2)`,
    /// `cos(q2)`, `t`, `temp` or a reading column; with several values per row, suffixed by the
    /// value (`torque_j2 [z]`).
    pub feature: String,
    /// Pearson correlation of the residual with the feature.
    pub correlation: f64,
}

/// One candidate in one selection step.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Candidate {
    /// The cause: its effect kind (`compliance` in files).
    pub cause: EffectKind,
    /// Joint 1..N for a per-joint cause.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    /// Held-out RMSE of the model with this candidate added, mm.
    pub heldout_rmse_mm: f64,
    /// For a cause that varies with time: the RMSE of the model with it on the rows judged
    /// forward in time (each later stretch of every run predicted by a fit on the rows before
    /// it, [`crate::diagnose::forward`]), mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward_rmse_mm: Option<f64>,
    /// Bonferroni-corrected p-value of the F test of the nested fits.
    pub p_value: f64,
    /// False when a fitted parameter is beyond [`IMPLAUSIBLE`](crate::diagnose::IMPLAUSIBLE) times its plausible size: the
    /// block then absorbs something else, and is not kept whatever its gain.
    pub plausible: bool,
    /// Size over its standard uncertainty (a cause needs `min_size_sigmas`).
    pub size_sigmas: f64,
    /// False for a size of unphysical sign (negative compliance or band width).
    pub physical_sign: bool,
    /// Wall time of the candidate's fit, s.
    pub seconds: f64,
}

/// A selection step: every candidate tried and the one kept (if any).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Step {
    /// Held-out RMSE of the model before this step, mm.
    pub heldout_rmse_before_mm: f64,
    /// The same on the rows judged forward in time, where a candidate varies with time, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward_rmse_before_mm: Option<f64>,
    /// Every candidate tried in this step.
    pub candidates: Vec<Candidate>,
    /// Label of the candidate kept (`backlash[j2]`); absent when none passed every test, which ends
    /// the selection.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kept: Option<String>,
    /// What the kept candidate was chosen on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kept_on: Option<KeptOn>,
}

/// What a selection step chose its cause on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KeptOn {
    /// The lowest held-out RMSE on the folds the diagnosis judges on.
    Folds,
    /// A cause that varies with time won on the folds; among its forms (and its rivals of that
    /// kind) the one that predicts later rows best, each stretch of every run from the rows
    /// before it.
    ForwardInTime,
}

/// A cause found in the data.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Cause {
    /// The cause: its effect kind (`compliance` in files).
    pub cause: EffectKind,
    /// Joint 1..N for per-joint effects.
    pub joint: Option<usize>,
    /// The cause's size from the final fit, in `unit`.
    pub magnitude: f64,
    /// Unit of `magnitude` and `uncertainty`.
    pub unit: String,
    /// Standard uncertainty of `magnitude`, in `unit`.
    pub uncertainty: f64,
    /// What the magnitude is.
    pub quantity: String,
    /// Held-out RMSE of the model before the cause was added, on the folds selection judged on, mm.
    pub heldout_rmse_before_mm: f64,
    /// Held-out RMSE of the model with the cause, on the folds selection judged on, mm.
    pub heldout_rmse_after_mm: f64,
    /// The same on the other kind of folds than the one the cause was judged on.
    pub heldout_rmse_other_folds_before_mm: f64,
    /// Held-out RMSE with the cause on the other kind of folds, mm.
    pub heldout_rmse_other_folds_after_mm: f64,
    /// RMSE on the confirmation rows (never used in selection) of the models fitted on the
    /// selection rows without and with this cause; NaN without a confirmation set.
    pub confirmation_rmse_before_mm: f64,
    /// Confirmation RMSE of the model with this cause, mm (see `confirmation_rmse_before_mm`).
    pub confirmation_rmse_after_mm: f64,
    /// Bonferroni-corrected p-value of the F test that kept the cause in its selection step.
    pub p_value: f64,
    /// The RMSE on the rows judged forward in time (each later stretch of every run predicted
    /// from the rows before it, [`crate::diagnose::forward`]) without and with the cause, mm; a
    /// cause that varies with time was chosen among its kind's forms on this. Absent where the
    /// runs are too short for it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward_rmse_before_mm: Option<f64>,
    /// See `forward_rmse_before_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward_rmse_after_mm: Option<f64>,
    /// Every parameter of the block (display units) with its standard uncertainty.
    pub parameters: Vec<(String, f64, f64)>,
}

impl Cause {
    /// Whether it is the effect block of `kind` on `block_joint` (0-based, as effect blocks
    /// number joints; the report's `joint` is 1-based).
    pub fn is(&self, kind: EffectKind, block_joint: Option<usize>) -> bool {
        self.cause == kind && self.joint == block_joint.map(|j| j + 1)
    }
    /// Its label, `compliance[j2]` (the joint 1-based), `thermal` for a whole-arm cause.
    pub fn label(&self) -> String {
        match self.joint {
            Some(j) => format!("{}[j{j}]", self.cause),
            None => self.cause.to_string(),
        }
    }
    /// One line: `compliance joint 2: compliance 9.66 ± 0.31 urad/Nm; held-out RMSE
    /// 0.0121 -> 0.0073 mm (p = 2.8e-25)`.
    pub fn summary(&self) -> String {
        let joint = self.joint.map(|j| format!(" joint {j}")).unwrap_or_default();
        let forward =
            self.forward_rmse_before_mm.zip(self.forward_rmse_after_mm).map_or(String::new(), |(b, a)| format!("; forward in time {b:.4} -> {a:.4} mm"));
        format!(
            "{}{joint}: {} {} {}; held-out RMSE {:.4} -> {:.4} mm (p = {:.1e}){forward}",
            self.cause,
            self.quantity,
            crate::units::with_uncertainty(self.magnitude, self.uncertainty),
            self.unit,
            self.heldout_rmse_before_mm,
            self.heldout_rmse_after_mm,
            self.p_value
        )
    }
}

/// The geometric model the selection starts from, and its errors.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Baseline {
    /// Name of the baseline model.
    pub model: String,
    /// On the folds the diagnosis judges on ([`Diagnosis::judged_on`]).
    pub heldout_rmse_mm: f64,
    /// On contiguous blocks of acquisition order (extrapolation across blocks) and on
    /// interleaved folds (every k-th row: interpolation).
    pub heldout_rmse_blocked_mm: f64,
    /// On interleaved folds, mm (see `heldout_rmse_blocked_mm`).
    pub heldout_rmse_interleaved_mm: f64,
    /// RMSE on the selection rows it was fitted to, mm.
    pub train_rmse_mm: f64,
}

/// The rows `--test-fraction` kept back from the diagnosis, never seen by it: how the geometric
/// model and the diagnosed model predict them.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Unseen {
    /// How many rows.
    pub rows: usize,
    /// How they were drawn (`time`: the last rows, judged forward).
    pub split_by: crate::calib::pipeline::SplitBy,
    /// RMSE per value of the geometric model calibrated on the diagnosed rows, mm.
    pub geometric_rmse_mm: f64,
    /// RMSE per value of the diagnosed model (its causes included), mm.
    pub final_rmse_mm: f64,
}

impl Unseen {
    /// One line for the report.
    pub fn line(&self) -> String {
        let how = match self.split_by {
            crate::calib::pipeline::SplitBy::Time => "the last rows in time",
            crate::calib::pipeline::SplitBy::Blocks => "whole blocks",
            crate::calib::pipeline::SplitBy::Rows => "rows stratified by the reading",
        };
        format!(
            "on the {} rows held out and never seen ({how}): geometric model {:.4} mm, with the causes {:.4} mm per value ({:+.1} %)",
            self.rows,
            self.geometric_rmse_mm,
            self.final_rmse_mm,
            100.0 * (self.final_rmse_mm / self.geometric_rmse_mm - 1.0)
        )
    }
}

/// The physical extension against a data-driven compensator on the same rows.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Comparison {
    /// Held-out RMSE (same folds): geometric, geometric + found effects, geometric + RBF network.
    pub heldout_rmse_mm: [f64; 3],
    /// Extrapolation: trained on rows with q2 at most `q2_split_deg`, tested on the others.
    pub q2_split_deg: f64,
    /// Extrapolation RMSE on the rows with q2 above `q2_split_deg`, mm, for the same three models.
    pub extrapolation_rmse_mm: [f64; 3],
    /// Rows trained on and rows tested on in the extrapolation.
    pub extrapolation_rows: [usize; 2],
}

/// Everything `diagnose` found.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Diagnosis {
    /// See [`crate::output::SCHEMA_VERSION`].
    #[serde(default = "crate::output::schema_version")]
    pub schema_version: u32,
    /// Version of twincal that wrote the diagnosis.
    pub twincal_version: String,
    /// Where the diagnosed data came from (the dataset's source).
    pub data: String,
    /// Rows in the dataset.
    pub rows: usize,
    /// What a row reads, for a reading of several values (a tracker's point): every RMSE here is
    /// then per coordinate. Empty for a cable length.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub reading: String,
    /// Where the instrument stood, when it stood at more than one station: each station's rows
    /// and its shift and turn from the first (set-up changes declared or found as change points).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<crate::calib::pipeline::SetupReport>,
    /// Rows kept out of the fits as outliers.
    pub outliers: Vec<Outlier>,
    /// Runs of consecutive outlier rows.
    pub outlier_runs: Vec<OutlierRun>,
    /// Rows (1-based) the screen first flagged against the geometric model that the model with
    /// its causes explains: they are in the final fit.
    #[serde(default)]
    pub explained_by_causes: Vec<usize>,
    /// Stretches of the acquisition whose readings sit one constant offset off (the reading
    /// jumped and stayed): a cause of the sensor, corrected and kept, not fitted by the model.
    #[serde(default)]
    pub reading_steps: Vec<crate::calib::fit::robust::ReadingStep>,
    /// What went wrong in each run of outlier rows and each reading step: the hypothesis that
    /// explains the rows as logged (the reading, one joint's logged angle, the instrument), or
    /// `unexplained` ([`faults`](crate::diagnose::faults)).
    #[serde(default)]
    pub run_faults: Vec<super::faults::RunFault>,
    /// The data's own floor ([`crate::calib::fit::floor`]): its total and a line naming its sources.
    pub noise_floor_mm: f64,
    /// Where the floor comes from, in one line: each source with its RMS.
    pub noise_floor_source: String,
    /// The floor with each of its sources.
    pub noise_floor: crate::calib::fit::floor::NoiseFloor,
    /// Which folds selection judged on: `blocked` (contiguous blocks of acquisition order) or
    /// `interleaved` (when blocks cover different parts of the joint space, so that blocked folds
    /// measure extrapolation: baseline blocked RMSE above 1.5x the interleaved one), and why.
    pub judged_on: String,
    /// Why selection judged on those folds.
    pub judged_on_reason: String,
    /// The acquisition's blocks of rows that share an error ([`crate::dataset::blocks`]): folds
    /// and the confirmation set take whole blocks, tests and uncertainties count them.
    #[serde(default = "no_structure")]
    pub acquisition: Structure,
    /// The joint angles' logging error as the fits' noise model (generalised least squares over
    /// the blocks, see [`crate::calib::fit::gls`]), where rows share blocks and the angles are logged
    /// at a step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_model: Option<NoiseModel>,
    /// Design effect of the geometric model's residuals over those blocks (1: independent rows):
    /// how many rows count as one.
    #[serde(default = "one")]
    pub design_effect: f64,
    /// Causes selection kept that the model fitted on every kept row turned unphysical, with
    /// why: left out of the model.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_physical: Vec<String>,
    /// Causes that gain on held-out rows, but explain less of them than
    /// [`BELOW_FLOOR_SHARE`](crate::diagnose::BELOW_FLOOR_SHARE) of the data's floor: left out of the model, with their figures.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub below_floor: Vec<String>,
    /// Rows selection saw and rows kept back to confirm its causes.
    pub selection_rows: usize,
    /// Rows kept back to confirm the causes (see `selection_rows`).
    pub confirmation_rows: usize,
    /// Causes selection found that the confirmation rows did not confirm (not in the model).
    pub unconfirmed: Vec<String>,
    /// The geometric model selection started from, and its errors.
    pub baseline: Baseline,
    /// Correlations of the baseline residual with the per-row features, strongest first.
    pub evidence: Vec<Evidence>,
    /// The selection's steps, in order.
    pub steps: Vec<Step>,
    /// Causes in the order found; empty = `geometric_only`.
    pub causes: Vec<Cause>,
    /// `geometric_only`, or the causes kept joined by ` + ` (`backlash[j2] + thermal`);
    /// `unexplained` (alone or after the causes) where what remains holds structure, or is
    /// white at several times the noise the instrument states ([`Self::unexplained`]).
    pub verdict: String,
    /// Where what remains holds structure ([`Self::remainder`]), or is white but stays above
    /// [`UNEXPLAINED_RATIO`] times a floor the data measure (repeatability, the rows' own
    /// standard deviations, a stated accuracy): what it follows, how far, and where it
    /// concentrates (stations, time). `None` otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unexplained: Option<String>,
    /// What remains after the named causes ([`crate::diagnose::remainder`]): white or
    /// structured (against the acquisition order, the stations, each joint, the temperature,
    /// the target's place), and its apparent noise per value beside what the instrument states;
    /// absent under 30 rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub remainder: Option<crate::diagnose::remainder::Remainder>,
    /// Held-out RMSE of the model with every kept cause, on the folds selection judged on, mm.
    pub final_heldout_rmse_mm: f64,
    /// The same over a 6-D pose's position values alone (what its floor describes), mm; absent
    /// for one kind of value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_heldout_rmse_position_mm: Option<f64>,
    /// RMSE of the final model (the one `--result` holds) on every kept row it was fitted to.
    pub final_train_rmse_mm: f64,
    /// Share of the final held-out mean square that the data's floor accounts for (floor² /
    /// held-out²): what remains is named, not fitted.
    #[serde(default)]
    pub floor_share_of_remaining: f64,
    /// The rows `--test-fraction` kept back: the geometric and the diagnosed model on them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unseen: Option<Unseen>,
    /// The physical extension against an RBF network on the geometric residuals; absent when the
    /// rows are too few for it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub comparison: Option<Comparison>,
    /// Wall time of the diagnosis, s.
    pub seconds: f64,
    /// The effects kept, as calibration effect options (for `calibrate --effects`).
    pub effects_option: String,
    /// Whether a thermal cause was kept without its sensor lag (its refinement did not earn its
    /// place): the same model by calibrate then takes `--no-sensor-lag`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub no_sensor_lag: bool,
    /// What the user should know about this diagnosis (a kept cause whose size the final fit
    /// turned unphysical, ...).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

pub(super) fn no_structure() -> Structure {
    crate::dataset::blocks::Blocks::singletons(0).structure(None)
}

pub(super) fn one() -> f64 {
    1.0
}

/// How many times a measured floor the final held-out RMSE may be before the rest is reported as
/// unexplained.
pub const UNEXPLAINED_RATIO: f64 = 3.0;

impl Diagnosis {
    /// The final held-out RMSE against the data's floor, in words: a ratio where a source the
    /// data or the instrument measure gives the floor (repeats, the rows' own standard
    /// deviations, a stated accuracy), else what is known of it.
    pub fn against_floor(&self) -> String {
        if let Some(p) = self.final_heldout_rmse_position_mm.filter(|_| self.noise_floor.by_group.first().is_some_and(|g| g.measured)) {
            let floor = self.noise_floor.of_group(0);
            format!("of the positions {p:.4} mm, {:.2} x their noise floor {floor:.4} mm", p / floor)
        } else if self.noise_floor.is_measured() {
            format!("{:.2} x the noise floor", self.final_heldout_rmse_mm / self.noise_floor_mm)
        } else {
            format!("no repeated configurations, so the floor is known only down to the logging resolution ({:.4} mm)", self.noise_floor_mm)
        }
    }
}
