//! `twincal diagnose`: from measured data alone (q, L and the optional t / temp columns), what
//! does the geometric model get wrong, which physical effect causes it, how big is it, and how
//! much better does the extended model predict rows it has not seen?
//!
//! 1. **Baseline.** The geometric model is calibrated (sensor placement unknown, as always).
//!    Rows far off the fit by a robust criterion (median ± k·1.4826·MAD of the residuals,
//!    iterated) are named as outliers and kept out of every fit and statistic.
//! 2. **Evidence.** The baseline residuals against per-row features: joint torques, their
//!    signs, approach directions, time, temperature, joint-angle harmonics, the reading.
//! 3. **Forward selection.** Every candidate effect block ([`crate::calib::effects`]) is added in
//!    turn, everything is refitted, and its held-out gain measured by cross-validation over
//!    contiguous blocks of acquisition order (so time-dependent effects must extrapolate). Its
//!    significance is the F test of the nested least-squares fits on every kept row,
//!    Bonferroni-corrected for the number of candidates. The candidate with the lowest held-out
//!    RMSE among those that are significant, gain at least `min_gain` and stay of a physical
//!    size ([`IMPLAUSIBLE`]) is kept, and the search repeats until nothing is left to gain.
//! 4. **Sizes.** Each kept effect's size with its standard uncertainty, in physical units.
//!
//! Nothing here reads how the data were made.

pub mod faults;
pub mod hidden;

use crate::calib::effects::inputs::{block_for, time_span, LoadOptions};
use crate::calib::effects::{EffectBlock, EffectKind, Size};
use crate::calib::model::CalibModel;
use crate::calib::problem::{ReadingFit, Samples};
use crate::calib::run::{identify, CalibOptions, Method, ModelSpec};
use crate::dataset::blocks::{Boundary, Structure};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::optim::{LevenbergMarquardt, NoObserver};
use crate::robot::Robot;
use crate::stats::nested_f_test_deff;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Settings of a diagnosis.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    pub model: ModelSpec,
    /// Inertial model for joint torques when `model` has none (generic 6R).
    pub inertial: Option<Robot>,
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
    pub rank_tol: f64,
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
        }
    }
    /// The calibration whose stages the diagnosis starts from: the geometric model with its
    /// instrument placed on every row, LM, no split and no screen (the diagnosis screens the
    /// rows itself, with their inputs).
    pub fn baseline_options(&self) -> CalibOptions {
        let mut o = CalibOptions::new(self.model.clone(), Method::Lm);
        o.test_fraction = Some(0.0);
        o.rank_tol = self.rank_tol;
        o.seed = self.seed;
        o.outlier_k = 0.0;
        o.inertial = self.inertial.clone();
        o.loads = self.loads.clone();
        o.row_std = self.row_std;
        o.instrument_accuracy_mm = self.instrument_accuracy_mm;
        o
    }
}

use crate::calib::problem::robust::Screen;
pub use crate::calib::problem::robust::{Outlier, OutlierRun};

/// How strongly the baseline residual follows a per-row feature.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Evidence {
    pub feature: String,
    /// Pearson correlation of the residual with the feature.
    pub correlation: f64,
}

/// One candidate in one selection step.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Candidate {
    pub cause: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    pub heldout_rmse_mm: f64,
    /// Bonferroni-corrected p-value of the F test of the nested fits.
    pub p_value: f64,
    /// False when a fitted parameter is beyond [`IMPLAUSIBLE`] times its plausible size: the
    /// block then absorbs something else, and is not kept whatever its gain.
    pub plausible: bool,
    /// Size over its standard uncertainty (a cause needs `min_size_sigmas`).
    pub size_sigmas: f64,
    /// False for a size of unphysical sign (negative compliance or band width).
    pub physical_sign: bool,
    pub seconds: f64,
}

/// A fitted effect parameter larger than this many times its plausible one-sigma size
/// ([`crate::calib::model::tolerance::effect_scale`]: e.g. 0.3° of eccentricity or backlash, 1.5 mrad/(N·m)
/// of compliance) is not physical.
pub const IMPLAUSIBLE: f64 = 30.0;

/// The physical range of a warm-up time constant, s: a joint or an arm reaches most of its
/// working temperature in minutes to a few hours (a time constant of 1 min – 6 h). Outside it the
/// data show a drift that never settles (a line in `t`) or one step, not a warm-up, and the size
/// "at full warm-up" is an extrapolation far beyond the data.
pub const WARM_UP_TAU_S: (f64, f64) = (60.0, 6.0 * 3600.0);

/// Why a parameter of effect block `b` of `model` at `x` is not physical (the first one that is
/// not), or `None`: an effect's size beyond [`IMPLAUSIBLE`] times its plausible one-sigma size,
/// a warm-up time constant outside [`WARM_UP_TAU_S`].
pub fn implausible_param(model: &CalibModel, x: &[f64], b: usize) -> Option<String> {
    use crate::calib::effects::EffectUnit;
    use crate::calib::model::Kind;
    model.effect_params(b).find_map(|k| match model.kinds[k] {
        Kind::Effect(EffectUnit::Seconds) => (!(WARM_UP_TAU_S.0..=WARM_UP_TAU_S.1).contains(&x[k])).then(|| {
            format!("{} = {:.3e} s is outside the physical range of a warm-up time constant ({}-{} s)", model.names[k], x[k], WARM_UP_TAU_S.0, WARM_UP_TAU_S.1)
        }),
        Kind::Effect(u) => {
            let limit = IMPLAUSIBLE * crate::calib::model::tolerance::effect_scale(u);
            (x[k].abs() > limit).then(|| {
                let d = model.kinds[k].display();
                format!("{} = {:.4} {} is beyond {IMPLAUSIBLE}x its plausible size ({:.4})", model.names[k], x[k] * d, model.kinds[k].unit(), limit * d)
            })
        }
        _ => None,
    })
}

/// Whether every parameter of the model's last effect block is of a physical size.
fn plausible(f: &Fitted) -> bool {
    implausible_param(&f.model, &f.x, f.model.effects.len() - 1).is_none()
}

/// A selection step: every candidate tried and the one kept (if any).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Step {
    pub heldout_rmse_before_mm: f64,
    pub candidates: Vec<Candidate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kept: Option<String>,
}

/// A cause found in the data.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Cause {
    pub cause: String,
    /// Joint 1..N for per-joint effects.
    pub joint: Option<usize>,
    pub magnitude: f64,
    pub unit: String,
    pub uncertainty: f64,
    /// What the magnitude is.
    pub quantity: String,
    pub heldout_rmse_before_mm: f64,
    pub heldout_rmse_after_mm: f64,
    /// The same on the other kind of folds than the one the cause was judged on.
    pub heldout_rmse_other_folds_before_mm: f64,
    pub heldout_rmse_other_folds_after_mm: f64,
    /// RMSE on the confirmation rows (never used in selection) of the models fitted on the
    /// selection rows without and with this cause; NaN without a confirmation set.
    pub confirmation_rmse_before_mm: f64,
    pub confirmation_rmse_after_mm: f64,
    pub p_value: f64,
    /// Every parameter of the block (display units) with its standard uncertainty.
    pub parameters: Vec<(String, f64, f64)>,
}

