//! The forward selection of causes, their confirmation on rows it never saw, the checks that
//! drop causes of no physical size or below the data's floor, and the causes' reports.

use super::fit::*;
use super::options::*;
use super::report::*;
use crate::calib::effects::{EffectBlock, Size};
use crate::calib::fit::floor::{NoiseFloor, ValueKind};
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::measurement::Measurement;
use crate::stats::rms;
use rayon::prelude::*;
use std::time::Instant;

/// The most a cause's gain on the held-out rows must reach, as a share of the data's floor
/// (mm RMS): √(before² − after²) of the held-out RMSE. Where the rows' errors are shared (a
/// sweep's rounding, few independent blocks) the floor's own sampling error over the held-out
/// rows is as large as the floor, and this share rules (at half the floor, effects hidden at
/// 0.13–0.19× the floor in sweeps logged at 0.1° and 0.01° were named: on blocked folds their
/// gains came out at 0.51–0.67× the floor, while effects at 1.5× and more gained 1.4× and more).
pub const BELOW_FLOOR_SHARE: f64 = 1.0;

/// How many standard errors of the floor's mean square over the held-out values a cause's
/// gain in mean square must reach (see [`gain_threshold`]).
pub const FLOOR_SAMPLING_Z: f64 = 3.0;

/// The gain (mm RMS, √(before² − after²) of the held-out RMSE) a cause must reach on `n`
/// held-out values with design effect `deff` (how many times the rows' shared errors inflate
/// the variance of a mean square over them) where the floor is `floor_mm`: the floor's mean
/// square varies by floor²·√(2·deff / n) from one set of held-out values to another, so a gain
/// in mean square of [`FLOOR_SAMPLING_Z`] such errors is beyond what the floor's sampling
/// gives; never more than [`BELOW_FLOOR_SHARE`] of the floor. On 300 independent tracker rows
/// (900 values) that is 0.38 of the floor: an effect of half one row's noise is named, while a
/// sweep's shared rounding (20 blocks of 20 rows, design effect near 20) still needs nearly the
/// whole floor.
pub fn gain_threshold(floor_mm: f64, n: usize, deff: f64) -> f64 {
    let share2 = (FLOOR_SAMPLING_Z * (2.0 * deff.max(1.0) / n.max(1) as f64).sqrt()).min(BELOW_FLOOR_SHARE * BELOW_FLOOR_SHARE);
    floor_mm * share2.sqrt()
}

/// A cause's gain on one kind of held-out value against that kind's floor.
struct GroupGain {
    /// `None`: every value of the reading.
    group: Option<ValueKind>,
    before: f64,
    after: f64,
    gain: f64,
    threshold: f64,
}

/// The gain of the model `after` over `before` (held-out residuals of readings of kind `m`)
/// on each kind of value the floor judges: the whole reading, or a pose's position and (where
/// repeats measure it) its orientation apart, each against its own floor and its own sampling
/// error (`groups`: the held-out rows' blocks).
fn group_gains(before: &[f64], after: &[f64], m: Measurement, floor: &NoiseFloor, groups: Option<&[usize]>) -> Vec<GroupGain> {
    let n_rows = before.len() / m.dim().max(1);
    (0..floor.by_group.len().max(1))
        .filter(|&g| floor.by_group.get(g).is_none_or(|f| g == 0 || f.measured))
        .map(|g| {
            let (b, a) = (m.group_values(before, g), m.group_values(after, g));
            let deff = groups.map_or(1.0, |gr| crate::stats::design_effect(&a, a.len() / n_rows.max(1), gr));
            let (before, after) = (rms(&b), rms(&a));
            GroupGain {
                group: floor.by_group.get(g).map(|f| f.group),
                before,
                after,
                gain: (before * before - after * after).max(0.0).sqrt(),
                threshold: gain_threshold(floor.of_group(g), a.len(), deff),
            }
        })
        .collect()
}

