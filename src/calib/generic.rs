//! The generic 6R model's structure, for arms without a published nominal: L-SHADE over broad
//! bounds from several seeded restarts (in parallel), each polished by LM; the best training fit wins.

use super::model::CalibModel;
use super::optim::{Bounds, De, DeVariant, LeastSquares, LevenbergMarquardt, NoObserver};
use super::problem::{FreeCost, LengthFit, Samples};
use super::run::CalibOptions;
use crate::error::{Error, Result};
use rayon::prelude::*;

/// Broad bounds for the generic 6R search: D-H angles over the full circle, lengths within ±1.5 m,
/// exit point within ±3 m, offset within ±2 m, tool point within ±0.3 m.
fn bounds(model: &CalibModel) -> Bounds {
    let pi = std::f64::consts::PI;
    let (lo, hi): (Vec<f64>, Vec<f64>) = model
        .names
        .iter()
        .map(|n| {
            if n.ends_with(".theta") || n.ends_with(".alpha") {
                (-pi, pi)
            } else if n.starts_with("exit.") {
                (-3.0, 3.0)
            } else if n == "length_offset" {
                (-2.0, 2.0)
            } else if n.starts_with("tool.") {
                (-0.3, 0.3)
            } else {
                (-1.5, 1.5)
            }
        })
        .unzip();
    Bounds::new(lo, hi)
}

/// Global search for the generic model: L-SHADE over broad bounds, several restarts, each
/// polished by LM; the best training fit wins.
pub fn search(model: &CalibModel, train: &Samples, opts: &CalibOptions) -> Result<Vec<f64>> {
    let bounds = bounds(model);
    let all: Vec<usize> = (0..model.n_params()).collect();
    // The global search sees an evenly spread subset (every k-th row, at most 400); LM then
    // polishes each candidate on every training row.
    let step = train.len().div_ceil(400).max(1);
    let rows: Vec<usize> = (0..train.len()).step_by(step).collect();
    let subset = train.subset(&rows);
    let fit = LengthFit { model, data: train };
    let lm = LevenbergMarquardt { max_iter: 300, ..Default::default() };
    let restarts = (4.0 * opts.effort).ceil() as u64;
    // Restarts are independent (own seeds) and run in parallel; the result does not depend on
    // the number of threads.
    let candidates: Vec<(f64, Vec<f64>)> = (0..restarts)
        .into_par_iter()
        .map(|r| {
            let cost = FreeCost { fit: LengthFit { model, data: &subset }, base: model.nominal.clone(), free: all.clone() };
            let de = De {
                variant: DeVariant::LShade { memory: 6, p: 0.11, min_pop: 6 },
                pop: 120,
                generations: 100_000,
                max_evals: Some((60_000.0 * opts.effort.min(1.0)) as usize),
                seed: opts.seed.wrapping_mul(31).wrapping_add(r),
                tol: 1e-12,
                patience: 300,
            };
            let g = de.minimize(&cost, &bounds, None, &mut NoObserver);
            let id = super::run::identify(&fit, &g.x, opts.rank_tol);
            let polished = lm.minimize(&fit, &g.x, &id.fixed_mask, &mut NoObserver);
            (LeastSquares::cost(&fit, &polished.x), polished.x)
        })
        .collect();
    let best = candidates.into_iter().filter(|c| c.0.is_finite()).min_by(|a, b| a.0.total_cmp(&b.0));
    best.map(|b| b.1).ok_or_else(|| Error::Calibration("global search found nothing".into()))
}
