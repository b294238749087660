//! The diagnosis as typed stages: the rows prepared and screened, the selection of causes, the
//! final fit of the model with its causes on every kept row, and the report.

use super::fit::*;
use super::options::*;
use super::report::*;
use super::screen::*;
use super::select::*;
use crate::calib::effects::inputs::time_span;
use crate::calib::effects::EffectBlock;
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::calib::pipeline::identify;
use crate::dataset::blocks::Structure;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::optim::{LevenbergMarquardt, NoObserver};
use crate::stats::rms;
use std::time::Instant;

/// Runs a diagnosis. `progress` receives a line per finished step.
///
/// When the screen against the geometric model flags rows that one candidate effect explains
/// (the screen of the model with it flags at most half as many, or as many with a tighter scale:
/// a backlash band seen by a precise instrument puts every row of its minority flank far off the
/// geometry), those rows stay in and the selection runs on them. Should the selection then keep
/// another effect first (a thermal drift of the whole arm where one joint's drift screened the
/// rows), the diagnosis runs again on that effect's screen if it too explains the flagged rows;
/// should it keep neither, on the rows the geometric screen kept.
///
/// Example: the whole job (the twin's data, this call, the others) runs as a doctest in [`crate::prelude`].
pub fn diagnose(data: &Dataset, opts: &DiagnoseOptions, progress: &dyn Fn(&str)) -> Result<(Diagnosis, crate::calib::pipeline::CalibResult)> {
    if opts.folds < 2 || opts.folds > 20 {
        return Err(Error::Invalid(format!("--folds must be in 2..=20, got {}", opts.folds)));
    }
    let (d, r, screened_with) = diagnose_screened(data, opts, progress, ScreenBy::BestEffect)?;
    // The exported model holds the named causes' blocks, in the order they were kept.
    let Some(b) = screened_with else { return Ok((d, r)) };
    // Blocks compared without their refinements (a thermal block's sensor lag).
    let holds = |r: &crate::calib::pipeline::CalibResult, b: &EffectBlock| r.model.effects.iter().any(|e| e.unrefined() == b.unrefined());
    if holds(&r, &b) {
        return Ok((d, r));
    }
    if let Some(f) = r.model.effects.first().map(EffectBlock::unrefined) {
        progress(&format!("{} explained the flagged rows but {} was kept first: the diagnosis again, on {}'s screen", b.label(), f.label(), f.label()));
        let (d2, r2, with) = diagnose_screened(data, opts, progress, ScreenBy::Effect(f.clone()))?;
        if with.as_ref().map(EffectBlock::unrefined) == Some(f.clone()) && holds(&r2, &f) {
            return Ok((d2, r2));
        }
    }
    progress(&format!("{} explained the flagged rows but was not kept: the diagnosis again, on the rows the geometric screen kept", b.label()));
    let (d, r, _) = diagnose_screened(data, opts, progress, ScreenBy::Geometry)?;
    Ok((d, r))
}

/// The rows of a diagnosis, prepared: the calibration's stages on every row (no split: the
/// diagnosis cross-validates), screened ([`screen_rows`]), with the faults of their outlier runs
/// and reading steps, their blocks and their noise model.
pub(super) struct Prepared {
    pub(super) base: CalibModel,
    pub(super) torque: Option<crate::calib::effects::inputs::TorqueModel>,
    /// Torques exist where there are inertial data (the nominal robot's or `--robot`'s).
    pub(super) has_torques: bool,
    /// Every row, with its inputs; readings in a reading step corrected by its offset.
    pub(super) all: Samples,
    pub(super) measurement: crate::measurement::Measurement,
    pub(super) fold_warning: Option<String>,
    /// The screen's kept rows (indices into `all`), outliers, their runs, the geometric fit on
    /// the kept rows, and the reading steps.
    pub(super) keep: Vec<usize>,
    pub(super) outliers: Vec<crate::calib::fit::robust::Outlier>,
    pub(super) outlier_runs: Vec<crate::calib::fit::robust::OutlierRun>,
    pub(super) x_base: Vec<f64>,
    pub(super) reading_steps: Vec<crate::calib::fit::robust::ReadingStep>,
    pub(super) screened_with: Option<EffectBlock>,
    pub(super) first_flagged: Vec<usize>,
    /// What went wrong in each run of outlier rows and each reading step.
    pub(super) run_faults: Vec<super::faults::RunFault>,
    pub(super) blocks: crate::dataset::blocks::Blocks,
    pub(super) acquisition: Structure,
    pub(super) noise_model: Option<NoiseModel>,
}

