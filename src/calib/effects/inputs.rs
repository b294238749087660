//! Per-row inputs of the effect blocks, computed once over the whole file in acquisition order
//! (before any train/test split): static joint torques from an inertial model (the URDF's
//! links, an optional payload and the cable's pull) and the backlash flank of every joint.
//!
//! The flank rule: where the static torque on a joint exceeds [`JointLoads::torque_threshold_nm`]
//! the load holds the link on the flank it points to; below it the link stays on the flank its
//! last motion left it on (the link trails the motor: a move towards larger angles leaves it on
//! the negative flank). The arm is assumed to start at its home pose (all angles zero).

use crate::calib::effects::{EffectBlock, EffectKind, RowInputs};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::robot::kinematics::{Chain, FkWork, PointJacobian};
use crate::robot::statics::{approach_sides, CableLoad, LoadModel, Payload, Push, GRAVITY};
use crate::robot::Robot;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// What loads the joints, as far as the user knows it.
#[derive(Clone, Debug)]
pub struct JointLoads {
    /// Payload on the flank (mass and centre of mass in the flange frame, mm).
    pub payload: Option<Payload>,
    /// Draw-wire spring tension, N (from the sensor's data sheet; 0 = ignore).
    pub cable_tension_n: f64,
    /// The force pressing the instrument's target against an artifact along the flange's z axis
    /// (a ball held in its socket, a probe on a face), N (0 = ignore).
    pub preload_n: f64,
    /// Static torque above which the load, not the approach motion, decides the backlash flank.
    pub torque_threshold_nm: f64,
}

impl Default for JointLoads {
    fn default() -> Self {
        JointLoads { payload: None, cable_tension_n: 0.0, preload_n: 0.0, torque_threshold_nm: 0.5 }
    }
}

/// What the rows' own payloads leave unsaid: rows that carry a `payload_kg` with no payload
/// centre of mass stated (it is then taken at the flange's origin, and a load-driven effect's
/// size depends on it), or a centre of mass stated with no payload on any row.
pub fn payload_warning(data: &crate::dataset::Dataset, loads: &JointLoads) -> Option<String> {
    let loaded = data.rows.iter().filter(|r| r.payload_kg.is_some_and(|m| m > 0.0)).count();
    match &loads.payload {
        None if loaded > 0 => Some(format!(
            "{loaded} rows carry a payload (payload_kg) but no centre of mass is stated: it is taken at the flange's origin; \
             state it with --payload-com-mm X,Y,Z (flange frame), as the sizes of load-driven effects (compliance) depend on it"
        )),
        Some(p) if p.mass_kg == 0.0 && p.com_mm != [0.0; 3] && loaded == 0 => {
            Some("--payload-com-mm is given with no payload: neither --payload-kg nor a payload_kg column loads the arm, so it changes nothing".into())
        }
        _ => None,
    }
}

/// The static-torque model of a calibration, self-contained so that a saved result can compute
/// the torques of new rows: the robot's nominal chain, its link masses and centres of mass, the
/// payload and the cable's pull.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TorqueModel {
    /// The robot's nominal chain (m, rad).
    pub chain: Chain,
    /// Per moving link: mass (kg) and centre of mass in the link frame (m).
    pub links: Vec<(f64, [f64; 3])>,
    /// Payload mass (kg) and centre of mass in the flange frame (m).
    pub payload: Option<(f64, [f64; 3])>,
    /// Cable exit point (base frame, m), tool point (flange frame, m) and tension (N); none
    /// without a tension or without a cable (another instrument).
    pub cable: Option<([f64; 3], [f64; 3], f64)>,
    /// The artifact pushing back on the instrument's target: where it acts (flange frame, m) and
    /// the preload (N); none without a preload or without an artifact.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub push: Option<([f64; 3], f64)>,
    /// Static torque above which the load, not the approach motion, decides the backlash flank,
    /// N·m.
    pub torque_threshold_nm: f64,
}

impl TorqueModel {
    /// Whether anything loads the joints: a link with mass (the URDF's `<inertial>`), a payload or
    /// a cable's tension. A URDF without inertials and no payload gives zero torque everywhere,
    /// and a torque-driven effect is not identifiable from it.
    pub fn carries_torque(&self) -> bool {
        self.links.iter().any(|(m, _)| *m > 0.0)
            || self.payload.is_some_and(|(m, _)| m > 0.0)
            || self.cable.is_some_and(|(_, _, f)| f > 0.0)
            || self.push.is_some_and(|(_, f)| f > 0.0)
    }
}

