//! Optimisers, generic over the problem (after argmin: problem, solver and observer are separate).
//!
//! * [`LeastSquares`]: residual vector and Jacobian — solved by Levenberg–Marquardt.
//! * [`Observations`]: one scalar measurement per sample — filtered by EKF and particle filters.
//! * [`Cost`] with [`Bounds`]: a scalar cost over a box — searched by PSO and the DE family.
//!
//! Progress goes to an [`Observer`], never to stdout.

use nalgebra::DMatrix;

/// A nonlinear least-squares problem: minimise ½‖r(x)‖².
pub trait LeastSquares: Sync {
    /// Number of parameters (the length of `x`).
    fn n_params(&self) -> usize;
    /// Number of residuals (the length of `r`).
    fn n_residuals(&self) -> usize;
    /// Residuals at `x` into `r` (len = n_residuals).
    fn residuals(&self, x: &[f64], r: &mut [f64]);
    /// Jacobian ∂r/∂x (n_residuals × n_params) into `j`. Default: central differences.
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        let (m, n) = (self.n_residuals(), self.n_params());
        let mut xp = x.to_vec();
        let mut rp = vec![0.0; m];
        let mut rm = vec![0.0; m];
        for k in 0..n {
            let h = 1e-6 * (1.0 + x[k].abs());
            xp[k] = x[k] + h;
            self.residuals(&xp, &mut rp);
            xp[k] = x[k] - h;
            self.residuals(&xp, &mut rm);
            xp[k] = x[k];
            for i in 0..m {
                j[(i, k)] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
    }
    /// Whether [`Self::residuals_and_jacobian`] has a pass of its own that costs less than the
    /// two apart (then LM asks for both at the trial points it expects to accept). Default: no.
    fn joint_pass(&self) -> bool {
        false
    }
    /// Residuals into `r` and the Jacobian into `j` at `x`: bit for bit what [`Self::residuals`]
    /// and [`Self::jacobian`] give. Default: the two.
    fn residuals_and_jacobian(&self, x: &[f64], r: &mut [f64], j: &mut DMatrix<f64>) {
        self.residuals(x, r);
        self.jacobian(x, j);
    }
    /// ½‖r(x)‖².
    fn cost(&self, x: &[f64]) -> f64 {
        let mut r = vec![0.0; self.n_residuals()];
        self.residuals(x, &mut r);
        0.5 * r.iter().map(|v| v * v).sum::<f64>()
    }
}

/// Scalar observations z_i = h_i(x) + noise, one per sample, for sequential filters.
pub trait Observations: Sync {
    /// Number of parameters (the length of `x`).
    fn n_params(&self) -> usize;
    /// Number of observations (samples `i` in `0..n_obs`).
    fn n_obs(&self) -> usize;
    /// The predicted observation h_i(x) of sample `i`.
    fn predict(&self, x: &[f64], i: usize) -> f64;
    /// The measured value z_i of sample `i`.
    fn measured(&self, i: usize) -> f64;
    /// ∂h_i/∂x into `g` (len = n_params).
    fn gradient(&self, x: &[f64], i: usize, g: &mut [f64]);
}

/// A scalar cost to minimise over a box.
pub trait Cost: Sync {
    /// Number of coordinates (the length of `x`).
    fn dim(&self) -> usize;
    /// The cost at `x`, to be minimised.
    fn cost(&self, x: &[f64]) -> f64;
    /// The cost of `x` after the cost may have improved `x` in place (a Lamarckian local step,
    /// such as solving the coordinates the cost is quadratic in; the result must stay inside
    /// the search box). The DE family evaluates through this. Default: [`Cost::cost`], `x` unchanged.
    fn cost_refine(&self, x: &mut [f64]) -> f64 {
        self.cost(x)
    }
}

/// Box bounds, `lower[k] < upper[k]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Bounds {
    /// Lower bound of each coordinate.
    pub lower: Vec<f64>,
    /// Upper bound of each coordinate.
    pub upper: Vec<f64>,
}

impl Bounds {
    /// The box `[lower[k], upper[k]]` (not checked).
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Self {
        Bounds { lower, upper }
    }
    /// A box of half-width `half[k]` around `centre`.
    pub fn around(centre: &[f64], half: &[f64]) -> Self {
        Bounds { lower: centre.iter().zip(half).map(|(c, h)| c - h).collect(), upper: centre.iter().zip(half).map(|(c, h)| c + h).collect() }
    }
    /// Number of coordinates.
    pub fn dim(&self) -> usize {
        self.lower.len()
    }
    /// Clamps each coordinate `x[k]` into `[lower[k], upper[k]]`, in place.
    pub fn clamp(&self, x: &mut [f64]) {
        for k in 0..x.len() {
            x[k] = x[k].clamp(self.lower[k], self.upper[k]);
        }
    }
}