/// [`Prepared`] rows for [`diagnose_screened`].
pub(super) fn prepare_rows(data: &Dataset, opts: &DiagnoseOptions, progress: &dyn Fn(&str), by: ScreenBy) -> Result<Prepared> {
    // Every row needs its reading: a cable length, or a tracker's point (x, y, z).
    let measurement = crate::calib::pipeline::reading_measurement(data)?;
    let dim = measurement.dim();
    // The calibration's stages on every row (no split: the diagnosis cross-validates), with
    // every row's inputs; the diagnosis screens the rows itself, inputs included.
    let prepared =
        crate::calib::pipeline::prepare(data, &opts.baseline_options(), crate::calib::methods::SolverNeeds { row_inputs: true, equal_weights: false })?;
    let base = prepared.model;
    let torque = prepared.split.torque_model;
    // Torques exist where something loads the joints: link masses (the nominal robot's or
    // `--robot`'s inertial data), a payload or a cable's tension.
    // Rows with their own payload load the joints too.
    let has_torques = torque.as_ref().is_some_and(|t| t.carries_torque() || data.rows.iter().any(|r| r.payload_kg.is_some_and(|m| m > 0.0)));
    let mut all = prepared.split.train;
    let fold_warning = fold_rows_check(all.len(), dim, prepared.id.fixed_mask.iter().filter(|f| !**f).count(), opts)?;

    let (mut screen, screened_with, first_flagged) = screen_rows(&base, &all, data, opts, has_torques, &by, progress)?;
    // What went wrong in each run of outlier rows and each reading step, tested on the rows as
    // logged (see `faults`).
    let spans: Vec<(usize, usize)> =
        screen.runs.iter().map(|r| (r.first_row - 1, r.last_row - 1)).chain(screen.steps.iter().map(|s| (s.first_row - 1, s.last_row - 1))).collect();
    let run_faults = super::faults::explain_runs(&base, &screen.x, &all, &spans, screen.scale_mm);
    // Readings in a reading step are taken corrected by its offset from here on.
    all.y = std::mem::take(&mut screen.corrected.y);
    for s in &screen.steps {
        progress(&format!("reading step: rows {}-{} read {:+.2} ± {:.2} mm off; corrected and kept", s.first_row, s.last_row, s.offset_mm, s.std_mm));
    }
    if !screen.outliers.is_empty() {
        progress(&format!("{} outlier rows kept out of the fit: {:?}", screen.outliers.len(), screen.outliers.iter().map(|o| o.row).collect::<Vec<_>>()));
    }
    let (blocks, acquisition, noise_model) = acquisition_structure(data, opts, &base, &screen, &mut all, progress);
    let (keep, outliers, outlier_runs, x_base, reading_steps) = (screen.keep, screen.outliers, screen.runs, screen.x, screen.steps);
    Ok(Prepared {
        base,
        torque,
        has_torques,
        all,
        measurement,
        fold_warning,
        keep,
        outliers,
        outlier_runs,
        x_base,
        reading_steps,
        screened_with,
        first_flagged,
        run_faults,
        blocks,
        acquisition,
        noise_model,
    })
}

/// Which folds the diagnosis judges on: blocked ones, unless the geometric model's blocked-fold
/// held-out RMSE is above [`EXTRAPOLATION_FACTOR`] times its interleaved one (then blocks cover
/// different parts of the joint space and blocked folds measure extrapolation; `ctx` and the
/// baseline's held-out residuals switch to interleaved folds). Returns the kind, why, and both
/// RMSEs (mm).
pub(super) fn judge_folds(ctx: &mut Ctx, baseline: &mut Fitted) -> (&'static str, String, f64, f64) {
    let other_oof = ctx.heldout(&baseline.model, &baseline.x, &baseline.fixed, &ctx.other_folds);
    let (rmse_blocked, rmse_interleaved) = (rms(&baseline.oof), rms(&other_oof));
    if rmse_blocked > EXTRAPOLATION_FACTOR * rmse_interleaved {
        std::mem::swap(&mut ctx.folds, &mut ctx.other_folds);
        baseline.oof = other_oof;
        let why = format!(
            "the geometric model's blocked-fold held-out RMSE ({rmse_blocked:.4} mm) is above {EXTRAPOLATION_FACTOR}x its interleaved one \
             ({rmse_interleaved:.4} mm): blocks of acquisition order cover different parts of the joint space, so blocked folds measure extrapolation"
        );
        ("interleaved", why, rmse_blocked, rmse_interleaved)
    } else {
        let why = format!("blocked and interleaved held-out RMSE of the geometric model agree ({rmse_blocked:.4} / {rmse_interleaved:.4} mm): time-dependent effects must extrapolate across blocks");
        ("blocked", why, rmse_blocked, rmse_interleaved)
    }
}

