//! Non-geometric effect blocks of a calibration model. Each block is one physical effect the twin
//! simulates (`src/effects`), with a few named, interpretable parameters, in the form a
//! calibration fits from q, L and the optional t / temp columns:
//!
//! | block | parameters | what it adds |
//! |---|---|---|
//! | `compliance` (joint j) | c_j, rad/(N·m) | joint angle + c_j·τ_j (static torque from the URDF inertials, payload, cable) |
//! | `backlash` (joint j) | h_j, rad (half band) | joint angle + h_j·side_j (load side, else approach side) |
//! | `thermal` | α, 1/K, and L, s (with `temp`; L with `t`) or s, τ (time only) | every link length × (1 + α·(T + L·dT/dt − T_ref)) or (1 + s·(1 − e^(−t/τ))) |
//! | `thermal` (joint j) | z_j, rad/K, and L_j, s (with `temp`) or z_j, τ_j (time only) | joint angle + z_j·(T + L_j·dT/dt − T_ref) or z_j·(1 − e^(−t/τ_j)): joint-zero drift |
//! | `eccentricity` (joint j) | a_j, b_j, rad | joint angle + a_j·sin q_j + b_j·cos q_j |
//! | `nonlinearity` | p2..p4, m | reading + Σ p_k·P_k(v), Legendre polynomials P2..P4 over the data's reading range |
//!
//! The per-row inputs they need (torques, sides, time, temperature) travel in one
//! [`RowInputs`] per sample. Derivatives are analytic and checked against finite differences.
//!
//! Each effect is one file here implementing [`Effect`]: its names and parameters, what it needs
//! of the data, its contribution to the joint angles and link scale, the size diagnose reports,
//! and how the hidden-effect generator puts it into a twin scenario. [`EffectKind::def`] is the
//! registry: one line per effect.

mod backlash;
mod choice;
mod compliance;
mod eccentricity;
pub mod inputs;
mod nonlinearity;
mod thermal;

pub use choice::EffectChoice;
pub use thermal::MIN_TEMP_SPREAD_K;

use crate::dataset::Dataset;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// One physical effect as a calibration block (see the module docs). Methods take the block
/// (its joint and set-up) and, where they read parameters, the index `k` of its first one in `x`.
pub trait Effect: Sync {
    /// The name in result files, `--effects` and reports.
    fn name(&self) -> &'static str;
    /// Whether the effect has one block per joint.
    fn per_joint(&self) -> bool;
    /// The joints a block may sit on for an arm of `n` joints (`None`: the whole arm).
    fn joint_options(&self, n: usize) -> Vec<Option<usize>> {
        if self.per_joint() {
            (0..n).map(Some).collect()
        } else {
            vec![None]
        }
    }
    /// Names and units of the block's parameters.
    fn params(&self, b: &EffectBlock) -> Vec<(String, EffectUnit)>;
    /// How many parameters the block has (`params(b).len()`, without building their names: the
    /// model's hot loops ask it on every row).
    fn n_params(&self, b: &EffectBlock) -> usize;
    /// Starting values (no effect); `t_span_s` is the data's time span.
    fn start(&self, b: &EffectBlock, _t_span_s: f64) -> Vec<f64> {
        vec![0.0; self.n_params(b)]
    }
    /// Whether the block reads the rows' joint torques (a result file must then carry the torque
    /// model that computes them on new rows).
    fn reads_torques(&self) -> bool {
        false
    }
    /// Sets the block up for these data, or says what they lack.
    fn configure(&self, _b: &mut EffectBlock, _data: &Dataset, _has_torques: bool) -> Result<()> {
        Ok(())
    }
    /// Adds the block's joint offsets and length scale for one row to `st`.
    fn apply(&self, _b: &EffectBlock, _x: &[f64], _k: usize, _q: &[f64], _inp: &RowInputs, _st: &mut EffectState) {}
    /// The size diagnose reports, from the parameters and their covariance `var(a, b)`.
    fn size(&self, b: &EffectBlock, x: &[f64], k: usize, var: &dyn Fn(usize, usize) -> f64) -> Size;
    /// Whether a block on a joint that does not move is a constant offset the geometry already
    /// holds (one backlash flank, one eccentricity phase throughout), so not a candidate there.
    fn constant_on_still_joint(&self) -> bool {
        false
    }
    /// Whether the effect changes over time (a warm-up, a drift with temperature): a diagnosis
    /// then judges it on rows later than those it was fitted to ([`crate::diagnose::forward`]).
    fn varies_in_time(&self) -> bool {
        false
    }
    /// Whether the fitted parameters have the sign physics allows.
    fn physical_sign(&self, _x: &[f64], _k: usize) -> bool {
        true
    }
    /// Whose effect a fitted size can be, where it is not the arm's own (a whole-arm expansion
    /// no metal of an arm has): a sentence for the report, or `None`.
    fn attribution(&self, _b: &EffectBlock, _size: &Size) -> Option<String> {
        None
    }
    /// Whether the block's later parameters act only through its first (a warm-up's time
    /// constant, a sensor's lag scale the size): at a size of zero the data cannot see them, so
    /// their identifiability is judged with the size at [`Effect::plausible`].
    fn later_params_scaled_by_size(&self, _b: &EffectBlock) -> bool {
        false
    }
    /// What an identified twin takes of the fitted block: its size and phase in the units the
    /// twin's `Effects::set_size` reads (the calibration block's internal ones), or why it takes
    /// none (a value physics forbids, an effect the twin does not take from a calibration).
    fn twin_size(&self, _b: &EffectBlock, _x: &[f64], _k: usize) -> std::result::Result<(f64, f64), String> {
        Err("identified, but the twin does not take it from a calibration yet".into())
    }
    /// Hidden-effect generator: the largest plausible size (internal units) on `joint`.
    fn plausible(&self, _joint: Option<usize>) -> f64 {
        0.0
    }
    /// Hidden-effect generator: internal size `v` in the unit diagnose reports.
    fn reported(&self, _joint: Option<usize>, v: f64) -> f64 {
        v
    }
}