impl Cause {
    /// One line: `joint_compliance joint 2: compliance 9.66 ± 0.31 urad/Nm; held-out RMSE
    /// 0.0121 -> 0.0073 mm (p = 2.8e-25)`.
    pub fn summary(&self) -> String {
        let joint = self.joint.map(|j| format!(" joint {j}")).unwrap_or_default();
        format!(
            "{}{joint}: {} {:.4} ± {:.4} {}; held-out RMSE {:.4} -> {:.4} mm (p = {:.1e})",
            self.cause, self.quantity, self.magnitude, self.uncertainty, self.unit, self.heldout_rmse_before_mm, self.heldout_rmse_after_mm, self.p_value
        )
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Baseline {
    pub model: String,
    /// On the folds the diagnosis judges on ([`Diagnosis::judged_on`]).
    pub heldout_rmse_mm: f64,
    /// On contiguous blocks of acquisition order (extrapolation across blocks) and on
    /// interleaved folds (every k-th row: interpolation).
    pub heldout_rmse_blocked_mm: f64,
    pub heldout_rmse_interleaved_mm: f64,
    pub train_rmse_mm: f64,
}

/// The physical extension against a data-driven compensator on the same rows.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Comparison {
    /// Held-out RMSE (same folds): geometric, geometric + found effects, geometric + RBF network.
    pub heldout_rmse_mm: [f64; 3],
    /// Extrapolation: trained on rows with q2 at most `q2_split_deg`, tested on the others.
    pub q2_split_deg: f64,
    pub extrapolation_rmse_mm: [f64; 3],
    pub extrapolation_rows: [usize; 2],
}

/// Everything `diagnose` found.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Diagnosis {
    /// See [`crate::io::SCHEMA_VERSION`].
    #[serde(default = "crate::io::schema_version")]
    pub schema_version: u32,
    pub twincal_version: String,
    pub data: String,
    pub rows: usize,
    /// What a row reads, for a reading of several values (a tracker's point): every RMSE here is
    /// then per coordinate. Empty for a cable length.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub reading: String,
    pub outliers: Vec<Outlier>,
    pub outlier_runs: Vec<OutlierRun>,
    /// Rows (1-based) the screen first flagged against the geometric model that the model with
    /// its causes explains: they are in the final fit.
    #[serde(default)]
    pub explained_by_causes: Vec<usize>,
    /// Stretches of the acquisition whose readings sit one constant offset off (the reading
    /// jumped and stayed): a cause of the sensor, corrected and kept, not fitted by the model.
    #[serde(default)]
    pub reading_steps: Vec<crate::calib::problem::robust::ReadingStep>,
    /// What went wrong in each run of outlier rows and each reading step: the hypothesis that
    /// explains the rows as logged (the reading, one joint's logged angle, the instrument), or
    /// `unexplained` ([`faults`]).
    #[serde(default)]
    pub run_faults: Vec<faults::RunFault>,
    /// The data's own floor ([`crate::calib::problem::floor`]): its total and a line naming its sources.
    pub noise_floor_mm: f64,
    pub noise_floor_source: String,
    pub noise_floor: crate::calib::problem::floor::NoiseFloor,
    /// Which folds selection judged on: `blocked` (contiguous blocks of acquisition order) or
    /// `interleaved` (when blocks cover different parts of the joint space, so that blocked folds
    /// measure extrapolation: baseline blocked RMSE above 1.5x the interleaved one), and why.
    pub judged_on: String,
    pub judged_on_reason: String,
    /// The acquisition's blocks of rows that share an error ([`crate::dataset::blocks`]): folds
    /// and the confirmation set take whole blocks, tests and uncertainties count them.
    #[serde(default = "no_structure")]
    pub acquisition: Structure,
    /// The joint angles' logging error as the fits' noise model (generalised least squares over
    /// the blocks, see [`crate::calib::problem::gls`]), where rows share blocks and the angles are logged
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
    /// [`BELOW_FLOOR_SHARE`] of the data's floor: left out of the model, with their figures.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub below_floor: Vec<String>,
    /// Rows selection saw and rows kept back to confirm its causes.
    pub selection_rows: usize,
    pub confirmation_rows: usize,
    /// Causes selection found that the confirmation rows did not confirm (not in the model).
    pub unconfirmed: Vec<String>,
    pub baseline: Baseline,
    pub evidence: Vec<Evidence>,
    pub steps: Vec<Step>,
    /// Causes in the order found; empty = `geometric_only`.
    pub causes: Vec<Cause>,
    pub verdict: String,
    pub final_heldout_rmse_mm: f64,
    /// RMSE of the final model (the one `--result` holds) on every kept row it was fitted to.
    pub final_train_rmse_mm: f64,
    /// Share of the final held-out mean square that the data's floor accounts for (floor² /
    /// held-out²): what remains is named, not fitted.
    #[serde(default)]
    pub floor_share_of_remaining: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub comparison: Option<Comparison>,
    pub seconds: f64,
    /// The effects kept, as calibration effect options (for `calibrate --effects`).
    pub effects_option: String,
    /// What the user should know about this diagnosis (a kept cause whose size the final fit
    /// turned unphysical, ...).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// The kept effect blocks whose fitted size in `x` has an unphysical sign (a negative
/// compliance or band width): accepted with a physical size when selected, turned by the causes
/// added after them. One warning each.
pub fn unphysical_causes(model: &CalibModel, x: &[f64], kept: &[EffectBlock]) -> Vec<String> {
    kept.iter()
        .filter_map(|block| {
            let b = model.effects.iter().position(|e| e == block)?;
            let k = model.effect_params(b).start;
            (!block.kind.def().physical_sign(x, k)).then(|| {
                format!(
                    "{} ends with an unphysical size in the final fit ({} = {:.4} {}): the causes added after it took its share; treat it as unconfirmed",
                    block.label(),
                    model.names[k],
                    x[k] * model.kinds[k].display(),
                    model.kinds[k].unit()
                )
            })
        })
        .collect()
}

pub use crate::calib::problem::gls::NoiseModel;

fn no_structure() -> Structure {
    crate::dataset::blocks::Blocks::singletons(0).structure(None)
}

fn one() -> f64 {
    1.0
}

impl Diagnosis {
    /// The final held-out RMSE against the data's floor, in words: a ratio where repeated
    /// configurations give the floor, else what is known of it.
    pub fn against_floor(&self) -> String {
        if self.noise_floor.sources.iter().any(|s| s.source == "repeatability") {
            format!("{:.2} x the noise floor", self.final_heldout_rmse_mm / self.noise_floor_mm)
        } else {
            format!("no repeated configurations, so the floor is known only down to the logging resolution ({:.4} mm)", self.noise_floor_mm)
        }
    }
}

/// A model with its fitted parameters and fixed mask on the kept rows.
#[derive(Clone)]
struct Fitted {
    model: CalibModel,
    x: Vec<f64>,
    fixed: Vec<bool>,
    /// Held-out residual of every kept row, mm.
    oof: Vec<f64>,
    /// In-sample residual sum of squares (mm²) and free parameters.
    rss: f64,
    n_free: usize,
    /// Design effect of the in-sample residuals over the acquisition's blocks (1 when every row
    /// is its own block): how much less than their number the rows count as evidence.
    deff: f64,
}

use crate::stats::rms;

struct Ctx {
    /// The selection rows (kept rows less the confirmation set), with their inputs.
    data: Samples,
    /// Folds over `data`: the kind selection judges on, then the other kind. Whole blocks of
    /// the acquisition go to one fold.
    folds: Vec<Vec<usize>>,
    other_folds: Vec<Vec<usize>>,
    /// Block of every selection row, where some block has more than one row.
    groups: Option<Vec<usize>>,
    rank_tol: f64,
}

impl Ctx {
    /// The selection rows of the kept rows `kept` (rows `keep` of the data, in blocks `blocks`)
    /// with their folds, and the confirmation set: every k-th block of kept rows in acquisition
    /// order (every k-th row when no rows share a block), never seen by selection. Also the
    /// warning of [`block_folds`].
    fn over_blocks(kept: &Samples, keep: &[usize], blocks: &crate::dataset::blocks::Blocks, opts: &DiagnoseOptions) -> (Ctx, Samples, Option<String>) {
        let every = if opts.confirm_fraction > 0.0 { (1.0 / opts.confirm_fraction).round().max(2.0) as usize } else { usize::MAX };
        let kept_groups = blocks.ids_of(keep);
        let (sel_idx, conf_idx): (Vec<usize>, Vec<usize>) = (0..kept.len()).partition(|&i| kept_groups[i] % every != every - 1);
        let sel_groups = blocks.ids_of(&sel_idx.iter().map(|&i| keep[i]).collect::<Vec<_>>());
        let shared = blocks.any_shared();
        let (folds, other_folds, few_blocks) = block_folds(&sel_groups, opts.folds, shared);
        let ctx = Ctx { folds, other_folds, groups: shared.then_some(sel_groups), data: kept.subset(&sel_idx), rank_tol: opts.rank_tol };
        (ctx, kept.subset(&conf_idx), few_blocks)
    }

    /// Fits `model` from `x0` on every selection row (identifiable parameters only), then the
    /// held-out residual of each fold from a fit on the other folds.
    fn evaluate(&self, model: CalibModel, x0: &[f64]) -> Fitted {
        let fit = ReadingFit { model: &model, data: &self.data };
        let (x, fixed) = refit(&model, &self.data, x0, self.rank_tol);
        let oof = self.heldout(&model, &x, &fixed, &self.folds);
        let res = fit.residuals_mm(&x);
        let rss = res.iter().map(|r| r * r).sum();
        let n_free = fixed.iter().filter(|f| !**f).count();
        let deff = self.groups.as_ref().map_or(1.0, |g| crate::stats::design_effect(&res, self.data.dim, g));
        Fitted { model, x, fixed, oof, rss, n_free, deff }
    }