/// The screen judged every row against the geometric model, before any cause was known: a row
/// that a cause pushes far from it looks like a glitch. Rows the model with its causes
/// (`current`) predicts within the same threshold (around the kept rows' residuals) are
/// explained, not outliers: they leave `outliers` (and their `runs`) and rejoin the rows of the final fit. Returns
/// the kept samples, their rows, their indices, and the rows explained (0-based).
#[allow(clippy::type_complexity)]
pub(super) fn rejoin_explained(
    current: &Fitted,
    all: &Samples,
    data: &Dataset,
    (kept, kept_rows, keep): (Samples, Dataset, Vec<usize>),
    (outliers, runs): (&mut Vec<crate::calib::fit::robust::Outlier>, &mut Vec<crate::calib::fit::robust::OutlierRun>),
    outlier_k: f64,
    progress: &dyn Fn(&str),
) -> (Samples, Dataset, Vec<usize>, Vec<usize>) {
    let explained = explained_by_causes(current, all, current.model.measurement.dim(), &keep, outliers, outlier_k);
    if explained.is_empty() {
        return (kept, kept_rows, keep, explained);
    }
    progress(&format!(
        "{} rows first taken for outliers are explained by the causes: {:?}",
        explained.len(),
        explained.iter().map(|i| i + 1).collect::<Vec<_>>()
    ));
    outliers.retain(|o| !explained.contains(&(o.row - 1)));
    *runs = crate::calib::fit::robust::runs(outliers);
    let keep: Vec<usize> = (0..all.len()).filter(|i| !outliers.iter().any(|o| o.row == i + 1)).collect();
    let rows = data.subset(&keep);
    (all.subset(&keep), rows, keep, explained)
}

/// The final model: `current` refitted on every kept row (selection and confirmation, whitened
/// by their noise model); its sizes, its residual and the --result file all come from this one
/// fit. Each cause's uncertainty counts the rows its blocks share (`groups`).
pub(super) struct FinalFit {
    pub(super) id: crate::calib::fit::identify::Identifiability,
    pub(super) x: Vec<f64>,
    pub(super) train_rmse_mm: f64,
    pub(super) covs: Covariances,
}

pub(super) fn final_fit(current: &Fitted, kept: &Samples, groups: Option<&[usize]>, rank_tol: f64) -> FinalFit {
    let fit = ReadingFit { model: &current.model, data: kept };
    let id = identify(&fit, &current.x, rank_tol);
    let x = LevenbergMarquardt::refit().minimize(&fit, &current.x, &id.fixed_mask, &mut NoObserver).x;
    let train_rmse_mm = rms(&ReadingFit { model: &current.model, data: &kept.unweighted() }.residuals_mm(&x));
    let covs = Covariances::of(&fit, &x, &id.fixed_mask, groups);
    FinalFit { id, x, train_rmse_mm, covs }
}

/// What a row reads, for the report: empty for one value, else the instrument and its columns.
pub(super) fn reading_note(measurement: crate::measurement::Measurement) -> String {
    if measurement.dim() > 1 {
        format!("each row reads a {} ({}): every RMSE is per coordinate", measurement.def().describe(), measurement.def().columns().join(", "))
    } else {
        String::new()
    }
}

/// A diagnosis whose rows are screened as `by` says ([`screen_rows`]), with the effect whose
/// screen it kept.
pub(super) fn diagnose_screened(
    data: &Dataset,
    opts: &DiagnoseOptions,
    progress: &dyn Fn(&str),
    by: ScreenBy,
) -> Result<(Diagnosis, crate::calib::pipeline::CalibResult, Option<EffectBlock>)> {
    let t0 = Instant::now();
    let mut prepared = prepare_rows(data, opts, progress, by)?;
    let screened_with = prepared.screened_with.take();
    let selected = select_stage(data, opts, progress, &prepared)?;
    let (diagnosis, result) = final_stage(data, opts, progress, prepared, selected, t0)?;
    Ok((diagnosis, result, screened_with))
}

