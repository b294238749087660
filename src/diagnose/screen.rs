//! The rows a diagnosis fits: the outlier screen (by the geometric model, or by a candidate
//! effect's where it explains what the geometric screen flags), the acquisition's blocks and its
//! noise model, and the candidate effects.

use super::fit::*;
use super::options::*;
use super::report::*;
use crate::calib::effects::inputs::{block_for, time_span};
use crate::calib::effects::{EffectBlock, EffectKind};
use crate::calib::fit::noise_model::Logging;
use crate::calib::fit::robust::Screen;
use crate::calib::fit::Samples;
use crate::calib::model::CalibModel;
use crate::dataset::blocks::{Boundary, Structure};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use rayon::prelude::*;

/// The acquisition's blocks (sweeps, pauses, declared blocks) and the ends of the reading steps
/// `steps` (rows that share an error are held out together and count as less than their
/// number), what they look like, and where rows share blocks and the angles are logged at a
/// step, the logging error as the noise model of every fit from here on: `all` gets its
/// whitening (generalised least squares over the blocks, see `calib::gls`), from the geometric
/// model `base` at `x` and the kept rows `keep`.
pub(super) fn acquisition_structure(
    data: &Dataset,
    opts: &DiagnoseOptions,
    base: &CalibModel,
    screen: &Screen,
    all: &mut Samples,
    progress: &dyn Fn(&str),
) -> (crate::dataset::blocks::Blocks, Structure, Option<NoiseModel>) {
    let (steps, x, keep) = (&screen.steps, &screen.x, &screen.keep[..]);
    let (mut blocks, angle_step) = crate::dataset::blocks::detect(data, opts.floor.angle_step_deg);
    for s in steps {
        blocks.split_before(s.first_row - 1, Boundary::ReadingStep);
        blocks.split_before(s.last_row, Boundary::ReadingStep);
    }
    let acquisition = blocks.structure(angle_step);
    if !blocks.any_shared() {
        return (blocks, acquisition, None);
    }
    progress(&format!("acquisition: {}", acquisition.summary));
    let Some(step) = angle_step.filter(|_| opts.floor.noise_model == crate::calib::fit::noise_model::NoiseChoice::Auto) else {
        return (blocks, acquisition, None);
    };
    let rows: Vec<usize> = (0..all.len()).collect();
    let m =
        std::sync::Arc::new(crate::calib::fit::noise_model::rounding_model_at(base, x, all, &rows, keep, Logging { data, blocks: &blocks, step_deg: step }));
    let noise = m.summary(step);
    progress(&format!(
        "joint angles logged at {step} deg: their shared error is a noise model of the fits (rounding {:.4} mm, reading noise {:.4} mm per value)",
        noise.rounding_mm, noise.reading_noise_mm
    ));
    all.gls = Some(crate::calib::fit::gls::Whitening::new(m, (0..all.len()).collect()));
    (blocks, acquisition, Some(noise))
}

/// The kept rows `kept` of the final fit with their noise model re-estimated at the model with its
/// causes (`current`): the reading noise of the first one (see [`acquisition_structure`]) is
/// what the geometric model leaves, the causes' signal included, and so takes most of what
/// remains for independent noise; the sweeps' shared logging error, then too small a share of
/// the covariance, would let a slow cause (a thermal drift over the sweeps) absorb it and state
/// too small an uncertainty. Unchanged without a noise model or a cause.
pub(super) fn final_whitening(
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
    let m = std::sync::Arc::new(crate::calib::fit::noise_model::rounding_model_at(
        &current.model,
        &current.x,
        &plain,
        &rows,
        keep,
        Logging { data, blocks, step_deg: n.angle_step_deg },
    ));
    let summary = m.summary(n.angle_step_deg);
    let whitened = Samples { gls: Some(crate::calib::fit::gls::Whitening::new(m, rows)), ..plain };
    (whitened.subset(keep), Some(summary))
}