    /// Held-out residual of every selection row: each fold predicted by a fit on the others.
    fn heldout(&self, model: &CalibModel, x: &[f64], fixed: &[bool], folds: &[Vec<usize>]) -> Vec<f64> {
        // Folds are independent fits: in parallel, scattered back in fold order.
        let per_fold: Vec<Vec<f64>> = folds
            .par_iter()
            .map(|fold| {
                let train: Vec<usize> = (0..self.data.len()).filter(|i| !fold.contains(i)).collect();
                let tr = self.data.subset(&train);
                let xf = LevenbergMarquardt::refit().minimize(&ReadingFit { model, data: &tr }, x, fixed, &mut NoObserver).x;
                // Judged in mm, unweighted (the rows' weights serve the fit).
                ReadingFit { model, data: &self.data.subset(fold).unweighted() }.residuals_mm(&xf)
            })
            .collect();
        scatter(folds, per_fold, self.data.len(), self.data.dim)
    }
}

/// Every fold's residuals (`dim` values per row, in the fold's row order) put back at their
/// rows: one vector of `n` rows of `dim` values.
fn scatter(folds: &[Vec<usize>], per_fold: Vec<Vec<f64>>, n: usize, dim: usize) -> Vec<f64> {
    let mut out = vec![0.0; n * dim];
    for (fold, r) in folds.iter().zip(per_fold) {
        for (k, &i) in fold.iter().enumerate() {
            out[i * dim..(i + 1) * dim].copy_from_slice(&r[k * dim..(k + 1) * dim]);
        }
    }
    out
}

/// The parameters of `model` that `data` identify at `x0` (the rest stay fixed there), and the
/// LM fit of those from `x0`: (fitted vector, fixed mask).
fn refit(model: &CalibModel, data: &Samples, x0: &[f64], rank_tol: f64) -> (Vec<f64>, Vec<bool>) {
    let fit = ReadingFit { model, data };
    let fixed = identify(&fit, x0, rank_tol).fixed_mask;
    (LevenbergMarquardt::refit().minimize(&fit, x0, &fixed, &mut NoObserver).x, fixed)
}

/// The acquisition's blocks (sweeps, pauses, declared blocks) and the ends of the reading steps
/// `steps` (rows that share an error are held out together and count as less than their
/// number), what they look like, and where rows share blocks and the angles are logged at a
/// step, the logging error as the noise model of every fit from here on: `all` gets its
/// whitening (generalised least squares over the blocks, see `calib::gls`), from the geometric
/// model `base` at `x` and the kept rows `keep`.
#[allow(clippy::too_many_arguments)]
fn acquisition_structure(
    data: &Dataset,
    opts: &DiagnoseOptions,
    steps: &[crate::calib::problem::robust::ReadingStep],
    base: &CalibModel,
    x: &[f64],
    all: &mut Samples,
    keep: &[usize],
    progress: &dyn Fn(&str),
) -> (crate::dataset::blocks::Blocks, Structure, Option<NoiseModel>) {
    let (mut blocks, angle_step) = crate::dataset::blocks::detect(data, opts.angle_step_deg);
    for s in steps {
        blocks.split_before(s.first_row - 1, Boundary::ReadingStep);
        blocks.split_before(s.last_row, Boundary::ReadingStep);
    }
    let acquisition = blocks.structure(angle_step);
    if !blocks.any_shared() {
        return (blocks, acquisition, None);
    }
    progress(&format!("acquisition: {}", acquisition.summary));
    let Some(step) = angle_step.filter(|_| opts.noise_model == crate::calib::problem::noise_model::NoiseChoice::Auto) else {
        return (blocks, acquisition, None);
    };
    let rows: Vec<usize> = (0..all.len()).collect();
    let m = std::sync::Arc::new(crate::calib::problem::noise_model::rounding_model_at(base, x, all, &rows, keep, data, &blocks, step));
    let noise = m.summary(step);
    progress(&format!(
        "joint angles logged at {step} deg: their shared error is a noise model of the fits (rounding {:.4} mm, reading noise {:.4} mm per value)",
        noise.rounding_mm, noise.reading_noise_mm
    ));
    all.gls = Some(crate::calib::problem::gls::Whitening::new(m, (0..all.len()).collect()));
    (blocks, acquisition, Some(noise))
}

/// The kept rows `kept` of the final fit with their noise model re-estimated at the model with its
/// causes (`current`): the reading noise of the first one (see [`acquisition_structure`]) is
/// what the geometric model leaves, the causes' signal included, and so takes most of what
/// remains for independent noise; the sweeps' shared logging error, then too small a share of
/// the covariance, would let a slow cause (a thermal drift over the sweeps) absorb it and state
/// too small an uncertainty. Unchanged without a noise model or a cause.
fn final_whitening(
    kept: Samples,
    noise_model: Option<NoiseModel>,
    all: &Samples,
    current: &Fitted,
    data: &Dataset,
    blocks: &crate::dataset::blocks::Blocks,
    keep: &[usize],
) -> (Samples, Option<NoiseModel>) {
    let Some(n) = noise_model.as_ref().filter(|_| !current.model.effects.is_empty() && all.gls.is_some()) else { return (kept, noise_model) };
    let rows: Vec<usize> = (0..all.len()).collect();
    let plain = Samples { gls: None, ..all.clone() };
    let m = std::sync::Arc::new(crate::calib::problem::noise_model::rounding_model_at(
        &current.model,
        &current.x,
        &plain,
        &rows,
        keep,
        data,
        blocks,
        n.angle_step_deg,
    ));
    let summary = m.summary(n.angle_step_deg);
    let whitened = Samples { gls: Some(crate::calib::problem::gls::Whitening::new(m, rows)), ..plain };
    (whitened.subset(keep), Some(summary))
}

/// Share of the data's floor (mm RMS) that what a cause explains of the held-out rows must reach
/// for it to be named: √(before² − after²) of the held-out RMSE. Below, the cause may be real and
/// significant, but its correction is smaller than the error the data's floor leaves in every
/// row. (At half the floor, effects hidden at 0.13–0.19× the floor in sweeps logged at 0.1° and
/// 0.01° were named: on blocked folds their gains came out at 0.51–0.67× the floor, while effects
/// at 1.5× and more gained 1.4× and more.)
pub const BELOW_FLOOR_SHARE: f64 = 1.0;

/// Every kept cause (`found`: block, held-out RMSE before and after, p; the first `confirmed`
/// of them) that explains at least [`BELOW_FLOOR_SHARE`] of the data's floor `floor_mm` on the
/// held-out rows: the first that does not ends the list, like an unconfirmed one (`confirmed` is
/// lowered). One line per cause left out, with its figures.
fn drop_below_floor(found: &[(EffectBlock, f64, f64, f64)], floor_mm: f64, confirmed: &mut usize, progress: &dyn Fn(&str)) -> Vec<String> {
    let Some(k) = found[..*confirmed].iter().position(|(_, before, after, _)| (before * before - after * after).max(0.0).sqrt() < BELOW_FLOOR_SHARE * floor_mm)
    else {
        return Vec::new();
    };
    let notes: Vec<String> = found[k..*confirmed]
        .iter()
        .map(|(b, before, after, _)| {
            format!(
                "{} left out of the model: it explains {:.4} mm RMS of the held-out rows ({before:.4} -> {after:.4} mm), below {BELOW_FLOOR_SHARE} x the data's floor {floor_mm:.4} mm",
                b.label(),
                (before * before - after * after).max(0.0).sqrt()
            )
        })
        .collect();
    notes.iter().for_each(|n| progress(&format!("below the floor: {n}")));
    *confirmed = k;
    notes
}

/// Every kept cause (`found`, the first `confirmed` of them; `chain[k]` the model with the first
/// k) of a physical size in the model fitted on every kept row (selection and confirmation;
/// `kept` gives them with the noise model at that model, as the final fit has them): the first
/// that is not ends the list, like an unconfirmed one (`confirmed` is lowered). One line per
/// cause left out, saying why.
#[allow(clippy::too_many_arguments)]
fn drop_not_physical(
    chain: &[Fitted],
    found: &[(EffectBlock, f64, f64, f64)],
    kept: &dyn Fn(&Fitted) -> Samples,
    groups: Option<&[usize]>,
    min_size_sigmas: f64,
    rank_tol: f64,
    confirmed: &mut usize,
    progress: &dyn Fn(&str),
) -> Vec<String> {
    let mut notes = Vec::new();
    while *confirmed > 0 {
        let m = &chain[*confirmed];
        let kept = kept(m);
        let (x, fixed) = refit(&m.model, &kept, &m.x, rank_tol);
        let covs = Covariances::of(&ReadingFit { model: &m.model, data: &kept }, &x, &fixed, groups);
        let Some((k, why)) = found[..*confirmed].iter().enumerate().find_map(|(k, f)| {
            let b = m.model.effects.iter().position(|e| e == &f.0)?;
            let size = covs.size(&f.0, &x, m.model.effect_params(b));
            let weak = (size.value.abs() < min_size_sigmas * size.uncertainty)
                .then(|| format!("its size {:.4} ± {:.4} {} is under {min_size_sigmas} of its uncertainties", size.value, size.uncertainty, size.unit));
            implausible_param(&m.model, &x, b).or(weak).map(|w| (k, w))
        }) else {
            break;
        };
        let dropped: Vec<String> = found[k..*confirmed].iter().map(|f| f.0.label()).collect();
        progress(&format!("not physical on every kept row: {why}; left out: {}", dropped.join(", ")));
        notes.push(format!("{} left out of the model: fitted on every kept row, {why}", dropped.join(", ")));
        *confirmed = k;
    }
    notes
}

/// No model predicts unseen rows better than the data's floor: a held-out RMSE below it means
/// the held-out rows shared errors with the training rows. The warning, if so (`shared`: the
/// data have blocks of several rows).
fn leak_warning(oof: &[f64], dim: usize, groups: Option<&[usize]>, floor_mm: f64, shared: bool) -> Option<String> {
    let heldout_mm = rms(oof);
    crate::stats::short_of_floor(oof, dim, groups, floor_mm).then(|| {
        let missed = if shared {
            "blocks the detection missed (declare them in a block column)"
        } else {
            "rows of one sweep or one logging error, not detected as blocks"
        };
        format!(
            "the final held-out RMSE ({heldout_mm:.4} mm) is below the data's floor ({floor_mm:.4} mm) by more than its sampling error: the held-out rows \
             share errors with the training rows (the split leaks), so it is optimistic; {missed}"
        )
    })
}

/// Blocked and interleaved folds over the selection rows' blocks (`groups`), and a warning when
/// there are fewer blocks than folds: the folds are then drawn over rows, and rows of one block
/// sit on both sides of a split.
fn block_folds(groups: &[usize], k: usize, shared: bool) -> (Vec<Vec<usize>>, Vec<Vec<usize>>, Option<String>) {
    use crate::stats::folds;
    let n_blocks = groups.last().map_or(0, |g| g + 1);
    if !shared || n_blocks < k {
        let warning = shared.then(|| {
            format!(
                "the selection rows form only {n_blocks} blocks of the acquisition for {k} folds: folds are drawn over rows, rows of one sweep sit on \
                 both sides of a split, and the held-out RMSE is optimistic"
            )
        });
        return (folds::blocked(groups.len(), k), folds::interleaved(groups.len(), k), warning);
    }
    (folds::blocked_groups(groups, k), folds::interleaved_groups(groups, k), None)
}

/// Blocked folds judge a diagnosis unless the baseline's blocked held-out RMSE exceeds the
/// interleaved one by this factor: the acquisition blocks then cover different parts of the
/// joint space (sweeps), and blocked folds measure extrapolation, not the model.
pub const EXTRAPOLATION_FACTOR: f64 = 1.5;

/// (size / uncertainty, physical sign) of the last effect block of a fitted model.
fn size_check(f: &Fitted, data: &Samples, groups: Option<&[usize]>) -> (f64, bool) {
    let b = f.model.effects.len() - 1;
    let block = &f.model.effects[b];
    let range = f.model.effect_params(b);
    let covs = Covariances::of(&ReadingFit { model: &f.model, data }, &f.x, &f.fixed, groups);
    let Size { value: mag, uncertainty: unc, .. } = covs.size(block, &f.x, range.clone());
    let sign_ok = block.kind.def().physical_sign(&f.x, range.start);
    let ratio = if unc > 0.0 { mag.abs() / unc } else { 0.0 };
    (ratio, sign_ok)
}

/// p-value of the F test that `b` (the model with the candidate) fits the kept rows better than
/// `a` (nested least-squares models, Gaussian reading noise); `n` reading values (rows × values
/// per row), counted as `n / deff` independent ones where rows share errors in blocks (the
/// Rao–Scott correction with `b`'s design effect: what is left once the candidate is in).
fn gain_p_value(a: &Fitted, b: &Fitted, n: usize) -> f64 {
    nested_f_test_deff(a.rss, b.rss, b.n_free.saturating_sub(a.n_free), n.saturating_sub(b.n_free), b.deff)
}

/// The covariances of a fit whose rows may share errors in blocks (`groups`: each row's block):
/// the classical one, and the cluster-robust one ([`crate::optim::cluster_covariance`]) where
/// some block holds several rows. A size's uncertainty is the larger of the two, so shared errors
/// can only widen it.
struct Covariances {
    classical: Option<nalgebra::DMatrix<f64>>,
    robust: Option<nalgebra::DMatrix<f64>>,
}

impl Covariances {
    fn of(fit: &ReadingFit, x: &[f64], fixed: &[bool], groups: Option<&[usize]>) -> Covariances {
        let per_value: Option<Vec<usize>> = groups.map(|g| g.iter().flat_map(|&b| std::iter::repeat_n(b, fit.data.dim)).collect());
        let (classical, robust) = crate::optim::covariances(fit, x, fixed, per_value.as_deref());
        Covariances { classical, robust }
    }