/// Every kept cause (`found`; `chain[k + 1]` the model with the first k + 1, whose held-out
/// residuals are `oof`; the first `confirmed` of them) whose gain on the held-out rows reaches
/// [`gain_threshold`] of the data's floor on some kind of value: the first that does not ends
/// the list, like an unconfirmed one (`confirmed` is lowered). One line per cause left out,
/// with its figures.
pub(super) fn drop_below_floor(
    found: &[Found],
    chain: &[Fitted],
    floor: &NoiseFloor,
    groups: Option<&[usize]>,
    confirmed: &mut usize,
    progress: &dyn Fn(&str),
) -> Vec<String> {
    let m = chain[0].model.measurement;
    let gains: Vec<Vec<GroupGain>> = (0..*confirmed).map(|k| group_gains(&chain[k].oof, &chain[k + 1].oof, m, floor, groups)).collect();
    let Some(k) = gains.iter().position(|g| !g.iter().any(|g| g.gain >= g.threshold)) else {
        return Vec::new();
    };
    let notes: Vec<String> = (k..*confirmed)
        .map(|i| {
            let parts: Vec<String> = gains[i]
                .iter()
                .map(|g| {
                    let of = g.group.map_or(String::new(), |k| format!(" of the {}", k.name()));
                    format!(
                        "it explains {:.4} mm RMS{of} ({:.4} -> {:.4} mm), below the {:.4} mm the floor's sampling allows",
                        g.gain, g.before, g.after, g.threshold
                    )
                })
                .collect();
            format!("{} left out of the model: on the held-out rows {} (the data's floor {:.4} mm)", found[i].block.label(), parts.join("; "), floor.total_mm)
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
pub(super) fn drop_not_physical(
    chain: &[Fitted],
    found: &[Found],
    kept: &dyn Fn(&Fitted) -> Samples,
    groups: Option<&[usize]>,
    opts: &DiagnoseOptions,
    confirmed: &mut usize,
    progress: &dyn Fn(&str),
) -> Vec<String> {
    let mut notes = Vec::new();
    while *confirmed > 0 {
        let m = &chain[*confirmed];
        let kept = kept(m);
        let (x, fixed) = refit(&m.model, &kept, &m.x, opts.rank_tol);
        let covs = Covariances::of(&ReadingFit { model: &m.model, data: &kept }, &x, &fixed, groups);
        let Some((k, why)) = found[..*confirmed].iter().enumerate().find_map(|(k, f)| {
            let b = m.model.effects.iter().position(|e| e == &f.block)?;
            let size = covs.size(&f.block, &x, m.model.effect_params(b));
            let weak = (size.value.abs() < opts.min_size_sigmas * size.uncertainty)
                .then(|| format!("its size {:.4} ± {:.4} {} is under {} of its uncertainties", size.value, size.uncertainty, size.unit, opts.min_size_sigmas));
            implausible_param(&m.model, &x, b).or(weak).map(|w| (k, w))
        }) else {
            break;
        };
        let dropped: Vec<String> = found[k..*confirmed].iter().map(|f| f.block.label()).collect();
        progress(&format!("not physical on every kept row: {why}; left out: {}", dropped.join(", ")));
        notes.push(format!("{} left out of the model: fitted on every kept row, {why}", dropped.join(", ")));
        *confirmed = k;
    }
    notes
}

/// A cause kept by the forward selection.
#[derive(Clone, Debug)]
pub(super) struct Found {
    pub(super) block: EffectBlock,
    /// Held-out RMSE before and after it on the folds selection judges on, mm.
    pub(super) before: f64,
    pub(super) after: f64,
    /// Its p-value.
    pub(super) p: f64,
    /// For a cause that varies with time: the RMSE of the rows judged forward in time before
    /// and after it, mm ([`super::forward`]), on which it was chosen among its rivals.
    pub(super) forward: Option<(f64, f64)>,
}

/// The selection's outcome: the fitted model after each kept cause (the baseline first), every
/// step's candidates, and the causes kept in order.
pub(super) struct Selection {
    pub(super) chain: Vec<Fitted>,
    pub(super) steps: Vec<Step>,
    pub(super) found: Vec<Found>,
    /// Refinements hard to tell from something else (a sensor lag longer than a third of a
    /// run), one line each saying whether the later rows kept them.
    pub(super) questioned: Vec<String>,
}

/// Forward selection over the candidate `pool`: at each step the candidate whose model predicts
/// the held-out folds best is kept if it is plausible, has the sign physics allows, is sized
/// beyond `opts.min_size_sigmas`, passes the Bonferroni-corrected gain test and gains at least
/// `opts.min_gain`; the first step with none ends the selection. A cause that varies with time
/// must also gain that much on the rows judged forward in time ([`super::forward`]); where one
/// wins the step, the forms of such causes compete on that forward gain.
pub(super) fn select_causes(ctx: &Ctx, pool: &[EffectBlock], baseline: &Fitted, opts: &DiagnoseOptions, span: f64, progress: &dyn Fn(&str)) -> Selection {
    let mut current = baseline.clone();
    let mut chain = vec![baseline.clone()];
    let mut steps = Vec::new();
    let mut found: Vec<Found> = Vec::new();
    let mut questioned = Vec::new();
    // The forward RMSE of `current`, once known (the kept candidate's, after each step).
    let mut current_forward: Option<f64> = None;
    for _ in 0..opts.max_effects {
        // Each candidate is tried without its refinement (a thermal block's sensor lag), which
        // is tested apart once the block is kept.
        let remaining: Vec<&EffectBlock> = pool.iter().filter(|b| !current.model.effects.iter().any(|e| e.unrefined() == b.unrefined())).collect();
        if remaining.is_empty() {
            break;
        }
        let before = rms(&current.oof);
        let forward_before =
            if remaining.iter().any(|b| b.varies_in_time()) { current_forward.or_else(|| forward_rmse(ctx, &current)) } else { current_forward };
        let results: Vec<(Candidate, Fitted)> = remaining.par_iter().map(|b| try_candidate(ctx, &current, b, remaining.len(), span)).collect();
        let passes = |(c, b): (&Candidate, &EffectBlock)| {
            let forward_ok = !b.varies_in_time() || forward_before.zip(c.forward_rmse_mm).is_none_or(|(fb, fa)| fa < (1.0 - opts.min_gain) * fb);
            c.plausible
                && c.physical_sign
                && c.size_sigmas >= opts.min_size_sigmas
                && c.p_value < opts.alpha
                && c.heldout_rmse_mm < (1.0 - opts.min_gain) * before
                && forward_ok
        };
        let eligible: Vec<usize> = (0..results.len()).filter(|&i| passes((&results[i].0, remaining[i]))).collect();
        let by = |key: fn(&Candidate) -> f64, among: &mut dyn Iterator<Item = usize>| among.min_by(|&a, &b| key(&results[a].0).total_cmp(&key(&results[b].0)));
        let mut best = by(|c| c.heldout_rmse_mm, &mut eligible.iter().copied());
        // A cause that varies with time won the step: its forms compete on what comes later.
        let forward_pick = best.filter(|&i| remaining[i].varies_in_time() && forward_before.is_some());
        if forward_pick.is_some() {
            best = by(|c| c.forward_rmse_mm.unwrap_or(f64::INFINITY), &mut eligible.iter().copied().filter(|&i| remaining[i].varies_in_time()));
        }
        let kept_label = best.map(|i| remaining[i].label());
        let kept_on = best.map(|_| if forward_pick.is_some() { KeptOn::ForwardInTime } else { KeptOn::Folds });
        steps.push(Step {
            heldout_rmse_before_mm: before,
            forward_rmse_before_mm: forward_before,
            candidates: results.iter().map(|r| r.0.clone()).collect(),
            kept: kept_label.clone(),
            kept_on,
        });
        let Some(i) = best else { break };
        let (mut c, f) = results.into_iter().nth(i).expect("index from the same list");
        // Every kept cause is judged forward in time too where the rows carry their time (a
        // time-varying one was chosen on it; another is reported with it, and warned of where it
        // loses there). Without `t` the later rows of an acquisition are another part of the
        // workspace, which the folds already judge.
        let timed = ctx.forward.as_ref().is_some_and(|f| f.timed);
        let forward_before = forward_before.or_else(|| timed.then(|| forward_rmse(ctx, &current)).flatten());
        if c.forward_rmse_mm.is_none() && forward_before.is_some() {
            c.forward_rmse_mm = forward_rmse(ctx, &f);
        }
        let forward_note = c.forward_rmse_mm.zip(forward_before).map_or(String::new(), |(a, b)| format!("; forward in time {b:.4} -> {a:.4} mm"));
        progress(&format!("kept {}: held-out RMSE {before:.4} -> {:.4} mm (p = {:.2e}){forward_note}", remaining[i].label(), c.heldout_rmse_mm, c.p_value));
        let (block, f, forward_after) = refined(ctx, &current, remaining[i], (f, c.forward_rmse_mm), (opts.alpha, span), &mut questioned, progress);
        found.push(Found { block, before, after: rms(&f.oof), p: c.p_value, forward: forward_before.zip(forward_after) });
        current_forward = forward_after;
        chain.push(f.clone());
        current = f;
    }
    Selection { chain, steps, found, questioned }
}

/// The RMSE of `f`'s model on the rows judged forward in time, mm; `None` without forward folds.
fn forward_rmse(ctx: &Ctx, f: &Fitted) -> Option<f64> {
    ctx.forward_heldout(&f.model, &f.x, &f.fixed).map(|r| rms(&r))
}

/// One candidate `b` added to `current` and judged: on the folds, by the gain test (corrected
/// for `n_candidates`), by its size and sign, and forward in time where it varies with time.
fn try_candidate(ctx: &Ctx, current: &Fitted, b: &EffectBlock, n_candidates: usize, span: f64) -> (Candidate, Fitted) {
    let tc = Instant::now();
    let (m, x0) = with_block(&current.model, &current.x, &b.unrefined(), span);
    let f = ctx.evaluate(m, &x0);
    let p = (gain_p_value(current, &f, ctx.data.y.len()) * n_candidates as f64).min(1.0);
    let (size_sigmas, physical_sign) = size_check(&f, &ctx.data, ctx.groups.as_deref());
    let c = Candidate {
        cause: b.kind,
        joint: b.joint.map(|j| j + 1),
        heldout_rmse_mm: rms(&f.oof),
        forward_rmse_mm: if b.varies_in_time() { forward_rmse(ctx, &f) } else { None },
        p_value: p,
        plausible: plausible(&f),
        size_sigmas,
        physical_sign,
        seconds: tc.elapsed().as_secs_f64(),
    };
    (c, f)
}

/// A sensor lag longer than this share of the longest run is questioned: hard to tell from a
/// slow drift over the run, it is kept only where it predicts the run's later rows better.
pub const LAG_RUN_SHARE: f64 = 1.0 / 3.0;

/// A kept block's refinement (`full`, of which `kept` fitted the unrefined form on `prev`'s
/// model, with its forward RMSE: a thermal block's sensor lag) tested against it: kept where the
/// nested test at `alpha` favours it, the held-out RMSE falls and the forward RMSE (where
/// judged) falls too; a lag beyond [`LAG_RUN_SHARE`] of the longest run is said so in
/// `questioned`, and dropped where no later rows judge it. Returns the block kept, its fit and
/// its forward RMSE.
fn refined(
    ctx: &Ctx,
    prev: &Fitted,
    full: &EffectBlock,
    (kept, kept_forward): (Fitted, Option<f64>),
    (alpha, span): (f64, f64),
    questioned: &mut Vec<String>,
    progress: &dyn Fn(&str),
) -> (EffectBlock, Fitted, Option<f64>) {
    let simple = full.unrefined();
    if *full == simple {
        return (simple, kept, kept_forward);
    }
    // From the kept fit: the refinement's parameters follow the block's own, the block last.
    let (m, mut x0) = with_block(&prev.model, &prev.x, full, span);
    x0[..kept.x.len()].copy_from_slice(&kept.x);
    let f = ctx.evaluate(m, &x0);
    let p = gain_p_value(&kept, &f, ctx.data.y.len());
    let (before, after) = (rms(&kept.oof), rms(&f.oof));
    if !(p < alpha && after < before) {
        return (simple, kept, kept_forward);
    }
    let forward = forward_rmse(ctx, &f);
    if let (Some(b), Some(a)) = (kept_forward, forward) {
        if a >= b {
            progress(&format!(
                "{}'s sensor lag gains on the folds ({before:.4} -> {after:.4} mm) but not forward in time ({b:.4} -> {a:.4} mm): not kept",
                full.label()
            ));
            return (simple, kept, kept_forward);
        }
    }
    // A lag as long as a third of a run is hard to tell from a slow drift over it: kept only
    // where it predicts the later rows better (above), and said so.
    let longest = ctx.forward.as_ref().map_or(0.0, |fw| fw.longest_run_s);
    if let Some(lag) = lag_of(&f).filter(|l| longest > 0.0 && l.abs() > LAG_RUN_SHARE * longest) {
        let judged = kept_forward.zip(forward).map(|(b, a)| format!("kept because it predicts the later rows better ({b:.4} -> {a:.4} mm)"));
        let note = format!(
            "{}'s sensor lag came out at {lag:.0} s, longer than a third of the longest run ({longest:.0} s), where a lag is hard to tell from a slow drift: {}",
            full.label(),
            judged.as_deref().unwrap_or("not kept (no later rows to judge it on)")
        );
        progress(&note);
        questioned.push(note);
        if judged.is_none() {
            return (simple, kept, kept_forward);
        }
    }
    progress(&format!("{} refined (its sensor lag): held-out RMSE {before:.4} -> {after:.4} mm (p = {p:.2e})", full.label()));
    (full.clone(), f, forward.or(kept_forward))
}

/// The sensor lag (s) of the last block of `f`'s model, where it has one.
fn lag_of(f: &Fitted) -> Option<f64> {
    use crate::calib::effects::EffectUnit;
    use crate::calib::model::Kind;
    let b = f.model.effects.len().checked_sub(1)?;
    f.model.effect_params(b).find(|&k| f.model.kinds[k] == Kind::Effect(EffectUnit::Lag)).map(|k| f.x[k])
}

/// Confirmation: each cause's model, fitted on the selection rows, must predict the
/// `confirmation` rows better than the model before it; the first cause that does not ends the
/// list. The confirmation RMSE of each model of `chain`, how many causes are confirmed, and the
/// labels of the rest.
pub(super) fn confirm_causes(chain: &[Fitted], found: &[Found], confirmation: &Samples, progress: &dyn Fn(&str)) -> (Vec<f64>, usize, Vec<String>) {
    let confirmation_mm = confirmation.unweighted();
    let conf_rmse: Vec<f64> = chain
        .iter()
        .map(|f| if confirmation.is_empty() { f64::NAN } else { rms(&ReadingFit { model: &f.model, data: &confirmation_mm }.residuals_mm(&f.x)) })
        .collect();
    let confirmed = (1..chain.len()).take_while(|&k| confirmation.is_empty() || conf_rmse[k] < conf_rmse[k - 1]).count();
    let unconfirmed: Vec<String> = found[confirmed..].iter().map(|f| f.block.label()).collect();
    if !unconfirmed.is_empty() {
        progress(&format!("not confirmed on the {} confirmation rows: {}", confirmation.len(), unconfirmed.join(", ")));
    }
    (conf_rmse, confirmed, unconfirmed)
}

/// The report of each kept cause: its size and uncertainty from the final fit (`x`, `covs`), its
/// parameters, and the held-out and confirmation RMSE before and after it.
pub(super) fn cause_reports(found: &[Found], model: &CalibModel, covs: &Covariances, final_x: &[f64], other_rmse: &[f64], conf_rmse: &[f64]) -> Vec<Cause> {
    let mut causes = Vec::new();
    for (n, Found { block, before, after, p, forward }) in found.iter().enumerate() {
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
            cause: block.kind,
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
            forward_rmse_before_mm: forward.map(|f| f.0),
            forward_rmse_after_mm: forward.map(|f| f.1),
            parameters,
        });
    }
    causes
}

/// The outlier rows (0-based) the model with its causes (`current`; `dim` values a row) predicts
/// within `outlier_k` robust standard deviations of the kept rows' residuals: explained, not glitches.
pub(super) fn explained_by_causes(current: &Fitted, all: &Samples, dim: usize, keep: &[usize], outliers: &[Outlier], outlier_k: f64) -> Vec<usize> {
    if current.model.effects.is_empty() {
        return Vec::new();
    }
    let res_all = ReadingFit { model: &current.model, data: &Samples { gls: None, ..all.clone() } }.residuals_mm(&current.x);
    let kept_res: Vec<f64> = keep.iter().flat_map(|&i| res_all[i * dim..(i + 1) * dim].iter().copied()).collect();
    let (med, scale) = crate::stats::robust_scale(&kept_res);
    let far = |i: usize| crate::calib::fit::robust::farthest_from(&res_all[i * dim..(i + 1) * dim], med);
    outliers.iter().map(|o| o.row - 1).filter(|&i| (far(i) - med).abs() <= outlier_k * scale).collect()
}

/// The verdict: `geometric_only`, or the causes kept (`backlash[j2] + thermal`).
pub(super) fn verdict_of(causes: &[Cause]) -> String {
    if causes.is_empty() {
        return "geometric_only".into();
    }
    causes.iter().map(Cause::label).collect::<Vec<_>>().join(" + ")
}

/// Held-out RMSE of the geometric model, the physical extension and an RBF compensator on the
/// geometric residuals, on the same folds; and their extrapolation to rows with q2 above its
/// 70th percentile when trained on the rest.
pub(super) fn compare_with_rbf(ctx: &Ctx, geo: &Fitted, ext: &Fitted, seed: u64) -> Option<Comparison> {
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