/// The size of an effect block in physical units, as diagnose reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct Size {
    /// What the size is (`compliance`, `band width (2 x half band)`, `expansion coefficient`, ...).
    pub quantity: String,
    /// The size, in `unit`.
    pub value: f64,
    /// Display unit of `value` and `uncertainty`.
    pub unit: String,
    /// Standard uncertainty of `value`, in `unit`.
    pub uncertainty: f64,
}

impl Size {
    fn new(quantity: &str, value: f64, unit: &str, uncertainty: f64) -> Size {
        Size { quantity: quantity.into(), value, unit: unit.into(), uncertainty }
    }
}

/// Degrees per radian.
const DEG: f64 = 180.0 / std::f64::consts::PI;

/// The effects a calibration model can represent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// Each joint gives way in proportion to the static torque it carries.
    #[serde(alias = "joint_compliance")]
    Compliance,
    /// Gear backlash: a joint sits half its band to the side the load (or the approach) puts it on.
    Backlash,
    /// Links grow with temperature (or a warm-up with time), and joint zeros drift with it.
    #[serde(alias = "thermal_drift")]
    Thermal,
    /// The true joint angle is the reading plus a first harmonic of it.
    #[serde(alias = "encoder_eccentricity")]
    Eccentricity,
    /// The reading plus Legendre polynomials P2..P4 over the reading range.
    #[serde(alias = "sensor_nonlinearity")]
    Nonlinearity,
}

impl std::fmt::Display for EffectKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl EffectKind {
    /// Every kind, in the order selection and reports list them.
    pub const ALL: [EffectKind; 5] = [EffectKind::Compliance, EffectKind::Backlash, EffectKind::Thermal, EffectKind::Eccentricity, EffectKind::Nonlinearity];