/// What the selection stage leaves: the selection and confirmation rows, the baseline and the
/// folds it is judged on, the chain of causes kept (after confirmation, the physical-size and
/// floor checks), and what each step said.
pub(super) struct Selected {
    pub(super) kept: Samples,
    pub(super) kept_rows: Dataset,
    pub(super) ctx: Ctx,
    pub(super) confirmation: Samples,
    pub(super) few_blocks: Option<String>,
    pub(super) baseline: Fitted,
    pub(super) judged_on: &'static str,
    pub(super) judged_on_reason: String,
    pub(super) rmse_blocked: f64,
    pub(super) rmse_interleaved: f64,
    pub(super) base_in: Vec<f64>,
    pub(super) evidence: Vec<Evidence>,
    pub(super) steps: Vec<Step>,
    pub(super) found: Vec<Found>,
    pub(super) current: Fitted,
    pub(super) unconfirmed: Vec<String>,
    pub(super) not_physical: Vec<String>,
    pub(super) below_floor: Vec<String>,
    /// Refinements hard to tell from something else, and what was made of them (see [`Selection`]).
    pub(super) questioned: Vec<String>,
    pub(super) other_rmse: Vec<f64>,
    pub(super) conf_rmse: Vec<f64>,
}

/// The selection stage on the prepared rows: folds over whole blocks, the geometric baseline,
/// the forward selection of causes, their confirmation on rows it never saw, and the checks
/// that drop causes of no physical size or below the data's floor.
pub(super) fn select_stage(data: &Dataset, opts: &DiagnoseOptions, progress: &dyn Fn(&str), p: &Prepared) -> Result<Selected> {
    let (base, keep, blocks) = (&p.base, &p.keep, &p.blocks);
    let kept = p.all.subset(keep);
    let kept_rows = data.subset(keep);
    let (mut ctx, confirmation, few_blocks) = Ctx::over_blocks(&kept, keep, blocks, opts);
    let mut baseline = ctx.evaluate(base.clone(), &p.x_base);
    let (judged_on, judged_on_reason, rmse_blocked, rmse_interleaved) = judge_folds(&mut ctx, &mut baseline);
    let base_in = ReadingFit { model: &baseline.model, data: &ctx.data.unweighted() }.residuals_mm(&baseline.x);
    let evidence = evidence(&ctx.data, &base_in, p.has_torques, base.measurement.def().columns());
    progress(&format!(
        "geometric baseline: held-out RMSE {rmse_blocked:.4} mm (blocked folds), {rmse_interleaved:.4} mm (interleaved); judged on {judged_on} folds"
    ));
    let pool = candidate_pool(&kept_rows, &kept.q, opts, p.has_torques)?;
    let Selection { chain, steps, mut found, questioned } = select_causes(&ctx, &pool, &baseline, opts, time_span(&kept_rows), progress);
    let (conf_rmse, mut confirmed, unconfirmed) = confirm_causes(&chain, &found, &confirmation, progress);
    let kept_groups = blocks.any_shared().then(|| blocks.ids_of(keep));
    // With the noise model re-estimated at each model, as the final fit will be: at the
    // geometric model's the causes' own signal counts as reading noise, and a slow cause fitted
    // with that whitening absorbs the sweeps' shared logging error (see `final_whitening`).
    let rewhitened = |m: &Fitted| final_whitening(kept.clone(), p.noise_model.clone(), &p.all, m, data, blocks, keep).0;
    let not_physical = drop_not_physical(&chain, &found, &rewhitened, kept_groups.as_deref(), opts, &mut confirmed, progress);
    let repeat = crate::calib::pipeline::reading_repeatability(&kept_rows);
    let floor = crate::calib::pipeline::floor_stage(base, &baseline.x, &kept_rows, &kept, &opts.floor, repeat.as_ref());
    let below_floor = drop_below_floor(&found, &chain, &floor, ctx.groups.as_deref(), &mut confirmed, progress);
    found.truncate(confirmed);
    let current = chain[confirmed].clone();
    let other_rmse: Vec<f64> = chain[..=confirmed].iter().map(|f| rms(&ctx.heldout(&f.model, &f.x, &f.fixed, &ctx.other_folds))).collect();
    Ok(Selected {
        kept,
        kept_rows,
        ctx,
        confirmation,
        few_blocks,
        baseline,
        judged_on,
        judged_on_reason,
        rmse_blocked,
        rmse_interleaved,
        base_in,
        evidence,
        steps,
        found,
        current,
        unconfirmed,
        not_physical,
        below_floor,
        questioned,
        other_rmse,
        conf_rmse,
    })
}

