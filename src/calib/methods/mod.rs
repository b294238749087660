//! Calibration methods as solver values. Each method is a struct that carries its own settings
//! and solves a [`Problem`]; the pipeline in [`super::pipeline`] only calls [`Solver::solve`], so a new
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
pub use solver::{Problem, Solution, Solver, SolverNeeds};

/// Which family a method belongs to: the core's baselines, Evo-NPH and its ablations, PSO-EKF-AWNN
/// and its ablations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// lm, ekf, pf, pso, rbf.
    Baseline,
    /// Evo-NPH (DS-ADE + GKAN) and its ablations.
    EvoNph,
    /// PSO-EKF-AWNN and its ablations.
    PsoEkfAwnn,
}

/// One registered method: the name it is chosen and stored by, what it does (the `--method`
/// help), its family, and its solver with the
/// default settings at an effort (a multiple of the stochastic methods' default budgets).
pub struct MethodDef {
    /// The name on the command line and in result.json.
    pub name: &'static str,
    /// One line for `--help`.
    pub help: &'static str,
    /// Its family.
    pub family: Family,
    /// The solver with its default settings at an effort.
    pub solver: fn(f64) -> Box<dyn Solver>,
}

/// A row of [`METHODS`].
const fn row(name: &'static str, family: Family, solver: fn(f64) -> Box<dyn Solver>, help: &'static str) -> MethodDef {
    MethodDef { name, help, family, solver }
}

fn evo(variant: EvoVariant, effort: f64) -> Box<dyn Solver> {
    Box::new(EvoNphSolver::new(variant, effort))
}

fn awnn(variant: Ablation, effort: f64) -> Box<dyn Solver> {
    Box::new(PsoEkfAwnn { pso_iterations: ((10.0 * effort).ceil() as usize).max(2), ..PsoEkfAwnn::variant(variant) })
}

/// Every method, in the order `--help` lists them: the one table that `--method` parses, lists
/// and documents (a new method is its file and its line here).
pub const METHODS: &[MethodDef] = &[
    row(LmSolver::NAME, Family::Baseline, |_| Box::new(LmSolver::default()), "Levenberg-Marquardt on the identifiable parameters"),
    row(EkfSolver::NAME, Family::Baseline, |e| Box::new(EkfSolver { epochs: (20.0 * e).ceil() as usize }), "the extended Kalman filter"),
    row(
        PfSolver::NAME,
        Family::Baseline,
        |e| Box::new(PfSolver { particles: (4000.0 * e).max(100.0) as usize, ..Default::default() }),
        "the regularised particle filter",
    ),
    row(
        PsoSolver::NAME,
        Family::Baseline,
        |e| Box::new(PsoSolver { iterations: (1500.0 * e).max(10.0) as usize, ..Default::default() }),
        "particle swarm optimisation",
    ),
    row(RbfSolver::NAME, Family::Baseline, |_| Box::new(RbfSolver::default()), "LM geometry, then an RBF network on its residuals"),
    row(EvoVariant::Full.method_name(), Family::EvoNph, |e| evo(EvoVariant::Full, e), "Evo-NPH: DS-ADE over the geometry and the GKAN's coefficients"),
    row(EvoVariant::Sequential.method_name(), Family::EvoNph, |e| evo(EvoVariant::Sequential, e), "Evo-NPH ablation V1: LM geometry, then the GKAN"),
    row(EvoVariant::Mlp.method_name(), Family::EvoNph, |e| evo(EvoVariant::Mlp, e), "Evo-NPH ablation V2: a ReLU MLP of matched size instead of the GKAN"),
    row(EvoVariant::SingleStrategy.method_name(), Family::EvoNph, |e| evo(EvoVariant::SingleStrategy, e), "Evo-NPH ablation V3: single-strategy DE"),
    row(Ablation::Full.method_name(), Family::PsoEkfAwnn, |e| awnn(Ablation::Full, e), "PSO-EKF-AWNN: PSO-tuned EKF, then an adaptive wavelet network"),
    row(
        Ablation::V1Symbolic.method_name(),
        Family::PsoEkfAwnn,
        |e| awnn(Ablation::V1Symbolic, e),
        "PSO-EKF-AWNN ablation V1: symbolic EKF then LM, no network",
    ),
    row(
        Ablation::V2RandomInit.method_name(),
        Family::PsoEkfAwnn,
        |e| awnn(Ablation::V2RandomInit, e),
        "PSO-EKF-AWNN ablation V2: hyperparameters drawn at random instead of by PSO",
    ),
    row(Ablation::V3Mlp.method_name(), Family::PsoEkfAwnn, |e| awnn(Ablation::V3Mlp, e), "PSO-EKF-AWNN ablation V3: a ReLU MLP instead of the wavelet network"),
    row(
        Ablation::V4Morlet.method_name(),
        Family::PsoEkfAwnn,
        |e| awnn(Ablation::V4Morlet, e),
        "PSO-EKF-AWNN ablation V4: Morlet instead of Mexican-hat wavelets",
    ),
    row(Ablation::V5Joint.method_name(), Family::PsoEkfAwnn, |e| awnn(Ablation::V5Joint, e), "PSO-EKF-AWNN ablation V5: geometry and network fitted jointly"),
    row(
        Ablation::Extended.method_name(),
        Family::PsoEkfAwnn,
        |e| awnn(Ablation::Extended, e),
        "PSO-EKF-AWNN extended: the network also sees temperature (or time) and backlash flanks, then network/LM alternations",
    ),
];

