//! Scenario files: which robot, its true deviations, effects, sensor, pose sampling and seed.
//! Unknown keys are rejected with the key named.

use crate::error::{Error, Result};
use crate::robot::{Robot, PARAM_SUFFIXES};
use crate::sim::effects::Effects;
use crate::sim::instrument::DrawWire;
use crate::sim::twin::tour::Acquisition;
use crate::sim::twin::SettleOptions;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Largest `sampling.poses`.
pub use crate::sim::twin::MAX_POSES;
/// Largest `sampling.angle_decimals` (1e-12 degree; an f64 angle below 720° holds about 15
/// significant digits).
pub const MAX_ANGLE_DECIMALS: usize = 12;

/// The scenario shipped with twincal and run by `twincal generate` without `--scenario`.
pub const DEFAULT_SCENARIO: &str = include_str!("../../scenarios/irb120_evo_nph.toml");
/// The name errors give the embedded [`DEFAULT_SCENARIO`].
pub const DEFAULT_SCENARIO_NAME: &str = "scenarios/irb120_evo_nph.toml (embedded)";

/// A scenario file: which robot, its true deviations, effects, instrument, pose sampling,
/// acquisition and seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// The scenario's name (recorded in the truth file).
    pub name: String,
    /// Free text saying what the scenario is for.
    #[serde(default)]
    pub description: String,
    /// Seed of every random stream of a run (geometry, sampling, noise, glitches): a scenario and
    /// seed give a byte-identical dataset.
    pub seed: u64,
    /// `irb120` for the embedded URDF, or a URDF path relative to the scenario file.
    #[serde(default = "Scenario::default_robot")]
    pub robot: String,
    /// The true geometric deviations.
    #[serde(default)]
    pub geometry: Geometry,
    /// The twin's non-geometric effects (compliance, backlash, thermal drift, ...); none by
    /// default.
    #[serde(default)]
    pub effects: Effects,
    /// The draw-wire sensor, the file's `[sensor]` table (with another instrument: the tool
    /// point, the hold and the samples averaged).
    #[serde(rename = "sensor", alias = "draw_wire", default)]
    pub draw_wire: DrawWire,
    /// An instrument that reads instead of the cable (`[tracker]`), each under its own key.
    #[serde(flatten)]
    pub instruments: crate::sim::instrument::Instruments,
    /// How the commanded poses are sampled.
    pub sampling: Sampling,
    /// Options of the rapier settling loop.
    #[serde(default)]
    pub simulation: SettleOptions,
    /// How the readings are acquired: settled poses (default), the quasi-static model, or the
    /// simulated tour with moves, holds and a stability gate.
    #[serde(default)]
    pub acquisition: Acquisition,
    /// Runs of disturbed readings (a bumped cable, a glitching reader), as real acquisitions have.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub glitches: Option<Glitches>,
    /// The cell around the arm (floor, keep-out boxes, link capsules, the instrument's line of
    /// sight and range): sampled and planned poses keep clear of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub workspace: Option<crate::sim::workspace::Workspace>,
    /// A ball on the flange seated in the sockets of an artifact (`[sockets]`): `generate`
    /// writes the seated joint angles instead of the instrument's readings
    /// ([`crate::sim::artifact`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sockets: Option<crate::sim::artifact::Sockets>,
    /// A probe (or dial indicator) on the flange touching the faces of a block (`[planes]`):
    /// `generate` writes the contacts' joint angles instead of the instrument's readings
    /// ([`crate::sim::planes`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planes: Option<crate::sim::planes::Planes>,
}

/// Runs of consecutive disturbed readings (in acquisition order): `runs` runs of `rows` rows
/// each, placed and signed from the seed, off by `size_mm` × (1 + U(0, 0.5)): by one common
/// offset per run (`kind = "offset"`, the default: the reading jumped and stayed, like a
/// draw-wire that slipped on its drum) or by a fresh size and sign on every row
/// (`kind = "scatter"`: a disturbed stretch, like a cable rubbing on the arm).
///
/// The other kinds leave the reading alone and corrupt the *logged* joint angles of the run
/// (the arm stands where it was commanded): `joint_offset` adds `size_deg` × (1 + U(0, 0.5)),
/// signed from the seed, to one joint; `joint_sign` logs one joint with the wrong sign (the
/// joint furthest from zero over the run); `joint_stale` repeats the joint's value of the row
/// before the run (the joint that moves most over the run: the controller stopped updating
/// it); `joint_swap` logs two neighbouring joints in each other's columns. `joint` (1-based)
/// names the joint (a swap's first) instead.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Glitches {
    /// Number of runs.
    pub runs: usize,
    /// Consecutive rows per run.
    pub rows: usize,
    /// Base size of a reading's disturbance, mm (each is `size_mm` × (1 + U(0, 0.5))).
    pub size_mm: f64,
    /// How the run is disturbed (default `offset`).
    #[serde(default, skip_serializing_if = "GlitchKind::is_default")]
    pub kind: GlitchKind,
    /// A joint fault's joint, 1-based.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    /// A `joint_offset`'s size, degrees (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size_deg: Option<f64>,
}

