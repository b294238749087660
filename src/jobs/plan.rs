//! `twincal plan`: a measurement plan for a scenario's arm, instrument and cell
//! ([`crate::plan`]), written as a pose list (`poses.csv`, what `generate --poses` and a robot
//! program step through) and its indices (`plan.json`), whole or not at all.

use super::files::{load_scenario, scenario_inputs, Recordings};
use crate::calib::model::Parametrisation;
use crate::calib::pipeline::CalibResult;
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use crate::plan::{plan, Plan, PlanOptions};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The pose list a plan writes in its folder.
pub const POSES_FILE: &str = "poses.csv";
/// The name of the measurement program `--program-format` writes in the plan's folder.
pub const PROGRAM_NAME: &str = "twincal_plan";
/// The plan's indices, pool and tour, in its folder.
pub const PLAN_FILE: &str = "plan.json";

/// A plan as `twincal plan` runs it; Python's `twincal.plan` arguments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct PlanJob {
    /// The scenario: its robot, its instrument's placement (`[sensor]`, `[tracker]`), the joint
    /// ranges and tool height of `[sampling]`, and the cell (`[workspace]`); default: the embedded
    /// one.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub scenario: Option<PathBuf>,
    /// Poses to plan.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 30))]
    #[serde(default = "default_poses")]
    pub poses: usize,
    /// Feasible candidates to choose from.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 10_000))]
    #[serde(default = "default_candidates")]
    pub candidates: usize,
    /// The index maximised: i (I-optimal: mean prediction variance over the candidates), d (O1,
    /// D-optimal), min-sv (O3), noise (O4, noise amplification) or a (O5).
    #[cfg_attr(feature = "clap", arg(long, default_value = "i"))]
    #[serde(default = "default_criterion")]
    pub criterion: String,
    /// The parametrisation the calibration will use: hayati (default), dh or frame.
    #[cfg_attr(feature = "clap", arg(long, value_enum, ignore_case = true))]
    #[serde(default)]
    pub params: Option<Parametrisation>,
    /// Plan the next calibration of this calibrated arm (a result.json or diagnosed.json): its
    /// parametrisation, its instrument's calibrated placement and its effect blocks, linearised
    /// at its calibrated values, with the payload it was calibrated with (or --payload-kg); the
    /// scenario gives the cell. Not with --params or --effects.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub model: Option<PathBuf>,
    /// Effects the calibration will fit beside the geometry, whose parameters the plan also
    /// makes observable: compliance, eccentricity, nonlinearity, ... (`KIND[:JOINT]`, comma-separated).
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ','))]
    #[serde(default)]
    pub effects: Vec<crate::calib::effects::EffectChoice>,
    /// The payload mounted while measuring, kg (default: the scenario's [effects.payload]); it
    /// loads the joints for the load-driven effects.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    #[serde(default)]
    pub payload_kg: Option<f64>,
    /// Payloads the engineer can mount, kg (comma-separated, e.g. 0,2,5): each pose is planned
    /// with the one that makes the load-driven effects most observable, and poses.csv says which
    /// (payload_kg); their centre of mass is --payload-com-mm's (the scenario's payload's). Needs
    /// a load-driven effect (--effects compliance, or a --model with one).
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ','))]
    #[serde(default)]
    pub payloads: Vec<f64>,
    /// Its centre of mass in the flange frame, mm (x,y,z).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y,Z"))]
    #[serde(default)]
    pub payload_com_mm: Option<Vec<f64>>,
    /// Seed of the candidate pool (default: the scenario's).
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub seed: Option<u64>,
    /// Also write the tour as a program the controller runs as it is, in --out: rapid
    /// (twincal_plan.mod), krl (twincal_plan.src and .dat) or urscript (twincal_plan.script):
    /// joint moves in the tour's order, the hold, then a wait until the pose is measured.
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    #[serde(default)]
    pub program_format: Option<crate::controller::Language>,
    /// Seconds the program holds the arm still at each pose before it waits for the measurement.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = crate::controller::DEFAULT_HOLD_S, allow_negative_numbers = true))]
    #[serde(default = "default_hold_s")]
    pub hold_s: f64,
    /// Folder to write poses.csv and plan.json in.
    #[cfg_attr(feature = "clap", arg(long, default_value = "plan"))]
    #[serde(default = "default_out")]
    pub out: PathBuf,
    /// Also write a Rerun recording of the plan here.
    #[cfg_attr(feature = "clap", arg(long))]
    #[serde(default)]
    pub rrd: Option<PathBuf>,
}

