//! Method `lm`: Levenberg–Marquardt.

use super::solver::{Problem, Solution, Solver};
use crate::error::Result;
use crate::optim::{LevenbergMarquardt, Observer};

/// Levenberg–Marquardt on all identifiable parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct LmSolver {
    /// The Levenberg–Marquardt settings.
    pub lm: LevenbergMarquardt,
    /// Squared residuals, or a robust loss by IRLS ([`crate::calib::fit::robust::irls`]).
    pub loss: crate::calib::fit::robust::Loss,
}

impl Default for LmSolver {
    fn default() -> Self {
        LmSolver { lm: LevenbergMarquardt::budget(2000), loss: crate::calib::fit::robust::Loss::L2 }
    }
}

impl LmSolver {
    /// The name the method is registered under (its row of [`super::METHODS`]).
    pub const NAME: &'static str = "lm";
}

impl Solver for LmSolver {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        Ok(Solution { report: crate::calib::fit::robust::irls(&self.lm, p.fit, p.x0, p.fixed, self.loss, obs), corrector: None })
    }
}