/// How the readings of a glitch run are disturbed, see [`Glitches`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GlitchKind {
    /// One offset per run: the reading jumped and stayed.
    #[default]
    Offset,
    /// A fresh size and sign on every row of the run.
    Scatter,
    /// One joint's logged angle is off by `size_deg` × (1 + U(0, 0.5)).
    JointOffset,
    /// One joint is logged with the wrong sign.
    JointSign,
    /// One joint's logged angle repeats the row before the run.
    JointStale,
    /// Two neighbouring joints are logged in each other's columns.
    JointSwap,
    /// One joint's logged angle is off as [`GlitchKind::JointOffset`] and the reading jumps at
    /// the same row by `size_mm` × (1 + U(0, 0.5)) (a cable re-hooked after the fault).
    JointOffsetAndReading,
}

impl GlitchKind {
    fn is_default(&self) -> bool {
        *self == GlitchKind::Offset
    }
    /// Whether the fault is in the logged joint angles (besides, for
    /// [`GlitchKind::JointOffsetAndReading`], the reading).
    pub fn in_joints(self) -> bool {
        matches!(self, GlitchKind::JointOffset | GlitchKind::JointSign | GlitchKind::JointStale | GlitchKind::JointSwap | GlitchKind::JointOffsetAndReading)
    }
}

/// Largest geometric deviation of a joint origin's offset `geometry.set` (and its random spread)
/// takes, mm: a metre is already no calibration error.
pub const MAX_DEVIATION_MM: f64 = 1000.0;
/// Largest angular deviation (origin rotation, joint zero) `geometry.set` takes, degrees.
pub const MAX_DEVIATION_DEG: f64 = 180.0;

/// True geometric deviations: random with the given standard deviations, then explicit values.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    /// Standard deviation of the random joint-origin offsets (`dx, dy, dz`), mm.
    #[serde(default)]
    pub origin_offset_std_mm: f64,
    /// Standard deviation of the random joint-origin rotations (`rx, ry, rz`), degrees.
    #[serde(default)]
    pub origin_rotation_std_deg: f64,
    /// Standard deviation of the random joint-zero offsets (`dtheta`), degrees.
    #[serde(default)]
    pub joint_zero_std_deg: f64,
    /// Explicit deviations by parameter name (`joint_2.dtheta`): mm for dx/dy/dz, degrees otherwise.
    #[serde(default)]
    pub set: BTreeMap<String, f64>,
}

/// The order the sampled poses are acquired in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Order {
    /// Halton order, as sampled.
    Halton,
    /// A seeded random permutation.
    Shuffled,
    /// Sweeps, as a calibration engineer jogs an arm: from a Halton base pose one joint (every
    /// other sweep two neighbouring joints) steps across its range in `sweep_length` poses while
    /// the others hold.
    Sweeps,
}

/// How the commanded poses are sampled: count, ranges, order and precision.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sampling {
    /// Number of poses sampled, test poses included (at most [`MAX_POSES`]).
    pub poses: usize,
    /// Poses held out for testing (stratified over the cable length).
    #[serde(default)]
    pub test: usize,
    /// Joint ranges in degrees; default: the URDF limits shrunk by `limit_margin_deg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ranges_deg: Option<Vec<[f64; 2]>>,
    /// Margin kept inside each URDF joint limit when `ranges_deg` is not given, degrees.
    #[serde(default = "Sampling::default_margin")]
    pub limit_margin_deg: f64,
    /// Lowest allowed nominal tool height, mm (keeps the tool off the table).
    #[serde(default = "Sampling::default_min_z")]
    pub min_tool_z_mm: f64,
    /// Joint speed while moving between poses, fraction of the URDF limit.
    #[serde(default = "Sampling::default_speed")]
    pub speed_fraction: f64,
    /// The order the poses are acquired in (default `halton`).
    #[serde(default = "Sampling::default_order")]
    pub order: Order,
    /// Decimals of a degree the commanded joint angles are rounded to (before simulation, so the
    /// dataset holds exactly the angles the twin was commanded to). At most
    /// [`MAX_ANGLE_DECIMALS`].
    #[serde(default = "Sampling::default_angle_decimals")]
    pub angle_decimals: usize,
    /// Decimals of a degree the controller logs the joint angles at (default: `angle_decimals`):
    /// the arm is at the commanded angle, the dataset holds it rounded, as a real log does.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub logged_decimals: Option<usize>,
    /// Poses per sweep with `order = "sweeps"`.
    #[serde(default = "Sampling::default_sweep_length")]
    pub sweep_length: usize,
}

