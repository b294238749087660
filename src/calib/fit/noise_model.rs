//! The joint angles' logging error as the noise model of a fit on a dataset: the
//! [`RoundingModel`] of its rows through a model ([`rounding_model_at`]), and what `calibrate`
//! does with it ([`remove_logging_error`]). The covariance and its whitening are in
//! [`crate::calib::fit::gls`].

use crate::calib::fit::gls::{NoiseModel, RoundingModel, Whitening};
use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::dataset::blocks::Blocks;
use crate::dataset::Dataset;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// How a dataset's joint angles were logged, as its rows show it: the dataset, its acquisition
/// blocks and the logging step (degrees). Resolved once ([`crate::calib::pipeline::SplitData`]
/// keeps the blocks and the step) and read by every stage that models the logging error.
#[derive(Clone, Copy)]
pub struct Logging<'a> {
    /// The dataset the rows index.
    pub data: &'a Dataset,
    /// Its acquisition blocks.
    pub blocks: &'a Blocks,
    /// The joint angles' logging step, degrees.
    pub step_deg: f64,
}

/// The logging error of the samples `s` (row `i` is the dataset `data`'s row `rows[i]`, the
/// acquisition's blocks `blocks`, angles logged at `step` degrees) through `base` at `x`:
/// each row's ∂reading/∂q, the joints that hold in its block (within half a step of the
/// block's first row throughout), and the reading's own noise: the mean squared residual of
/// the samples `keep` less what the logging explains, at least a twentieth of the latter (so
/// that the covariance stays well conditioned).
pub fn rounding_model_at(base: &CalibModel, x: &[f64], s: &Samples, rows: &[usize], keep: &[usize], log: Logging) -> RoundingModel {
    let Logging { data, blocks, step_deg: step } = log;
    let (dim, nj) = (s.dim, base.chain.n_joints);
    let mut w = base.work();
    let (mut y, mut g) = (vec![0.0; dim], vec![0.0; nj * dim]);
    let jq: Vec<Vec<f64>> = (0..s.len())
        .map(|i| {
            base.readings_grad_q(x, &s.q[i], &s.inputs[i], &mut w, &mut y, &mut g);
            g.iter().map(crate::units::to_mm).collect()
        })
        .collect();
    // The joints whose logging error each block shares, over all of its rows in the dataset.
    let mut holds_of_block = vec![Vec::new(); blocks.len()];
    for &(first, _) in &blocks.starts {
        let b = blocks.of_row[first];
        let block_rows: Vec<usize> = (first..data.rows.len()).take_while(|&i| blocks.of_row[i] == b).collect();
        let q: Vec<&[f64]> = block_rows.iter().map(|&i| &data.rows[i].q_deg[..]).collect();
        holds_of_block[b] = (0..nj).map(|j| shares_rounding(&q, j, step)).collect();
    }
    let block: Vec<usize> = rows.iter().map(|&r| blocks.of_row[r]).collect();
    let holds: Vec<Vec<bool>> = block.iter().map(|&b| holds_of_block[b].clone()).collect();
    let res = ReadingFit { model: base, data: &s.subset(keep).unweighted() }.residuals_mm(x);
    let total = res.iter().map(|r| r * r).sum::<f64>() / res.len().max(1) as f64;
    let model = RoundingModel::new(dim, block, jq, holds, step, 0.0);
    let rounding = model.rounding_var();
    model.with_noise_var((total - rounding).max(0.05 * rounding).max(1e-12))
}

/// Whether the rows `q` of one block (logged angles, degrees, in acquisition order) share joint
/// `j`'s logging error: the joint holds (within half a step of the first row throughout), or it
/// steps evenly (every logged increment the same to within half a step, at least three rows). A
/// controller sweep commanded in round increments (5°, 0.25°: whole multiples of the logging
/// step) reads every row of the sweep off by the same rounding, as a holding joint does; where the
/// increment is not a multiple of the step the logged increments differ by a step somewhere along
/// any sweep long enough for the rounding to change, and the joint's error is taken per row.
pub fn shares_rounding(q: &[&[f64]], j: usize, step: f64) -> bool {
    if q.len() < 2 {
        return false;
    }
    let holds = q.iter().all(|r| (r[j] - q[0][j]).abs() <= 0.5 * step);
    let d0 = q[1][j] - q[0][j];
    let even = q.len() >= 3 && q.windows(2).all(|w| (w[1][j] - w[0][j] - d0).abs() <= 0.5 * step);
    holds || even
}

