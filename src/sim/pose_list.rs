//! Pose lists: what `twincal plan` writes, a robot program can step through and
//! `generate --poses` measures — joint angles per pose, in order, and optionally the payload
//! mounted for each (`payload_kg`).
//!
//! A list with payloads is measured one payload at a time, as an engineer measures it: each run
//! of consecutive poses with the same payload is an acquisition of its own (the twin carries that
//! payload at the scenario's `[effects.payload]` centre of mass, the flange's origin without
//! one), its rows' times following the previous run's last after [`PAYLOAD_CHANGE_S`] for the
//! change. Every run measures the same arm (its true geometry drawn once, from the scenario's
//! seed); each run's noise and acquisition are seeded apart ([`Stream::PayloadRun`]), so that no
//! two runs share an error. A thermal scenario is refused: its warm-up would restart with each
//! run while the times go on.

use crate::error::{Error, Result};
use crate::progress::Progress;
use crate::robot::statics::Payload;
use crate::robot::Robot;
use crate::seed::{stream_seed, Stream};
use crate::sim::generate::{generate_at, Generated};
use crate::sim::scenario::Scenario;
use crate::units::round_decimals;

/// A pose list: joint angles (rad) per pose, in order, and the payload mounted for each (kg).
#[derive(Clone, Debug, PartialEq)]
pub struct PoseList {
    /// The poses, rad.
    pub q: Vec<Vec<f64>>,
    /// The payload mounted for each pose, kg (`None`: the scenario's for every pose).
    pub payload_kg: Option<Vec<f64>>,
}

/// Seconds between the last reading with one payload and the first move with the next.
pub const PAYLOAD_CHANGE_S: f64 = 60.0;

/// A pose list as CSV: a header `pose,q1..qN[,payload_kg]`, then one row per pose in the order
/// given, the joint angles in degrees at `decimals`.
pub fn pose_list_csv(list: &PoseList, decimals: usize) -> String {
    use std::fmt::Write;
    let n = list.q.first().map_or(0, |q| q.len());
    let mut out = String::from("pose");
    (1..=n).for_each(|j| out.push_str(&format!(",q{j}")));
    if list.payload_kg.is_some() {
        out.push_str(",payload_kg");
    }
    out.push('\n');
    for (i, q) in list.q.iter().enumerate() {
        out.push_str(&(i + 1).to_string());
        for v in q {
            let _ = write!(out, ",{:.*}", decimals, round_decimals(v.to_degrees(), decimals));
        }
        if let Some(p) = &list.payload_kg {
            let _ = write!(out, ",{}", p[i]);
        }
        out.push('\n');
    }
    out
}

/// The pose list of a file (columns `q1..qN`, degrees, and optionally `payload_kg`; other
/// columns ignored) for `robot`, by the dataset reader's rules, read once; each pose inside the
/// URDF's joint limits, each payload in [0, 1000] kg. Errors name the file and the first bad pose.
pub fn read_pose_list(path: &std::path::Path, robot: &Robot) -> Result<PoseList> {
    let n = robot.dof();
    let at = path.display();
    let t = crate::dataset::CsvColumns::read(path)?;
    if t.has(&format!("q{}", n + 1)) {
        return Err(Error::data(&at, format!("the pose list has a column q{}: the robot ({}) has {n} joints", n + 1, robot.name)));
    }
    let names: Vec<String> = (1..=n).map(|j| format!("q{j}")).collect();
    let cols: Vec<&str> = names.iter().map(String::as_str).collect();
    let rows = t.columns(&cols).map_err(|e| Error::Invalid(format!("{e} (a pose list for {}, {n} joints, needs q1..q{n} in degrees)", robot.name)))?;
    if rows.is_empty() {
        return Err(Error::data(&at, "no poses after the header"));
    }
    if rows.len() > crate::sim::scenario::MAX_POSES {
        return Err(Error::data(&at, format!("{} poses: a run takes at most {}", rows.len(), crate::sim::scenario::MAX_POSES)));
    }
    if let Some((largest, j, span)) = crate::dataset::looks_like_radians(&rows, crate::dataset::RADIANS_MAX_ABS) {
        return Err(Error::data(
            &at,
            format!(
                "columns q1..q{n} look like radians (all {} poses have |q| <= {largest:.3}, q{} spans {span:.3}): a pose list holds joint angles in degrees (x 180/pi)",
                rows.len(),
                j + 1
            ),
        ));
    }
    let limits = robot.limits();
    let mut q = Vec::with_capacity(rows.len());
    for (i, row) in rows.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            let (lo, hi) = limits[j];
            if !v.is_finite() {
                return Err(Error::data(&at, format!("pose {}: q{} = {v} is not a number of degrees", i + 1, j + 1)));
            }
            if v.to_radians() < lo - 1e-9 || v.to_radians() > hi + 1e-9 {
                return Err(Error::data(
                    &at,
                    format!(
                        "pose {}: q{} = {v}° is outside joint {}'s limits [{:.2}, {:.2}]° (angles are degrees)",
                        i + 1,
                        j + 1,
                        j + 1,
                        lo.to_degrees(),
                        hi.to_degrees()
                    ),
                ));
            }
        }
        q.push(row.iter().map(|d| d.to_radians()).collect());
    }
    let payload_kg = match t.has("payload_kg") {
        false => None,
        true => {
            let p: Vec<f64> = t.columns(&["payload_kg"])?.into_iter().map(|v| v[0]).collect();
            if let Some((i, m)) = p.iter().enumerate().find(|(_, m)| !(m.is_finite() && (0.0..=crate::dataset::MAX_PAYLOAD_KG).contains(*m))) {
                return Err(Error::data(
                    &at,
                    format!("pose {}: payload_kg = {m} is not a payload (finite, in [0, {}] kg)", i + 1, crate::dataset::MAX_PAYLOAD_KG),
                ));
            }
            Some(p)
        }
    };
    Ok(PoseList { q, payload_kg })
}