impl Sampling {
    /// Joint ranges in degrees that look like radians (every bound within the radians' range
    /// [`crate::dataset::RADIANS_MAX_ABS`] and one range wider than
    /// [`crate::dataset::RADIANS_MIN_SPAN`], as the data's reader judges angles): a warning, since
    /// a scenario of narrow ranges may be meant.
    pub fn radians_warning(&self) -> Option<String> {
        let ranges = self.ranges_deg.as_ref()?;
        let largest = ranges.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        let widest = ranges.iter().map(|[lo, hi]| hi - lo).fold(0.0f64, f64::max);
        (largest <= crate::dataset::RADIANS_MAX_ABS && widest > crate::dataset::RADIANS_MIN_SPAN).then(|| {
            format!("sampling.ranges_deg: every bound is within ±{largest:.2}, as radians would be; the ranges are degrees (the twin samples within ±{largest:.2}°)")
        })
    }

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
    fn default_angle_decimals() -> usize {
        6
    }
    fn default_sweep_length() -> usize {
        20
    }
    /// Decimals the dataset writes the joint angles at.
    pub fn written_decimals(&self) -> usize {
        self.logged_decimals.unwrap_or(self.angle_decimals)
    }
}

/// The first array of a scenario's text (`raw`) whose length the parsed scenario (`kept`,
/// serialised back) does not keep, as an error naming its key; `path` is the key so far.
fn array_lengths(raw: &toml::Value, kept: &toml::Value, path: &str) -> std::result::Result<(), String> {
    match (raw, kept) {
        (toml::Value::Table(a), toml::Value::Table(b)) => a
            .iter()
            .filter_map(|(k, v)| Some((k, v, b.get(k)?)))
            .try_for_each(|(k, v, w)| array_lengths(v, w, &if path.is_empty() { k.clone() } else { format!("{path}.{k}") })),
        (toml::Value::Array(a), toml::Value::Array(b)) if a.len() != b.len() => Err(format!("{path} has {} values; it takes {}", a.len(), b.len())),
        (toml::Value::Array(a), toml::Value::Array(b)) => a.iter().zip(b).enumerate().try_for_each(|(i, (v, w))| array_lengths(v, w, &format!("{path}[{i}]"))),
        _ => Ok(()),
    }
}

impl Scenario {
    /// How the scenario's tour moves and reads: its speed, ramps, hold and reading window.
    pub fn timing(&self) -> crate::sim::twin::tour::Timing {
        crate::sim::twin::tour::Timing {
            speed_fraction: self.sampling.speed_fraction,
            ramp_s: self.acquisition.ramp_s,
            hold_s: self.draw_wire.hold_s,
            window_s: self.draw_wire.window_s(),
        }
    }

    fn default_robot() -> String {
        "irb120".into()
    }