/// Largest mass (kg) of a link or payload a result file may hold: heavier than any arm's link.
pub const MAX_MASS_KG: f64 = 10_000.0;
/// Farthest (m) a centre of mass, a cable's exit or tool point sits from its frame.
pub const MAX_LOAD_POINT_M: f64 = 100.0;
/// Largest cable tension (N) a result file may hold: a draw-wire pulls a few newtons.
pub const MAX_CABLE_TENSION_N: f64 = 1_000.0;
/// Largest preload (N) on an artifact: a hand pushes tens of newtons.
pub const MAX_PRELOAD_N: f64 = 1_000.0;

impl TorqueModel {
    /// The torque model of `robot` (its link inertials) under `loads`; the cable's pull from exit
    /// point `exit_m` (base frame, m; `None`: no cable) to the tool point `tool_m` (flange frame,
    /// m), when the tension is not zero; the preload on `tool_m` when the instrument reads an
    /// artifact (`artifact`) and the preload is not zero.
    pub fn new(robot: &Robot, loads: &JointLoads, exit_m: Option<Vector3<f64>>, tool_m: Vector3<f64>, artifact: bool) -> TorqueModel {
        let load = LoadModel::new(robot, loads.payload.as_ref(), None);
        TorqueModel {
            chain: robot.error_chain(),
            links: load.links.iter().map(|(m, c)| (*m, [c.x, c.y, c.z])).collect(),
            // A payload stated at zero mass still states where the rows' own payloads sit.
            payload: loads.payload.as_ref().map(|p| (p.mass_kg, p.com_mm.map(crate::units::to_m))),
            cable: exit_m.filter(|_| loads.cable_tension_n > 0.0).map(|e| ([e.x, e.y, e.z], [tool_m.x, tool_m.y, tool_m.z], loads.cable_tension_n)),
            push: (artifact && loads.preload_n > 0.0).then_some(([tool_m.x, tool_m.y, tool_m.z], loads.preload_n)),
            torque_threshold_nm: loads.torque_threshold_nm,
        }
    }

    /// Checks a torque model read from a file: a valid chain, one mass per moving link at most,
    /// masses ≥ 0 and every value finite.
    pub fn validate(&self, n_joints: usize) -> std::result::Result<(), String> {
        self.chain.validate()?;
        let point_ok = |c: &[f64; 3]| c.iter().all(|v| v.is_finite() && v.abs() <= MAX_LOAD_POINT_M);
        let mass_ok = |m: f64| m.is_finite() && (0.0..=MAX_MASS_KG).contains(&m);
        let bad = |what: String| Err(format!("torque_model: {what} (edited result file?)"));
        if self.chain.n_joints != n_joints || self.links.len() != n_joints {
            return bad(format!("{} joints and {} link masses for a model of {n_joints} joints", self.chain.n_joints, self.links.len()));
        }
        if let Some(j) = self.links.iter().position(|(m, c)| !mass_ok(*m) || !point_ok(c)) {
            return bad(format!(
                "link {} has mass {} kg at ({}) m; a link's mass is in [0, {MAX_MASS_KG}] kg, its centre of mass within {MAX_LOAD_POINT_M} m",
                j + 1,
                crate::error::shown(self.links[j].0),
                self.links[j].1.map(crate::error::shown).join(", ")
            ));
        }
        if let Some((m, c)) = self.payload.filter(|(m, c)| !mass_ok(*m) || !point_ok(c)) {
            return bad(format!("payload {} kg at ({}) m is out of range", crate::error::shown(m), c.map(crate::error::shown).join(", ")));
        }
        if let Some((_, _, f)) = self.cable.filter(|(e, t, f)| !(point_ok(e) && point_ok(t) && f.is_finite() && (0.0..=MAX_CABLE_TENSION_N).contains(f))) {
            return bad(format!("cable tension {} N or its points are out of range (tension in [0, {MAX_CABLE_TENSION_N}] N)", crate::error::shown(f)));
        }
        if let Some((_, f)) = self.push.filter(|(p, f)| !(point_ok(p) && f.is_finite() && (0.0..=MAX_PRELOAD_N).contains(f))) {
            return bad(format!("preload {} N or its point is out of range (preload in [0, {MAX_PRELOAD_N}] N)", crate::error::shown(f)));
        }
        if !(self.torque_threshold_nm >= 0.0 && self.torque_threshold_nm <= MAX_LOAD_POINT_M * MAX_MASS_KG * 10.0) {
            return bad(format!("torque threshold {} N·m is out of range", crate::error::shown(self.torque_threshold_nm)));
        }
        Ok(())
    }

    /// Static joint torques (N·m) at commanded angles `q` (rad).
    pub fn torques(&self, q: &[f64]) -> Vec<f64> {
        self.torques_under(q, None)
    }