    /// The registry: the component behind each kind.
    pub fn def(self) -> &'static dyn Effect {
        match self {
            EffectKind::Compliance => &compliance::Compliance,
            EffectKind::Backlash => &backlash::Backlash,
            EffectKind::Thermal => &thermal::Thermal,
            EffectKind::Eccentricity => &eccentricity::Eccentricity,
            EffectKind::Nonlinearity => &nonlinearity::Nonlinearity,
        }
    }
    /// The kind's name in files and options (`compliance`, `backlash`, ...).
    pub fn name(self) -> &'static str {
        self.def().name()
    }
    /// Whether the effect has one block per joint.
    pub fn per_joint(self) -> bool {
        self.def().per_joint()
    }
    /// The joints a block of this kind may sit on: every joint for per-joint effects, none for
    /// whole-arm effects; thermal drift is both (the length scale, and each joint's zero drift).
    pub fn joint_options(self, n_joints: usize) -> Vec<Option<usize>> {
        self.def().joint_options(n_joints)
    }
    /// Whether a block of this kind can sit on a joint.
    pub fn takes_joint(self) -> bool {
        self.def().joint_options(1).iter().any(Option::is_some)
    }
    /// The names earlier versions wrote in result files and reports, read as the kinds' names
    /// (the `serde` aliases of [`EffectKind`] say the same).
    pub const FORMER_NAMES: [(&'static str, EffectKind); 4] = [
        ("joint_compliance", EffectKind::Compliance),
        ("thermal_drift", EffectKind::Thermal),
        ("encoder_eccentricity", EffectKind::Eccentricity),
        ("sensor_nonlinearity", EffectKind::Nonlinearity),
    ];

    /// The kind of a name (any case; a former name is read as the kind it named).
    pub fn parse(s: &str) -> Result<EffectKind> {
        let s = s.trim().to_ascii_lowercase();
        let former = EffectKind::FORMER_NAMES.iter().find(|(n, _)| *n == s).map(|(_, k)| *k);
        EffectKind::ALL.into_iter().find(|k| k.name() == s).or(former).ok_or_else(|| {
            let names: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
            Error::Invalid(format!(
                "unknown effect '{s}' (expected {} or {}, optionally with :JOINT, e.g. compliance:2)",
                names[..names.len() - 1].join(", "),
                names[names.len() - 1]
            ))
        })
    }
}

/// Physical unit of an effect parameter, for display and priors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectUnit {
    /// rad/(N·m), shown in µrad/(N·m).
    Compliance,
    /// rad, shown in millidegrees.
    SmallAngle,
    /// rad/K, shown in millidegrees per kelvin.
    AnglePerKelvin,
    /// 1/K, shown in ppm/K.
    PerKelvin,
    /// dimensionless, shown in ppm.
    Ratio,
    /// s: a warm-up's time constant (positive).
    Seconds,
    /// s, signed: a temperature sensor's lag behind the structure (negative: the structure's
    /// behind the air the sensor reads).
    Lag,
    /// m, shown in mm.
    Length,
}

impl EffectUnit {
    /// Factor from internal units to display units.
    pub fn display(self) -> f64 {
        match self {
            EffectUnit::Compliance | EffectUnit::PerKelvin | EffectUnit::Ratio => 1e6,
            EffectUnit::SmallAngle | EffectUnit::AnglePerKelvin => 180.0 / std::f64::consts::PI * 1e3,
            EffectUnit::Seconds | EffectUnit::Lag => 1.0,
            EffectUnit::Length => crate::units::MM_PER_M,
        }
    }
    /// The display unit (`urad/Nm`, `mdeg`, ...).
    pub fn unit(self) -> &'static str {
        match self {
            EffectUnit::Compliance => "urad/Nm",
            EffectUnit::SmallAngle => "mdeg",
            EffectUnit::AnglePerKelvin => "mdeg/K",
            EffectUnit::PerKelvin => "ppm/K",
            EffectUnit::Ratio => "ppm",
            EffectUnit::Seconds | EffectUnit::Lag => "s",
            EffectUnit::Length => "mm",
        }
    }
}

/// How the thermal block is driven.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ThermalDrive {
    /// Measured temperature: scale = 1 + α·(T − `ref_c`), or with the sensor's lag fitted
    /// 1 + α·(T + L·dT/dt − `ref_c`).
    Temperature {
        /// Reference temperature T_ref, °C.
        ref_c: f64,
        /// Whether the block fits the sensor's lag L (s) behind the structure besides its size:
        /// the structure's temperature taken as T + L·dT/dt (a first-order sensor that lags the
        /// structure by L > 0 reads exactly that; a structure that lags the air a sensor reads,
        /// L < 0, to first order). On when the rows have a `t` column to take dT/dt from.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        sensor_lag: bool,
    },
    /// Time only: first-order warm-up, scale = 1 + s·(1 − e^(−t/τ)).
    WarmUp,
}

