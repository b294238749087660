//! The options of a calibration: the model to fit, the method, the split, the noise model and
//! what the stages may do.

use crate::calib::effects::inputs::JointLoads;
use crate::calib::effects::EffectKind;
use crate::calib::fit::noise_model::NoiseChoice;
use crate::calib::fit::robust::Loss;
use crate::calib::methods::Method;
use crate::calib::model::tolerance::Tolerances;
use crate::calib::model::DrawWireGuess;
use crate::error::{Error, Result};
use crate::robot::Robot;
use serde::{Deserialize, Serialize};
use std::path::Path;

pub use crate::calib::model::Parametrisation;

/// Which kinematic model to calibrate.
#[derive(Clone, Debug)]
pub enum ModelSpec {
    /// A robot with a nominal URDF (the embedded IRB 120 or a file) in a parametrisation.
    Nominal {
        /// The nominal robot.
        robot: Box<Robot>,
        /// How its errors are parametrised.
        parametrisation: Parametrisation,
    },
    /// An arm with no published nominal (6 or 7 revolute joints, as the data hold): its axes
    /// are found from the data by a global search ([`crate::calib::pipeline::generic`]).
    Generic,
}

impl ModelSpec {
    /// The nominal `robot` in parametrisation `p`.
    pub fn nominal(robot: Robot, p: Parametrisation) -> ModelSpec {
        ModelSpec::Nominal { robot: Box::new(robot), parametrisation: p }
    }
    /// Names of the generic arm: `generic` (the joints as the data hold them), `generic6r` and
    /// `generic7r` (the same search; the data's joint count decides).
    pub const GENERIC_NAMES: [&'static str; 3] = ["generic", "generic6r", "generic7r"];
    /// Whether `model` names the generic arm.
    pub fn is_generic_name(model: &str) -> bool {
        Self::GENERIC_NAMES.contains(&model)
    }
    /// The model named by `model` (`irb120`, `generic` or a `.urdf` path) in parametrisation
    /// `p` (ignored by the generic arm).
    pub fn parse(model: &str, p: Parametrisation) -> Result<ModelSpec> {
        match model {
            "irb120" => Ok(ModelSpec::Nominal { robot: Box::new(Robot::irb120()), parametrisation: p }),
            name if Self::is_generic_name(name) => Ok(ModelSpec::Generic),
            path if path.ends_with(".urdf") => {
                let robot = Robot::from_urdf_file(Path::new(path))?;
                Ok(ModelSpec::Nominal { robot: Box::new(robot), parametrisation: p })
            }
            other => Err(Error::Invalid(format!("unknown model '{other}' (expected irb120, generic or a .urdf path)"))),
        }
    }
    /// The nominal robot, where there is one.
    pub fn robot(&self) -> Option<&Robot> {
        match self {
            ModelSpec::Nominal { robot, .. } => Some(robot.as_ref()),
            ModelSpec::Generic => None,
        }
    }
}

/// Default identifiability threshold: a parameter combination the data see at less than this
/// fraction of the strongest one (column-scaled Jacobian) is fixed, so that the identifiable
/// set's condition number stays below its inverse. Weakly seen combinations above it carry
/// real information on measured data (raising it to 1e-4 fixed six of 21 parameters of an
/// earlier HSR generic model and tripled its held-out error, and cost RobotCali's LM 0.08 mm);
/// the Levenberg–Marquardt stall test ends the slow creep along them instead.
pub const DEFAULT_RANK_TOL: f64 = 1e-7;

/// Default outlier threshold, robust standard deviations: 6σ of Gaussian noise happens once in
/// 500 million rows, so what lies beyond is not noise.
pub const DEFAULT_OUTLIER_K: f64 = 6.0;

/// How a calibration holds rows out for its test (`--test-fraction`, `--split-by`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SplitOptions {
    /// Hold out this fraction instead of the dataset's split column.
    pub test_fraction: Option<f64>,
    /// How the fraction draws its rows.
    pub by: SplitBy,
}

/// The robust screen of the rows (`--outliers`, `--no-reading-steps`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenOptions {
    /// Rows more than this many robust standard deviations off the fit are outliers, kept out
    /// and listed ([`crate::calib::fit::robust::screen`]); 0 keeps every row.
    pub outlier_k: f64,
    /// Runs of outliers that are one constant offset of the reading are corrected and kept
    /// ([`crate::calib::fit::robust::reading_steps`]) instead of kept out.
    pub reading_steps: bool,
}

impl Default for ScreenOptions {
    fn default() -> Self {
        ScreenOptions { outlier_k: DEFAULT_OUTLIER_K, reading_steps: true }
    }
}