    /// [`Self::torques`] with a payload of `mass_kg` mounted instead of the model's (at the
    /// model's payload's centre of mass, the flange's origin without one); `None`: the model's.
    pub fn torques_under(&self, q: &[f64], mass_kg: Option<f64>) -> Vec<f64> {
        let payload = match mass_kg {
            Some(m) => Some((m, self.payload.map_or([0.0; 3], |p| p.1))),
            None => self.payload,
        };
        let load = LoadModel {
            gravity: Vector3::new(0.0, 0.0, -GRAVITY),
            links: self.links.iter().map(|(m, c)| (*m, Vector3::from(*c))).collect(),
            payload: payload.map(|(m, c)| (m, Vector3::from(c))),
            cable: self.cable.map(|(e, t, f)| CableLoad { exit_point: Vector3::from(e), tool_point: Vector3::from(t), tension: f }),
            push: self.push.map(|(p, f)| Push { point: Vector3::from(p), force_n: f }),
        };
        let zero = vec![0.0; self.chain.n_params()];
        let mut ws = FkWork::new(&self.chain);
        let mut jac = PointJacobian::new(&self.chain);
        let mut tau = vec![0.0; self.chain.n_joints];
        self.chain.forward(q, &zero, 1.0, &mut ws);
        load.torques(&self.chain, &ws, &mut jac, &mut tau);
        tau
    }
}

/// Inputs of every row of `data` (file order): the torques under the row's own payload where it
/// has one (`payload_kg`), else the torque model's. Without a torque model the torques are zero
/// and the flanks follow the approach motion only. The rows' stations and mounts are numbered as
/// [`Dataset::stations`] and [`Dataset::mounts`] number them.
pub fn row_inputs(data: &Dataset, torque: Option<&TorqueModel>) -> Vec<RowInputs> {
    let n = data.rows.len();
    let (stations, mounts) = (data.stations(), data.mounts());
    let rates = temperature_rates(data);
    let first = data.measurement();
    let mut out: Vec<RowInputs> = data
        .rows
        .iter()
        .zip(stations.of_row.iter().zip(&mounts.of_row))
        .zip(rates)
        .map(|((r, (&station, &mount)), rate)| {
            let instrument = usize::from(r.measurement().is_some() && r.measurement() != first);
            RowInputs { t_s: r.t_s, temp_c: r.temp_c, temp_rate_k_per_s: rate, station, mount, instrument, ..Default::default() }
        })
        .collect();
    let nq = data.n_joints();
    for (i, r) in data.rows.iter().enumerate() {
        out[i].torque = match torque {
            Some(tm) => {
                let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
                let mut t = tm.torques_under(&q, r.payload_kg);
                t.resize(nq, 0.0);
                t
            }
            None => vec![0.0; nq],
        };
    }
    let threshold = torque.map(|t| t.torque_threshold_nm).unwrap_or(f64::INFINITY);
    // Approach flanks in file order from the home pose (the twin's rule), then the load rule.
    let poses: Vec<Vec<f64>> = data.rows.iter().map(|r| r.q_deg.to_vec()).collect();
    let approach = approach_sides(&vec![0.0; nq], &poses);
    for i in 0..n {
        out[i].side = (0..nq)
            .map(|j| {
                let tau = out[i].torque[j];
                if tau.abs() > threshold {
                    tau.signum()
                } else {
                    approach[i][j]
                }
            })
            .collect();
    }
    out
}

/// Share of a run's time span on either side of a row over which its temperature rate is taken.
pub const RATE_WINDOW_SHARE: f64 = 0.05;

/// The rate of the measured temperature at every row of `data` (K/s, file order): the
/// least-squares slope of `temp` against `t` over the rows of the row's run within ±h of it, h
/// a [`RATE_WINDOW_SHARE`] of the run's time span. A run is a stretch of rows, in file order,
/// whose `t` never goes back (a session that restarts its clock starts a new one), so that no
/// rate mixes two sessions. `None` where a row lacks `t` or `temp` or its window holds fewer
/// than three rows of two distinct times.
pub fn temperature_rates(data: &Dataset) -> Vec<Option<f64>> {
    let n = data.rows.len();
    let mut out = vec![None; n];
    let mut start = 0;
    while start < n {
        let mut end = start + 1;
        while end < n && matches!((data.rows[end - 1].t_s, data.rows[end].t_s), (Some(a), Some(b)) if b >= a) {
            end += 1;
        }
        let run: Option<Vec<(f64, f64)>> = data.rows[start..end].iter().map(|r| Some((r.t_s?, r.temp_c?))).collect();
        if let Some(run) = run {
            let h = RATE_WINDOW_SHARE * (run[run.len() - 1].0 - run[0].0);
            for (i, &(t, _)) in run.iter().enumerate() {
                let (lo, hi) = (run.partition_point(|p| p.0 < t - h), run.partition_point(|p| p.0 <= t + h));
                out[start + i] = crate::stats::slope(&run[lo..hi]);
            }
        }
        start = end;
    }
    out
}