/// One effect in a calibration model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectBlock {
    /// Which effect.
    pub kind: EffectKind,
    /// Joint (0-based) of a per-joint effect.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    /// How a thermal drift block is driven (thermal blocks only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal: Option<ThermalDrive>,
    /// Sensor nonlinearity: reading range [lo, hi] (m) its polynomials are normalised over.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_m: Option<[f64; 2]>,
}

impl EffectBlock {
    /// A block of `kind` on joint `j` (0-based).
    pub fn joint(kind: EffectKind, j: usize) -> Self {
        EffectBlock { kind, joint: Some(j), thermal: None, range_m: None }
    }
    /// A short label: `compliance[j2]`, `thermal`.
    pub fn label(&self) -> String {
        match self.joint {
            Some(j) => format!("{}[j{}]", self.kind.name(), j + 1),
            None => self.kind.name().to_string(),
        }
    }
    /// Names and units of the block's parameters.
    pub fn params(&self) -> Vec<(String, EffectUnit)> {
        self.kind.def().params(self)
    }
    /// Whether the block changes over time ([`Effect::varies_in_time`]).
    pub fn varies_in_time(&self) -> bool {
        self.kind.def().varies_in_time()
    }
    /// Number of the block's parameters (allocates nothing).
    pub fn n_params(&self) -> usize {
        self.kind.def().n_params(self)
    }
    /// Starting values of the parameters (no effect): zero, except a warm-up time constant,
    /// which starts at a third of the data's time span `t_span_s`.
    pub fn start(&self, t_span_s: f64) -> Vec<f64> {
        self.kind.def().start(self, t_span_s)
    }
    /// Whether the block fits a temperature sensor's lag besides its size (a temperature drive
    /// over rows with time).
    pub fn fits_sensor_lag(&self) -> bool {
        matches!(self.thermal, Some(ThermalDrive::Temperature { sensor_lag: true, .. }))
    }
    /// The block without the refinement a diagnosis tests apart, once the block itself has
    /// earned its place (a thermal block's sensor lag); the block itself where it has none.
    pub fn unrefined(&self) -> EffectBlock {
        match self.thermal {
            Some(ThermalDrive::Temperature { ref_c, sensor_lag: true }) => {
                EffectBlock { thermal: Some(ThermalDrive::Temperature { ref_c, sensor_lag: false }), ..self.clone() }
            }
            _ => self.clone(),
        }
    }
    /// The number `j + 1` of the block's joint in parameter names (0 for a whole-arm block).
    fn joint_number(&self) -> usize {
        self.joint.map(|j| j + 1).unwrap_or(0)
    }
}

/// What one sample carries besides q and L.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RowInputs {
    /// Time from the start of acquisition, s.
    pub t_s: Option<f64>,
    /// Measured temperature, °C.
    pub temp_c: Option<f64>,
    /// Rate of the measured temperature, K/s: the slope of `temp` against `t` over the row's
    /// neighbours in time ([`inputs::temperature_rates`]); `None` without both columns.
    pub temp_rate_k_per_s: Option<f64>,
    /// Static joint torques, N·m, one per joint; empty without an inertial model (read as zero).
    pub torque: Vec<f64>,
    /// Backlash flank per joint (±1; 0 when unknown); empty when no flank is known.
    pub side: Vec<f64>,
    /// The instrument's station the row was read from: an index into the model's
    /// [`stations`](crate::calib::model::CalibModel::stations), 0 for the first (and only).
    pub station: usize,
    /// The target's mount on the flange the row was read with: an index into the model's
    /// [`mounts`](crate::calib::model::CalibModel::mounts), 0 for the first (and only).
    pub mount: usize,
    /// Which instrument read the row: 0 the model's, 1 the other one beside it
    /// ([`crate::calib::model::CalibModel::also`]: a tracker's points beside seated rows).
    pub instrument: usize,
}