fn default_poses() -> usize {
    30
}
fn default_candidates() -> usize {
    10_000
}
fn default_criterion() -> String {
    "i".into()
}
fn default_hold_s() -> f64 {
    crate::controller::DEFAULT_HOLD_S
}
fn default_out() -> PathBuf {
    PathBuf::from("plan")
}

impl Default for PlanJob {
    fn default() -> Self {
        PlanJob {
            scenario: None,
            poses: default_poses(),
            candidates: default_candidates(),
            criterion: default_criterion(),
            params: None,
            model: None,
            effects: Vec::new(),
            payload_kg: None,
            payloads: Vec::new(),
            payload_com_mm: None,
            seed: None,
            program_format: None,
            hold_s: default_hold_s(),
            out: default_out(),
            rrd: None,
        }
    }
}

/// An artifact's plan as the rows to record: each configuration's joint angles (degrees, as
/// planned on the nominal arm: where to seat the ball or touch the face from), its placement and
/// its feature (`features`: `placement/feature`, of kind `kind`).
fn artifact_csv(p: &Plan, features: &[String], kind: crate::measurement::FeatureKind) -> String {
    let rows = p
        .poses_deg
        .iter()
        .zip(features)
        .map(|(q, f)| {
            let (placement, label) = f.rsplit_once('/').map_or((None, f.as_str()), |(a, b)| (Some(a.to_string()), b));
            crate::dataset::Row {
                q_deg: q.clone(),
                station: placement,
                feature: Some(crate::dataset::Feature { kind, label: label.to_string() }),
                ..Default::default()
            }
        })
        .collect();
    crate::dataset::Dataset { rows, source: POSES_FILE.into() }.to_csv_string()
}

/// Most candidates a plan draws.
pub const MAX_CANDIDATES: usize = 100_000;

/// Most payloads a plan chooses from.
pub const MAX_PAYLOADS: usize = 10;

/// Most poses a plan chooses (the exchange visits each against every candidate).
pub const MAX_PLAN_POSES: usize = 2_000;

impl PlanJob {
    /// The options that need no file, checked before any is read.
    fn check(&self) -> Result<()> {
        if self.out.exists() && !self.out.is_dir() {
            return Err(Error::Invalid(format!("--out {} is a file; plan writes a folder ({POSES_FILE}, {PLAN_FILE})", self.out.display())));
        }
        if !(1..=MAX_PLAN_POSES).contains(&self.poses) {
            return Err(Error::Invalid(format!("--poses must be in 1..={MAX_PLAN_POSES}, got {}", self.poses)));
        }
        if !(self.poses..=MAX_CANDIDATES).contains(&self.candidates) {
            return Err(Error::Invalid(format!("--candidates must be in {}..={MAX_CANDIDATES} (at least --poses), got {}", self.poses, self.candidates)));
        }
        crate::plan::criterion(&self.criterion)?;
        if self.model.is_some() && (self.params.is_some() || !self.effects.is_empty()) {
            return Err(Error::Invalid(
                "--model plans for the calibrated model's own parametrisation and effect blocks: not with --params or --effects".into(),
            ));
        }
        if self.program_format.is_some() {
            crate::controller::check_hold_s(self.hold_s)?;
        }
        if let Some(m) = self.payloads.iter().find(|m| !(m.is_finite() && (0.0..=crate::dataset::MAX_PAYLOAD_KG).contains(*m))) {
            return Err(Error::Invalid(format!("--payloads: {m} kg is not a payload (finite, in [0, {}] kg)", crate::dataset::MAX_PAYLOAD_KG)));
        }
        if self.payloads.len() > MAX_PAYLOADS {
            return Err(Error::Invalid(format!("--payloads lists {} payloads; at most {MAX_PAYLOADS}", self.payloads.len())));
        }
        if self.payloads.iter().enumerate().any(|(i, m)| self.payloads[..i].contains(m)) {
            return Err(Error::Invalid("--payloads lists a payload twice".into()));
        }
        Ok(())
    }