/// A block of `kind` (on joint `joint` for per-joint effects) set up for these data: the thermal
/// block is driven by the `temp` column when every row has one, else by `t`; the nonlinearity
/// is normalised over the data's reading range. Errors name what the data lack.
pub fn block_for(data: &Dataset, kind: EffectKind, joint: Option<usize>, has_torques: bool) -> Result<EffectBlock> {
    let mut b = EffectBlock { kind, joint, thermal: None, range_m: None };
    let nq = data.n_joints();
    if !kind.joint_options(nq).contains(&joint) {
        return Err(Error::Invalid(match joint {
            None => format!("{} needs a joint 1..{nq}", kind.name()),
            Some(j) if kind.takes_joint() => {
                format!("{}: joint {} is beyond the data's {nq} joints (q1..q{nq})", kind.name(), j + 1)
            }
            Some(_) => format!("{} takes no joint", kind.name()),
        }));
    }
    kind.def().configure(&mut b, data, has_torques)?;
    Ok(b)
}

/// Time span of the data, s (0 without a t column).
pub fn time_span(data: &Dataset) -> f64 {
    let ts: Vec<f64> = data.rows.iter().filter_map(|r| r.t_s).collect();
    if ts.is_empty() {
        return 0.0;
    }
    ts.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - ts.iter().cloned().fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Row;

    /// With no load model the flanks are the approach flanks, by the twin's own rule: a joint
    /// that last moved up rests on its negative flank, one that did not move keeps its flank.
    #[test]
    fn row_flanks_follow_the_twins_approach_rule() {
        let q1 = [10.0, 10.0, 5.0, 20.0, -3.0];
        let rows: Vec<Row> = q1.iter().map(|&a| Row { q_deg: vec![a, 0.0, -a, 0.0, 0.0, 0.0], reading_mm: vec![500.0], ..Default::default() }).collect();
        let data = Dataset { rows, source: "test".into() };
        let inp = row_inputs(&data, None);
        let side = |j: usize| inp.iter().map(|r| r.side[j]).collect::<Vec<f64>>();
        assert_eq!(side(0), vec![-1.0, -1.0, 1.0, -1.0, 1.0]);
        assert_eq!(side(2), vec![1.0, 1.0, -1.0, 1.0, -1.0]);
        assert_eq!(side(1), vec![-1.0; 5], "a joint that never moves stays on its starting flank");
        let poses: Vec<Vec<f64>> = data.rows.iter().map(|r| r.q_deg.iter().map(|d| d.to_radians()).collect()).collect();
        let twin = crate::robot::statics::approach_sides(&[0.0; 6], &poses);
        assert!(inp.iter().zip(&twin).all(|(r, t)| r.side.iter().zip(t).all(|(a, b)| a == b)));
    }

    /// The temperature's rate is the local slope of `temp` against `t`, within each run of rows
    /// whose clock never goes back; none without both columns or with too few rows.
    #[test]
    fn temperature_rates_follow_each_run() {
        let row = |t: f64, temp: f64| Row { q_deg: vec![0.0; 6], reading_mm: vec![500.0], t_s: Some(t), temp_c: Some(temp), ..Default::default() };
        // A ramp of 0.01 K/s over 100 s, then a second session restarting its clock at 0 and
        // cooling at 0.002 K/s.
        let mut rows: Vec<Row> = (0..=100).map(|k| row(k as f64, 20.0 + 0.01 * k as f64)).collect();
        rows.extend((0..=50).map(|k| row(2.0 * k as f64, 25.0 - 0.004 * k as f64)));
        let data = Dataset { rows, source: "test".into() };
        let rates = temperature_rates(&data);
        assert!(rates[..101].iter().all(|r| r.is_some_and(|v| (v - 0.01).abs() < 1e-12)), "{:?}", &rates[..3]);
        assert!(rates[101..].iter().all(|r| r.is_some_and(|v| (v + 0.002).abs() < 1e-12)), "{:?}", &rates[101..104]);
        // The inputs carry them.
        let inp = row_inputs(&data, None);
        assert_eq!(inp[50].temp_rate_k_per_s, rates[50]);
        // Without temperatures, or with two rows, no rate.
        let no_temp = Dataset { rows: data.rows.iter().map(|r| Row { temp_c: None, ..r.clone() }).collect(), source: "test".into() };
        assert!(temperature_rates(&no_temp).iter().all(Option::is_none));
        let two = Dataset { rows: data.rows[..2].to_vec(), source: "test".into() };
        assert!(temperature_rates(&two).iter().all(Option::is_none));
    }
}