/// What the data's floor is made of and how the rows are weighted (`--angle-resolution-deg`,
/// `--instrument-accuracy-mm`, `--ignore-row-std`, `--noise-model`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloorOptions {
    /// Logging step of the joint angles, degrees (default: from the data's decimals).
    pub angle_step_deg: Option<f64>,
    /// The instrument's stated accuracy, mm per coordinate (or of the cable length).
    pub instrument_accuracy_mm: Option<f64>,
    /// Weight the fits by the rows' own standard deviations where the data give them (a
    /// tracker's `sx, sy, sz`; [`crate::calib::fit::weighting`]).
    pub row_std: bool,
    /// Whether the joint angles' logging error is modelled where rows share blocks.
    pub noise_model: NoiseChoice,
}

impl Default for FloorOptions {
    fn default() -> Self {
        FloorOptions { angle_step_deg: None, instrument_accuracy_mm: None, row_std: true, noise_model: NoiseChoice::Auto }
    }
}

/// What loads the joints and whose inertial data give their torques (`--payload-kg`,
/// `--payload-com-mm`, `--cable-tension-n`, `--robot`).
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// The payload and the cable's tension.
    pub joints: JointLoads,
    /// Inertial model for the joint torques when the calibrated model has none (the generic
    /// arm), or given for the purpose.
    pub inertial: Option<Robot>,
}

/// Everything a calibration run is asked to do, beside its data.
#[derive(Clone, Debug)]
pub struct CalibOptions {
    /// The kinematic model to calibrate.
    pub model: ModelSpec,
    /// The calibration method.
    pub method: Method,
    /// How rows are held out.
    pub split: SplitOptions,
    /// Seed of the split and of the stochastic methods.
    pub seed: u64,
    /// Relative singular-value tolerance of the identifiability analysis.
    pub rank_tol: f64,
    /// Sensor geometry guess; estimated from the data when absent.
    pub draw_wire_guess: Option<DrawWireGuess>,
    /// Effort scale for the stochastic methods (1 = default budget).
    pub effort: f64,
    /// Manufacturing and set-up tolerances (priors and search boxes of the methods).
    pub tolerances: Tolerances,
    /// Non-geometric effects to fit beside the geometry: a kind, on one joint (0-based) or,
    /// for per-joint kinds given without a joint, on every joint.
    pub effects: Vec<(EffectKind, Option<usize>)>,
    /// Whether a temperature-driven thermal block fits the sensor's lag where the rows have a
    /// time column (see [`crate::calib::effects::ThermalDrive`]).
    pub sensor_lag: bool,
    /// What loads the joints, for the torque-driven effects.
    pub loads: LoadOptions,
    /// The robust screen of the training rows.
    pub screen: ScreenOptions,
    /// The loss of the least-squares methods (`lm`): squared, or Huber / Cauchy by IRLS.
    pub loss: Loss,
    /// The data's floor and the rows' weights.
    pub floor: FloorOptions,
    /// Which parameters are fitted; the others are held at their nominal values.
    pub free: FreeParams,
    /// Where the instrument's stations come from ([`super::setup`]).
    pub stations: StationSource,
    /// Known distances between sockets of the artifact a ball was seated in (its rows'
    /// scale); refused for another instrument's rows.
    pub spacings: Vec<crate::calib::model::KnownSpacing>,
}

/// Default effort of the stochastic methods and of the generic arm's search (their default
/// budgets).
pub const DEFAULT_EFFORT: f64 = 1.0;

impl CalibOptions {
    /// The options of calibrating `model` by `method`, every other option at its default.
    pub fn new(model: ModelSpec, method: Method) -> Self {
        CalibOptions {
            model,
            method,
            split: SplitOptions::default(),
            seed: 0,
            rank_tol: DEFAULT_RANK_TOL,
            draw_wire_guess: None,
            effort: DEFAULT_EFFORT,
            tolerances: Tolerances::default(),
            effects: Vec::new(),
            sensor_lag: true,
            loads: LoadOptions::default(),
            screen: ScreenOptions::default(),
            loss: Loss::default(),
            floor: FloorOptions::default(),
            free: FreeParams::All,
            stations: StationSource::Auto,
            spacings: Vec::new(),
        }
    }
    /// The robot whose inertial data give the joint torques: the one given for the purpose
    /// (`--robot`), else the calibrated nominal robot.
    pub fn inertial_robot(&self) -> Option<&Robot> {
        self.loads.inertial.as_ref().or(self.model.robot())
    }
}

/// Beyond this (mm) between two arms' flanges at the same joint angles, they are two arms. One
/// arm's own calibrated geometry departs from its URDF by millimetres (a UR's factory
/// calibration; the UR10 tracker twin's arm by up to 2.1 mm); another make or size of arm by
/// hundreds.
pub const OTHER_ARM_MM: f64 = 20.0;

