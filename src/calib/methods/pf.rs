//! Method `pf`: The regularised particle filter.

use super::solver::{Problem, Solution, Solver};
use crate::error::Result;
use crate::optim::{LeastSquares, Observer, ParticleFilter};

/// Regularised particle filter: particles drawn from the tolerance prior around the start.
#[derive(Clone, Debug, PartialEq)]
pub struct PfSolver {
    /// Number of particles.
    pub particles: usize,
    /// Passes over the shuffled training observations.
    pub epochs: usize,
    /// Observations per weight update.
    pub batch: usize,
    /// Roughening constant of the jitter after each resampling.
    pub roughening: f64,
}

impl Default for PfSolver {
    fn default() -> Self {
        PfSolver { particles: 4000, epochs: 4, batch: 10, roughening: 0.1 }
    }
}

impl PfSolver {
    /// The name the method is registered under (its row of [`super::METHODS`]).
    pub const NAME: &'static str = "pf";
}

impl Solver for PfSolver {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn needs_noise(&self) -> bool {
        true
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        // The likelihood is tempered to the starting misfit (never sharper than the noise), so
        // the weights do not collapse onto a handful of particles in the first batches.
        let r0 = 2.0 * LeastSquares::cost(p.fit, p.x0) / p.fit.data.y.len() as f64;
        let pf = ParticleFilter {
            particles: self.particles,
            epochs: self.epochs,
            batch: self.batch,
            r: r0.max(p.noise_mm.powi(2)),
            roughening: self.roughening,
            seed: p.seed,
        };
        Ok(Solution { report: pf.run(p.fit, p.x0, p.prior_std, p.fixed, &p.shuffled_rows(), obs), corrector: None })
    }
}