impl Selected {
    /// The lines of the causes the checks left out of the model, and of the refinements
    /// questioned.
    fn dropped(&self) -> impl Iterator<Item = String> + '_ {
        self.not_physical.iter().chain(&self.below_floor).chain(&self.questioned).cloned()
    }
}

/// The final stage: rows the causes explain rejoin, the model with its causes is refitted on
/// every kept row with its own noise model, and the diagnosis and its result file are written
/// from that one fit.
pub(super) fn final_stage(
    data: &Dataset,
    opts: &DiagnoseOptions,
    progress: &dyn Fn(&str),
    p: Prepared,
    sel: Selected,
    t0: Instant,
) -> Result<(Diagnosis, crate::calib::pipeline::CalibResult)> {
    let Prepared {
        base,
        torque,
        all,
        measurement,
        fold_warning,
        keep,
        mut outliers,
        mut outlier_runs,
        x_base,
        reading_steps,
        first_flagged,
        run_faults,
        blocks,
        acquisition,
        noise_model,
        ..
    } = p;
    let dropped: Vec<String> = sel.dropped().collect();
    let Selected { kept, kept_rows, ctx, confirmation, few_blocks, baseline, current, found, .. } = sel;
    let shared = blocks.any_shared();
    // Rows first taken for outliers that the causes explain rejoin the final fit.
    let (kept, kept_rows, final_keep, explained) =
        rejoin_explained(&current, &all, data, (kept, kept_rows, keep), (&mut outliers, &mut outlier_runs), opts.screen.outlier_k, progress);
    let explained_rows = sorted_rows(explained.iter().map(|i| i + 1).chain(first_flagged));
    let groups = shared.then(|| blocks.ids_of(&final_keep));
    let (kept, noise_model) = final_whitening(kept, noise_model, &all, &current, data, &blocks, &final_keep);
    let FinalFit { id: final_id, x: final_x, train_rmse_mm: final_train_rmse_mm, covs } = final_fit(&current, &kept, groups.as_deref(), opts.rank_tol);
    let unphysical = unphysical_causes(&current.model, &final_x, &found.iter().map(|f| f.block.clone()).collect::<Vec<EffectBlock>>());
    let set_up = [fold_warning, crate::calib::effects::inputs::payload_warning(data, &opts.loads.joints), few_blocks].into_iter().flatten();
    let mut warnings: Vec<String> = set_up.chain(dropped).chain(unphysical).collect();
    let causes = cause_reports(&found, &current.model, &covs, &final_x, &sel.other_rmse, &sel.conf_rmse);
    warnings.extend(attributions(&found, &causes).into_iter().chain(losing_forward(&found)));
    let fitted = crate::calib::pipeline::FittedModel {
        model: current.model.clone(),
        x0: base_start(&current.model, &x_base),
        x: final_x,
        id: final_id,
        torque_model: torque,
    };
    // The data's own floor: repeatability and logging resolutions, never the fit's residual.
    let result = crate::calib::pipeline::result_of_fit(&kept_rows, &kept, fitted, opts.seed, opts.floor.angle_step_deg, opts.floor.instrument_accuracy_mm)?;
    let noise_floor = result.evaluation.noise_floor.clone().expect("result_of_fit sets the floor");
    let (noise_floor_mm, noise_floor_source, current_oof) = (noise_floor.total_mm, floor_source_text(&noise_floor), rms(&current.oof));
    warnings.extend(leak_on_positions(&current.oof, measurement, ctx.groups.as_deref(), &noise_floor, shared));
    let (remainder, unexplained) = what_remains(&current, (&kept, &result.x), groups.as_deref(), &noise_floor, &ctx.data, data, (&outliers, &run_faults));
    let (position_rms, judged_floor) = ((!noise_floor.by_group.is_empty()).then(|| rms(&measurement.group_values(&current.oof, 0))), noise_floor.of_group(0));
    let diagnosis = Diagnosis {
        schema_version: crate::output::SCHEMA_VERSION,
        warnings,
        acquisition,
        noise_model,
        design_effect: baseline.deff,
        not_physical: sel.not_physical,
        below_floor: sel.below_floor,
        twincal_version: env!("CARGO_PKG_VERSION").into(),
        data: data.source.clone(),
        rows: data.rows.len(),
        reading: reading_note(measurement),
        setup: None,
        outliers,
        outlier_runs,
        explained_by_causes: explained_rows,
        reading_steps,
        run_faults,
        noise_floor_mm,
        noise_floor_source,
        noise_floor,
        judged_on: sel.judged_on.into(),
        judged_on_reason: sel.judged_on_reason,
        selection_rows: ctx.data.len(),
        confirmation_rows: confirmation.len(),
        unconfirmed: sel.unconfirmed,
        baseline: baseline_report(&base.name, &baseline, &sel.base_in, sel.rmse_blocked, sel.rmse_interleaved),
        evidence: sel.evidence,
        steps: sel.steps,
        unexplained,
        remainder,
        verdict: String::new(),
        causes,
        final_heldout_rmse_mm: current_oof,
        final_heldout_rmse_position_mm: position_rms,
        final_train_rmse_mm,
        floor_share_of_remaining: (judged_floor / position_rms.unwrap_or(current_oof)).powi(2).min(1.0),
        unseen: None,
        comparison: compare_with_rbf(&ctx, &baseline, &current, opts.seed),
        seconds: t0.elapsed().as_secs_f64(),
        effects_option: effects_option(&current.model),
        no_sensor_lag: without_sensor_lag(&current.model),
    };
    Ok((Diagnosis { verdict: verdict_with(&diagnosis.causes, diagnosis.unexplained.is_some()), ..diagnosis }, result))
}