/// The largest distance (mm) between the flanges of `a` and `b` at their nominal geometry over
/// 16 seeded configurations inside `a`'s limits; `None` where their joint counts differ.
pub fn flange_gap_mm(a: &Robot, b: &Robot) -> Option<f64> {
    use rand::{Rng, SeedableRng};
    if a.dof() != b.dof() {
        return None;
    }
    let (ca, cb) = (a.error_chain(), b.error_chain());
    let (za, zb) = (vec![0.0; ca.n_params()], vec![0.0; cb.n_params()]);
    let (mut wa, mut wb) = (crate::robot::kinematics::FkWork::new(&ca), crate::robot::kinematics::FkWork::new(&cb));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let gap = (0..16)
        .map(|_| {
            let q: Vec<f64> = a.limits().iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect();
            ca.forward(&q, &za, 1.0, &mut wa);
            cb.forward(&q, &zb, 1.0, &mut wb);
            crate::units::to_mm((ca.frame(&wa, ca.flange()).pos - cb.frame(&wb, cb.flange()).pos).norm())
        })
        .fold(0.0, f64::max);
    Some(gap)
}

/// `--robot` (the URDF whose inertial data give the torques) must be the arm the model is of:
/// the same joints and, for a nominal arm, the same flange within [`OTHER_ARM_MM`]. A URDF of
/// another arm beside the default model (`irb120`) is what a user who meant `--model` gives.
pub fn check_inertial(model: &ModelSpec, inertial: Option<&Robot>, source: &str) -> Result<()> {
    let (Some(given), Some(nominal)) = (inertial, model.robot()) else { return Ok(()) };
    let why = match flange_gap_mm(nominal, given) {
        None => format!("it has {} joints, the model's arm {}", given.dof(), nominal.dof()),
        Some(gap) if gap > OTHER_ARM_MM => format!("its flange stands up to {gap:.1} mm from the model's at the same joint angles"),
        Some(_) => return Ok(()),
    };
    Err(Error::Invalid(format!(
        "--robot {source} is another arm than the model's ({}): {why}; give the arm to calibrate as --model {source} (--robot only lends the model's arm its inertial data)",
        nominal.name
    )))
}

/// Which parameters a calibration fits (the rest held at their nominal values).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FreeParams {
    /// Every identifiable parameter.
    #[default]
    All,
    /// The instrument's placement only (`--placement-only`): the nominal twin of a set-up whose
    /// instrument was not surveyed.
    Placement,
    /// What a controller that takes no new kinematic model can be given (`--controller-subset`):
    /// the joints' zero offsets, and the placement (the base frame against the instrument) with
    /// the tool point.
    Controller,
}

/// How `--test-fraction` draws its test rows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum SplitBy {
    /// Whole blocks of the acquisition ([`crate::dataset::blocks`]) where rows share a sweep, a
    /// pause or a declared block (rows otherwise): test rows share no error with training rows.
    #[default]
    Blocks,
    /// Rows, stratified by the reading, whatever blocks they are in (as the papers split; rows
    /// of one sweep then sit on both sides).
    Rows,
    /// The last rows of the acquisition (rows are in time order): trained on the earlier rows,
    /// judged on the later, as a drift that has to hold tomorrow must be.
    Time,
}

/// Where a calibration takes the instrument's stations from (`--stations`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum StationSource {
    /// The `station` column where the file has one; for a tracker, then the change points a
    /// first fit finds ([`super::setup`]) (a re-stationed, re-registered or bumped tracker).
    #[default]
    Auto,
    /// The `station` column only (one station without it).
    Declared,
    /// Each declared block (`block` column) a station of its own.
    Blocks,
    /// One placement for every row, whatever the file says.
    One,
}

impl StationSource {
    /// Its name as `--stations` takes it.
    pub fn name(self) -> &'static str {
        match self {
            StationSource::Auto => "auto",
            StationSource::Declared => "declared",
            StationSource::Blocks => "blocks",
            StationSource::One => "one",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UR10's URDF given as `--robot` beside the default IRB 120 model is another arm (it was
    /// ignored without a word); the model's own arm, or any with the generic arm, is not.
    #[test]
    fn a_robot_for_the_torques_must_be_the_models_arm() {
        let ur10 = Robot::from_urdf_file(&Path::new(env!("CARGO_MANIFEST_DIR")).join("urdf/ur10.urdf")).unwrap();
        let irb = ModelSpec::nominal(Robot::irb120(), Parametrisation::Hayati);
        let e = check_inertial(&irb, Some(&ur10), "ur10.urdf").unwrap_err().to_string();
        assert!(e.contains("--robot ur10.urdf is another arm than the model's") && e.contains("--model ur10.urdf"), "{e}");
        assert!(check_inertial(&irb, Some(&Robot::irb120()), "irb120.urdf").is_ok());
        assert!(check_inertial(&ModelSpec::Generic, Some(&ur10), "ur10.urdf").is_ok());
        assert_eq!(flange_gap_mm(&Robot::irb120(), &Robot::irb120()), Some(0.0));
        // Given, it is the one whose inertial data give the torques.
        let mut opts = CalibOptions::new(ModelSpec::nominal(ur10.clone(), Parametrisation::Hayati), Method::LM);
        opts.loads.inertial = Some(ur10.clone());
        assert_eq!(opts.inertial_robot().map(|r| r.name.as_str()), Some(ur10.name.as_str()));
    }
}
