//! Calibration methods as solver values. Each method is a struct that carries its own settings
//! and solves a [`Problem`]; the pipeline in [`super::run`] only calls [`Solver::solve`], so a new
//! method (or one with other settings) is added beside these, not inside the pipeline.
//!
//! Nothing here knows how the data were made: spreads come from the documented
//! [`Tolerances`](crate::calib::model::tolerance::Tolerances) (via [`Problem::prior_std`]) and noise levels
//! from the data ([`Problem::noise_mm`]).

pub mod awnn_select;
mod ekf;
pub mod evonph;
pub mod gkan_select;
mod lm;
mod pf;
mod pso;
pub mod psoekf;
mod rbf;
pub mod ridge_cv;
mod solver;

use crate::error::{Error, Result};
pub use ekf::EkfSolver;
use evonph::{EvoNphSolver, EvoVariant};
pub use lm::LmSolver;
pub use pf::PfSolver;
pub use pso::PsoSolver;
use psoekf::{Ablation, PsoEkfAwnn};
pub use rbf::RbfSolver;
use serde::{Deserialize, Serialize};
pub use solver::{Problem, Solution, Solver};

/// The methods the command line offers by name (stored in result.json by that name).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum Method {
    /// Levenberg–Marquardt on the identifiable parameters.
    Lm,
    /// The extended Kalman filter.
    Ekf,
    /// The regularised particle filter.
    Pf,
    /// Particle swarm optimisation.
    Pso,
    /// Levenberg–Marquardt geometry, then an RBF network on its residuals.
    Rbf,
    /// Evo-NPH: DS-ADE over geometry and GKAN coefficients ([`evonph`]).
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
    /// PSO-EKF-AWNN or one of its ablations (see [`psoekf`]).
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
    /// The core's baseline methods.
    pub const ALL: [Method; 5] = [Method::Lm, Method::Ekf, Method::Pf, Method::Pso, Method::Rbf];

    /// The Evo-NPH method and its ablations (not in [`Method::ALL`], the core's baselines).
    pub const EVO_NPH: [Method; 4] = [Method::DsadeGkan, Method::DsadeGkanV1, Method::DsadeGkanV2, Method::DsadeGkanV3];

    /// The method called `s` (any case), or an error listing the names.
    pub fn parse(s: &str) -> Result<Method> {
        let s = s.trim().to_ascii_lowercase();
        Method::ALL.into_iter().chain(Method::EVO_NPH).chain(Ablation::ALL.map(Method::PsoEkfAwnn)).find(|m| m.name() == s).ok_or_else(|| {
            Error::Invalid(format!(
                "unknown method '{s}' (expected lm, ekf, pf, pso, rbf, dsade-gkan or its ablations dsade-gkan-v1, -v2, -v3, \
                 pso-ekf-awnn or its ablations pso-ekf-awnn-v1 .. -v5 and pso-ekf-awnn-x)"
            ))
        })
    }
    /// The name the method is registered and stored under (`lm`, `dsade-gkan-v2`, `pso-ekf-awnn-x`,
    /// ...).
    pub fn name(self) -> &'static str {
        match self {
            Method::Lm => "lm",
            Method::Ekf => "ekf",
            Method::Pf => "pf",
            Method::Pso => "pso",
            Method::Rbf => "rbf",
            Method::DsadeGkan => EvoVariant::Full.method_name(),
            Method::DsadeGkanV1 => EvoVariant::Sequential.method_name(),
            Method::DsadeGkanV2 => EvoVariant::Mlp.method_name(),
            Method::DsadeGkanV3 => EvoVariant::SingleStrategy.method_name(),
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
