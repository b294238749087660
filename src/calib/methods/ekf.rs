//! Method `ekf`: The extended Kalman filter.

use super::solver::{Problem, Solution, Solver};
use crate::error::Result;
use crate::optim::{Ekf, Observer};

/// Extended Kalman filter over the parameters: prior covariance from the tolerances, measurement
/// variance from the estimated noise, several passes over the shuffled training rows.
#[derive(Clone, Debug, PartialEq)]
pub struct EkfSolver {
    /// Passes over the shuffled training observations (at least one).
    pub epochs: usize,
}

impl EkfSolver {
    /// The name the method is registered under (its row of [`super::METHODS`]).
    pub const NAME: &'static str = "ekf";
}

impl Solver for EkfSolver {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn needs_noise(&self) -> bool {
        true
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        // A diffuse prior (3 tolerances): the filter should not pull towards the nominal.
        let p0 = p.prior_std.iter().map(|s| (3.0 * s).powi(2)).collect();
        let ekf = Ekf { epochs: self.epochs.max(1), q: 0.0, r: p.noise_mm.powi(2), p0, tol: 1e-10 };
        Ok(Solution { report: ekf.run(p.fit, p.x0, p.fixed, &p.shuffled_rows(), obs), corrector: None })
    }
}