    /// The size of `block` (parameters `range` of `x`) with the larger of its two uncertainties.
    fn size(&self, block: &EffectBlock, x: &[f64], range: std::ops::Range<usize>) -> Size {
        let mut s = magnitude(block, x, self.classical.as_ref(), range.clone());
        if let Some(r) = &self.robust {
            let u = magnitude(block, x, Some(r), range).uncertainty;
            if u > s.uncertainty || !s.uncertainty.is_finite() {
                s.uncertainty = u;
            }
        }
        s
    }

    /// Standard uncertainty of parameter `k`, the larger of the two; NaN without a covariance.
    fn sd(&self, k: usize) -> f64 {
        let var = |c: &Option<nalgebra::DMatrix<f64>>| c.as_ref().map(|c| c[(k, k)].max(0.0));
        match (var(&self.classical), var(&self.robust)) {
            (Some(a), Some(b)) => a.max(b).sqrt(),
            (Some(a), None) | (None, Some(a)) => a.sqrt(),
            (None, None) => f64::NAN,
        }
    }
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        0.0
    }
}

/// Correlations of the residual with the per-row features, strongest first. With several values
/// per row (a tracker's point), each value's residual against each feature, named
/// `feature [value]` (e.g. `torque_j2 [z]`); the readings themselves are features too.
fn evidence(data: &Samples, residual: &[f64], has_torques: bool, columns: &[&str]) -> Vec<Evidence> {
    let mut feats: Vec<(String, Vec<f64>)> = Vec::new();
    let col = |f: &dyn Fn(usize) -> f64| (0..data.len()).map(f).collect::<Vec<f64>>();
    for j in 0..data.q.first().map_or(0, |q| q.len()) {
        if has_torques {
            feats.push((format!("torque_j{}", j + 1), col(&|i| data.inputs[i].torque(j))));
            feats.push((format!("sign(torque_j{})", j + 1), col(&|i| data.inputs[i].torque(j).signum())));
        }
        feats.push((format!("backlash_side_j{}", j + 1), col(&|i| data.inputs[i].side(j))));
        feats.push((format!("sin(q{})", j + 1), col(&|i| data.q[i][j].sin())));
        feats.push((format!("cos(q{})", j + 1), col(&|i| data.q[i][j].cos())));
    }
    if data.inputs.iter().all(|r| r.t_s.is_some()) {
        feats.push(("t".into(), col(&|i| data.inputs[i].t_s.unwrap_or(0.0))));
    }
    if data.inputs.iter().all(|r| r.temp_c.is_some()) {
        feats.push(("temp".into(), col(&|i| data.inputs[i].temp_c.unwrap_or(0.0))));
    }
    let d = data.dim;
    for (c, name) in columns.iter().enumerate() {
        feats.push((name.to_string(), col(&|i| data.y[i * d + c])));
    }
    let mut ev: Vec<Evidence> = if d == 1 {
        feats.into_iter().map(|(f, v)| Evidence { feature: f, correlation: pearson(residual, &v) }).collect()
    } else {
        let per: Vec<Vec<f64>> = (0..d).map(|c| col(&|i| residual[i * d + c])).collect();
        feats
            .iter()
            .flat_map(|(f, v)| columns.iter().zip(&per).map(move |(name, r)| Evidence { feature: format!("{f} [{name}]"), correlation: pearson(r, v) }))
            .collect()
    };
    ev.sort_by(|a, b| b.correlation.abs().total_cmp(&a.correlation.abs()));
    ev
}

/// The size of an effect block in physical units with its uncertainty, as its effect defines it
/// (the uncertainty is NaN without a covariance).
fn magnitude(block: &EffectBlock, x: &[f64], cov: Option<&nalgebra::DMatrix<f64>>, range: std::ops::Range<usize>) -> Size {
    let var = |a: usize, b: usize| cov.map(|c| c[(a, b)]).unwrap_or(f64::NAN);
    block.kind.def().size(block, x, range.start, &var)
}

/// The candidate blocks: every kind on every joint the data support, or those listed (a kind
/// with a joint is that block only), each block once however often it is listed. A listed
/// candidate the data cannot support (no torques for compliance, no temp or t for thermal, a
/// joint beyond the data's) is an error naming what is missing.
fn candidates(data: &Dataset, listed: &[(EffectKind, Option<usize>)], has_torques: bool) -> Result<Vec<EffectBlock>> {
    let all: Vec<(EffectKind, Option<usize>)> = EffectKind::ALL.iter().map(|&k| (k, None)).collect();
    let mut out: Vec<EffectBlock> = Vec::new();
    for &(kind, joint) in if listed.is_empty() { &all } else { listed } {
        let joints = match joint {
            Some(j) => vec![Some(j)],
            None => kind.joint_options(data.n_joints()),
        };
        let mut first_error = None;
        let mut supported = false;
        for j in joints {
            match block_for(data, kind, j, has_torques) {
                Ok(b) => {
                    supported = true;
                    if !out.contains(&b) {
                        out.push(b);
                    }
                }
                Err(e) => first_error = first_error.or(Some(e)),
            }
        }
        if let (false, false, Some(e)) = (listed.is_empty(), supported, first_error) {
            let e = e.to_string();
            let e = e.strip_prefix(&format!("{}: ", kind.name())).unwrap_or(&e);
            return Err(Error::Invalid(format!("--candidates {}: {e}", kind.name())));
        }
    }
    Ok(out)
}

/// Runs a diagnosis. `progress` receives a line per finished step.
///
/// When the screen against the geometric model flags rows that one candidate effect explains
/// (the screen of the model with it flags at most half as many, or as many with a tighter scale:
/// a backlash band seen by a precise instrument puts every row of its minority flank far off the
/// geometry), those rows stay in and the selection runs on them. Should the selection then keep
/// another effect first (a thermal drift of the whole arm where one joint's drift screened the
/// rows), the diagnosis runs again on that effect's screen if it too explains the flagged rows;
/// should it keep neither, on the rows the geometric screen kept.
pub fn diagnose(data: &Dataset, opts: &DiagnoseOptions, progress: &dyn Fn(&str)) -> Result<(Diagnosis, crate::calib::run::CalibResult)> {
    if opts.folds < 2 || opts.folds > 20 {
        return Err(Error::Invalid(format!("--folds must be in 2..=20, got {}", opts.folds)));
    }
    let (d, r, screened_with) = diagnose_screened(data, opts, progress, ScreenBy::BestEffect)?;
    // The exported model holds the named causes' blocks, in the order they were kept.
    let Some(b) = screened_with else { return Ok((d, r)) };
    if r.model.effects.contains(&b) {
        return Ok((d, r));
    }
    if let Some(f) = r.model.effects.first().cloned() {
        progress(&format!("{} explained the flagged rows but {} was kept first: the diagnosis again, on {}'s screen", b.label(), f.label(), f.label()));
        let (d2, r2, with) = diagnose_screened(data, opts, progress, ScreenBy::Effect(f.clone()))?;
        if with.as_ref() == Some(&f) && r2.model.effects.contains(&f) {
            return Ok((d2, r2));
        }
    }
    progress(&format!("{} explained the flagged rows but was not kept: the diagnosis again, on the rows the geometric screen kept", b.label()));
    let (d, r, _) = diagnose_screened(data, opts, progress, ScreenBy::Geometry)?;
    Ok((d, r))
}

