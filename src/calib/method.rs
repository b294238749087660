//! Calibration methods as solver values. Each method is a struct that carries its own settings
//! and solves a [`Problem`]; the pipeline in [`super::run`] only calls [`Solver::solve`], so a new
//! method (or one with other settings) is added beside these, not inside the pipeline.
//!
//! Nothing here knows how the data were made: spreads come from the documented
//! [`Tolerances`](super::tolerance::Tolerances) (via [`Problem::prior_std`]) and noise levels
//! from the data ([`Problem::noise_mm`]).

use super::corrector::Corrector;
use super::evonph::{EvoNphSolver, EvoVariant};
use super::problem::{FreeCost, ReadingFit};
use super::psoekf::{Ablation, PsoEkfAwnn};
use super::rbf::RbfNetwork;
use crate::error::{Error, Result};
use crate::optim::{Bounds, Ekf, LeastSquares, LevenbergMarquardt, Observer, ParticleFilter, Pso, Report};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// The methods the command line offers by name (stored in result.json by that name).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum Method {
    Lm,
    Ekf,
    Pf,
    Pso,
    Rbf,
    /// Evo-NPH: DS-ADE over geometry and GKAN coefficients ([`super::evonph`]).
    #[serde(rename = "dsade-gkan")]
    DsadeGkan,
    /// Evo-NPH ablation V1: sequential (LM geometry, then the GKAN).
    #[serde(rename = "dsade-gkan-v1")]
    DsadeGkanV1,
    /// Evo-NPH ablation V2: a matched-size ReLU MLP instead of the GKAN.
    #[serde(rename = "dsade-gkan-v2")]
    DsadeGkanV2,
    /// Evo-NPH ablation V3: single-strategy DE.
    #[serde(rename = "dsade-gkan-v3")]
    DsadeGkanV3,
    /// PSO-EKF-AWNN or one of its ablations (see [`super::psoekf`]).
    PsoEkfAwnn(Ablation),
}

impl Method {
    /// Whether the method adds a learned corrector of the residuals (rbf and the papers'
    /// methods): they fit with equal weights, as their correctors learn plain residuals.
    pub fn learns_corrector(self) -> bool {
        matches!(self, Method::Rbf | Method::DsadeGkan | Method::DsadeGkanV1 | Method::DsadeGkanV2 | Method::DsadeGkanV3 | Method::PsoEkfAwnn(_))
    }
}

impl From<Method> for String {
    fn from(m: Method) -> String {
        m.name().into()
    }
}

impl TryFrom<String> for Method {
    type Error = Error;
    fn try_from(s: String) -> Result<Method> {
        Method::parse(&s)
    }
}

impl Method {
    pub const ALL: [Method; 5] = [Method::Lm, Method::Ekf, Method::Pf, Method::Pso, Method::Rbf];

    /// The Evo-NPH method and its ablations (not in [`Method::ALL`], the core's baselines).
    pub const EVO_NPH: [Method; 4] = [Method::DsadeGkan, Method::DsadeGkanV1, Method::DsadeGkanV2, Method::DsadeGkanV3];

    pub fn parse(s: &str) -> Result<Method> {
        let s = s.trim().to_ascii_lowercase();
        Method::ALL.into_iter().chain(Method::EVO_NPH).chain(Ablation::ALL.map(Method::PsoEkfAwnn)).find(|m| m.name() == s).ok_or_else(|| {
            Error::Invalid(format!(
                "unknown method '{s}' (expected lm, ekf, pf, pso, rbf, dsade-gkan or its ablations dsade-gkan-v1, -v2, -v3, \
                 pso-ekf-awnn or its ablations pso-ekf-awnn-v1 .. -v5 and pso-ekf-awnn-x)"
            ))
        })
    }
    pub fn name(self) -> &'static str {
        match self {
            Method::Lm => "lm",
            Method::Ekf => "ekf",
            Method::Pf => "pf",
            Method::Pso => "pso",
            Method::Rbf => "rbf",
            Method::DsadeGkan => "dsade-gkan",
            Method::DsadeGkanV1 => "dsade-gkan-v1",
            Method::DsadeGkanV2 => "dsade-gkan-v2",
            Method::DsadeGkanV3 => "dsade-gkan-v3",
            Method::PsoEkfAwnn(v) => v.method_name(),
        }
    }
    /// The method with its default settings; `effort` scales the budget of the stochastic ones.
    pub fn solver(self, effort: f64) -> Box<dyn Solver> {
        match self {
            Method::Lm => Box::new(LmSolver::default()),
            Method::Ekf => Box::new(EkfSolver { epochs: (20.0 * effort).ceil() as usize }),
            Method::Pf => Box::new(PfSolver { particles: (4000.0 * effort).max(100.0) as usize, ..Default::default() }),
            Method::Pso => Box::new(PsoSolver { iterations: (1500.0 * effort).max(10.0) as usize, ..Default::default() }),
            Method::Rbf => Box::new(RbfSolver::default()),
            Method::DsadeGkan => Box::new(EvoNphSolver::new(EvoVariant::Full, effort)),
            Method::DsadeGkanV1 => Box::new(EvoNphSolver::new(EvoVariant::Sequential, effort)),
            Method::DsadeGkanV2 => Box::new(EvoNphSolver::new(EvoVariant::Mlp, effort)),
            Method::DsadeGkanV3 => Box::new(EvoNphSolver::new(EvoVariant::SingleStrategy, effort)),
            Method::PsoEkfAwnn(v) => Box::new(PsoEkfAwnn { pso_iterations: ((10.0 * effort).ceil() as usize).max(2), ..PsoEkfAwnn::variant(v) }),
        }
    }
}

