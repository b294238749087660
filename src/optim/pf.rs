//! Regularised sequential-importance-resampling (SIR) particle filter for *static* parameters.
//!
//! Particles are drawn from an independent Gaussian prior `N(prior_mean, prior_std²)`
//! (fixed parameters sit exactly at `prior_mean`). The observations listed in `order` are
//! consumed in batches of `batch`; each batch multiplies every particle's weight by the
//! Gaussian likelihood `exp(−½ Σ_batch (z_i − h_i(x))² / r)`. Weights are kept as normalised
//! log-weights (log-sum-exp), so even very peaked likelihoods do not underflow to all-zero.
//!
//! When the effective sample size `ESS = 1 / Σ w²` drops below `N/2` the particles are
//! resampled systematically (one uniform draw, `N` evenly spaced pointers — low variance,
//! O(N)) and then *roughened* (Gordon, Salmond & Smith 1993) to fight sample impoverishment,
//! which is otherwise fatal for static parameters (no process noise ever re-diversifies them):
//!
//! ```text
//! x_k ← x_k + σ_k·ε,  ε ~ N(0, 1),  σ_k = K · E_k · N^(−1/d)
//! ```
//!
//! with `E_k` the range (max − min) of the resampled particles in free dimension `k`,
//! `d` the number of free dimensions and `K = roughening`.
//!
//! After each epoch (one pass over `order`) an [`Event`] reports the weighted mean and the cost
//! `½ Σ_{i∈order} (z_i − h_i(mean))²`. The report holds the weighted mean and weighted covariance.
//!
//! Likelihoods are evaluated in parallel over particles (rayon) when `particles·batch` is large;
//! each particle's sum is computed in a fixed order and all random numbers are drawn on the
//! calling thread, so results are identical for any thread count.
//!
//! Non-finite predictions give the particle zero weight. If a batch gives *every* particle
//! zero weight it is ignored (the weights are left unchanged) and counted in the report reason.
//!
//! Caveats: more than one epoch re-uses the data, so the particle cloud contracts beyond the
//! true posterior (roughly like 1/epochs in variance); roughening itself slightly inflates
//! the spread. Use one epoch when the covariance should be read as a posterior.

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

use super::util::{free_indices, obs_cost};
use super::{Event, Observations, Observer, Report, Termination};

const METHOD: &str = "particle-filter";
/// Use rayon for the likelihood when particles × batch reaches this many predictions.
const PAR_MIN_WORK: usize = 4096;

/// Particle filter settings. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleFilter {
    /// Number of particles N.
    pub particles: usize,
    /// Passes over `order`.
    pub epochs: usize,
    /// Observations per weight update (≥ 1).
    pub batch: usize,
    /// Measurement-noise variance.
    pub r: f64,
    /// Roughening constant K: jitter σ_k = K·E_k·N^(−1/d) after each resampling.
    pub roughening: f64,
    /// RNG seed (ChaCha8).
    pub seed: u64,
}

impl Default for ParticleFilter {
    fn default() -> Self {
        ParticleFilter { particles: 2000, epochs: 1, batch: 5, r: 1.0, roughening: 0.2, seed: 0 }
    }
}

/// Log-likelihood of one particle for a batch (without the constant), −∞ when not finite.
fn log_lik<O: Observations>(o: &O, x: &[f64], batch: &[usize], inv_r: f64) -> f64 {
    let mut s = 0.0;
    for &i in batch {
        let e = o.measured(i) - o.predict(x, i);
        s += e * e;
    }
    let l = -0.5 * s * inv_r;
    if l.is_nan() {
        f64::NEG_INFINITY
    } else {
        l
    }
}

/// Weighted mean of the free coordinates into `mean` (len n) for row-major particles; fixed
/// coordinates are copied from the first particle (they are identical in all particles), so they
/// come back bit for bit rather than as a rounded weighted sum.
fn weighted_mean(parts: &[f64], logw: &[f64], n: usize, free: &[usize], mean: &mut [f64]) {
    mean.copy_from_slice(&parts[..n]);
    for &k in free {
        mean[k] = 0.0;
    }
    for (row, &lw) in parts.chunks_exact(n).zip(logw) {
        let w = lw.exp();
        for &k in free {
            mean[k] += w * row[k];
        }
    }
}