/// The candidate blocks for the rows of `data` (joint angles `q`, rad): [`candidates`] less the
/// blocks on a joint that does not move whose effect is then constant (one backlash side and one
/// eccentricity phase throughout: offsets the geometry already holds).
fn candidate_pool(data: &Dataset, q: &[Vec<f64>], opts: &DiagnoseOptions, has_torques: bool) -> Result<Vec<EffectBlock>> {
    let still = crate::calib::run::still_joints(q);
    Ok(candidates(data, &opts.candidates, has_torques)?
        .into_iter()
        .filter(|b| !(b.kind.def().constant_on_still_joint() && b.joint.is_some_and(|j| still.contains(&j))))
        .collect())
}

/// `model` with `block` added (data time span `span`, s), and the start `x` extended by the
/// block's "no effect" values.
fn with_block(model: &CalibModel, x: &[f64], block: &EffectBlock, span: f64) -> (CalibModel, Vec<f64>) {
    let mut m = model.clone();
    m.add_effect(block.clone(), span);
    let mut x0 = x.to_vec();
    x0.extend_from_slice(&m.nominal[x.len()..]);
    (m, x0)
}

/// Whether each cross-validation fold trains on enough values for the geometric model's
/// `n_free` identifiable parameters (before any cause is added): an error when a fold's training
/// rows could be fitted exactly (the held-out RMSE and the outlier screen then say nothing), a
/// warning below three values per parameter.
fn fold_rows_check(rows: usize, dim: usize, n_free: usize, opts: &DiagnoseOptions) -> Result<Option<String>> {
    let every = if opts.confirm_fraction > 0.0 { (1.0 / opts.confirm_fraction).round().max(2.0) as usize } else { usize::MAX };
    let selection = rows - rows / every;
    let train = selection - selection.div_ceil(opts.folds.max(1));
    let values = train * dim;
    if values <= n_free {
        return Err(Error::Calibration(format!(
            "{rows} rows leave {train} training rows per fold ({} folds, every {every}th row kept back to confirm) for {n_free} identifiable \
             parameters of the geometric model: an exact fit says nothing; measure more poses (at least {} rows recommended)",
            opts.folds,
            ((3 * n_free) as f64 / dim as f64 / ((1.0 - 1.0 / every as f64) * (1.0 - 1.0 / opts.folds as f64))).ceil()
        )));
    }
    Ok((values < 3 * n_free).then(|| {
        format!(
            "only {train} training rows per fold for {n_free} identifiable parameters of the geometric model (3x as many values recommended): \
             held-out RMSE and sizes are uncertain"
        )
    }))
}

/// Fewest rows, and smallest share of the rows, the geometric screen must flag before candidate
/// effects are tried as their explanation: a few glitches are glitches (HSR's 7 of 1614 rows),
/// while an effect puts many rows off (a backlash band's minority flank: a sixth of the rows).
pub const EFFECT_SCREEN_MIN_ROWS: usize = 3;
pub const EFFECT_SCREEN_MIN_SHARE: f64 = 0.01;
/// A candidate explains the flagged rows only if the rows its screen keeps sit no wider around
/// its fit than the geometric screen's (robust scale at most this factor of it): a flexible
/// block that widens the scale until the rows are in explains nothing.
pub const EFFECT_SCREEN_MAX_SCALE: f64 = 1.1;
/// ... and a candidate whose screen flags no more outlier rows than the geometric one explains
/// them when the rows it keeps sit markedly tighter around its fit (robust scale at most this
/// factor of the geometric one): where an effect shifts whole stretches of rows (a backlash
/// flank held over a sweep), the geometric screen takes them for reading steps and corrects
/// them away instead of flagging them.
pub const EFFECT_SCREEN_TIGHTER: f64 = 0.8;

/// Rows the screen `s` takes out of the plain model's account: outliers and the rows of
/// reading steps.
fn flagged_rows(s: &crate::calib::problem::robust::Screen) -> usize {
    s.outliers.len() + s.steps.iter().map(|st| st.rows).sum::<usize>()
}

/// The candidate effect whose model, screened on every row, flags the fewest rows (of those whose
/// scale stays within [`EFFECT_SCREEN_MAX_SCALE`] of the geometric one; ties to the narrower
/// scale), with its screen, when that is at most half of what the geometric screen (`geo`)
/// flagged, or no more with a scale within [`EFFECT_SCREEN_TIGHTER`] of the geometric one.
fn screen_with_effects(
    base: &CalibModel,
    all: &Samples,
    data: &Dataset,
    opts: &DiagnoseOptions,
    has_torques: bool,
    geo: &Screen,
    only: Option<&EffectBlock>,
) -> Result<Option<(EffectBlock, Screen)>> {
    let span = time_span(data);
    let pool: Vec<EffectBlock> = candidate_pool(data, &all.q, opts, has_torques)?.into_iter().filter(|b| only.is_none_or(|o| o == b)).collect();
    let rows: Vec<usize> = (0..all.len()).collect();
    let tried: Vec<(EffectBlock, Screen)> = pool
        .par_iter()
        .map(|b| {
            let (m, x0) = with_block(base, &geo.x, b, span);
            let refit = |d: &Samples, x: &[f64]| crate::calib::problem::robust::screen_fit(&m, d, x, opts.rank_tol);
            let s = crate::calib::problem::robust::screen(&m, &x0, all, &rows, geo.rule, &refit);
            (b.clone(), s)
        })
        .collect();
    // Fewest rows flagged among the candidates that keep the scale; of those, the narrowest.
    let fewer = |s: &crate::calib::problem::robust::Screen| 2 * s.outliers.len() <= geo.outliers.len() && !geo.outliers.is_empty();
    let tighter = |s: &crate::calib::problem::robust::Screen| s.outliers.len() <= geo.outliers.len() && s.scale_mm <= EFFECT_SCREEN_TIGHTER * geo.scale_mm;
    Ok(tried
        .into_iter()
        .filter(|(_, s)| s.scale_mm <= EFFECT_SCREEN_MAX_SCALE * geo.scale_mm && (fewer(s) || tighter(s)))
        .min_by(|a, b| a.1.outliers.len().cmp(&b.1.outliers.len()).then(a.1.scale_mm.total_cmp(&b.1.scale_mm))))
}

/// Which screen a diagnosis keeps its rows by (see [`screen_rows`]).
#[derive(Clone, Debug)]
enum ScreenBy {
    /// The geometric model's.
    Geometry,
    /// The candidate effect's that explains best what the geometric one flags.
    BestEffect,
    /// This effect's, where it explains what the geometric one flags.
    Effect(EffectBlock),
}

/// The rows' screen: against the geometric model, or (unless `by` is [`ScreenBy::Geometry`],
/// when that flags at least [`EFFECT_SCREEN_MIN_ROWS`] rows and [`EFFECT_SCREEN_MIN_SHARE`] of
/// them, outliers or reading steps) against the candidate effect that explains them
/// ([`screen_with_effects`]; `by` may name it), with that effect and the rows the geometric
/// screen flagged that it keeps.
fn screen_rows(
    base: &CalibModel,
    all: &Samples,
    data: &Dataset,
    opts: &DiagnoseOptions,
    has_torques: bool,
    by: &ScreenBy,
    progress: &dyn Fn(&str),
) -> Result<(crate::calib::problem::robust::Screen, Option<EffectBlock>, Vec<usize>)> {
    let refit_rows = |d: &Samples, x: &[f64]| crate::calib::problem::robust::screen_fit(base, d, x, opts.rank_tol);
    // No row is an outlier for lying as far off as the angles' logging alone puts a reading.
    let rule = crate::calib::run::screen_rule(base, data, all, opts.outlier_k, opts.reading_steps, opts.angle_step_deg);
    let geo_screen = crate::calib::problem::robust::screen(base, &base.nominal, all, &(0..all.len()).collect::<Vec<_>>(), rule, &refit_rows);
    let flagged = flagged_rows(&geo_screen);
    // Rows the geometric screen flagged that a candidate effect explains stay in.
    let only = match by {
        ScreenBy::Effect(b) => Some(b),
        _ => None,
    };
    let effect_screen = !matches!(by, ScreenBy::Geometry);
    Ok(match effect_screen && flagged >= EFFECT_SCREEN_MIN_ROWS && flagged as f64 >= EFFECT_SCREEN_MIN_SHARE * all.len() as f64 {
        true => match screen_with_effects(base, all, data, opts, has_torques, &geo_screen, only)? {
            Some((b, mut s)) => {
                progress(&format!(
                    "the geometric model's screen flags {} rows (outliers or reading steps), {}'s {}, with the kept rows' \
                         robust scale {:.4} -> {:.4} mm: its screen is kept",
                    flagged,
                    b.label(),
                    flagged_rows(&s),
                    geo_screen.scale_mm,
                    s.scale_mm
                ));
                // The geometric fit of the rows kept.
                s.x = refit_rows(&s.corrected.subset(&s.keep), &geo_screen.x);
                let flagged: Vec<usize> = geo_screen.outliers.iter().map(|o| o.row).filter(|r| !s.outliers.iter().any(|o| o.row == *r)).collect();
                (s, Some(b), flagged)
            }
            None => (geo_screen, None, Vec::new()),
        },
        false => (geo_screen, None, Vec::new()),
    })
}