/// Every pose of a list must pass the scenario's feasibility check (the tool's height, the
/// instrument's range, the `[workspace]`'s floor, keep-out boxes, self-collision and line of
/// sight), as sampled poses do: the first that does not is named by its row, with how many
/// others fail.
fn check_feasible(s: &Scenario, robot: &Robot, q: &[Vec<f64>]) -> Result<()> {
    let cell = s.cell(robot);
    let mut fk = cell.work();
    let refused: Vec<(usize, crate::sim::workspace::Refusal)> =
        q.iter().enumerate().filter_map(|(i, p)| cell.check(p, &mut fk).err().map(|r| (i, r))).collect();
    let Some((row, why)) = refused.first() else { return Ok(()) };
    let others = match refused.len() {
        1 => String::new(),
        n => format!(" (and {} more poses)", n - 1),
    };
    Err(Error::Invalid(format!(
        "pose {} of the list{others} fails the scenario's feasibility check: {}; the twin measures only poses its cell allows (the tool's height, the instrument's range, [workspace]): drop them or change the scenario",
        row + 1,
        why.name()
    )))
}

/// Measures a pose list on the twin of `s`, in its order, every pose a training row (see the
/// module docs for lists with payloads).
pub fn generate_pose_list(s: &Scenario, robot: &Robot, list: PoseList, progress: &dyn Progress) -> Result<Generated> {
    crate::sim::generate::refuse_artifact(s)?;
    check_feasible(s, robot, &list.q)?;
    let mut s = s.clone();
    s.sampling.poses = list.q.len();
    s.sampling.test = 0;
    let Some(payloads) = list.payload_kg else { return generate_at(&s, robot, list.q, None, progress) };
    if payloads.len() != list.q.len() {
        return Err(Error::Invalid(format!("{} payloads for {} poses: one payload per pose", payloads.len(), list.q.len())));
    }
    if list.q.is_empty() {
        return Err(Error::Invalid("no poses".into()));
    }
    if s.effects.thermal.is_some() {
        return Err(Error::Invalid(
            "a pose list with payloads is measured one payload at a time, each run a new acquisition; the scenario's thermal drift would restart its warm-up with each run: drop payload_kg or [effects.thermal]".into(),
        ));
    }
    // The same arm in every run: its true geometry drawn once and pinned.
    for (name, v) in robot.param_names().iter().zip(s.true_params(robot)) {
        let display = if matches!(name.rsplit('.').next(), Some("dx" | "dy" | "dz")) { crate::units::to_mm(v) } else { v.to_degrees() };
        s.geometry.set.insert(name.clone(), display);
    }
    let com = s.effects.payload.as_ref().map_or([0.0; 3], |p| p.com_mm);
    let mut merged: Option<Generated> = None;
    let mut start = 0;
    for (run, len) in runs(&payloads).into_iter().enumerate() {
        let m = payloads[start];
        let mut sk = s.clone();
        sk.effects.payload = Some(Payload { mass_kg: m, com_mm: com });
        sk.sampling.poses = len;
        if run > 0 {
            sk.seed = stream_seed(s.seed, Stream::PayloadRun, run as u64);
        }
        let mut g = generate_at(&sk, robot, list.q[start..start + len].to_vec(), None, progress)?;
        let offset = merged.as_ref().and_then(|a| a.dataset.rows.last()).and_then(|r| r.t_s).map_or(0.0, |t| t + PAYLOAD_CHANGE_S);
        for r in &mut g.dataset.rows {
            r.payload_kg = Some(m);
            r.t_s = r.t_s.map(|t| round_decimals(t + offset, crate::sim::generate::T_DECIMALS));
        }
        for p in &mut g.truth.poses {
            p.index += start;
            p.t_s = round_decimals(p.t_s + offset, crate::sim::generate::T_DECIMALS);
        }
        g.truth.rejected.iter_mut().for_each(|r| r.index += start);
        merged = Some(match merged {
            None => g,
            Some(mut a) => {
                let rows_before = a.dataset.rows.len();
                a.truth.glitch_rows.extend(g.truth.glitch_rows.iter().map(|k| k + rows_before));
                a.dataset.rows.extend(g.dataset.rows);
                a.truth.poses.extend(g.truth.poses);
                a.truth.rejected.extend(g.truth.rejected);
                a.frames.extend(g.frames);
                a
            }
        });
        start += len;
    }
    let mut g = merged.expect("a pose list has at least one pose");
    g.truth.seed = s.seed;
    Ok(g)
}

/// The lengths of the runs of equal consecutive values.
fn runs(v: &[f64]) -> Vec<usize> {
    let mut out: Vec<usize> = Vec::new();
    for (i, x) in v.iter().enumerate() {
        match out.last_mut() {
            Some(n) if i > 0 && v[i - 1] == *x => *n += 1,
            _ => out.push(1),
        }
    }
    out
}
