//! Method `pso`: Particle swarm optimisation.

use super::solver::{Problem, Solution, Solver};
use crate::calib::fit::{FreeCost, ReadingFit};
use crate::error::Result;
use crate::optim::{Bounds, Observer, Pso};

/// Particle swarm over the identifiable parameters inside ± `width_sigmas` tolerances.
#[derive(Clone, Debug, PartialEq)]
pub struct PsoSolver {
    /// Swarm size.
    pub particles: usize,
    /// Iteration budget.
    pub iterations: usize,
    /// Stalled iterations before stopping (0 = never stop early).
    pub patience: usize,
    /// Half-width of the search box around the start, in tolerances (prior standard deviations).
    pub width_sigmas: f64,
}

impl Default for PsoSolver {
    fn default() -> Self {
        PsoSolver { particles: 60, iterations: 1500, patience: 200, width_sigmas: 5.0 }
    }
}

/// Re-expresses observed free-parameter vectors as full vectors for the caller's observer.
struct Expand<'a, 'b> {
    cost: &'a FreeCost<'b>,
    inner: &'a mut dyn Observer,
}

impl Observer for Expand<'_, '_> {
    fn observe(&mut self, e: &crate::optim::Event) {
        let x = self.cost.expand(e.x);
        self.inner.observe(&crate::optim::Event { x: &x, ..e.clone() });
    }
}

impl PsoSolver {
    /// The name the method is registered under (its row of [`super::METHODS`]).
    pub const NAME: &'static str = "pso";
}

impl Solver for PsoSolver {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        let free = p.free();
        let half: Vec<f64> = free.iter().map(|&k| self.width_sigmas * p.prior_std[k]).collect();
        let centre: Vec<f64> = free.iter().map(|&k| p.x0[k]).collect();
        let bounds = Bounds::around(&centre, &half);
        let cost = FreeCost { fit: ReadingFit { model: p.fit.model, data: p.fit.data }, base: p.x0.to_vec(), free };
        let pso = Pso { particles: self.particles, iterations: self.iterations, seed: p.seed, patience: self.patience, ..Default::default() };
        let mut report = pso.minimize(&cost, &bounds, Some(&centre), &mut Expand { cost: &cost, inner: obs });
        report.x = cost.expand(&report.x);
        Ok(Solution { report, corrector: None })
    }
}
