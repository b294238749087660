//! Small helpers shared by the solvers in this module (not part of the public API).

use rayon::prelude::*;

use super::{Cost, Observations};

/// Below this many cost evaluations per batch the swarm / population is evaluated serially:
/// spawning rayon tasks costs more than it saves for cheap, small batches.
const PAR_MIN_BATCH: usize = 8;

/// Map a cost to something totally ordered for minimisation: NaN (and −∞, which only a broken
/// cost produces) become +∞, so a NaN is never selected as "best" and never panics a sort.
#[inline]
pub(crate) fn sanitize(f: f64) -> f64 {
    if f.is_nan() || f == f64::NEG_INFINITY {
        f64::INFINITY
    } else {
        f
    }
}

/// Indices `k` with `fixed[k] == false`. A `fixed` slice shorter than `n` is treated as
/// "free" for the missing entries.
pub(crate) fn free_indices(fixed: &[bool], n: usize) -> Vec<usize> {
    (0..n).filter(|&k| !fixed.get(k).copied().unwrap_or(false)).collect()
}

/// Evaluate `c` on every row of the row-major `n × d` matrix `xs`, writing sanitised costs to
/// `out` (len n). Each cost depends only on its own row, so the result is identical whatever
/// the number of rayon threads.
pub(crate) fn eval_rows<C: Cost>(c: &C, xs: &[f64], d: usize, out: &mut [f64]) {
    debug_assert_eq!(xs.len(), out.len() * d);
    if out.len() >= PAR_MIN_BATCH {
        out.par_iter_mut().zip(xs.par_chunks_exact(d)).for_each(|(o, x)| *o = sanitize(c.cost(x)));
    } else {
        for (o, x) in out.iter_mut().zip(xs.chunks_exact(d)) {
            *o = sanitize(c.cost(x));
        }
    }
}

/// Like [`eval_rows`] through [`Cost::cost_refine`]: each row may be refined in place.
pub(crate) fn eval_rows_refine<C: Cost>(c: &C, xs: &mut [f64], d: usize, out: &mut [f64]) {
    debug_assert_eq!(xs.len(), out.len() * d);
    if out.len() >= PAR_MIN_BATCH {
        out.par_iter_mut().zip(xs.par_chunks_exact_mut(d)).for_each(|(o, x)| *o = sanitize(c.cost_refine(x)));
    } else {
        for (o, x) in out.iter_mut().zip(xs.chunks_exact_mut(d)) {
            *o = sanitize(c.cost_refine(x));
        }
    }
}

/// Early-stopping rule shared by the population methods: stop once the best cost has failed
/// to improve by more than `tol · |best|` (relative) for `patience` consecutive iterations.
/// `patience == 0` disables early stopping.
#[derive(Clone, Debug)]
pub(crate) struct Stall {
    tol: f64,
    patience: usize,
    best: f64,
    count: usize,
}

impl Stall {
    pub(crate) fn new(tol: f64, patience: usize, best: f64) -> Self {
        Stall { tol, patience, best, count: 0 }
    }

    /// Feed the best cost after an iteration; returns true when the run should stop.
    pub(crate) fn update(&mut self, best: f64) -> bool {
        let improved = if self.best.is_finite() { self.best - best > self.tol * self.best.abs() } else { best < self.best };
        if improved {
            self.count = 0;
        } else {
            self.count += 1;
        }
        if best < self.best {
            self.best = best;
        }
        self.patience > 0 && self.count >= self.patience
    }
}

/// Index of the smallest value (first one on ties), for already sanitised costs.
pub(crate) fn argmin(v: &[f64]) -> usize {
    let mut b = 0;
    for (i, &f) in v.iter().enumerate() {
        if f < v[b] {
            b = i;
        }
    }
    b
}

/// `½ Σ (z_i − h_i(x))²` over the observations `order` (the epoch cost of the sequential
/// filters), NaN → +∞.
pub(crate) fn obs_cost<O: Observations>(o: &O, x: &[f64], order: &[usize]) -> f64 {
    let c = 0.5
        * order
            .iter()
            .map(|&i| {
                let e = o.measured(i) - o.predict(x, i);
                e * e
            })
            .sum::<f64>();
    sanitize(c)
}

#[cfg(test)]
pub(crate) mod testfns {
    //! Benchmark functions used by the tests of several solvers.
    use super::super::Cost;

    pub struct Sphere(pub usize);
    impl Cost for Sphere {
        fn dim(&self) -> usize {
            self.0
        }
        fn cost(&self, x: &[f64]) -> f64 {
            x.iter().map(|v| v * v).sum()
        }
    }

    pub struct Rosenbrock;
    impl Cost for Rosenbrock {
        fn dim(&self) -> usize {
            2
        }
        fn cost(&self, x: &[f64]) -> f64 {
            let (a, b) = (1.0 - x[0], x[1] - x[0] * x[0]);
            a * a + 100.0 * b * b
        }
    }

    /// A cost that is NaN on part of the box, to check nothing panics.
    pub struct NanHole;
    impl Cost for NanHole {
        fn dim(&self) -> usize {
            2
        }
        fn cost(&self, x: &[f64]) -> f64 {
            if x[0] > 1.0 {
                f64::NAN
            } else {
                (x[0] - 0.5).powi(2) + x[1] * x[1]
            }
        }
    }
}