/// The verdict: the causes ([`verdict_of`]), and `unexplained` where the rest stays far above
/// the floor.
fn verdict_with(causes: &[Cause], unexplained: bool) -> String {
    match (unexplained, causes.is_empty()) {
        (false, _) => verdict_of(causes),
        (true, true) => "unexplained".into(),
        (true, false) => format!("{} + unexplained", verdict_of(causes)),
    }
}

/// What remains of the final model (`current`'s blocks at `x`, fitted on `kept`, whose blocks
/// are `groups`) characterised ([`super::remainder`]), and what is unexplained: a structured
/// remainder above the floor, a white one far above what the instrument states (`current`'s
/// held-out residuals on the selection rows `selection`), outlier rows no fault explains.
fn what_remains(
    current: &Fitted,
    (kept, x): (&Samples, &[f64]),
    groups: Option<&[usize]>,
    floor: &crate::calib::fit::floor::NoiseFloor,
    selection: &Samples,
    data: &Dataset,
    (outliers, faults): (&[crate::calib::fit::robust::Outlier], &[super::faults::RunFault]),
) -> (Option<super::remainder::Remainder>, Option<String>) {
    // The final model's residual on every kept row it was fitted to (blocked folds' held-out
    // residuals would hold the extrapolation across blocks as well).
    let res = ReadingFit { model: &current.model, data: &kept.unweighted() }.residuals_mm(x);
    let remainder = super::remainder::characterise(&res, kept, current.model.measurement, groups, floor);
    let far = unexplained_note(current, selection, floor, data);
    let unexplained = join_notes(unexplained_of(remainder.as_ref(), far, floor.of_group(0)), unexplained_outliers(outliers, faults, data.rows.len()));
    (remainder, unexplained)
}

/// Row numbers in ascending order.
fn sorted_rows(rows: impl Iterator<Item = usize>) -> Vec<usize> {
    let mut v: Vec<usize> = rows.collect();
    v.sort_unstable();
    v
}

/// A warning for each kept cause that gains on the held-out folds but loses on the rows judged
/// forward in time (where those rows are predicted about as well as the folds, within
/// [`EXTRAPOLATION_FACTOR`]).
fn losing_forward(found: &[Found]) -> Vec<String> {
    found
        .iter()
        .filter_map(|f| {
            let (b, a) = f.forward?;
            // Forward stretches far worse than the folds measure extrapolation to another part
            // of the workspace, not what holds tomorrow.
            (a >= b && b <= EXTRAPOLATION_FACTOR * f.before).then(|| {
                format!(
                    "{} gains on the held-out folds ({:.4} -> {:.4} mm) but not on the later rows of each run, each predicted from the rows before them ({b:.4} -> {a:.4} mm): whether it holds tomorrow is in doubt",
                    f.block.label(),
                    f.before,
                    f.after
                )
            })
        })
        .collect()
}

/// A structured remainder is unexplained only where it stays above this many times the data's
/// floor (every source, the logging steps included): within it, structure is the floor's own.
pub const STRUCTURE_ABOVE_FLOOR: f64 = 1.2;

/// Outlier rows beyond this share of the rows that neither the causes nor a fault of their run
/// explain are unexplained: the model leaves a part of the data out, not a glitch.
pub const OUTLIER_SHARE: f64 = 0.05;