/// Whether two byte strings are equal (in a `const fn`).
const fn same(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// A registered method (a row of [`METHODS`]), stored in result.json by its name.
#[derive(Clone, Copy)]
pub struct Method(&'static MethodDef);

impl PartialEq for Method {
    fn eq(&self, other: &Method) -> bool {
        self.0.name == other.0.name
    }
}

impl Eq for Method {}

impl std::fmt::Debug for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Method({})", self.0.name)
    }
}

impl Serialize for Method {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.0.name)
    }
}

impl<'de> Deserialize<'de> for Method {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Method, D::Error> {
        let name = String::deserialize(d)?;
        Method::parse(&name).map_err(serde::de::Error::custom)
    }
}

impl Default for Method {
    /// Levenberg–Marquardt.
    fn default() -> Method {
        Method::LM
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0.name)
    }
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Method> {
        Method::parse(s)
    }
}

/// Every registered method, in the table's order, as clap's possible values take them.
#[cfg(feature = "clap")]
static ALL_METHODS: std::sync::LazyLock<Vec<Method>> = std::sync::LazyLock::new(|| Method::all().collect());

#[cfg(feature = "clap")]
impl clap::ValueEnum for Method {
    fn value_variants<'a>() -> &'a [Method] {
        &ALL_METHODS
    }
    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.0.name).help(self.0.help))
    }
}

impl Method {
    /// Levenberg-Marquardt.
    pub const LM: Method = Method::registered(LmSolver::NAME);
    /// The extended Kalman filter.
    pub const EKF: Method = Method::registered(EkfSolver::NAME);
    /// The regularised particle filter.
    pub const PF: Method = Method::registered(PfSolver::NAME);
    /// Particle swarm optimisation.
    pub const PSO: Method = Method::registered(PsoSolver::NAME);
    /// LM, then an RBF network.
    pub const RBF: Method = Method::registered(RbfSolver::NAME);
    /// Evo-NPH.
    pub const DSADE_GKAN: Method = Method::registered(EvoVariant::Full.method_name());
    /// Evo-NPH ablation V1.
    pub const DSADE_GKAN_V1: Method = Method::registered(EvoVariant::Sequential.method_name());
    /// Evo-NPH ablation V2.
    pub const DSADE_GKAN_V2: Method = Method::registered(EvoVariant::Mlp.method_name());
    /// Evo-NPH ablation V3.
    pub const DSADE_GKAN_V3: Method = Method::registered(EvoVariant::SingleStrategy.method_name());
    /// PSO-EKF-AWNN.
    pub const PSO_EKF_AWNN: Method = Method::registered(Ablation::Full.method_name());