/// The candidate blocks: every kind on every joint the data support, or those listed (a kind
/// with a joint is that block only), each block once however often it is listed. A listed
/// candidate the data cannot support (no torques for compliance, no temp or t for thermal, a
/// joint beyond the data's) is an error naming what is missing.
pub(super) fn candidates(data: &Dataset, listed: &[(EffectKind, Option<usize>)], has_torques: bool) -> Result<Vec<EffectBlock>> {
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

/// The candidate blocks for the rows of `data` (joint angles `q`, rad): [`candidates`] less the
/// blocks on a joint that does not move whose effect is then constant (one backlash side and one
/// eccentricity phase throughout: offsets the geometry already holds).
pub(super) fn candidate_pool(data: &Dataset, q: &[Vec<f64>], opts: &DiagnoseOptions, has_torques: bool) -> Result<Vec<EffectBlock>> {
    let still = crate::calib::pipeline::still_joints(q);
    Ok(candidates(data, &opts.candidates, has_torques)?
        .into_iter()
        .filter(|b| !(b.kind.def().constant_on_still_joint() && b.joint.is_some_and(|j| still.contains(&j))))
        .collect())
}

/// Whether each cross-validation fold trains on enough values for the geometric model's
/// `n_free` identifiable parameters (before any cause is added): an error when a fold's training
/// rows could be fitted exactly (the held-out RMSE and the outlier screen then say nothing), a
/// warning below three values per parameter.
pub(super) fn fold_rows_check(rows: usize, dim: usize, n_free: usize, opts: &DiagnoseOptions) -> Result<Option<String>> {
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

/// ... and the smallest share of the rows.
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
pub(super) fn flagged_rows(s: &crate::calib::fit::robust::Screen) -> usize {
    s.outliers.len() + s.steps.iter().map(|st| st.rows).sum::<usize>()
}

/// The candidate effect whose model, screened on every row, flags the fewest rows (of those whose
/// scale stays within [`EFFECT_SCREEN_MAX_SCALE`] of the geometric one; ties to the narrower
/// scale), with its screen, when that is at most half of what the geometric screen (`geo`)
/// flagged, or no more with a scale within [`EFFECT_SCREEN_TIGHTER`] of the geometric one.
pub(super) fn screen_with_effects(
    base: &CalibModel,
    all: &Samples,
    data: &Dataset,
    opts: &DiagnoseOptions,
    has_torques: bool,
    geo: &Screen,
    only: Option<&EffectBlock>,
) -> Result<Option<(EffectBlock, Screen)>> {
    let span = time_span(data);
    // Each candidate in its unrefined form, as the selection first tries it.
    let pool: Vec<EffectBlock> =
        candidate_pool(data, &all.q, opts, has_torques)?.iter().map(EffectBlock::unrefined).filter(|b| only.is_none_or(|o| o.unrefined() == *b)).collect();
    let rows: Vec<usize> = (0..all.len()).collect();
    let tried: Vec<(EffectBlock, Screen)> = pool
        .par_iter()
        .map(|b| {
            let (m, x0) = with_block(base, &geo.x, b, span);
            let refit = |d: &Samples, x: &[f64]| crate::calib::fit::robust::screen_fit(&m, d, x, opts.rank_tol);
            let s = crate::calib::fit::robust::screen(&m, &x0, all, &rows, geo.rule, &refit);
            (b.clone(), s)
        })
        .collect();
    // Fewest rows flagged among the candidates that keep the scale; of those, the narrowest.
    let fewer = |s: &crate::calib::fit::robust::Screen| 2 * s.outliers.len() <= geo.outliers.len() && !geo.outliers.is_empty();
    let tighter = |s: &crate::calib::fit::robust::Screen| s.outliers.len() <= geo.outliers.len() && s.scale_mm <= EFFECT_SCREEN_TIGHTER * geo.scale_mm;
    Ok(tried
        .into_iter()
        .filter(|(_, s)| s.scale_mm <= EFFECT_SCREEN_MAX_SCALE * geo.scale_mm && (fewer(s) || tighter(s)))
        .min_by(|a, b| a.1.outliers.len().cmp(&b.1.outliers.len()).then(a.1.scale_mm.total_cmp(&b.1.scale_mm))))
}

/// Which screen a diagnosis keeps its rows by (see [`screen_rows`]).
#[derive(Clone, Debug)]
pub(super) enum ScreenBy {
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
pub(super) fn screen_rows(
    base: &CalibModel,
    all: &Samples,
    data: &Dataset,
    opts: &DiagnoseOptions,
    has_torques: bool,
    by: &ScreenBy,
    progress: &dyn Fn(&str),
) -> Result<(crate::calib::fit::robust::Screen, Option<EffectBlock>, Vec<usize>)> {
    let refit_rows = |d: &Samples, x: &[f64]| crate::calib::fit::robust::screen_fit(base, d, x, opts.rank_tol);
    // No row is an outlier for lying as far off as the angles' logging alone puts a reading.
    let rule = crate::calib::pipeline::screen_rule(base, data, all, opts.screen.outlier_k, opts.screen.reading_steps, opts.floor.angle_step_deg);
    let geo_screen = crate::calib::fit::robust::screen(base, &base.nominal, all, &(0..all.len()).collect::<Vec<_>>(), rule, &refit_rows);
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
