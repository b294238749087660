//! Method `rbf`: LM geometry plus an RBF network.

use super::lm::LmSolver;
use super::solver::{Problem, Solution, Solver};
use crate::calib::correctors::rbf::RbfNetwork;
use crate::calib::correctors::Corrector;
use crate::error::{Error, Result};
use crate::optim::Observer;

/// LM geometry, then a Gaussian RBF network on the training residuals (centres and ridge by
/// cross-validation).
#[derive(Clone, Debug, PartialEq)]
pub struct RbfSolver {
    /// The geometric fit.
    pub lm: LmSolver,
    /// Candidate numbers of centres, chosen by cross-validation.
    pub centres: Vec<usize>,
    /// Candidate ridge weights, chosen by cross-validation.
    pub ridges: Vec<f64>,
}

impl Default for RbfSolver {
    fn default() -> Self {
        RbfSolver { lm: LmSolver::default(), centres: RbfNetwork::CV_CENTRES.to_vec(), ridges: RbfNetwork::CV_RIDGES.to_vec() }
    }
}

impl RbfSolver {
    /// The name the method is registered under (its row of [`super::METHODS`]).
    pub const NAME: &'static str = "rbf";
}

impl Solver for RbfSolver {
    fn learns_corrector(&self) -> bool {
        true
    }
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        let report = self.lm.solve(p, obs)?.report;
        let res = p.fit.residuals_mm(&report.x);
        let fit = |r: &[f64]| -> Result<Corrector> {
            let (net, _) =
                RbfNetwork::fit_cv(&p.fit.data.q, r, &self.centres, &self.ridges, p.seed).map_err(|e| Error::Calibration(format!("RBF network: {e}")))?;
            Ok(Corrector::Rbf(net))
        };
        // One network per reading value, each on that value's residuals.
        let d = p.fit.data.dim;
        let corrector = Corrector::of_values((0..d).map(|c| fit(&crate::stats::value_column(&res, d, c))).collect::<Result<Vec<_>>>()?);
        Ok(Solution { report, corrector: Some(corrector) })
    }
}