/// What a solver is given: the fit on the training rows, the start, the fixed (non-identifiable)
/// parameters, a one-sigma prior spread per parameter and the noise level estimated from the data.
pub struct Problem<'a> {
    pub fit: &'a ReadingFit<'a>,
    pub x0: &'a [f64],
    pub fixed: &'a [bool],
    /// One standard deviation per parameter, internal units (from the tolerances).
    pub prior_std: &'a [f64],
    /// Standard deviation of one reading, mm, estimated from the data.
    pub noise_mm: f64,
    pub seed: u64,
}

impl Problem<'_> {
    fn free(&self) -> Vec<usize> {
        (0..self.x0.len()).filter(|k| !self.fixed[*k]).collect()
    }
    /// The training observations (reading values) in a seeded random order (for the sequential filters).
    fn shuffled_rows(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.fit.data.y.len()).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(self.seed));
        order
    }
}

/// A solver's answer: the optimiser's report and, for methods that add one, a learned corrector
/// of what the geometry leaves (see [`super::corrector`]).
pub struct Solution {
    pub report: Report,
    pub corrector: Option<Corrector>,
}

/// A calibration method with its settings.
pub trait Solver: Send + Sync {
    fn method(&self) -> Method;
    /// Whether the method uses [`Problem::noise_mm`] (the pipeline then estimates it first).
    fn needs_noise(&self) -> bool {
        false
    }
    /// Whether the method reads the rows' inputs ([`super::effects::RowInputs`]: time,
    /// temperature, flanks, torques) even when the model has no effect blocks (the pipeline
    /// then computes them, with the torque model when the robot has inertial data).
    fn needs_row_inputs(&self) -> bool {
        false
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution>;
}

/// Levenberg–Marquardt on all identifiable parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct LmSolver {
    pub lm: LevenbergMarquardt,
    /// Squared residuals, or a robust loss by IRLS ([`super::robust::irls`]).
    pub loss: super::robust::Loss,
}

impl Default for LmSolver {
    fn default() -> Self {
        LmSolver { lm: LevenbergMarquardt::budget(2000), loss: super::robust::Loss::L2 }
    }
}

impl Solver for LmSolver {
    fn method(&self) -> Method {
        Method::Lm
    }
    fn solve(&self, p: &Problem, obs: &mut dyn Observer) -> Result<Solution> {
        Ok(Solution { report: super::robust::irls(&self.lm, p.fit, p.x0, p.fixed, self.loss, obs), corrector: None })
    }
}

/// Extended Kalman filter over the parameters: prior covariance from the tolerances, measurement
/// variance from the estimated noise, several passes over the shuffled training rows.
#[derive(Clone, Debug, PartialEq)]
pub struct EkfSolver {
    pub epochs: usize,
}

impl Solver for EkfSolver {
    fn method(&self) -> Method {
        Method::Ekf
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

/// Regularised particle filter: particles drawn from the tolerance prior around the start.
#[derive(Clone, Debug, PartialEq)]
pub struct PfSolver {
    pub particles: usize,
    pub epochs: usize,
    pub batch: usize,
    pub roughening: f64,
}

impl Default for PfSolver {
    fn default() -> Self {
        PfSolver { particles: 4000, epochs: 4, batch: 10, roughening: 0.1 }
    }
}

impl Solver for PfSolver {
    fn method(&self) -> Method {
        Method::Pf
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

/// Particle swarm over the identifiable parameters inside ± `width_sigmas` tolerances.
#[derive(Clone, Debug, PartialEq)]
pub struct PsoSolver {
    pub particles: usize,
    pub iterations: usize,
    pub patience: usize,
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

impl Solver for PsoSolver {
    fn method(&self) -> Method {
        Method::Pso
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

/// LM geometry, then a Gaussian RBF network on the training residuals (centres and ridge by
/// cross-validation).
#[derive(Clone, Debug, PartialEq)]
pub struct RbfSolver {
    pub lm: LmSolver,
    pub centres: Vec<usize>,
    pub ridges: Vec<f64>,
}

impl Default for RbfSolver {
    fn default() -> Self {
        RbfSolver { lm: LmSolver::default(), centres: RbfNetwork::CV_CENTRES.to_vec(), ridges: RbfNetwork::CV_RIDGES.to_vec() }
    }
}

impl Solver for RbfSolver {
    fn method(&self) -> Method {
        Method::Rbf
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
        let corrector = Corrector::of_values((0..d).map(|c| fit(&super::stats::value_column(&res, d, c))).collect::<Result<Vec<_>>>()?);
        Ok(Solution { report, corrector: Some(corrector) })
    }
}