    /// Parses a scenario from TOML text, without validating it; `origin` names the text in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Scenario> {
        let bad = |msg: String| Error::Scenario { path: origin.to_string(), msg };
        let mut s: Scenario = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        // A fixed-length array given more values reads its first ones and drops the rest
        // without a word: every array must keep its length through the scenario.
        let raw: toml::Table = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        s.resolve_target(raw.contains_key("sensor") || raw.contains_key("draw_wire")).map_err(bad)?;
        let kept = toml::Table::try_from(&s).map_err(|e| bad(e.to_string()))?;
        array_lengths(&toml::Value::Table(raw), &toml::Value::Table(kept), "").map_err(bad)?;
        Ok(s)
    }

    /// The target, hold and samples of a scenario without a draw-wire (`[sensor]` absent:
    /// `sensor_given` false) from its `[acquisition]` table, into the one place every stage
    /// reads them (the `[sensor]` table's); a draw-wire's scenario gives them in `[sensor]` only.
    fn resolve_target(&mut self, sensor_given: bool) -> std::result::Result<(), String> {
        let a = &mut self.acquisition;
        let given: Vec<&str> =
            [("tool_point_mm", a.tool_point_mm.is_some()), ("hold_s", a.hold_s.is_some()), ("samples", a.samples.is_some()), ("rate_hz", a.rate_hz.is_some())]
                .into_iter()
                .filter_map(|(k, g)| g.then_some(k))
                .collect();
        if sensor_given {
            return match given.is_empty() {
                true => Ok(()),
                false => {
                    Err(format!("acquisition.{} and [sensor] both given: with a draw-wire they are its table's; give them once", given.join(", acquisition.")))
                }
            };
        }
        let artifact = self.sockets.is_some() || self.planes.is_some();
        if self.instruments.active().is_none() && !artifact {
            return Err("no instrument: a scenario needs a [sensor] (draw-wire), a [tracker], [sockets] or [planes]".into());
        }
        let tool = match a.tool_point_mm {
            Some(t) => t,
            None if self.instruments.active().is_none() => [0.0; 3],
            None => return Err("without a [sensor], the target the tracker reads is acquisition.tool_point_mm (flange frame, mm)".into()),
        };
        let d = DrawWire::default();
        self.draw_wire = DrawWire {
            tool_point_mm: tool,
            hold_s: a.hold_s.take().unwrap_or(d.hold_s),
            samples: a.samples.take().unwrap_or(d.samples),
            rate_hz: a.rate_hz.take().unwrap_or(d.rate_hz),
            ..d
        };
        a.tool_point_mm = None;
        // The held-out rows are stratified over each pose's distance from the draw-wire's exit
        // point; without one, from the instrument's origin (a tracker's).
        if self.instruments.active().is_some() {
            let p = crate::sim::instrument::placement(&self.draw_wire, &self.instruments);
            self.draw_wire.exit_point_mm = crate::units::to_mm(p.measurement.def().frame(&p.own).origin).into();
            // (No cable's range to keep the poses in.)
            self.draw_wire.range_mm = [0.0, crate::measurement::length::MAX_L_MM];
        }
        Ok(())
    }

    /// Reads a scenario file, loads its robot (a URDF path relative to the file's folder) and
    /// validates both; warns on stderr about joints without a velocity limit.
    pub fn load(path: &Path) -> Result<(Scenario, Robot)> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let origin = path.display().to_string();
        let s = Scenario::from_toml(&text, &origin)?;
        let robot = s.load_robot(path.parent())?;
        s.validate(&robot, &origin)?;
        if let Some(w) = s.sampling.radians_warning() {
            eprintln!("warning: {origin}: {w}");
        }
        for j in robot.joints.iter().filter(|j| !j.has_speed_limit()) {
            eprintln!(
                "warning: joint '{}' of robot '{}' has no velocity limit in its URDF (<limit velocity=...> is 0 or absent); \
                 the acquisition moves it at sampling.speed_fraction x {} rad/s",
                j.name,
                robot.name,
                crate::robot::DEFAULT_JOINT_SPEED_RAD_S
            );
        }
        Ok((s, robot))
    }

    /// The embedded default scenario.
    pub fn default_embedded() -> Result<(Scenario, Robot)> {
        let s = Scenario::from_toml(DEFAULT_SCENARIO, DEFAULT_SCENARIO_NAME)?;
        let robot = s.load_robot(None)?;
        s.validate(&robot, DEFAULT_SCENARIO_NAME)?;
        Ok((s, robot))
    }

    /// The robot the scenario names: the embedded IRB 120, or its URDF file (a relative path is
    /// taken from `dir`).
    pub fn load_robot(&self, dir: Option<&Path>) -> Result<Robot> {
        match self.robot_file(dir) {
            None => Ok(Robot::irb120()),
            Some(p) => Robot::from_urdf_file(&p),
        }
    }

    /// The URDF file the scenario's `robot` names (relative to the scenario's folder `dir`);
    /// `None` for the embedded IRB 120.
    pub fn robot_file(&self, dir: Option<&Path>) -> Option<PathBuf> {
        if self.robot == "irb120" {
            return None;
        }
        let p = PathBuf::from(&self.robot);
        Some(if p.is_relative() { dir.map(|d| d.join(&p)).unwrap_or(p) } else { p })
    }

    /// The feasibility check of this scenario's commanded poses on `robot`: the tool above
    /// `sampling.min_tool_z_mm`, the instrument's range (the cable's, or the tracker's
    /// `workspace.tracker_range_mm`) and the `[workspace]`, if any.
    pub fn cell(&self, robot: &Robot) -> crate::sim::workspace::Cell {
        use crate::sim::workspace::{Cell, Reach};
        let reach = match (&self.instruments.tracker, self.instruments.active()) {
            (Some(_), Some(i)) => {
                let pl = i.placement(self.draw_wire.tool_point_m());
                let origin = pl.measurement.def().frame(&pl.own).origin;
                Reach::Tracker { origin, range_mm: self.workspace.as_ref().and_then(|w| w.tracker_range_mm) }
            }
            _ => Reach::Cable(self.draw_wire.clone()),
        };
        Cell::new(robot.error_chain(), self.draw_wire.tool_point_m(), self.sampling.min_tool_z_mm, Some(reach), self.workspace.clone())
    }

    /// Checks every section against `robot`; the error names `origin` and the first bad key.
    pub fn validate(&self, robot: &Robot, origin: &str) -> Result<()> {
        let err = |msg: String| Error::Scenario { path: origin.to_string(), msg };
        if robot.dof() == 0 || robot.dof() > crate::dataset::MAX_JOINTS {
            return Err(err(format!(
                "robot '{}' has {} revolute joints; a dataset holds 1..{} joint angles",
                robot.name,
                robot.dof(),
                crate::dataset::MAX_JOINTS
            )));
        }
        self.effects.validate(robot.dof()).map_err(err)?;
        self.draw_wire.validate().map_err(err)?;
        self.instruments.validate().map_err(err)?;
        if let Some(w) = &self.workspace {
            w.validate().map_err(err)?;
            if w.tracker_range_mm.is_some() && self.instruments.tracker.is_none() {
                return Err(err("workspace.tracker_range_mm needs a [tracker]".into()));
            }
        }
        if let Some(i) = self.instruments.active() {
            if self.draw_wire.tension_n != 0.0 {
                return Err(err(format!("sensor.tension_n = {}: with a [{}] no cable pulls on the tool; set it to 0", self.draw_wire.tension_n, i.key())));
            }
            if self.glitches.is_some() {
                return Err(err(format!("[glitches] disturb a cable's reading; a [{}] scenario has none", i.key())));
            }
        }
        if let Some(a) = &self.sockets {
            a.validate().map_err(err)?;
        }
        if let Some(a) = &self.planes {
            a.validate().map_err(err)?;
            if let Some(k) = self.sockets.as_ref().filter(|k| k.ball_mm != a.stylus_mm) {
                return Err(err(format!(
                    "[sockets] and [planes]: one ball is seated in the sockets and touches the faces; planes.stylus_mm {:?} must equal sockets.ball_mm {:?}",
                    a.stylus_mm, k.ball_mm
                )));
            }
        }
        self.validate_geometry(robot).map_err(err)?;
        self.validate_sampling(robot).map_err(err)?;
        self.validate_glitches().map_err(err)?;
        self.simulation.validate().map_err(err)?;
        self.acquisition.validate(self.simulation.dt_s, self.draw_wire.rate_hz).map_err(err)?;
        Ok(())
    }

    /// The geometry section: parameters the robot has, finite spreads, deviations within
    /// [`MAX_DEVIATION_MM`] and [`MAX_DEVIATION_DEG`].
    fn validate_geometry(&self, robot: &Robot) -> std::result::Result<(), String> {
        let names = robot.param_names();
        for k in self.geometry.set.keys() {
            if !names.contains(k) {
                return Err(format!("geometry.set: unknown parameter '{k}' (expected <joint>.<{}>)", PARAM_SUFFIXES.join("|")));
            }
        }
        let g = &self.geometry;
        let stds = [
            ("origin_offset_std_mm", g.origin_offset_std_mm),
            ("origin_rotation_std_deg", g.origin_rotation_std_deg),
            ("joint_zero_std_deg", g.joint_zero_std_deg),
        ];
        for (key, v) in stds {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("geometry.{key} = {v} must be finite and >= 0"));
            }
        }
        if let Some((k, v)) = g.set.iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!("geometry.set.\"{k}\" = {v} must be finite"));
        }
        // A deviation of an arm's geometry, not another arm: a metre, half a turn at most.
        for (k, v) in &g.set {
            let (limit, unit) = match crate::robot::GeoKind::of_name(k) {
                Some(crate::robot::GeoKind::Length) => (MAX_DEVIATION_MM, "mm"),
                _ => (MAX_DEVIATION_DEG, "degrees"),
            };
            if v.abs() > limit {
                return Err(format!(
                    "geometry.set.\"{k}\" = {} {unit} is beyond the {limit} {unit} a geometric error can be (a deviation from the URDF, not another arm)",
                    crate::error::shown(*v)
                ));
            }
        }
        for (key, v, limit) in [
            ("origin_offset_std_mm", g.origin_offset_std_mm, MAX_DEVIATION_MM),
            ("origin_rotation_std_deg", g.origin_rotation_std_deg, MAX_DEVIATION_DEG),
            ("joint_zero_std_deg", g.joint_zero_std_deg, MAX_DEVIATION_DEG),
        ] {
            if v > limit {
                return Err(format!("geometry.{key} = {} is beyond {limit}", crate::error::shown(v)));
            }
        }
        Ok(())
    }

    /// The sampling section: pose counts, ranges inside the joint limits, margins, decimals.
    fn validate_sampling(&self, robot: &Robot) -> std::result::Result<(), String> {
        let sm = &self.sampling;
        if sm.poses == 0 || sm.poses > MAX_POSES || sm.test >= sm.poses {
            return Err(format!(
                "sampling.poses = {} and sampling.test = {}: need 1 <= poses <= {MAX_POSES} and \
                 test < poses",
                sm.poses, sm.test
            ));
        }
        if let Some(r) = &sm.ranges_deg {
            if r.len() != robot.dof() {
                return Err(format!("sampling.ranges_deg has {} ranges, the robot has {} joints", r.len(), robot.dof()));
            }
            for (j, [lo, hi]) in r.iter().enumerate() {
                let (l, u) = (robot.joints[j].lower.to_degrees(), robot.joints[j].upper.to_degrees());
                let increasing = lo.partial_cmp(hi) == Some(std::cmp::Ordering::Less);
                if !increasing || *lo < l - 1e-9 || *hi > u + 1e-9 {
                    return Err(format!(
                        "sampling.ranges_deg[{j}] = [{lo}, {hi}] must be increasing and inside \
                         the joint limits [{l:.2}, {u:.2}] degrees"
                    ));
                }
            }
        }
        let m = sm.limit_margin_deg;
        if !(m.is_finite() && m >= 0.0) {
            return Err(format!("sampling.limit_margin_deg = {m} must be finite and >= 0"));
        }
        if sm.ranges_deg.is_none() {
            for j in &robot.joints {
                let (l, u) = (j.lower.to_degrees(), j.upper.to_degrees());
                if l + m >= u - m {
                    return Err(format!(
                        "sampling.limit_margin_deg = {m} leaves no range for joint '{}' (limits \
                         [{l:.2}, {u:.2}] degrees)",
                        j.name
                    ));
                }
            }
        }
        if !sm.min_tool_z_mm.is_finite() {
            return Err(format!("sampling.min_tool_z_mm = {} must be finite", sm.min_tool_z_mm));
        }
        if !(sm.speed_fraction > 0.0 && sm.speed_fraction <= 1.0) {
            return Err(format!("sampling.speed_fraction = {} must be in (0, 1]", sm.speed_fraction));
        }
        if sm.angle_decimals > MAX_ANGLE_DECIMALS {
            return Err(format!("sampling.angle_decimals = {} must be at most {MAX_ANGLE_DECIMALS}", sm.angle_decimals));
        }
        if let Some(d) = sm.logged_decimals.filter(|d| *d > sm.angle_decimals) {
            return Err(format!("sampling.logged_decimals = {d} must be at most sampling.angle_decimals = {}", sm.angle_decimals));
        }
        if !(2..=1000).contains(&sm.sweep_length) {
            return Err(format!("sampling.sweep_length = {} must be in 2..=1000", sm.sweep_length));
        }
        Ok(())
    }

    /// The glitches section: runs, sizes, the joint.
    fn validate_glitches(&self) -> std::result::Result<(), String> {
        let sm = &self.sampling;
        if let Some(g) = &self.glitches {
            if g.runs == 0 || g.rows == 0 || g.runs * g.rows > sm.poses / 4 {
                return Err(format!("glitches: {} runs of {} rows must be at least one row and at most a quarter of the {} poses", g.runs, g.rows, sm.poses));
            }
            if !(g.size_mm.is_finite() && g.size_mm > 0.0 && g.size_mm <= 0.1 * (self.draw_wire.range_mm[1] - self.draw_wire.range_mm[0])) {
                return Err(format!("glitches.size_mm = {} must be positive and at most 10 % of the sensor range", g.size_mm));
            }
            let joints = self.sampling.ranges_deg.as_ref().map_or(usize::MAX, |r| r.len());
            if let Some(j) = g.joint.filter(|&j| j == 0 || j > joints.min(crate::dataset::MAX_JOINTS)) {
                return Err(format!("glitches.joint = {j} must be a joint of the arm, 1-based"));
            }
            if let Some(d) = g.size_deg.filter(|d| !(d.is_finite() && *d > 0.0 && *d <= 30.0)) {
                return Err(format!("glitches.size_deg = {d} must be in (0, 30] degrees"));
            }
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
        let draw = |rng: &mut ChaCha8Rng, std: f64| {
            if std > 0.0 {
                Normal::new(0.0, std).map(|n| n.sample(rng)).unwrap_or(0.0)
            } else {
                0.0
            }
        };
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
                    crate::units::to_m(v)
                } else {
                    v.to_radians()
                }
            })
            .collect()
    }
}