/// The outlier rows kept out of the fits that no fault of their run explains (a run named
/// `unexplained`, or a row alone), where they are more than [`OUTLIER_SHARE`] of `rows`.
fn unexplained_outliers(outliers: &[crate::calib::fit::robust::Outlier], faults: &[super::faults::RunFault], rows: usize) -> Option<String> {
    let named = |row: usize| faults.iter().any(|f| f.cause != super::faults::FaultKind::Unexplained && (f.first_row..=f.last_row).contains(&row));
    let left = outliers.iter().filter(|o| !named(o.row)).count();
    (left as f64 > OUTLIER_SHARE * rows as f64).then(|| {
        format!(
            "{left} rows ({:.0} %) were kept out as outliers that no cause named and no fault of their run explains: the model leaves a part of the data out",
            100.0 * left as f64 / rows.max(1) as f64
        )
    })
}

/// Two notes as one (either may be absent).
fn join_notes(a: Option<String>, b: Option<String>) -> Option<String> {
    match (a, b) {
        (Some(a), Some(b)) => Some(format!("{a}; {b}")),
        (a, b) => a.or(b),
    }
}

/// What is unexplained, given what remains ([`super::remainder`]) and the note of a remainder far
/// above a floor the data measure (`far`, [`unexplained_note`]): where the remainder holds
/// structure above [`STRUCTURE_ABOVE_FLOOR`] times the data's floor `floor_mm`, that structure
/// (beside `far`); where it is white, `far` only when its apparent noise
/// exceeds [`UNEXPLAINED_RATIO`] times what the instrument states; where it could not be
/// characterised, `far`.
pub(super) fn unexplained_of(remainder: Option<&super::remainder::Remainder>, far: Option<String>, floor_mm: f64) -> Option<String> {
    let Some(r) = remainder else { return far };
    // Structure within the data's own floor (a sweep's shared rounding follows the joints that
    // carry it) is no model's to explain.
    if !r.white && r.apparent_position_mm > STRUCTURE_ABOVE_FLOOR * floor_mm {
        let s: Vec<String> = r.structure().take(4).map(|t| format!("{} [{}] {:.0} % of its mean square", t.against, t.value, 100.0 * t.share)).collect();
        let what = format!(
            "what remains ({:.4} mm RMS over the positions) is not white: it follows {}, which no cause named explains",
            r.apparent_position_mm,
            s.join(", ")
        );
        return Some(far.map_or(what.clone(), |f| format!("{f}; {what}")));
    }
    far.filter(|_| r.noise_ratio().is_some_and(|k| k > UNEXPLAINED_RATIO))
        .map(|f| format!("{f}; what remains is white, at {:.2}x the noise the instrument states", r.noise_ratio().unwrap_or(f64::NAN)))
}

/// The final fit's held-out residual where it stays above [`UNEXPLAINED_RATIO`] times a floor the
/// data measure: how far, and where it concentrates. The position values alone are compared
/// with the floor (a 6-D pose's axes have a noise of their own).
pub(super) fn unexplained_note(current: &Fitted, rows: &Samples, floor: &crate::calib::fit::floor::NoiseFloor, data: &Dataset) -> Option<String> {
    let measured_floor = floor.sources.iter().filter(|s| s.source.measured()).map(|s| s.rms_mm * s.rms_mm).sum::<f64>().sqrt();
    let d = rows.dim;
    if measured_floor <= 0.0 || current.oof.len() != rows.len() * d {
        return None;
    }
    let m = current.model.measurement;
    let groups = m.def().value_groups();
    let position = |c: usize| groups.get(c).copied().unwrap_or(0) == 0;
    let rms_of = |idx: &mut dyn Iterator<Item = usize>| {
        let v: Vec<f64> = idx.flat_map(|i| (0..d).filter(|c| position(*c)).map(move |c| current.oof[i * d + c])).collect();
        (!v.is_empty()).then(|| rms(&v))
    };
    let all = rms_of(&mut (0..rows.len()))?;
    // The positions' own floor where a reading holds other kinds of values too.
    let floor_mm = match floor.by_group.first() {
        Some(g) if g.measured => g.total_mm,
        _ => floor.total_mm.max(measured_floor),
    };
    if all <= UNEXPLAINED_RATIO * floor_mm {
        return None;
    }
    let mut at = Vec::new();
    let stations = data.stations();
    if !stations.is_single() {
        let per: Vec<String> = (0..stations.len())
            .filter_map(|s| rms_of(&mut (0..rows.len()).filter(|i| rows.inputs[*i].station == s)).map(|v| format!("station {} {v:.4} mm", stations.labels[s])))
            .collect();
        at.push(format!("by station: {}", per.join(", ")));
    }
    if rows.inputs.iter().all(|i| i.t_s.is_some()) && rows.len() >= 30 {
        let mut order: Vec<usize> = (0..rows.len()).collect();
        order.sort_by(|a, b| rows.inputs[*a].t_s.partial_cmp(&rows.inputs[*b].t_s).unwrap_or(std::cmp::Ordering::Equal));
        let thirds: Vec<String> = order.chunks(order.len().div_ceil(3)).filter_map(|c| rms_of(&mut c.iter().copied())).map(|v| format!("{v:.4}")).collect();
        at.push(format!("by time (first, middle, last third): {} mm", thirds.join(", ")));
    }
    let what = if m.n_value_groups() > 1 { "of the positions " } else { "" };
    Some(format!(
        "the final held-out RMSE {what}{all:.4} mm is {:.1}x the data's floor ({floor_mm:.4} mm: {}); neither the causes named nor the set-up's stations explain the rest{}",
        all / floor_mm,
        floor.sources.iter().map(|s| s.source.name()).collect::<Vec<_>>().join(", "),
        if at.is_empty() { String::new() } else { format!("; it concentrates {}", at.join("; ")) }
    ))
}