impl ParticleFilter {
    /// Run the filter. `prior_mean`/`prior_std` define the independent Gaussian prior;
    /// `fixed[k] == true` pins parameter `k` at `prior_mean[k]`. `order` lists the observation
    /// indices processed in every epoch.
    ///
    /// `Report::x` is the weighted mean, `Report::covariance` the weighted covariance (zero for
    /// fixed parameters), `Report::evaluations` counts calls to `predict`. `converged` is true
    /// when the final cost is finite (the filter has no convergence test of its own).
    ///
    /// # Panics
    /// If `prior_mean` or `prior_std` do not have `o.n_params()` entries.
    pub fn run<O: Observations>(&self, o: &O, prior_mean: &[f64], prior_std: &[f64], fixed: &[bool], order: &[usize], obs: &mut dyn Observer) -> Report {
        let n = o.n_params();
        assert_eq!(prior_mean.len(), n, "prior_mean must have {n} entries");
        assert_eq!(prior_std.len(), n, "prior_std must have {n} entries");
        let free = free_indices(fixed, n);
        let np = self.particles.max(1);
        let batch = self.batch.max(1);
        let inv_r = if self.r > 0.0 { 1.0 / self.r } else { f64::INFINITY };
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);

        // Row-major particle matrix (np × n) and its resampling twin.
        let mut parts = vec![0.0; np * n];
        for row in parts.chunks_exact_mut(n) {
            row.copy_from_slice(prior_mean);
            for &k in &free {
                let e: f64 = rng.sample(StandardNormal);
                row[k] += prior_std[k].abs() * e;
            }
        }
        let mut spare = parts.clone();
        let uniform = -(np as f64).ln();
        let mut logw = vec![uniform; np];
        let mut cand = vec![0.0; np];
        let mut loglik = vec![0.0; np];
        let mut mean = vec![0.0; n];
        let mut lo = vec![0.0; n];
        let mut hi = vec![0.0; n];
        let dfree = free.len().max(1) as f64;
        let shrink = (np as f64).powf(-1.0 / dfree);

        let mut evaluations = 0usize;
        let mut resamplings = 0usize;
        let mut ignored = 0usize;
        let mut iterations = 0;
        let mut cost = f64::INFINITY;

        while iterations < self.epochs {
            iterations += 1;
            for chunk in order.chunks(batch) {
                if np * chunk.len() >= PAR_MIN_WORK {
                    loglik.par_iter_mut().zip(parts.par_chunks_exact(n)).for_each(|(l, x)| *l = log_lik(o, x, chunk, inv_r));
                } else {
                    for (l, x) in loglik.iter_mut().zip(parts.chunks_exact(n)) {
                        *l = log_lik(o, x, chunk, inv_r);
                    }
                }
                evaluations += np * chunk.len();

                let Some(ess) = reweight(&mut logw, &loglik, &mut cand) else {
                    ignored += 1;
                    continue;
                };
                if ess < 0.5 * np as f64 {
                    resamplings += 1;
                    systematic_resample(&mut parts, &mut spare, &logw, n, &mut rng);
                    logw.iter_mut().for_each(|w| *w = uniform);
                    if self.roughening > 0.0 {
                        roughen(&mut parts, n, &free, (self.roughening, shrink), (&mut lo, &mut hi), &mut rng);
                    }
                }
            }

            weighted_mean(&parts, &logw, n, &free, &mut mean);
            cost = obs_cost(o, &mean, order);
            evaluations += order.len();
            obs.observe(&Event { method: METHOD, iteration: iterations, cost, x: &mean });
        }
        if iterations == 0 {
            weighted_mean(&parts, &logw, n, &free, &mut mean);
            cost = obs_cost(o, &mean, order);
            evaluations += order.len();
        }

        let cov = weighted_covariance(&parts, &logw, &mean, &free);