/// A diagnosis whose rows are screened as `by` says ([`screen_rows`]), with the effect whose
/// screen it kept.
fn diagnose_screened(
    data: &Dataset,
    opts: &DiagnoseOptions,
    progress: &dyn Fn(&str),
    by: ScreenBy,
) -> Result<(Diagnosis, crate::calib::run::CalibResult, Option<EffectBlock>)> {
    let t0 = Instant::now();
    // Every row needs its reading: a cable length, or a tracker's point (x, y, z).
    let measurement = crate::calib::run::reading_measurement(data)?;
    let dim = measurement.dim();
    // The calibration's stages on every row (no split: the diagnosis cross-validates), with
    // every row's inputs; the diagnosis screens the rows itself, inputs included.
    let prepared = crate::calib::run::prepare(data, &opts.baseline_options(), true)?;
    let base = prepared.model;
    let torque = prepared.split.torque_model;
    // Torques exist where there are inertial data (the nominal robot's or `--robot`'s).
    let has_torques = torque.is_some();
    let mut all = prepared.split.train;
    let fold_warning = fold_rows_check(all.len(), dim, prepared.id.fixed_mask.iter().filter(|f| !**f).count(), opts)?;

    let (screen, screened_with, first_flagged) = screen_rows(&base, &all, data, opts, has_torques, &by, progress)?;
    let (keep, mut outliers, mut outlier_runs, x_base, reading_steps) = (screen.keep, screen.outliers, screen.runs, screen.x, screen.steps);
    // What went wrong in each run of outlier rows and each reading step, tested on the rows as
    // logged (see `faults`).
    let spans: Vec<(usize, usize)> =
        outlier_runs.iter().map(|r| (r.first_row - 1, r.last_row - 1)).chain(reading_steps.iter().map(|s| (s.first_row - 1, s.last_row - 1))).collect();
    let run_faults = faults::explain_runs(&base, &x_base, &all, &spans, screen.scale_mm);
    // Readings in a reading step are taken corrected by its offset from here on.
    all.y = screen.corrected.y;
    for s in &reading_steps {
        progress(&format!("reading step: rows {}-{} read {:+.2} ± {:.2} mm off; corrected and kept", s.first_row, s.last_row, s.offset_mm, s.std_mm));
    }
    if !outliers.is_empty() {
        progress(&format!("{} outlier rows kept out of the fit: {:?}", outliers.len(), outliers.iter().map(|o| o.row).collect::<Vec<_>>()));
    }
    let (blocks, acquisition, noise_model) = acquisition_structure(data, opts, &reading_steps, &base, &x_base, &mut all, &keep, progress);
    let shared = blocks.any_shared();
    let kept = all.subset(&keep);
    let kept_rows = Dataset { rows: keep.iter().map(|&i| data.rows[i].clone()).collect(), source: data.source.clone() };
    let (mut ctx, confirmation, few_blocks) = Ctx::over_blocks(&kept, &keep, &blocks, opts);
    let mut baseline = ctx.evaluate(base.clone(), &x_base);
    let other_oof = ctx.heldout(&baseline.model, &baseline.x, &baseline.fixed, &ctx.other_folds);
    let (rmse_blocked, rmse_interleaved) = (rms(&baseline.oof), rms(&other_oof));
    let (judged_on, judged_on_reason) = if rmse_blocked > EXTRAPOLATION_FACTOR * rmse_interleaved {
        std::mem::swap(&mut ctx.folds, &mut ctx.other_folds);
        baseline.oof = other_oof;
        (
            "interleaved",
            format!(
                "the geometric model's blocked-fold held-out RMSE ({rmse_blocked:.4} mm) is above {EXTRAPOLATION_FACTOR}x its interleaved one \
                 ({rmse_interleaved:.4} mm): blocks of acquisition order cover different parts of the joint space, so blocked folds measure extrapolation"
            ),
        )
    } else {
        ("blocked", format!("blocked and interleaved held-out RMSE of the geometric model agree ({rmse_blocked:.4} / {rmse_interleaved:.4} mm): time-dependent effects must extrapolate across blocks"))
    };
    let base_in = ReadingFit { model: &baseline.model, data: &ctx.data.unweighted() }.residuals_mm(&baseline.x);
    let evidence = evidence(&ctx.data, &base_in, has_torques, base.measurement.def().columns());
    progress(&format!(
        "geometric baseline: held-out RMSE {rmse_blocked:.4} mm (blocked folds), {rmse_interleaved:.4} mm (interleaved); judged on {judged_on} folds"
    ));

    let span = time_span(&kept_rows);
    let pool = candidate_pool(&kept_rows, &kept.q, opts, has_torques)?;
    let Selection { chain, steps, mut found } = select_causes(&ctx, &pool, &baseline, opts, span, progress);

    let (conf_rmse, mut confirmed, unconfirmed) = confirm_causes(&chain, &found, &confirmation, progress);
    let kept_groups = shared.then(|| blocks.ids_of(&keep));
    // With the noise model re-estimated at each model, as the final fit will be: at the
    // geometric model's the causes' own signal counts as reading noise, and a slow cause fitted
    // with that whitening absorbs the sweeps' shared logging error (see `final_whitening`).
    let rewhitened = |m: &Fitted| final_whitening(kept.clone(), noise_model.clone(), &all, m, data, &blocks, &keep).0;
    let not_physical = drop_not_physical(&chain, &found, &rewhitened, kept_groups.as_deref(), opts.min_size_sigmas, opts.rank_tol, &mut confirmed, progress);
    let floor_mm = {
        let repeat = crate::calib::run::reading_repeatability(&kept_rows);
        crate::calib::run::floor_stage(&base, &baseline.x, &kept_rows, &kept, opts.angle_step_deg, opts.instrument_accuracy_mm, repeat.as_ref()).total_mm
    };
    let below_floor = drop_below_floor(&found, floor_mm, &mut confirmed, progress);
    found.truncate(confirmed);
    let current = chain[confirmed].clone();
    let other_rmse: Vec<f64> = chain[..=confirmed].iter().map(|f| rms(&ctx.heldout(&f.model, &f.x, &f.fixed, &ctx.other_folds))).collect();

    // The final model: refitted on every kept row (selection and confirmation); its sizes, its
    // residual and the --result file all come from this one fit.
    // The screen judged every row against the geometric model, before any cause was known: a
    // row that a cause pushes far from it looks like a glitch. Rows the model with its causes
    // predicts within the same threshold (around the kept rows' residuals) are explained, not
    // outliers: they rejoin the rows of the final fit, and are listed.
    let explained = explained_by_causes(&current, &all, dim, &keep, &outliers, opts.outlier_k);
    let (kept, kept_rows, final_keep) = if explained.is_empty() {
        (kept, kept_rows, keep)
    } else {
        progress(&format!(
            "{} rows first taken for outliers are explained by the causes: {:?}",
            explained.len(),
            explained.iter().map(|i| i + 1).collect::<Vec<_>>()
        ));
        outliers.retain(|o| !explained.contains(&(o.row - 1)));
        outlier_runs = crate::calib::problem::robust::runs(&outliers);
        let keep: Vec<usize> = (0..all.len()).filter(|i| !outliers.iter().any(|o| o.row == i + 1)).collect();
        (all.subset(&keep), Dataset { rows: keep.iter().map(|&i| data.rows[i].clone()).collect(), source: data.source.clone() }, keep)
    };
    let final_groups = shared.then(|| blocks.ids_of(&final_keep));
    let mut explained_rows: Vec<usize> = explained.iter().map(|i| i + 1).chain(first_flagged).collect();
    explained_rows.sort_unstable();
    let (kept, noise_model) = final_whitening(kept, noise_model, &all, &current, data, &blocks, &final_keep);
    let fit = ReadingFit { model: &current.model, data: &kept };
    let final_id = identify(&fit, &current.x, opts.rank_tol);
    let final_x = LevenbergMarquardt::refit().minimize(&fit, &current.x, &final_id.fixed_mask, &mut NoObserver).x;
    let final_train_rmse_mm = rms(&ReadingFit { model: &current.model, data: &kept.unweighted() }.residuals_mm(&final_x));
    let kept_blocks: Vec<EffectBlock> = found.iter().map(|f| f.0.clone()).collect();
    let mut warnings: Vec<String> = fold_warning
        .into_iter()
        .chain(few_blocks)
        .chain(not_physical.iter().cloned())
        .chain(below_floor.iter().cloned())
        .chain(unphysical_causes(&current.model, &final_x, &kept_blocks))
        .collect();
    // Each cause's uncertainty counts the rows its blocks share.
    let covs = Covariances::of(&fit, &final_x, &final_id.fixed_mask, final_groups.as_deref());
    let causes = cause_reports(&found, &current.model, &covs, &final_x, &other_rmse, &conf_rmse);

    // The data's own floor: repeatability and logging resolutions, never the fit's residual.
    let fitted = crate::calib::run::FittedModel {
        model: current.model.clone(),
        x0: base_start(&current.model, &x_base),
        x: final_x.clone(),
        id: final_id,
        torque_model: torque.clone(),
    };
    let result = crate::calib::run::result_of_fit(&kept_rows, &kept, fitted, opts.seed, opts.angle_step_deg, opts.instrument_accuracy_mm)?;
    let noise_floor = result.noise_floor.clone().expect("result_of_fit sets the floor");
    let noise_floor_mm = noise_floor.total_mm;
    let noise_floor_source = floor_source_text(&noise_floor);
    let comparison = compare_with_rbf(&ctx, &baseline, &current, opts.seed);
    let current_oof = rms(&current.oof);
    warnings.extend(leak_warning(&current.oof, dim, ctx.groups.as_deref(), noise_floor_mm, shared));
    let effects_option = effects_option(&current.model);

    let diagnosis = Diagnosis {
        schema_version: crate::io::SCHEMA_VERSION,
        warnings,
        acquisition,
        noise_model,
        design_effect: baseline.deff,
        not_physical,
        below_floor,
        twincal_version: env!("CARGO_PKG_VERSION").into(),
        data: data.source.clone(),
        rows: data.rows.len(),
        reading: if dim > 1 {
            format!("each row reads a {} ({}): every RMSE is per coordinate", measurement.def().describe(), measurement.def().columns().join(", "))
        } else {
            String::new()
        },
        outliers,
        outlier_runs,
        explained_by_causes: explained_rows,
        reading_steps,
        run_faults,
        noise_floor_mm,
        noise_floor_source,
        noise_floor,
        judged_on: judged_on.into(),
        judged_on_reason,
        selection_rows: ctx.data.len(),
        confirmation_rows: confirmation.len(),
        unconfirmed,
        baseline: Baseline {
            model: base.name.clone(),
            heldout_rmse_mm: rms(&baseline.oof),
            heldout_rmse_blocked_mm: rmse_blocked,
            heldout_rmse_interleaved_mm: rmse_interleaved,
            train_rmse_mm: rms(&base_in),
        },
        evidence,
        steps,
        verdict: verdict_of(&causes),
        causes,
        final_heldout_rmse_mm: current_oof,
        final_train_rmse_mm,
        floor_share_of_remaining: (noise_floor_mm / current_oof).powi(2).min(1.0),
        comparison,
        seconds: t0.elapsed().as_secs_f64(),
        effects_option,
    };
    Ok((diagnosis, result, screened_with))
}