    /// Plans and writes poses.csv, plan.json and the recording, if asked.
    pub fn run(&self, recordings: &dyn Recordings) -> Result<Plan> {
        self.check()?;
        let parametrisation = self.params.unwrap_or_default();
        let (s, robot) = load_scenario(self.scenario.as_deref())?;
        let (poses_path, plan_path) = (self.out.join(POSES_FILE), self.out.join(PLAN_FILE));
        let program_paths: Vec<PathBuf> =
            self.program_format.map(|l| l.file_names(PROGRAM_NAME).iter().map(|n| self.out.join(n)).collect()).unwrap_or_default();
        let mut outs = vec![("--out", poses_path.as_path()), ("--out", plan_path.as_path())];
        if let Some(r) = &self.rrd {
            outs.push(("--rrd", r.as_path()));
        }
        for p in &program_paths {
            outs.push(("--program-format", p.as_path()));
        }
        let mut inputs = scenario_inputs(self.scenario.as_deref(), &s);
        if let Some(m) = &self.model {
            inputs.push(("--model", m.clone()));
        }
        check_outputs(&inputs, &outs)?;
        let calibrated = self.model.as_deref().map(CalibResult::load).transpose()?.map(std::sync::Arc::new);
        let effects: Vec<_> = self.effects.iter().map(|c| c.pair()).collect();
        // A calibrated model of another arm than the scenario's plans nothing worth measuring.
        if let Some(gap) = calibrated.as_ref().map(|r| super::export::nominal_gap_mm(r, &robot)).filter(|g| *g > crate::calib::pipeline::OTHER_ARM_MM) {
            return Err(Error::Invalid(format!(
                "--model is another arm than the scenario's {}: its flange stands up to {gap:.1} mm from the scenario robot's at the same joint angles",
                robot.name
            )));
        }
        let loaded = effects.iter().any(|(k, _)| k.def().reads_torques())
            || calibrated.as_ref().is_some_and(|r| r.model.effects.iter().any(|b| b.kind.def().reads_torques()));
        if !self.payloads.is_empty() && !loaded {
            return Err(Error::Invalid(
                "--payloads changes only what load-driven effects see: plan them with --effects compliance (or a --model with compliance)".into(),
            ));
        }
        let mut loads =
            crate::requests::Loads { payload_kg: self.payload_kg, payload_com_mm: self.payload_com_mm.clone(), ..Default::default() }.resolve()?.joints;
        // The payload mounted: the one asked for, else the scenario's (a calibrated model's own
        // when planning for it).
        if loads.payload.is_none() && calibrated.is_none() {
            loads.payload = s.effects.payload.clone();
        }
        if s.instruments.active().is_none() {
            loads.cable_tension_n = s.draw_wire.tension_n;
        }
        let opts = PlanOptions {
            n: self.poses,
            candidates: self.candidates,
            criterion: self.criterion.clone(),
            parametrisation,
            seed: self.seed.unwrap_or(s.seed),
            effects,
            loads,
            calibrated,
            payloads: self.payloads.clone(),
            ..PlanOptions::default()
        };
        if self.program_format.is_some() && (s.sockets.is_some() || s.planes.is_some()) {
            return Err(Error::Invalid(
                "--program-format: an artifact's configurations are reached by seating the ball (touching the face) by hand; a program's joint moves would drive the tool into the artifact wherever the nominal arm errs".into(),
            ));
        }
        let mut p = plan(&s, &robot, &opts)?;
        if self.payload_kg.is_some() && !loaded {
            p.warnings.push("--payload-kg changes only what load-driven effects see, and none is planned: plan them with --effects compliance (or a --model with compliance)".into());
        }
        let mut outputs = OutputSet::new();
        if let Some(r) = &self.rrd {
            recordings.plan(&p, &s, &robot, &mut outputs, r)?;
        }
        let list = crate::sim::pose_list::PoseList { q: p.poses.clone(), payload_kg: p.payload_kg.clone() };
        let csv = match &p.features {
            Some(f) => artifact_csv(&p, f, if s.planes.is_some() { crate::measurement::FeatureKind::Plane } else { crate::measurement::FeatureKind::Socket }),
            None => crate::sim::pose_list::pose_list_csv(&list, s.sampling.angle_decimals),
        };
        outputs.write(&poses_path, csv.as_bytes())?;
        if let Some(lang) = self.program_format {
            let tour = crate::controller::Tour {
                name: PROGRAM_NAME.into(),
                q: p.poses.clone(),
                payload_kg: p.payload_kg.clone(),
                hold_s: self.hold_s,
                speed_fraction: s.sampling.speed_fraction,
                about: vec![format!("Planned by twincal plan for the scenario {} ({}), criterion {}, seed {}.", p.scenario, p.robot, p.criterion, p.seed)],
            };
            for f in lang.measurement_program(&tour)? {
                outputs.write(&self.out.join(&f.name), f.text.as_bytes())?;
            }
        }
        outputs.write_json(&plan_path, &p)?;
        outputs.commit()?;
        Ok(p)
    }
}