        let mut reason = format!("{iterations} epochs, {resamplings} resamplings");
        if ignored > 0 {
            reason.push_str(&format!(", {ignored} batches ignored (zero likelihood for every particle)"));
        }
        let termination = if cost.is_finite() { Termination::Completed } else { Termination::NonFinite };
        Report { x: mean, cost, iterations, evaluations, termination, reason, covariance: Some(cov) }
    }
}

/// Multiplies the weights by the batch's likelihoods (log-weights `logw` + `loglik`, through
/// `cand`) and normalises them with log-sum-exp; returns the effective sample size, or None when
/// every particle's likelihood is zero (the weights are then left as they were).
fn reweight(logw: &mut [f64], loglik: &[f64], cand: &mut [f64]) -> Option<f64> {
    let mut mx = f64::NEG_INFINITY;
    for i in 0..logw.len() {
        cand[i] = logw[i] + loglik[i];
        if cand[i] > mx {
            mx = cand[i];
        }
    }
    if !mx.is_finite() {
        return None;
    }
    let sum: f64 = cand.iter().map(|&c| (c - mx).exp()).sum();
    let lse = mx + sum.ln();
    let mut sum_w2 = 0.0;
    for i in 0..logw.len() {
        logw[i] = cand[i] - lse;
        let w = logw[i].exp();
        sum_w2 += w * w;
    }
    Some(1.0 / sum_w2)
}

/// Systematic resampling of the row-major particles (`n` parameters a row) by their log-weights:
/// pointers (u0 + j)/N against the cumulative weights; `spare` is the work buffer, swapped in.
fn systematic_resample(parts: &mut Vec<f64>, spare: &mut Vec<f64>, logw: &[f64], n: usize, rng: &mut ChaCha8Rng) {
    let np = logw.len();
    let u0: f64 = rng.random::<f64>();
    let mut cum = logw[0].exp();
    let mut src = 0;
    for j in 0..np {
        let u = (u0 + j as f64) / np as f64;
        while cum < u && src + 1 < np {
            src += 1;
            cum += logw[src].exp();
        }
        spare[j * n..(j + 1) * n].copy_from_slice(&parts[src * n..(src + 1) * n]);
    }
    std::mem::swap(parts, spare);
}

/// Roughening: a jitter of `roughening` times the resampled cloud's spread times `shrink`, per
/// free dimension (`lo`, `hi` the work buffers of the spread).
fn roughen(parts: &mut [f64], n: usize, free: &[usize], (roughening, shrink): (f64, f64), (lo, hi): (&mut [f64], &mut [f64]), rng: &mut ChaCha8Rng) {
    for &k in free {
        lo[k] = f64::INFINITY;
        hi[k] = f64::NEG_INFINITY;
    }
    for row in parts.chunks_exact(n) {
        for &k in free {
            lo[k] = lo[k].min(row[k]);
            hi[k] = hi[k].max(row[k]);
        }
    }
    for row in parts.chunks_exact_mut(n) {
        for &k in free {
            let sigma = roughening * (hi[k] - lo[k]) * shrink;
            let e: f64 = rng.sample(StandardNormal);
            if sigma.is_finite() {
                row[k] += sigma * e;
            }
        }
    }
}

/// The particles' weighted covariance about `mean` (zero for the parameters not in `free`).
fn weighted_covariance(parts: &[f64], logw: &[f64], mean: &[f64], free: &[usize]) -> DMatrix<f64> {
    let n = mean.len();
    let mut cov = DMatrix::<f64>::zeros(n, n);
    for (row, &lw) in parts.chunks_exact(n).zip(logw) {
        let w = lw.exp();
        for &a in free {
            let da = row[a] - mean[a];
            for &b in free {
                cov[(a, b)] += w * da * (row[b] - mean[b]);
            }
        }
    }
    cov
}

#[cfg(test)]
mod tests {
    use super::super::NoObserver;
    use super::*;
    use nalgebra::DVector;
    use rand_distr::{Distribution, Normal};