/// A cause kept by the forward selection: its block, the held-out RMSE before and after it (mm)
/// and its p-value.
type Found = (EffectBlock, f64, f64, f64);

/// The forward selection's outcome: the fitted model after each kept cause (the baseline
/// first), every step's candidates, and the causes kept in order.
struct Selection {
    chain: Vec<Fitted>,
    steps: Vec<Step>,
    found: Vec<Found>,
}

/// Forward selection over the candidate `pool`: at each step the candidate whose model predicts
/// the held-out folds best is kept if it is plausible, has the sign physics allows, is sized
/// beyond `opts.min_size_sigmas`, passes the Bonferroni-corrected gain test and gains at least
/// `opts.min_gain`; the first step with none ends the selection.
fn select_causes(ctx: &Ctx, pool: &[EffectBlock], baseline: &Fitted, opts: &DiagnoseOptions, span: f64, progress: &dyn Fn(&str)) -> Selection {
    let mut current = baseline.clone();
    let mut chain = vec![baseline.clone()];
    let mut steps = Vec::new();
    let mut found: Vec<Found> = Vec::new();
    for _ in 0..opts.max_effects {
        let remaining: Vec<&EffectBlock> = pool.iter().filter(|b| !current.model.effects.contains(b)).collect();
        if remaining.is_empty() {
            break;
        }
        let before = rms(&current.oof);
        let results: Vec<(Candidate, Fitted)> = remaining
            .par_iter()
            .map(|b| {
                let tc = Instant::now();
                let (m, x0) = with_block(&current.model, &current.x, b, span);
                let f = ctx.evaluate(m, &x0);
                let p = (gain_p_value(&current, &f, ctx.data.y.len()) * remaining.len() as f64).min(1.0);
                let (size_sigmas, physical_sign) = size_check(&f, &ctx.data, ctx.groups.as_deref());
                let c = Candidate {
                    cause: b.kind.name().into(),
                    joint: b.joint.map(|j| j + 1),
                    heldout_rmse_mm: rms(&f.oof),
                    p_value: p,
                    plausible: plausible(&f),
                    size_sigmas,
                    physical_sign,
                    seconds: tc.elapsed().as_secs_f64(),
                };
                (c, f)
            })
            .collect();
        let best = results
            .iter()
            .enumerate()
            .filter(|(_, (c, _))| {
                c.plausible
                    && c.physical_sign
                    && c.size_sigmas >= opts.min_size_sigmas
                    && c.p_value < opts.alpha
                    && c.heldout_rmse_mm < (1.0 - opts.min_gain) * before
            })
            .min_by(|a, b| a.1 .0.heldout_rmse_mm.total_cmp(&b.1 .0.heldout_rmse_mm))
            .map(|(i, _)| i);
        let kept_label = best.map(|i| remaining[i].label());
        steps.push(Step { heldout_rmse_before_mm: before, candidates: results.iter().map(|r| r.0.clone()).collect(), kept: kept_label.clone() });
        let Some(i) = best else { break };
        let (c, f) = results.into_iter().nth(i).expect("index from the same list");
        progress(&format!("kept {}: held-out RMSE {before:.4} -> {:.4} mm (p = {:.2e})", remaining[i].label(), c.heldout_rmse_mm, c.p_value));
        found.push((remaining[i].clone(), before, c.heldout_rmse_mm, c.p_value));
        chain.push(f.clone());
        current = f;
    }
    Selection { chain, steps, found }
}

/// Confirmation: each cause's model, fitted on the selection rows, must predict the
/// `confirmation` rows better than the model before it; the first cause that does not ends the
/// list. The confirmation RMSE of each model of `chain`, how many causes are confirmed, and the
/// labels of the rest.
fn confirm_causes(chain: &[Fitted], found: &[Found], confirmation: &Samples, progress: &dyn Fn(&str)) -> (Vec<f64>, usize, Vec<String>) {
    let confirmation_mm = confirmation.unweighted();
    let conf_rmse: Vec<f64> = chain
        .iter()
        .map(|f| if confirmation.is_empty() { f64::NAN } else { rms(&ReadingFit { model: &f.model, data: &confirmation_mm }.residuals_mm(&f.x)) })
        .collect();
    let confirmed = (1..chain.len()).take_while(|&k| confirmation.is_empty() || conf_rmse[k] < conf_rmse[k - 1]).count();
    let unconfirmed: Vec<String> = found[confirmed..].iter().map(|f| f.0.label()).collect();
    if !unconfirmed.is_empty() {
        progress(&format!("not confirmed on the {} confirmation rows: {}", confirmation.len(), unconfirmed.join(", ")));
    }
    (conf_rmse, confirmed, unconfirmed)
}

/// The report of each kept cause: its size and uncertainty from the final fit (`x`, `covs`), its
/// parameters, and the held-out and confirmation RMSE before and after it.
fn cause_reports(found: &[Found], model: &CalibModel, covs: &Covariances, final_x: &[f64], other_rmse: &[f64], conf_rmse: &[f64]) -> Vec<Cause> {
    let mut causes = Vec::new();
    for (n, (block, before, after, p)) in found.iter().enumerate() {
        let b = model.effects.iter().position(|e| e == block).expect("kept block is in the model");
        let range = model.effect_params(b);
        let Size { quantity, value: mag, unit, uncertainty: unc } = covs.size(block, final_x, range.clone());
        let parameters = range
            .clone()
            .map(|k| {
                let d = model.kinds[k].display();
                let sd = covs.sd(k) * d;
                (model.names[k].clone(), final_x[k] * d, sd)
            })
            .collect();
        causes.push(Cause {
            cause: block.kind.name().into(),
            joint: block.joint.map(|j| j + 1),
            magnitude: mag,
            unit,
            uncertainty: unc,
            quantity,
            heldout_rmse_before_mm: *before,
            heldout_rmse_after_mm: *after,
            heldout_rmse_other_folds_before_mm: other_rmse[n],
            heldout_rmse_other_folds_after_mm: other_rmse[n + 1],
            confirmation_rmse_before_mm: conf_rmse[n],
            confirmation_rmse_after_mm: conf_rmse[n + 1],
            p_value: *p,
            parameters,
        });
    }
    causes
}

/// The outlier rows (0-based) the model with its causes (`current`; `dim` values a row) predicts
/// within `outlier_k` robust standard deviations of the kept rows' residuals: explained, not glitches.
fn explained_by_causes(current: &Fitted, all: &Samples, dim: usize, keep: &[usize], outliers: &[Outlier], outlier_k: f64) -> Vec<usize> {
    if current.model.effects.is_empty() {
        return Vec::new();
    }
    let res_all = ReadingFit { model: &current.model, data: &Samples { gls: None, ..all.clone() } }.residuals_mm(&current.x);
    let kept_res: Vec<f64> = keep.iter().flat_map(|&i| res_all[i * dim..(i + 1) * dim].iter().copied()).collect();
    let (med, scale) = crate::stats::robust_scale(&kept_res);
    let far = |i: usize| crate::calib::problem::robust::farthest_from(&res_all[i * dim..(i + 1) * dim], med);
    outliers.iter().map(|o| o.row - 1).filter(|&i| (far(i) - med).abs() <= outlier_k * scale).collect()
}

/// Where the floor comes from, as one line: each source with its RMS, and a note when it is a
/// lower bound (no repeated configurations).
fn floor_source_text(floor: &crate::calib::problem::floor::NoiseFloor) -> String {
    let mut text: Vec<String> = floor.sources.iter().map(|s| format!("{} {:.4} mm: {}", s.source, s.rms_mm, s.detail)).collect();
    if !floor.sources.iter().any(|s| s.source == "repeatability") {
        text.push("no repeated configurations: the reading's repeatability is unknown, so this is a lower bound".into());
    }
    text.join("; ")
}