/// One progress event.
#[derive(Clone, Debug)]
pub struct Event<'a> {
    /// Name of the reporting method (e.g. `"levenberg-marquardt"`, `"pso"`, `"lshade"`).
    pub method: &'a str,
    /// The iteration the event belongs to (LM outer iteration, PSO iteration, DE generation or
    /// filter epoch), counted from 1.
    pub iteration: usize,
    /// Best cost so far (½ sum of squares for least squares; the method's cost otherwise).
    pub cost: f64,
    /// Current best parameters.
    pub x: &'a [f64],
}

/// Receives progress events (progress bars, convergence recordings, ...).
pub trait Observer {
    /// Receives one progress event. Default: ignores it.
    fn observe(&mut self, _event: &Event) {}
}

/// Ignores everything.
pub struct NoObserver;
impl Observer for NoObserver {}

/// Records the cost and parameters at every iteration.
#[derive(Clone, Debug, Default)]
pub struct History {
    /// [`Event::cost`] of every event, in order.
    pub cost: Vec<f64>,
    /// [`Event::x`] of every event, in order.
    pub x: Vec<Vec<f64>>,
}
impl Observer for History {
    fn observe(&mut self, e: &Event) {
        self.cost.push(e.cost);
        self.x.push(e.x.to_vec());
    }
}

/// What a solver returns.
#[derive(Clone, Debug)]
pub struct Report {
    /// The estimate: the best point found (LM, PSO, DE), the final state (EKF) or the weighted
    /// particle mean (PF).
    pub x: Vec<f64>,
    /// The cost at `x` (½ sum of squared residuals or innovations for LM and the filters; the
    /// [`Cost`] otherwise).
    pub cost: f64,
    /// Iterations run (LM outer iterations, PSO iterations, DE generations, filter epochs).
    pub iterations: usize,
    /// Objective evaluations (residual vectors, costs or observations, as the method counts them).
    pub evaluations: usize,
    /// Why it stopped, as one value every optimiser shares.
    pub termination: Termination,
    /// Why it stopped, in words (the optimiser's own, with its details).
    pub reason: String,
    /// Method-specific covariance of x where the method has one (EKF, PF), else None.
    pub covariance: Option<DMatrix<f64>>,
}

/// Why an optimiser stopped: the one termination type of every optimiser (the words of
/// [`Report::reason`] add each one's details).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Termination {
    /// The iteration budget (iterations, generations, epochs) ran out.
    Budget,
    /// The evaluation budget ran out.
    EvaluationBudget,
    /// The cost stopped improving over a window (LM's stall test, DE's and PSO's patience).
    Stalled,
    /// The relative cost change fell below its tolerance.
    CostTolerance,
    /// The relative step fell below its tolerance.
    StepTolerance,
    /// The gradient fell below its tolerance.
    GradientTolerance,
    /// The cost is zero.
    ZeroCost,
    /// A non-finite cost or Jacobian.
    NonFinite,
    /// No step reduces the cost (LM's damping overflow).
    NoDescent,
    /// Nothing to estimate (no free parameters or no observations).
    NothingToDo,
    /// A fixed schedule ran to its end (the particle filter's epochs, a method's own stages).
    Completed,
}

impl Termination {
    /// Whether this way of stopping counts as converged.
    pub fn converged(self) -> bool {
        !matches!(self, Termination::Budget | Termination::EvaluationBudget | Termination::NonFinite | Termination::NoDescent)
    }
}

impl Report {
    /// Whether the optimiser converged ([`Termination::converged`]).
    pub fn converged(&self) -> bool {
        self.termination.converged()
    }
}

pub mod de;
pub mod ekf;
pub mod lm;
mod normal;
pub mod pf;
pub mod pso;
mod util;

pub use de::{De, DeVariant};
pub use ekf::{Ekf, NoHook, ObservationHook};
pub use lm::{cluster_covariance, covariance, covariances, Damping, LevenbergMarquardt};
pub use pf::ParticleFilter;
pub use pso::Pso;