/// Whether `calibrate` models the joint angles' logging error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum NoiseChoice {
    /// Where training rows share blocks and the angles are logged at a step
    /// ([`remove_logging_error`]); rows otherwise as they are.
    #[default]
    Auto,
    /// Rows as they are, whatever the acquisition.
    Off,
}

/// The training readings `train` with the joint angles' logging error taken out (row `i` is the
/// dataset `data`'s row `rows[i]`) where they share blocks and the angles are logged at a step
/// (`blocks` and the step of [`crate::dataset::blocks::detect`]), before any method fits them: `model` is fitted from
/// `x0` (parameters `fixed` held) by least squares, then by generalised least squares with the
/// covariance the logging implies ([`RoundingModel`]); the logging error that fit's residuals
/// show, per block and joint ([`Whitening::rounding_estimate`], at most half a step), is taken
/// out of the readings. A parametric fit on the corrected readings is then the generalised
/// least-squares fit (exactly so where no offset reaches half a step), and a learned corrector
/// finds no rounding in them to learn. Returns the noise model, the whitening of the rows and
/// the corrected samples, or `None` where the rows are independent, weighted by their own standard deviations, or the
/// angles unrounded (the readings untouched).
pub fn remove_logging_error(
    model: &CalibModel,
    x0: &[f64],
    fixed: &[bool],
    train: &Samples,
    rows: &[usize],
    log: Option<Logging>,
) -> Option<(NoiseModel, Whitening, Samples)> {
    let log = log?;
    let (blocks, step) = (log.blocks, log.step_deg);
    let ids: Vec<usize> = rows.iter().map(|&r| blocks.of_row[r]).collect();
    if !ids.windows(2).any(|w| w[0] == w[1]) || train.w.is_some() {
        return None;
    }
    let lm = crate::optim::LevenbergMarquardt::refit;
    let plain = train.unweighted();
    let x1 = lm().minimize(&ReadingFit { model, data: &plain }, x0, fixed, &mut crate::optim::NoObserver).x;
    let all: Vec<usize> = (0..train.len()).collect();
    let m = Arc::new(rounding_model_at(model, &x1, &plain, rows, &all, log));
    let whitening = Whitening::new(m.clone(), all);
    let gls = Samples { gls: Some(whitening.clone()), ..plain.clone() };
    let x2 = lm().minimize(&ReadingFit { model, data: &gls }, &x1, fixed, &mut crate::optim::NoObserver).x;
    let r = ReadingFit { model, data: &plain }.residuals_mm(&x2);
    let u = whitening.rounding_estimate(&r);
    let corrected = Samples { y: train.y.iter().zip(&u).map(|(y, u)| y - crate::units::to_m(u)).collect(), ..plain };
    let removed = (u.iter().map(|v| v * v).sum::<f64>() / u.len().max(1) as f64).sqrt();
    Some((NoiseModel { removed_rms_mm: Some(removed), ..m.summary(step) }, whitening, corrected))
}

#[cfg(test)]
mod tests {
    use super::shares_rounding;

    fn rows(v: &[[f64; 2]]) -> Vec<&[f64]> {
        v.iter().map(|r| &r[..]).collect()
    }

    #[test]
    fn a_joint_shares_its_rounding_where_it_holds_or_steps_evenly() {
        // Joint 0 steps by 5.00° (a multiple of the 0.01° step); joint 1 holds.
        let even = [[10.03, -4.21], [15.03, -4.21], [20.03, -4.21], [25.03, -4.21]];
        assert!(shares_rounding(&rows(&even), 0, 0.01) && shares_rounding(&rows(&even), 1, 0.01));
        // A true increment of 5.004°: the logged increments read 5.00 and 5.01 by turns.
        let uneven: Vec<[f64; 2]> = (0..6).map(|i| [((10.031 + 5.004 * i as f64) * 100.0).round() / 100.0, -4.21]).collect();
        assert!(!shares_rounding(&rows(&uneven), 0, 0.01), "{uneven:?}");
        // Two rows stepping once tell nothing about the increment; one row shares nothing.
        assert!(!shares_rounding(&rows(&even[..2]), 0, 0.01) && shares_rounding(&rows(&even[..2]), 1, 0.01));
        assert!(!shares_rounding(&rows(&even[..1]), 1, 0.01));
    }
}