/// The `--effects` value that calibrates `model`'s effect blocks (`backlash:2,thermal_drift`).
fn effects_option(model: &CalibModel) -> String {
    model
        .effects
        .iter()
        .map(|e| match e.joint {
            Some(j) => format!("{}:{}", e.kind.name(), j + 1),
            None => e.kind.name().to_string(),
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// The verdict: `geometric_only`, or the causes kept (`backlash[j2] + thermal_drift`).
fn verdict_of(causes: &[Cause]) -> String {
    if causes.is_empty() {
        return "geometric_only".into();
    }
    causes
        .iter()
        .map(|c| match c.joint {
            Some(j) => format!("{}[j{j}]", c.cause),
            None => c.cause.clone(),
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

/// The start of the final model's parameters for its report: the baseline's geometry with every
/// effect at "no effect".
fn base_start(model: &CalibModel, x_base: &[f64]) -> Vec<f64> {
    let mut x = model.nominal.clone();
    x[..x_base.len()].copy_from_slice(x_base);
    x
}

/// Held-out RMSE of the geometric model, the physical extension and an RBF compensator on the
/// geometric residuals, on the same folds; and their extrapolation to rows with q2 above its
/// 70th percentile when trained on the rest.
fn compare_with_rbf(ctx: &Ctx, geo: &Fitted, ext: &Fitted, seed: u64) -> Option<Comparison> {
    use crate::calib::correctors::rbf::RbfNetwork;
    let (n, d) = (ctx.data.len(), ctx.data.dim);
    // One network per reading value (a tracker's x, y and z each get their own), fitted on the
    // geometric residuals of the training rows.
    let rbf_fit = |rows: &[usize], model: &CalibModel, x: &[f64]| -> Option<(Vec<f64>, Vec<RbfNetwork>)> {
        let tr = ctx.data.subset(rows);
        let xf = refit(model, &tr, x, ctx.rank_tol).0;
        let res = ReadingFit { model, data: &tr.unweighted() }.residuals_mm(&xf);
        let columns: Vec<Vec<f64>> = (0..d).map(|c| crate::stats::value_column(&res, d, c)).collect();
        let columns: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
        let nets = RbfNetwork::fit_cv_many(&tr.q, &columns, &RbfNetwork::CV_CENTRES, &RbfNetwork::CV_RIDGES, seed)
            .into_iter()
            .map(|r| r.ok().map(|(net, _)| net))
            .collect::<Option<Vec<_>>>()?;
        Some((xf, nets))
    };
    // The residuals of `te` at `xf` less the networks' corrections.
    let corrected = |te: &Samples, model: &CalibModel, xf: &[f64], nets: &[RbfNetwork]| -> Vec<f64> {
        let r = ReadingFit { model, data: te }.residuals_mm(xf);
        r.iter().enumerate().map(|(k, ri)| ri - nets[k % d].predict(&te.q[k / d])).collect()
    };
    let per_fold: Vec<Option<Vec<f64>>> = ctx
        .folds
        .par_iter()
        .map(|fold| {
            let train: Vec<usize> = (0..n).filter(|i| !fold.contains(i)).collect();
            let (xf, nets) = rbf_fit(&train, &geo.model, &geo.x)?;
            Some(corrected(&ctx.data.subset(fold).unweighted(), &geo.model, &xf, &nets))
        })
        .collect();
    let rbf_oof = scatter(&ctx.folds, per_fold.into_iter().collect::<Option<Vec<_>>>()?, n, d);
    // Extrapolation in q2.
    let mut q2: Vec<f64> = ctx.data.q.iter().map(|q| q[1]).collect();
    q2.sort_by(f64::total_cmp);
    let split = q2[(EXTRAPOLATION_QUANTILE * (n - 1) as f64) as usize];
    let train: Vec<usize> = (0..n).filter(|&i| ctx.data.q[i][1] <= split).collect();
    let test: Vec<usize> = (0..n).filter(|&i| ctx.data.q[i][1] > split).collect();
    if train.len() < 20 || test.len() < 5 {
        return None;
    }
    let te = ctx.data.subset(&test).unweighted();
    // The geometric fit on the training part serves both the geometric model and the RBF.
    let (xg, nets) = rbf_fit(&train, &geo.model, &geo.x)?;
    let r = ReadingFit { model: &geo.model, data: &te }.residuals_mm(&xg);
    let rbf_ex = rms(&corrected(&te, &geo.model, &xg, &nets));
    let xe = refit(&ext.model, &ctx.data.subset(&train), &ext.x, ctx.rank_tol).0;
    let ext_ex = rms(&ReadingFit { model: &ext.model, data: &te }.residuals_mm(&xe));
    Some(Comparison {
        heldout_rmse_mm: [rms(&geo.oof), rms(&ext.oof), rms(&rbf_oof)],
        q2_split_deg: split.to_degrees(),
        extrapolation_rmse_mm: [rms(&r), ext_ex, rbf_ex],
        extrapolation_rows: [train.len(), test.len()],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Row;

    fn data() -> Dataset {
        let rows = (0..20)
            .map(|i| {
                let a = i as f64;
                Row {
                    q_deg: vec![a, -a, 2.0 * a, 0.5 * a, 10.0 - a, a],
                    reading_mm: vec![500.0 + a],
                    t_s: Some(10.0 * a),
                    temp_c: None,
                    split: None,
                    std_mm: None,
                    block: None,
                }
            })
            .collect();
        Dataset { rows, source: "test".into() }
    }

    #[test]
    fn listed_candidates_keep_their_joint_count_once_and_name_what_the_data_lack() {
        let d = data();
        // Every kind on every joint the data support (no torques: no compliance).
        let all = candidates(&d, &[], false).unwrap();
        assert!(all.iter().all(|b| b.kind != EffectKind::JointCompliance));
        assert_eq!(all.iter().filter(|b| b.kind == EffectKind::Backlash).count(), 6);
        // A joint given is that block only; listed twice, it is still one candidate.
        let two = candidates(&d, &[(EffectKind::Backlash, Some(1)), (EffectKind::Backlash, Some(1))], false).unwrap();
        assert_eq!(two.len(), 1);
        assert_eq!((two[0].kind, two[0].joint), (EffectKind::Backlash, Some(1)));
        // A listed candidate the data cannot support is an error, not a silent "geometric only".
        let e = candidates(&d, &[(EffectKind::JointCompliance, None)], false).unwrap_err().to_string();
        assert!(e.contains("joint torques"), "{e}");
        let e = candidates(&d, &[(EffectKind::Backlash, Some(8))], false).unwrap_err().to_string();
        assert!(e.contains("joint 9 is beyond the data's 6 joints"), "{e}");
    }

    #[test]
    fn a_warm_up_outside_its_physical_range_or_an_oversized_effect_is_not_physical() {
        use crate::calib::effects::ThermalDrive;
        use crate::calib::model::SensorGuess;
        let robot = Robot::irb120();
        let guess = SensorGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.06, 0.0, 0.0] };
        let mut m = CalibModel::dh(&robot, &guess, true);
        m.add_effect(EffectBlock { kind: EffectKind::ThermalDrift, joint: Some(0), thermal: Some(ThermalDrive::WarmUp), range_m: None }, 3600.0);
        let k = m.effect_params(0).start;
        let mut x = m.nominal.clone();
        (x[k], x[k + 1]) = (0.01f64.to_radians(), 1200.0);
        assert_eq!(implausible_param(&m, &x, 0), None);
        // The case: 2.1e8 s and thousands of degrees; a time constant of seconds.
        for tau in [2.1e8, 20.0, -70.0] {
            x[k + 1] = tau;
            let why = implausible_param(&m, &x, 0).expect("not physical");
            assert!(why.contains("warm-up time constant"), "{why}");
        }
        (x[k], x[k + 1]) = (87.5, 1200.0);
        assert!(implausible_param(&m, &x, 0).expect("not physical").contains("beyond 30x its plausible size"));
    }

    #[test]
    fn a_kept_cause_that_ends_unphysical_is_named_in_a_warning() {
        use crate::calib::model::SensorGuess;
        let robot = Robot::irb120();
        let guess = SensorGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.06, 0.0, 0.0] };
        let mut m = CalibModel::dh(&robot, &guess, true);
        let (band, spring) = (EffectBlock::joint(EffectKind::Backlash, 2), EffectBlock::joint(EffectKind::JointCompliance, 1));
        m.add_effect(spring.clone(), 3600.0);
        m.add_effect(band.clone(), 3600.0);
        let mut x = m.nominal.clone();
        let (kc, kb) = (m.effect_params(0).start, m.effect_params(1).start);
        x[kc] = 40e-6;
        x[kb] = 0.005f64.to_radians();
        assert!(unphysical_causes(&m, &x, &[spring.clone(), band.clone()]).is_empty());
        x[kb] = -0.005f64.to_radians();
        let w = unphysical_causes(&m, &x, &[spring.clone(), band.clone()]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("backlash[j3] ends with an unphysical size") && w[0].contains("backlash.j3 = -5.0000 mdeg"), "{w:?}");
        x[kc] = -1e-6;
        assert_eq!(unphysical_causes(&m, &x, &[spring, band]).len(), 2);
    }

    #[test]
    fn a_leak_is_warned_only_beyond_the_held_out_mean_squares_sampling_error() {
        // 20 blocks of 20 rows sharing one error each, of RMS 0.22 mm against a 0.25 mm floor:
        // a realised shortfall that a few dozen shared errors give by chance.
        let (blocks, rows) = (20usize, 20usize);
        let groups: Vec<usize> = (0..blocks * rows).map(|i| i / rows).collect();
        let shared: Vec<f64> =
            groups.iter().map(|&b| 0.22 * std::f64::consts::SQRT_2 * ((b as f64) * 0.7).sin().signum() * ((b % 3) as f64 / 2.0 + 0.25)).collect();
        let floor = 1.1 * rms(&shared);
        assert!(leak_warning(&shared, 1, Some(&groups), floor, true).is_none());
        // The same rows as independent: 400 values well below the floor are a leak.
        assert!(leak_warning(&shared, 1, None, floor, true).is_some());
        // Every block predicted at half the floor, evenly: a leak whatever the blocks.
        let even: Vec<f64> = (0..blocks * rows).map(|i| if i % 2 == 0 { 0.5 * floor } else { -0.5 * floor }).collect();
        let w = leak_warning(&even, 1, Some(&groups), floor, true).expect("a leak");
        assert!(w.contains("split leaks") && w.contains("declare them in a block column"), "{w}");
    }
}