pub use crate::seed::{stream_seed, Stream};

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

/// Halton base per joint (the first 12 primes): sampling supports up to 12 joints.
pub const HALTON_BASES: [u64; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];

#[cfg(test)]
mod tests {
    use super::*;

    const IDEAL: &str = include_str!("../../scenarios/irb120_ideal.toml");

    /// The ideal scenario with `table.key = value` set (TOML syntax for the value).
    fn with(table: &str, key: &str, value: &str) -> String {
        let mut doc: toml::Table = toml::from_str(IDEAL).expect("ideal scenario parses");
        let v: toml::Table = toml::from_str(&format!("v = {value}")).expect("value parses");
        let t = doc.entry(table.to_string()).or_insert_with(|| toml::Value::Table(Default::default()));
        t.as_table_mut().expect("a table").insert(key.into(), v["v"].clone());
        toml::to_string(&doc).expect("serialise")
    }

    /// The error for the patched scenario; it must fail to load or to validate.
    fn error(table: &str, key: &str, value: &str) -> String {
        let text = with(table, key, value);
        let robot = Robot::irb120();
        let e = match Scenario::from_toml(&text, "patched.toml") {
            Err(e) => e,
            Ok(s) => s.validate(&robot, "patched.toml").expect_err(&format!("{table}.{key} = {value}")),
        };
        let msg = e.to_string();
        assert!(msg.contains("patched.toml"), "{msg}");
        msg
    }