/// [`leak_warning`] on the values the floor describes: a 6-D pose's positions against the
/// positions' floor (its axes have a noise of their own, smaller, and nine values' RMSE set
/// against the positions' floor would always look short of it), else every value.
fn leak_on_positions(
    oof: &[f64],
    m: crate::measurement::Measurement,
    groups: Option<&[usize]>,
    floor: &crate::calib::fit::floor::NoiseFloor,
    shared: bool,
) -> Option<String> {
    if floor.by_group.is_empty() {
        return leak_warning(oof, m.dim(), groups, floor.total_mm, shared);
    }
    let positions = m.group_values(oof, 0);
    let per_row = positions.len() / (oof.len() / m.dim()).max(1);
    leak_warning(&positions, per_row, groups, floor.of_group(0), shared)
}

/// The geometric baseline's report: its model's name and its held-out and training RMSE.
fn baseline_report(model: &str, baseline: &Fitted, base_in: &[f64], blocked: f64, interleaved: f64) -> Baseline {
    Baseline {
        model: model.into(),
        heldout_rmse_mm: rms(&baseline.oof),
        heldout_rmse_blocked_mm: blocked,
        heldout_rmse_interleaved_mm: interleaved,
        train_rmse_mm: rms(base_in),
    }
}

/// Where the floor comes from, as one line: each source with its RMS, and a note when it is a
/// lower bound (no repeated configurations).
pub(super) fn floor_source_text(floor: &crate::calib::fit::floor::NoiseFloor) -> String {
    let mut text: Vec<String> = floor.sources.iter().map(|s| format!("{} {:.4} mm: {}", s.source, s.rms_mm, s.detail)).collect();
    if !floor.is_measured() {
        text.push("no repeated configurations: the reading's repeatability is unknown, so this is a lower bound".into());
    }
    text.join("; ")
}

/// Whose drift each named cause can be where it is not the arm's own
/// ([`Effect::attribution`](crate::calib::effects::Effect::attribution)).
fn attributions(found: &[Found], causes: &[Cause]) -> Vec<String> {
    found
        .iter()
        .zip(causes)
        .filter_map(|(Found { block: b, .. }, c)| {
            let size = crate::calib::effects::Size { quantity: c.quantity.clone(), value: c.magnitude, unit: c.unit.clone(), uncertainty: c.uncertainty };
            b.kind.def().attribution(b, &size)
        })
        .collect()
}

/// The `--effects` value that calibrates `model`'s effect blocks (`backlash:2,thermal`).
pub(super) fn effects_option(model: &CalibModel) -> String {
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

/// Whether `model` holds a temperature-driven thermal block that fits no sensor lag (calibrate
/// then needs `--no-sensor-lag` to fit the same model on rows with a time column).
pub(super) fn without_sensor_lag(model: &CalibModel) -> bool {
    model.effects.iter().any(|e| matches!(e.thermal, Some(crate::calib::effects::ThermalDrive::Temperature { sensor_lag: false, .. })))
}

/// The start of the final model's parameters for its report: the baseline's geometry with every
/// effect at "no effect".
pub(super) fn base_start(model: &CalibModel, x_base: &[f64]) -> Vec<f64> {
    let mut x = model.nominal.clone();
    x[..x_base.len()].copy_from_slice(x_base);
    x
}
