//! Scenario files: which robot, its true deviations, effects, sensor, pose sampling and seed.
//! Unknown keys are rejected with the key named.

use crate::effects::Effects;
use crate::error::{Error, Result};
use crate::robot::{Robot, PARAM_SUFFIXES};
use crate::sensor::DrawWire;
use crate::twin::SettleOptions;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The scenario shipped with twincal and run by `twincal generate` without `--scenario`.
pub const DEFAULT_SCENARIO: &str = include_str!("../scenarios/irb120_evo_nph.toml");
pub const DEFAULT_SCENARIO_NAME: &str = "scenarios/irb120_evo_nph.toml (embedded)";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub seed: u64,
    /// `irb120` for the embedded URDF, or a URDF path relative to the scenario file.
    #[serde(default = "Scenario::default_robot")]
    pub robot: String,
    #[serde(default)]
    pub geometry: Geometry,
    #[serde(default)]
    pub effects: Effects,
    pub sensor: DrawWire,
    pub sampling: Sampling,
    #[serde(default)]
    pub simulation: SettleOptions,
}

/// True geometric deviations: random with the given standard deviations, then explicit values.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    #[serde(default)]
    pub origin_offset_std_mm: f64,
    #[serde(default)]
    pub origin_rotation_std_deg: f64,
    #[serde(default)]
    pub joint_zero_std_deg: f64,
    /// Explicit deviations by parameter name (`joint_2.dtheta`): mm for dx/dy/dz, degrees otherwise.
    #[serde(default)]
    pub set: BTreeMap<String, f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Order {
    /// Halton order, as sampled.
    Halton,
    /// A seeded random permutation.
    Shuffled,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sampling {
    pub poses: usize,
    /// Poses held out for testing (stratified over the cable length).
    #[serde(default)]
    pub test: usize,
    /// Joint ranges in degrees; default: the URDF limits shrunk by `limit_margin_deg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ranges_deg: Option<Vec<[f64; 2]>>,
    #[serde(default = "Sampling::default_margin")]
    pub limit_margin_deg: f64,
    /// Lowest allowed nominal tool height, mm (keeps the tool off the table).
    #[serde(default = "Sampling::default_min_z")]
    pub min_tool_z_mm: f64,
    /// Joint speed while moving between poses, fraction of the URDF limit.
    #[serde(default = "Sampling::default_speed")]
    pub speed_fraction: f64,
    #[serde(default = "Sampling::default_order")]
    pub order: Order,
}

impl Sampling {
    fn default_margin() -> f64 {
        5.0
    }
    fn default_min_z() -> f64 {
        50.0
    }
    fn default_speed() -> f64 {
        0.2
    }
    fn default_order() -> Order {
        Order::Halton
    }
}

impl Scenario {
    fn default_robot() -> String {
        "irb120".into()
    }

    pub fn from_toml(text: &str, origin: &str) -> Result<Scenario> {
        let s: Scenario = toml::from_str(text).map_err(|e| Error::Scenario { path: origin.to_string(), msg: e.to_string() })?;
        Ok(s)
    }

    pub fn load(path: &Path) -> Result<(Scenario, Robot)> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let origin = path.display().to_string();
        let s = Scenario::from_toml(&text, &origin)?;
        let robot = s.load_robot(path.parent())?;
        s.validate(&robot, &origin)?;
        Ok((s, robot))
    }

    /// The embedded default scenario.
    pub fn default_embedded() -> Result<(Scenario, Robot)> {
        let s = Scenario::from_toml(DEFAULT_SCENARIO, DEFAULT_SCENARIO_NAME)?;
        let robot = s.load_robot(None)?;
        s.validate(&robot, DEFAULT_SCENARIO_NAME)?;
        Ok((s, robot))
    }

    pub fn load_robot(&self, dir: Option<&Path>) -> Result<Robot> {
        if self.robot == "irb120" {
            return Ok(Robot::irb120());
        }
        let p = PathBuf::from(&self.robot);
        let p = if p.is_relative() { dir.map(|d| d.join(&p)).unwrap_or(p) } else { p };
        Robot::from_urdf_file(&p)
    }

    pub fn validate(&self, robot: &Robot, origin: &str) -> Result<()> {
        let err = |msg: String| Error::Scenario { path: origin.to_string(), msg };
        if robot.dof() != 6 {
            return Err(err(format!("robot '{}' has {} revolute joints; datasets hold six joint angles (q1..q6)", robot.name, robot.dof())));
        }
        self.effects.validate(robot.dof()).map_err(err)?;
        self.sensor.validate().map_err(err)?;
        let names = robot.param_names();
        for k in self.geometry.set.keys() {
            if !names.contains(k) {
                return Err(err(format!("geometry.set: unknown parameter '{k}' (expected <joint>.<{}>)", PARAM_SUFFIXES.join("|"))));
            }
        }
        let g = &self.geometry;
        if [g.origin_offset_std_mm, g.origin_rotation_std_deg, g.joint_zero_std_deg].iter().any(|v| !(v.is_finite() && *v >= 0.0))
            || g.set.values().any(|v| !v.is_finite())
        {
            return Err(err("geometry: standard deviations must be >= 0 and values finite".into()));
        }
        let sm = &self.sampling;
        if sm.poses == 0 || sm.test >= sm.poses {
            return Err(err(format!("sampling: need poses >= 1 and test < poses (got poses = {}, test = {})", sm.poses, sm.test)));
        }
        if let Some(r) = &sm.ranges_deg {
            if r.len() != robot.dof() {
                return Err(err(format!("sampling.ranges_deg has {} ranges, the robot has {} joints", r.len(), robot.dof())));
            }
            for (j, [lo, hi]) in r.iter().enumerate() {
                let (l, u) = (robot.joints[j].lower.to_degrees(), robot.joints[j].upper.to_degrees());
                if !(lo < hi) || *lo < l - 1e-9 || *hi > u + 1e-9 {
                    return Err(err(format!("sampling.ranges_deg[{j}] = [{lo}, {hi}] must be increasing and inside the joint limits [{l:.2}, {u:.2}] degrees")));
                }
            }
        }
        if !(sm.speed_fraction > 0.0 && sm.speed_fraction <= 1.0) {
            return Err(err("sampling.speed_fraction must be in (0, 1]".into()));
        }
        let st = &self.simulation;
        if !(st.dt_s > 0.0 && st.dt_s <= 0.01) || st.max_steps == 0 || !(st.damping_ratio > 0.0) {
            return Err(err("simulation: dt_s must be in (0, 0.01], max_steps >= 1, damping_ratio > 0".into()));
        }
        Ok(())
    }

    /// Sampling ranges in radians.
    pub fn ranges_rad(&self, robot: &Robot) -> Vec<(f64, f64)> {
        match &self.sampling.ranges_deg {
            Some(r) => r.iter().map(|[a, b]| (a.to_radians(), b.to_radians())).collect(),
            None => {
                let m = self.sampling.limit_margin_deg.to_radians();
                robot.joints.iter().map(|j| (j.lower + m, j.upper - m)).collect()
            }
        }
    }

    /// The true geometric error parameters (chain units, m and rad), drawn from the seed.
    pub fn true_params(&self, robot: &Robot) -> Vec<f64> {
        let names = robot.param_names();
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(self.seed, Stream::Geometry, 0));
        let g = &self.geometry;
        let draw = |rng: &mut ChaCha8Rng, std: f64| if std > 0.0 { Normal::new(0.0, std).map(|n| n.sample(rng)).unwrap_or(0.0) } else { 0.0 };
        names
            .iter()
            .map(|name| {
                let suffix = name.rsplit('.').next().unwrap_or("");
                let is_len = matches!(suffix, "dx" | "dy" | "dz");
                let random = match suffix {
                    "dx" | "dy" | "dz" => draw(&mut rng, g.origin_offset_std_mm),
                    "dtheta" => draw(&mut rng, g.joint_zero_std_deg),
                    _ => draw(&mut rng, g.origin_rotation_std_deg),
                };
                let v = g.set.get(name).copied().unwrap_or(random);
                if is_len {
                    v * 1e-3
                } else {
                    v.to_radians()
                }
            })
            .collect()
    }
}

/// Independent random streams derived from one recorded seed.
#[derive(Clone, Copy)]
pub enum Stream {
    Geometry = 1,
    Sampling = 2,
    Split = 3,
    Noise = 4,
}

/// A seed for stream `s`, item `i` (SplitMix64 of the mixed inputs).
pub fn stream_seed(seed: u64, s: Stream, i: u64) -> u64 {
    let mut z = seed ^ ((s as u64) << 56) ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Radical inverse of `i` in base `b` (Halton coordinate).
pub fn halton(mut i: u64, b: u64) -> f64 {
    let mut f = 1.0;
    let mut r = 0.0;
    while i > 0 {
        f /= b as f64;
        r += f * (i % b) as f64;
        i /= b;
    }
    r
}

pub const HALTON_BASES: [u64; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];