    /// The row of [`METHODS`] called `name`, found when the program is compiled (a name that is
    /// not registered stops the build), so the table's order is free.
    const fn registered(name: &str) -> Method {
        let mut i = 0;
        while i < METHODS.len() {
            if same(METHODS[i].name.as_bytes(), name.as_bytes()) {
                return Method(&METHODS[i]);
            }
            i += 1;
        }
        panic!("a Method constant names a method that is not in METHODS")
    }

    /// Every registered method.
    pub fn all() -> impl Iterator<Item = Method> {
        METHODS.iter().map(Method)
    }

    /// The methods of a family, in the table's order.
    pub fn family(family: Family) -> impl Iterator<Item = Method> {
        Method::all().filter(move |m| m.0.family == family)
    }

    /// The method called `s` (any case), or an error listing the names.
    pub fn parse(s: &str) -> Result<Method> {
        let s = s.trim().to_ascii_lowercase();
        Method::all()
            .find(|m| m.name() == s)
            .ok_or_else(|| Error::Invalid(format!("unknown method '{s}' (expected one of {})", METHODS.iter().map(|m| m.name).collect::<Vec<_>>().join(", "))))
    }

    /// The name the method is registered and stored under (`lm`, `dsade-gkan-v2`,
    /// `pso-ekf-awnn-x`, ...).
    pub fn name(self) -> &'static str {
        self.0.name
    }

    /// Its line of `--help`.
    pub fn help(self) -> &'static str {
        self.0.help
    }

    /// The method with its default settings; `effort` scales the budget of the stochastic ones.
    pub fn solver(self, effort: f64) -> Box<dyn Solver> {
        (self.0.solver)(effort)
    }

    /// What its solver needs prepared ([`SolverNeeds::of`]).
    pub fn needs(self) -> SolverNeeds {
        SolverNeeds::of(self.solver(1.0).as_ref())
    }
}

impl Ablation {
    /// The registered method of this variant.
    pub fn method(self) -> Method {
        Method::registered(self.method_name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_registered_method_names_itself_and_parses_back() {
        for (i, def) in METHODS.iter().enumerate() {
            assert_eq!((def.solver)(1.0).name(), def.name, "row {i}: the solver names itself otherwise");
            assert_eq!(Method::parse(&def.name.to_ascii_uppercase()).unwrap().name(), def.name);
            assert!(METHODS[..i].iter().all(|d| d.name != def.name), "{} registered twice", def.name);
        }
        for (m, name) in [(Method::LM, "lm"), (Method::EKF, "ekf"), (Method::PF, "pf"), (Method::PSO, "pso"), (Method::RBF, "rbf")] {
            assert_eq!(m.name(), name);
        }
        for (m, name) in [(Method::DSADE_GKAN, "dsade-gkan"), (Method::DSADE_GKAN_V1, "dsade-gkan-v1"), (Method::DSADE_GKAN_V2, "dsade-gkan-v2")] {
            assert_eq!(m.name(), name);
        }
        assert_eq!((Method::DSADE_GKAN_V3.name(), Method::PSO_EKF_AWNN.name()), ("dsade-gkan-v3", "pso-ekf-awnn"));
        assert!(Ablation::ALL.iter().all(|a| a.method().name() == a.method_name()));
        let err = Method::parse("newton").unwrap_err().to_string();
        assert!(err.contains("unknown method 'newton'") && err.contains("pso-ekf-awnn-x"), "{err}");
        assert_eq!(serde_json::to_string(&Method::RBF).unwrap(), "\"rbf\"");
        assert_eq!(serde_json::from_str::<Method>("\"pso-ekf-awnn-v4\"").unwrap(), Ablation::V4Morlet.method());
    }
}