    fn assert_names(table: &str, key: &str, value: &str) {
        let msg = error(table, key, value);
        let full = format!("{table}.{key}");
        assert!(msg.contains(&full), "{full} = {value}: message does not name the key: {msg}");
    }

    fn valid(text: &str) -> bool {
        let s = Scenario::from_toml(text, "ok.toml").expect("parses");
        s.validate(&Robot::irb120(), "ok.toml").is_ok()
    }

    #[test]
    fn shipped_scenarios_validate() {
        assert!(valid(IDEAL));
        for name in ["irb120_geometric", "irb120_pso_ekf", "irb120_full", "irb120_evo_nph"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios").join(format!("{name}.toml"));
            Scenario::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        assert_eq!(Scenario::from_toml(IDEAL, "x").expect("ideal").sampling.angle_decimals, 6);
    }

    /// A fixed-length array given more values is refused naming its key (serde read the first
    /// ones and dropped the rest); arrays of the right length, and lists of any length, pass.
    #[test]
    fn arrays_of_the_wrong_length_are_refused_naming_the_key() {
        let tracker = include_str!("../../scenarios/irb120_tracker.toml");
        for (from, to, key) in [
            ("exit_point_mm = [800.0, 300.0, 50.0]", "exit_point_mm = [800.0, 300.0, 50.0, 999.0]", "sensor.exit_point_mm has 4 values; it takes 3"),
            ("ranges_deg = [[-90, 90],", "ranges_deg = [[-90, 90, 5],", "sampling.ranges_deg[0] has 3 values; it takes 2"),
            (
                "[sensor]\n",
                "[sensor]\npolynomial = { range_mm = [100.0, 900.0], legendre_mm = [1.0, 2.0, 3.0, 4.0, 5.0] }\n",
                "sensor.polynomial.legendre_mm has 5 values",
            ),
        ] {
            let text = tracker.replacen(from, to, 1);
            assert_ne!(text, tracker, "{from}");
            let e = Scenario::from_toml(&text, "t.toml").expect_err(key).to_string();
            assert!(e.contains(key), "{e}");
        }
        assert!(Scenario::from_toml(tracker, "t.toml").is_ok());
    }

    /// Ranges written in radians are warned (every bound within the radians' range); degree
    /// ranges are not.
    #[test]
    fn ranges_in_radians_are_warned() {
        let tracker = include_str!("../../scenarios/irb120_tracker.toml");
        assert_eq!(Scenario::from_toml(tracker, "t.toml").unwrap().sampling.radians_warning(), None);
        let rad = tracker.replacen("ranges_deg = [[-90, 90],", "ranges_deg = [[-1.57, 1.57],", 1);
        let rad = rad.replace("[-45, 80]", "[-0.8, 1.4]").replace("[-90, 50]", "[-1.5, 0.8]").replace("[-150, 150]", "[-2.6, 2.6]");
        let rad = rad.replace("[-100, 100]", "[-1.7, 1.7]").replace("[-180, 180]", "[-3.1, 3.1]");
        let w = Scenario::from_toml(&rad, "t.toml").unwrap().sampling.radians_warning().expect("radians");
        assert!(w.contains("sampling.ranges_deg") && w.contains("3.10"), "{w}");
    }

    #[test]
    fn bad_values_are_refused_naming_the_key() {
        let cases: &[(&str, &str, &str)] = &[
            ("sampling", "limit_margin_deg", "-1.0"),
            ("sampling", "limit_margin_deg", "nan"),
            ("sampling", "min_tool_z_mm", "inf"),
            ("sampling", "min_tool_z_mm", "nan"),
            ("sampling", "speed_fraction", "nan"),
            ("sampling", "angle_decimals", "13"),
            ("sensor", "resolution_mm", "300.0"),
            ("sensor", "resolution_mm", "-0.1"),
            ("sensor", "noise_std_mm", "250.0"),
            ("sensor", "noise_std_mm", "nan"),
            ("sensor", "rate_hz", "0.5"),
            ("sensor", "rate_hz", "2e6"),
            ("sensor", "rate_hz", "inf"),
            ("sensor", "hold_s", "3601.0"),
            ("sensor", "hold_s", "-1.0"),
            ("sensor", "samples", "0"),
            ("sensor", "samples", "100001"),
            ("sensor", "samples", "4000000000"),
            ("sensor", "length_offset_mm", "nan"),
            ("sensor", "exit_point_mm", "[0.0, inf, 0.0]"),
            ("sensor", "linearity_pct_fs", "6.0"),
            ("simulation", "step_tolerance_rad", "-1e-13"),
            ("simulation", "step_tolerance_rad", "0.0"),
            ("simulation", "step_tolerance_rad", "nan"),
            ("simulation", "max_steps", "1000001"),
            ("simulation", "max_steps", "0"),
            ("simulation", "quiet_steps", "0"),
            ("simulation", "damping_ratio", "inf"),
            ("simulation", "dt_s", "nan"),
            ("acquisition", "damping_ratio", "-0.05"),
            ("acquisition", "ramp_s", "0.0"),
            ("acquisition", "gate_window_s", "inf"),
            ("acquisition", "gate_mm", "-1.0"),
            ("acquisition", "coarse_dt_s", "0.0001"),
            ("acquisition", "chunk_poses", "0"),
        ];
        for (table, key, value) in cases {
            assert_names(table, key, value);
        }
        // poses: bound and message.
        let msg = error("sampling", "poses", "100001");
        assert!(msg.contains("poses") && msg.contains("100000"), "{msg}");
        // A float where a count is expected is a parse error naming the key, not hours of work.
        let msg = error("sensor", "samples", "4e9");
        assert!(msg.contains("samples"), "{msg}");
        // The limits of what is allowed are allowed.
        assert!(valid(&with("sensor", "samples", "100000")));
        assert!(valid(&with("sensor", "rate_hz", "1.0")));
        assert!(valid(&with("sensor", "noise_std_mm", "200.0")));
        assert!(valid(&with("simulation", "max_steps", "1000000")));
        assert!(valid(&with("sampling", "limit_margin_deg", "0.0")));
    }

    /// The ideal scenario with TOML `tables` appended; the error it loads or validates with.
    fn appended_error(tables: &str) -> Option<String> {
        let text = format!("{IDEAL}\n{tables}");
        match Scenario::from_toml(&text, "patched.toml") {
            Err(e) => Some(e.to_string()),
            Ok(s) => s.validate(&Robot::irb120(), "patched.toml").err().map(|e| e.to_string()),
        }
    }

    #[test]
    fn eccentricity_and_temperature_sensor_keys_are_checked_naming_the_key() {
        let thermal = "[effects.thermal]\nalpha_per_k = 23e-6\ndelta_t_max_k = 5.0\ntime_constant_s = 900.0\n";
        let ecc = |a: &str, p: &str| format!("[effects.eccentricity]\namplitude_deg = {a}\nphase_deg = {p}\n");
        let six = "[0.005, 0.005, 0.005, 0.0, 0.0, 0.0]";
        let good = format!("{thermal}temp_lag_s = 120.0\ntemp_offset_k = 0.3\ntemp_noise_k = 0.05\ntemp_column = false\n{}", ecc(six, "[0, 90, -45, 0, 0, 0]"));
        assert_eq!(appended_error(&good), None);
        let s = Scenario::from_toml(&format!("{IDEAL}\n{thermal}"), "x").expect("parses");
        let th = s.effects.thermal.expect("thermal");
        assert!(th.temp_column && th.temp_lag_s == 0.0 && th.temp_offset_k == 0.0 && th.temp_noise_k == 0.0, "defaults: {th:?}");
        let cases: Vec<(String, &str)> = vec![
            (format!("{thermal}temp_lag_s = -1.0\n"), "effects.thermal.temp_lag_s"),
            (format!("{thermal}temp_lag_s = nan\n"), "effects.thermal.temp_lag_s"),
            (format!("{thermal}temp_offset_k = inf\n"), "effects.thermal.temp_offset_k"),
            (format!("{thermal}temp_noise_k = -0.05\n"), "effects.thermal.temp_noise_k"),
            (format!("{thermal}temp_noise_k = nan\n"), "effects.thermal.temp_noise_k"),
            (format!("{thermal}temp_lagg = 3.0\n"), "temp_lagg"),
            (format!("{thermal}temp_column = 1\n"), "temp_column"),
            (ecc("[0.005, 0.005, 0.005]", "[0, 0, 0, 0, 0, 0]"), "effects.eccentricity.amplitude_deg"),
            (ecc("[0.005, 0.005, 1.0, 0.0, 0.0, 0.0]", "[0, 0, 0, 0, 0, 0]"), "effects.eccentricity.amplitude_deg"),
            (ecc("[0.005, 0.005, nan, 0.0, 0.0, 0.0]", "[0, 0, 0, 0, 0, 0]"), "effects.eccentricity.amplitude_deg"),
            (ecc(six, "[0, 0, 0, 0, 0, 0, 0]"), "effects.eccentricity.phase_deg"),
            (ecc(six, "[0, 0, inf, 0, 0, 0]"), "effects.eccentricity.phase_deg"),
            (format!("[effects.eccentricity]\namplitude_deg = {six}\n"), "phase_deg"),
            (format!("{}phase_offset = 1.0\n", ecc(six, "[0, 0, 0, 0, 0, 0]")), "phase_offset"),
        ];
        for (tables, key) in cases {
            let msg = appended_error(&tables).unwrap_or_else(|| panic!("accepted: {tables}"));
            assert!(msg.contains("patched.toml") && msg.contains(key), "{tables}: message does not name {key}: {msg}");
        }
    }

    #[test]
    fn limit_margin_must_leave_a_range_when_it_is_used() {
        // The ideal scenario gives explicit ranges, so the margin is unused there; without them
        // a margin swallowing a joint's range is refused naming the joint.
        let mut doc: toml::Table = toml::from_str(IDEAL).expect("parses");
        let sampling = doc.get_mut("sampling").and_then(|v| v.as_table_mut()).expect("table");
        sampling.remove("ranges_deg");
        sampling.insert("limit_margin_deg".into(), toml::Value::Float(170.0));
        let s = Scenario::from_toml(&toml::to_string(&doc).expect("toml"), "m.toml").expect("parses");
        let msg = s.validate(&Robot::irb120(), "m.toml").expect_err("no range left").to_string();
        assert!(msg.contains("sampling.limit_margin_deg") && msg.contains("joint_"), "{msg}");
    }
}
