//! Models fitted over folds of whole blocks: the fitted chain's models, their held-out residuals,
//! sizes and their uncertainty with shared errors, the evidence features and the plausibility of
//! a cause's size.

use super::options::*;
use super::report::*;
use crate::calib::effects::{EffectBlock, Size};
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::calib::pipeline::identify;
use crate::optim::{LevenbergMarquardt, NoObserver};
use crate::stats::nested_f_test_deff;
use crate::stats::rms;
use rayon::prelude::*;

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
pub(super) fn plausible(f: &Fitted) -> bool {
    implausible_param(&f.model, &f.x, f.model.effects.len() - 1).is_none()
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

/// A model with its fitted parameters and fixed mask on the kept rows.
#[derive(Clone)]
pub(super) struct Fitted {
    pub(super) model: CalibModel,
    pub(super) x: Vec<f64>,
    pub(super) fixed: Vec<bool>,
    /// Held-out residual of every kept row, mm.
    pub(super) oof: Vec<f64>,
    /// In-sample residual sum of squares (mm²) and free parameters.
    pub(super) rss: f64,
    pub(super) n_free: usize,
    /// Design effect of the in-sample residuals over the acquisition's blocks (1 when every row
    /// is its own block): how much less than their number the rows count as evidence.
    pub(super) deff: f64,
}

pub(super) struct Ctx {
    /// The selection rows (kept rows less the confirmation set), with their inputs.
    pub(super) data: Samples,
    /// Folds over `data`: the kind selection judges on, then the other kind. Whole blocks of
    /// the acquisition go to one fold.
    pub(super) folds: Vec<Vec<usize>>,
    pub(super) other_folds: Vec<Vec<usize>>,
    /// Block of every selection row, where some block has more than one row.
    pub(super) groups: Option<Vec<usize>>,
    pub(super) rank_tol: f64,
    /// Rolling-origin folds over the selection rows ([`super::forward`]): what causes that vary
    /// with time are judged on besides `folds`; `None` where the runs are too short.
    pub(super) forward: Option<super::forward::Forward>,
}

impl Ctx {
    /// The selection rows of the kept rows `kept` (rows `keep` of the data, in blocks `blocks`)
    /// with their folds, and the confirmation set: every k-th block of kept rows in acquisition
    /// order (every k-th row when no rows share a block), never seen by selection. Also the
    /// warning of [`block_folds`].
    pub(super) fn over_blocks(
        kept: &Samples,
        keep: &[usize],
        blocks: &crate::dataset::blocks::Blocks,
        opts: &DiagnoseOptions,
    ) -> (Ctx, Samples, Option<String>) {
        let every = if opts.confirm_fraction > 0.0 { (1.0 / opts.confirm_fraction).round().max(2.0) as usize } else { usize::MAX };
        let kept_groups = blocks.ids_of(keep);
        let (sel_idx, conf_idx): (Vec<usize>, Vec<usize>) = (0..kept.len()).partition(|&i| kept_groups[i] % every != every - 1);
        let sel_groups = blocks.ids_of(&sel_idx.iter().map(|&i| keep[i]).collect::<Vec<_>>());
        let shared = blocks.any_shared();
        let (folds, other_folds, few_blocks) = block_folds(&sel_groups, opts.folds, shared);
        let data = kept.subset(&sel_idx);
        let times: Vec<Option<f64>> = data.inputs.iter().map(|i| i.t_s).collect();
        let forward = super::forward::Forward::over(&times, shared.then_some(&sel_groups[..]));
        let ctx = Ctx { folds, other_folds, groups: shared.then_some(sel_groups), data, rank_tol: opts.rank_tol, forward };
        (ctx, kept.subset(&conf_idx), few_blocks)
    }

    /// Fits `model` from `x0` on every selection row (identifiable parameters only), then the
    /// held-out residual of each fold from a fit on the other folds.
    pub(super) fn evaluate(&self, model: CalibModel, x0: &[f64]) -> Fitted {
        let fit = ReadingFit { model: &model, data: &self.data };
        let (x, fixed) = refit(&model, &self.data, x0, self.rank_tol);
        let oof = self.heldout(&model, &x, &fixed, &self.folds);
        let res = fit.residuals_mm(&x);
        let rss = res.iter().map(|r| r * r).sum();
        let n_free = fixed.iter().filter(|f| !**f).count();
        let deff = self.groups.as_ref().map_or(1.0, |g| crate::stats::design_effect(&res, self.data.dim, g));
        Fitted { model, x, fixed, oof, rss, n_free, deff }
    }

    /// The residuals of the rows judged forward in time ([`super::forward::Forward::judged_rows`]),
    /// each stretch predicted by a fit on every row before it; `None` without forward folds.
    pub(super) fn forward_heldout(&self, model: &CalibModel, x: &[f64], fixed: &[bool]) -> Option<Vec<f64>> {
        let forward = self.forward.as_ref()?;
        let per_fold: Vec<Vec<f64>> = forward
            .folds
            .par_iter()
            .map(|(train, judged)| {
                let tr = self.data.subset(train);
                let xf = LevenbergMarquardt::refit().minimize(&ReadingFit { model, data: &tr }, x, fixed, &mut NoObserver).x;
                ReadingFit { model, data: &self.data.subset(judged).unweighted() }.residuals_mm(&xf)
            })
            .collect();
        Some(per_fold.concat())
    }

    /// Held-out residual of every selection row: each fold predicted by a fit on the others.
    pub(super) fn heldout(&self, model: &CalibModel, x: &[f64], fixed: &[bool], folds: &[Vec<usize>]) -> Vec<f64> {
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
pub(super) fn scatter(folds: &[Vec<usize>], per_fold: Vec<Vec<f64>>, n: usize, dim: usize) -> Vec<f64> {
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
pub(super) fn refit(model: &CalibModel, data: &Samples, x0: &[f64], rank_tol: f64) -> (Vec<f64>, Vec<bool>) {
    let fit = ReadingFit { model, data };
    let fixed = identify(&fit, x0, rank_tol).fixed_mask;
    (LevenbergMarquardt::refit().minimize(&fit, x0, &fixed, &mut NoObserver).x, fixed)
}

/// No model predicts unseen rows better than the data's floor: a held-out RMSE below it means
/// the held-out rows shared errors with the training rows. The warning, if so (`shared`: the
/// data have blocks of several rows).
pub(super) fn leak_warning(oof: &[f64], dim: usize, groups: Option<&[usize]>, floor_mm: f64, shared: bool) -> Option<String> {
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
pub(super) fn block_folds(groups: &[usize], k: usize, shared: bool) -> (Vec<Vec<usize>>, Vec<Vec<usize>>, Option<String>) {
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
pub(super) fn size_check(f: &Fitted, data: &Samples, groups: Option<&[usize]>) -> (f64, bool) {
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
pub(super) fn gain_p_value(a: &Fitted, b: &Fitted, n: usize) -> f64 {
    nested_f_test_deff(a.rss, b.rss, b.n_free.saturating_sub(a.n_free), n.saturating_sub(b.n_free), b.deff)
}

/// The covariances of a fit whose rows may share errors in blocks (`groups`: each row's block):
/// the classical one, and the cluster-robust one ([`crate::optim::cluster_covariance`]) where
/// some block holds several rows. A size's uncertainty is the larger of the two, so shared errors
/// can only widen it.
pub(super) struct Covariances {
    pub(super) classical: Option<nalgebra::DMatrix<f64>>,
    pub(super) robust: Option<nalgebra::DMatrix<f64>>,
}

impl Covariances {
    pub(super) fn of(fit: &ReadingFit, x: &[f64], fixed: &[bool], groups: Option<&[usize]>) -> Covariances {
        let per_value: Option<Vec<usize>> = groups.map(|g| g.iter().flat_map(|&b| std::iter::repeat_n(b, fit.data.dim)).collect());
        let (classical, robust) = crate::optim::covariances(fit, x, fixed, per_value.as_deref());
        Covariances { classical, robust }
    }

    /// The size of `block` (parameters `range` of `x`) with the larger of its two uncertainties.
    pub(super) fn size(&self, block: &EffectBlock, x: &[f64], range: std::ops::Range<usize>) -> Size {
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
    pub(super) fn sd(&self, k: usize) -> f64 {
        let var = |c: &Option<nalgebra::DMatrix<f64>>| c.as_ref().map(|c| c[(k, k)].max(0.0));
        match (var(&self.classical), var(&self.robust)) {
            (Some(a), Some(b)) => a.max(b).sqrt(),
            (Some(a), None) | (None, Some(a)) => a.sqrt(),
            (None, None) => f64::NAN,
        }
    }
}

pub(super) fn pearson(a: &[f64], b: &[f64]) -> f64 {
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
pub(super) fn evidence(data: &Samples, residual: &[f64], has_torques: bool, columns: &[&str]) -> Vec<Evidence> {
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
pub(super) fn magnitude(block: &EffectBlock, x: &[f64], cov: Option<&nalgebra::DMatrix<f64>>, range: std::ops::Range<usize>) -> Size {
    let var = |a: usize, b: usize| cov.map(|c| c[(a, b)]).unwrap_or(f64::NAN);
    block.kind.def().size(block, x, range.start, &var)
}

/// `model` with `block` added (data time span `span`, s), and the start `x` extended by the
/// block's "no effect" values.
pub(super) fn with_block(model: &CalibModel, x: &[f64], block: &EffectBlock, span: f64) -> (CalibModel, Vec<f64>) {
    let mut m = model.clone();
    m.add_effect(block.clone(), span);
    let mut x0 = x.to_vec();
    x0.extend_from_slice(&m.nominal[x.len()..]);
    (m, x0)
}