    /// z = a + b·t + noise.
    struct Line {
        t: Vec<f64>,
        z: Vec<f64>,
    }
    impl Line {
        fn new(a: f64, b: f64, m: usize, sigma: f64, seed: u64) -> Self {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let nd = Normal::new(0.0, sigma).unwrap();
            let t: Vec<f64> = (0..m).map(|i| i as f64 / (m - 1) as f64 * 4.0 - 2.0).collect();
            let z = t.iter().map(|&t| a + b * t + nd.sample(&mut rng)).collect();
            Line { t, z }
        }
    }
    impl Observations for Line {
        fn n_params(&self) -> usize {
            2
        }
        fn n_obs(&self) -> usize {
            self.t.len()
        }
        fn predict(&self, x: &[f64], i: usize) -> f64 {
            x[0] + x[1] * self.t[i]
        }
        fn measured(&self, i: usize) -> f64 {
            self.z[i]
        }
        fn gradient(&self, _x: &[f64], i: usize, g: &mut [f64]) {
            g[0] = 1.0;
            g[1] = self.t[i];
        }
    }

    /// Exact Gaussian posterior (prior × likelihood) of the linear model.
    fn exact_posterior(l: &Line, m0: &[f64], s0: &[f64], r: f64) -> (DVector<f64>, DMatrix<f64>) {
        let x = DMatrix::from_fn(l.t.len(), 2, |i, k| if k == 0 { 1.0 } else { l.t[i] });
        let mut prec = x.transpose() * &x / r;
        let mut rhs = x.transpose() * DVector::from_column_slice(&l.z) / r;
        for k in 0..2 {
            prec[(k, k)] += 1.0 / (s0[k] * s0[k]);
            rhs[k] += m0[k] / (s0[k] * s0[k]);
        }
        let cov = prec.try_inverse().unwrap();
        (&cov * rhs, cov)
    }

    fn setup() -> (Line, Vec<usize>, ParticleFilter) {
        let l = Line::new(0.8, -0.6, 40, 0.2, 11);
        let order: Vec<usize> = (0..l.t.len()).collect();
        let pf = ParticleFilter { particles: 3000, epochs: 1, batch: 2, r: 0.04, roughening: 0.1, seed: 42 };
        (l, order, pf)
    }

    #[test]
    fn linear_model_posterior_mean() {
        let (l, order, pf) = setup();
        let (m0, s0) = ([0.0, 0.0], [2.0, 2.0]);
        let (post_mean, post_cov) = exact_posterior(&l, &m0, &s0, pf.r);
        let rep = pf.run(&l, &m0, &s0, &[], &order, &mut NoObserver);
        for k in 0..2 {
            let sd = post_cov[(k, k)].sqrt();
            assert!((rep.x[k] - post_mean[k]).abs() < 3.0 * sd, "pf {:?} vs exact {post_mean} (sd {sd})", rep.x);
        }
        let cov = rep.covariance.unwrap();
        assert!(cov[(0, 0)] > 0.0 && cov[(1, 1)] > 0.0);
    }

    #[test]
    fn deterministic_and_fixed() {
        let (l, order, pf) = setup();
        let a = pf.run(&l, &[0.0, -0.6], &[1.0, 1.0], &[false, true], &order, &mut NoObserver);
        let b = pf.run(&l, &[0.0, -0.6], &[1.0, 1.0], &[false, true], &order, &mut NoObserver);
        assert_eq!(a.x, b.x);
        assert_eq!(a.x[1].to_bits(), (-0.6f64).to_bits());
        let cov = a.covariance.clone().unwrap();
        assert_eq!(cov[(1, 1)], 0.0);
        assert!((a.x[0] - 0.8).abs() < 0.2, "{a:?}");
        // Large batch → parallel likelihood path; still deterministic.
        let big = ParticleFilter { batch: 20, ..pf };
        let c = big.run(&l, &[0.0, 0.0], &[2.0, 2.0], &[], &order, &mut NoObserver);
        let d = big.run(&l, &[0.0, 0.0], &[2.0, 2.0], &[], &order, &mut NoObserver);
        assert_eq!(c.x, d.x);
    }
}