impl RowInputs {
    /// Static torque of joint `j`, N·m (0 when unknown).
    pub fn torque(&self, j: usize) -> f64 {
        self.torque.get(j).copied().unwrap_or(0.0)
    }
    /// Backlash flank of joint `j` (±1; 0 when unknown).
    pub fn side(&self, j: usize) -> f64 {
        self.side.get(j).copied().unwrap_or(0.0)
    }
}

pub use crate::math::legendre;

/// The effect state of one row: joint offsets and length scale, with the partial derivatives of
/// each with respect to the effect parameters.
#[derive(Clone, Debug, Default)]
pub struct EffectState {
    /// Offset of each joint, rad.
    pub dq: Vec<f64>,
    /// ∂Δq_j/∂q_j: how each joint's offset changes with its own commanded angle.
    pub ddq_dq: Vec<f64>,
    /// Length scale (1: none).
    pub scale: f64,
    /// (parameter index, joint, ∂Δq_joint/∂param).
    pub joint_terms: Vec<(usize, usize, f64)>,
    /// (parameter index, ∂scale/∂param).
    pub scale_terms: Vec<(usize, f64)>,
}

/// Evaluates the joint-offset and scale effects of `blocks` whose parameters start at `first`
/// in `x`, for a row with commanded angles `q` (rad) and inputs `inp`.
pub fn joint_and_scale_effects(blocks: &[EffectBlock], first: usize, x: &[f64], q: &[f64], inp: &RowInputs, st: &mut EffectState) {
    // Resized to the row's joints; after the first row this allocates nothing.
    st.dq.clear();
    st.dq.resize(q.len(), 0.0);
    st.ddq_dq.clear();
    st.ddq_dq.resize(q.len(), 0.0);
    st.scale = 1.0;
    st.joint_terms.clear();
    st.scale_terms.clear();
    let mut k = first;
    for b in blocks {
        b.kind.def().apply(b, x, k, q, inp, st);
        k += b.n_params();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_block_counts_the_parameters_it_names() {
        for kind in EffectKind::ALL {
            for joint in kind.joint_options(3) {
                let lagged = |sensor_lag| Some(ThermalDrive::Temperature { ref_c: 20.0, sensor_lag });
                for thermal in [None, Some(ThermalDrive::WarmUp), lagged(false), lagged(true)] {
                    let b = EffectBlock { kind, joint, thermal, range_m: None };
                    assert_eq!(b.n_params(), b.params().len(), "{}", b.label());
                    assert_eq!(b.start(600.0).len(), b.n_params(), "{}", b.label());
                }
            }
        }
    }

    /// A whole-arm expansion no metal of an arm has is attributed to what else can drift;
    /// within the metals' range (by 3σ), a joint's drift or a time-only warm-up, nothing is said.
    #[test]
    fn an_expansion_beyond_the_arms_metals_is_attributed_elsewhere() {
        let arm =
            EffectBlock { kind: EffectKind::Thermal, joint: None, thermal: Some(ThermalDrive::Temperature { ref_c: 20.0, sensor_lag: true }), range_m: None };
        let say = |b: &EffectBlock, value: f64, uncertainty: f64| {
            b.kind.def().attribution(b, &Size { quantity: "expansion coefficient".into(), value, unit: "ppm/K".into(), uncertainty })
        };
        let far = say(&arm, 87.0, 0.12).expect("87 ppm/K is no arm's metal");
        assert!(far.contains("3.3x") && far.contains("air compensation"), "{far}");
        assert!(say(&arm, -5.0, 0.5).is_some_and(|s| s.contains("below")));
        assert!(say(&arm, 23.0, 0.2).is_none());
        assert!(say(&arm, 28.0, 1.0).is_none(), "within 3 sigma of the range");
        let joint = EffectBlock { joint: Some(1), ..arm.clone() };
        assert!(say(&joint, 87.0, 0.1).is_none());
        let warm_up = EffectBlock { thermal: Some(ThermalDrive::WarmUp), ..arm };
        assert!(say(&warm_up, 500.0, 1.0).is_none());
    }
}
