//! What every calibration method is: a [`Solver`] that solves a [`Problem`] into a [`Solution`].

use crate::calib::correctors::Corrector;
use crate::calib::fit::ReadingFit;
use crate::error::Result;
use crate::optim::{Observer, Report};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// What a solver is given: the fit on the training rows, the start, the fixed (non-identifiable)
/// parameters, a one-sigma prior spread per parameter and the noise level estimated from the data.
pub struct Problem<'a> {
    /// The fit on the training rows.
    pub fit: &'a ReadingFit<'a>,
    /// The start, internal units.
    pub x0: &'a [f64],
    /// Per parameter, whether it is held at its start (not identifiable).
    pub fixed: &'a [bool],
    /// One standard deviation per parameter, internal units (from the tolerances).
    pub prior_std: &'a [f64],
    /// Standard deviation of one reading, mm, estimated from the data.
    pub noise_mm: f64,
    /// Seed of the method's random draws.
    pub seed: u64,
}

impl Problem<'_> {
    pub(crate) fn free(&self) -> Vec<usize> {
        (0..self.x0.len()).filter(|k| !self.fixed[*k]).collect()
    }
    /// The training observations (reading values) in a seeded random order (for the sequential filters).
    pub(crate) fn shuffled_rows(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.fit.data.y.len()).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(self.seed));
        order
    }
}

/// A solver's answer: the optimiser's report and, for methods that add one, a learned corrector
/// of what the geometry leaves (see [`crate::calib::correctors`]).
pub struct Solution {
    /// The optimiser's report; `x` is the calibrated parameter vector.
    pub report: Report,
    /// The learned corrector of what the geometry leaves, for methods that fit one.
    pub corrector: Option<Corrector>,
}

/// A calibration method with its settings.
pub trait Solver: Send + Sync {
    /// Its name, recorded in the result (`provenance.method`): a registered method's is the name
    /// [`super::Method::parse`] reads; a solver of the user's own names itself.
    fn name(&self) -> &'static str;
    /// Whether the method uses [`Problem::noise_mm`] (the pipeline then estimates it first).
    fn needs_noise(&self) -> bool {
        false
    }
    /// Whether the method reads the rows' inputs ([`crate::calib::effects::RowInputs`]: time,
    /// temperature, flanks, torques) even when the model has no effect blocks (the pipeline
    /// then computes them, with the torque model when the robot has inertial data).
    fn needs_row_inputs(&self) -> bool {
        false
    }
    /// Whether the method adds a learned corrector of the residuals (rbf and the papers'
    /// methods): the pipeline then fits with equal weights, as the corrector learns plain
    /// residuals.
    fn learns_corrector(&self) -> bool {
        false
    }
    /// Solves `p`, reporting progress to `obs`.
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution>;
}

/// What the stages before the solve prepare for the solver that follows
/// ([`crate::calib::pipeline::prepare`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SolverNeeds {
    /// Every row its inputs (and the split its torque model) even without effect blocks
    /// ([`Solver::needs_row_inputs`]).
    pub row_inputs: bool,
    /// Equal weights for every row, whatever their standard deviations
    /// ([`Solver::learns_corrector`]).
    pub equal_weights: bool,
}

impl SolverNeeds {
    /// What `solver` needs.
    pub fn of(solver: &dyn Solver) -> SolverNeeds {
        SolverNeeds { row_inputs: solver.needs_row_inputs(), equal_weights: solver.learns_corrector() }
    }
}
