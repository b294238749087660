//! The joint angles' logging error as the noise model of a fit on a dataset: the
//! [`RoundingModel`] of its rows through a model ([`rounding_model_at`]), and what `calibrate`
//! does with it ([`remove_logging_error`]). The covariance and its whitening are in
//! [`super::gls`].

use super::gls::{NoiseModel, RoundingModel, Whitening};
use super::model::CalibModel;
use super::problem::{ReadingFit, Samples};
use crate::dataset::blocks::Blocks;
use crate::dataset::Dataset;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The logging error of the samples `s` (row `i` is the dataset `data`'s row `rows[i]`, the
/// acquisition's blocks `blocks`, angles logged at `step` degrees) through `base` at `x`:
/// each row's ∂reading/∂q, the joints that hold in its block (within half a step of the
/// block's first row throughout), and the reading's own noise: the mean squared residual of
/// the samples `keep` less what the logging explains, at least a twentieth of the latter (so
/// that the covariance stays well conditioned).
#[allow(clippy::too_many_arguments)]
pub fn rounding_model_at(
    base: &CalibModel,
    x: &[f64],
    s: &Samples,
    rows: &[usize],
    keep: &[usize],
    data: &Dataset,
    blocks: &Blocks,
    step: f64,
) -> RoundingModel {
    let (dim, nj) = (s.dim, base.chain.n_joints);
    let mut w = base.work();
    let (mut y, mut g) = (vec![0.0; dim], vec![0.0; nj * dim]);
    let jq: Vec<Vec<f64>> = (0..s.len())
        .map(|i| {
            base.readings_grad_q(x, &s.q[i], &s.inputs[i], &mut w, &mut y, &mut g);
            g.iter().map(|v| v * 1e3).collect()
        })
        .collect();
    // The joints that hold throughout each block, over all of its rows in the dataset.
    let mut holds_of_block = vec![Vec::new(); blocks.len()];
    for &(first, _) in &blocks.starts {
        let b = blocks.of_row[first];
        let block_rows: Vec<usize> = (first..data.rows.len()).take_while(|&i| blocks.of_row[i] == b).collect();
        holds_of_block[b] = (0..nj)
            .map(|j| block_rows.len() > 1 && block_rows.iter().all(|&i| (data.rows[i].q_deg[j] - data.rows[first].q_deg[j]).abs() <= 0.5 * step))
            .collect();
    }
    let block: Vec<usize> = rows.iter().map(|&r| blocks.of_row[r]).collect();
    let holds: Vec<Vec<bool>> = block.iter().map(|&b| holds_of_block[b].clone()).collect();
    let res = ReadingFit { model: base, data: &s.subset(keep).unweighted() }.residuals_mm(x);
    let total = res.iter().map(|r| r * r).sum::<f64>() / res.len().max(1) as f64;
    let model = RoundingModel::new(dim, block, jq, holds, step, 0.0);
    let rounding = model.rounding_var();
    model.with_noise_var((total - rounding).max(0.05 * rounding).max(1e-12))
}

/// Whether `calibrate` models the joint angles' logging error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NoiseChoice {
    /// Where training rows share blocks and the angles are logged at a step
    /// ([`remove_logging_error`]); rows otherwise as they are.
    #[default]
    Auto,
    /// Rows as they are, whatever the acquisition.
    Off,
}

impl std::str::FromStr for NoiseChoice {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<NoiseChoice> {
        match s {
            "auto" => Ok(NoiseChoice::Auto),
            "off" => Ok(NoiseChoice::Off),
            _ => Err(crate::error::Error::Invalid(format!("--noise-model must be auto or off, not '{s}'"))),
        }
    }
}

/// The training readings `train` with the joint angles' logging error taken out (row `i` is the
/// dataset `data`'s row `rows[i]`) where they share blocks and the angles are logged at a step
/// (`step_deg`, or the data's decimals), before any method fits them: `model` is fitted from
/// `x0` (parameters `fixed` held) by least squares, then by generalised least squares with the
/// covariance the logging implies ([`RoundingModel`]); the logging error that fit's residuals
/// show, per block and joint ([`Whitening::rounding_estimate`], at most half a step), is taken
/// out of the readings. A parametric fit on the corrected readings is then the generalised
/// least-squares fit (exactly so where no offset reaches half a step), and a learned corrector
/// finds no rounding in them to learn. Returns the noise model, the whitening of the rows and
/// the corrected samples, or `None` where the rows are independent, weighted by their own standard deviations, or the
/// angles unrounded (the readings untouched).
#[allow(clippy::too_many_arguments)]
pub fn remove_logging_error(
    model: &CalibModel,
    x0: &[f64],
    fixed: &[bool],
    train: &Samples,
    rows: &[usize],
    data: &Dataset,
    step_deg: Option<f64>,
) -> Option<(NoiseModel, Whitening, Samples)> {
    let (blocks, step) = crate::dataset::blocks::detect(data, step_deg);
    let step = step?;
    let ids: Vec<usize> = rows.iter().map(|&r| blocks.of_row[r]).collect();
    if !ids.windows(2).any(|w| w[0] == w[1]) || train.w.is_some() {
        return None;
    }
    let lm = crate::optim::LevenbergMarquardt::refit;
    let plain = train.unweighted();
    let x1 = lm().minimize(&ReadingFit { model, data: &plain }, x0, fixed, &mut crate::optim::NoObserver).x;
    let all: Vec<usize> = (0..train.len()).collect();
    let m = Arc::new(rounding_model_at(model, &x1, &plain, rows, &all, data, &blocks, step));
    let whitening = Whitening::new(m.clone(), all);
    let gls = Samples { gls: Some(whitening.clone()), ..plain.clone() };
    let x2 = lm().minimize(&ReadingFit { model, data: &gls }, &x1, fixed, &mut crate::optim::NoObserver).x;
    let r = ReadingFit { model, data: &plain }.residuals_mm(&x2);
    let u = whitening.rounding_estimate(&r);
    let corrected = Samples { y: train.y.iter().zip(&u).map(|(y, u)| y - u * 1e-3).collect(), ..plain };
    let removed = (u.iter().map(|v| v * v).sum::<f64>() / u.len().max(1) as f64).sqrt();
    Some((NoiseModel { removed_rms_mm: Some(removed), ..m.summary(step) }, whitening, corrected))
}
