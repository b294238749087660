//! The cell around the arm (the scenario's `[workspace]`): what a commanded pose must keep clear
//! of. Each link is a capsule around the segment between consecutive joint origins (the tool a
//! capsule from the flange to the tool point), of one radius; a pose is refused when
//!
//! * a link's capsule dips below the floor plane or enters a keep-out box (a fixture, a table,
//!   the instrument's stand),
//! * two links at least three apart along the chain touch (self-collision; nearer links share a
//!   joint and are kept apart by the joint limits),
//! * the instrument's line to the target (a tracker's beam, a draw-wire's cable) passes through a
//!   link other than the tool itself,
//! * a tracker's target is outside its distance range.
//!
//! The URDF's collision meshes are not read: the capsules are the geometry, and their radius is
//! the scenario's (`link_radius_mm`).

use crate::robot::kinematics::{Chain, FkWork};
use nalgebra::Vector3;
use rapier3d_f64::parry::math::Vector as PVec;
use rapier3d_f64::parry::query::closest_points::closest_points_segment_segment_with_locations_nD;
use rapier3d_f64::parry::shape::{Capsule, Cuboid, Segment};
use serde::{Deserialize, Serialize};

/// A box no link may enter, base frame, mm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeepOut {
    /// What it is (named in the counts of refused poses).
    #[serde(default)]
    pub name: String,
    /// Lowest corner, mm.
    pub min_mm: [f64; 3],
    /// Highest corner, mm.
    pub max_mm: [f64; 3],
}

/// The scenario's `[workspace]`: the geometry every commanded pose keeps clear of (see the
/// module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Workspace {
    /// Radius of the capsule around every link, mm.
    #[serde(default = "Workspace::default_radius")]
    pub link_radius_mm: f64,
    /// A floor plane at this height (base frame), mm: every link's capsule but the base's stays
    /// above it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_z_mm: Option<f64>,
    /// Boxes no link may enter.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keep_out: Vec<KeepOut>,
    /// Refuse poses whose links touch (links at least three apart along the chain).
    #[serde(default = "yes")]
    pub self_collision: bool,
    /// Refuse poses where a link blocks the instrument's line to the target.
    #[serde(default = "yes")]
    pub line_of_sight: bool,
    /// A tracker's distance range [min, max] to the target, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracker_range_mm: Option<[f64; 2]>,
}

fn yes() -> bool {
    true
}

impl Default for Workspace {
    fn default() -> Self {
        Workspace {
            link_radius_mm: Workspace::default_radius(),
            floor_z_mm: None,
            keep_out: Vec::new(),
            self_collision: true,
            line_of_sight: true,
            tracker_range_mm: None,
        }
    }
}

impl Workspace {
    fn default_radius() -> f64 {
        50.0
    }

    /// An error naming the key whose value is out of range.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.link_radius_mm.is_finite() && self.link_radius_mm > 0.0 && self.link_radius_mm <= 1000.0) {
            return Err(format!("workspace.link_radius_mm must be in (0, 1000] mm, got {}", self.link_radius_mm));
        }
        if self.floor_z_mm.is_some_and(|z| !z.is_finite()) {
            return Err("workspace.floor_z_mm must be finite".into());
        }
        for (k, b) in self.keep_out.iter().enumerate() {
            if b.min_mm.iter().chain(&b.max_mm).any(|v| !v.is_finite()) || (0..3).any(|i| b.min_mm[i] >= b.max_mm[i]) {
                return Err(format!("workspace.keep_out[{k}] ({}) needs finite min_mm below max_mm on every axis", b.name));
            }
            // The arm's fixed base stands at the base frame's origin: a box around it refuses
            // every pose, which is no plan.
            let gap = (0..3).map(|i| b.min_mm[i].max(-b.max_mm[i]).max(0.0)).map(|d| d * d).sum::<f64>().sqrt();
            if gap <= self.link_radius_mm {
                return Err(format!(
                    "workspace.keep_out[{k}] ({}) holds the robot's fixed base (the base frame's origin, within the link radius {} mm): every pose would be refused; keep the box off the base",
                    b.name, self.link_radius_mm
                ));
            }
        }
        if let Some([lo, hi]) = self.tracker_range_mm {
            if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo < hi) {
                return Err(format!("workspace.tracker_range_mm must be [min, max] with 0 <= min < max, got [{lo}, {hi}]"));
            }
        }
        Ok(())
    }
}

/// Why a pose was refused (see [`Cell::check`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Refusal {
    /// The tool point is below the sampling's `min_tool_z_mm`.
    ToolTooLow,
    /// The instrument cannot read it (the cable's range, the tracker's distance range).
    OutOfRange,
    /// A link's capsule is below the floor plane.
    Floor,
    /// A link's capsule enters a keep-out box.
    KeepOut,
    /// Two links touch.
    SelfCollision,
    /// A link blocks the instrument's line to the target.
    LineOfSight,
}

impl Refusal {
    /// Every refusal, in the order the checks run.
    pub const ALL: [Refusal; 6] = [Refusal::ToolTooLow, Refusal::OutOfRange, Refusal::Floor, Refusal::KeepOut, Refusal::SelfCollision, Refusal::LineOfSight];
    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Refusal::ToolTooLow => "tool below min_tool_z_mm",
            Refusal::OutOfRange => "outside the instrument's range",
            Refusal::Floor => "link below the floor",
            Refusal::KeepOut => "link in a keep-out box",
            Refusal::SelfCollision => "self-collision",
            Refusal::LineOfSight => "line of sight blocked",
        }
    }
}

/// The instrument's side of the feasibility check.
#[derive(Clone, Debug)]
pub enum Reach {
    /// A draw-wire: its nominal reading (distance + offset) inside its range, 1 % of the range
    /// kept clear at each end; the cable runs from its exit point.
    Cable(crate::sim::instrument::DrawWire),
    /// A tracker at `origin` (base frame, m), the target within `range_mm` of it (any distance
    /// when `None`).
    Tracker {
        /// The tracker's head, base frame, m.
        origin: Vector3<f64>,
        /// Distance range [min, max], mm.
        range_mm: Option<[f64; 2]>,
    },
}

impl Reach {
    fn origin(&self) -> Vector3<f64> {
        match self {
            Reach::Cable(s) => s.exit_point_m(),
            Reach::Tracker { origin, .. } => *origin,
        }
    }
    fn reads(&self, p: &Vector3<f64>) -> bool {
        match self {
            Reach::Cable(s) => {
                let [lo, hi] = s.range_mm;
                let margin = 0.01 * (hi - lo);
                let l = s.ideal_length(p);
                l > lo + margin && l < hi - margin
            }
            Reach::Tracker { origin, range_mm } => {
                let d = crate::units::to_mm((p - origin).norm());
                range_mm.is_none_or(|[lo, hi]| d >= lo && d <= hi)
            }
        }
    }
}

/// A feasibility check of commanded poses: the nominal chain, the tool point and the cell.
#[derive(Clone, Debug)]
pub struct Cell {
    chain: Chain,
    zero: Vec<f64>,
    tool: Vector3<f64>,
    min_tool_z_mm: f64,
    reach: Option<Reach>,
    ws: Option<Workspace>,
}

/// Links shorter than this (m) are merged into their neighbour's capsule.
const MIN_LINK_M: f64 = 1e-3;

impl Cell {
    /// The check for `chain` (nominal parameters) carrying the target `tool` (flange frame, m),
    /// with the tool point at or above `min_tool_z_mm`, the instrument's `reach` and the cell
    /// `ws` (without one: only the tool height and the reach are checked).
    pub fn new(chain: Chain, tool: Vector3<f64>, min_tool_z_mm: f64, reach: Option<Reach>, ws: Option<Workspace>) -> Cell {
        let zero = vec![0.0; chain.n_params()];
        Cell { chain, zero, tool, min_tool_z_mm, reach, ws }
    }

    /// A workspace sized for [`Self::check`].
    pub fn work(&self) -> FkWork {
        FkWork::new(&self.chain)
    }

    /// The link capsules' axes at `q` (base frame, m), base to tool: consecutive joint origins,
    /// the flange, the tool point; links shorter than 1 mm merged.
    pub fn links(&self, q: &[f64], fk: &mut FkWork) -> Vec<(Vector3<f64>, Vector3<f64>)> {
        self.chain.forward(q, &self.zero, 1.0, fk);
        let flange = self.chain.frame(fk, self.chain.flange());
        let mut pts: Vec<Vector3<f64>> = (0..self.chain.n_frames()).map(|f| self.chain.frame(fk, f).pos).collect();
        pts.push(flange.point(&self.tool));
        let mut kept = vec![pts[0]];
        for p in &pts[1..] {
            if (p - kept.last().expect("starts with the base")).norm() > MIN_LINK_M {
                kept.push(*p);
            }
        }
        kept.windows(2).map(|w| (w[0], w[1])).collect()
    }

    /// `Ok` when pose `q` (rad) is feasible, else the first check it fails, in
    /// [`Refusal::ALL`]'s order.
    pub fn check(&self, q: &[f64], fk: &mut FkWork) -> Result<(), Refusal> {
        let links = self.links(q, fk);
        let target = links.last().map_or(Vector3::zeros(), |l| l.1);
        if !(crate::units::to_mm(target.z) >= self.min_tool_z_mm) {
            return Err(Refusal::ToolTooLow);
        }
        if self.reach.as_ref().is_some_and(|r| !r.reads(&target)) {
            return Err(Refusal::OutOfRange);
        }
        let Some(ws) = &self.ws else { return Ok(()) };
        let r = crate::units::to_m(ws.link_radius_mm);
        if let Some(z) = ws.floor_z_mm {
            let z = crate::units::to_m(z);
            // The first link stands on the base: it may reach down to the floor.
            if links.iter().skip(1).any(|(a, b)| a.z.min(b.z) - r < z) {
                return Err(Refusal::Floor);
            }
        }
        for b in &ws.keep_out {
            let lo = Vector3::from(b.min_mm).map(crate::units::to_m);
            let hi = Vector3::from(b.max_mm).map(crate::units::to_m);
            if links.iter().any(|l| capsule_box_distance(l, r, &lo, &hi) <= 0.0) {
                return Err(Refusal::KeepOut);
            }
        }
        if ws.self_collision {
            for i in 0..links.len() {
                for j in i + 3..links.len() {
                    if segment_distance(&links[i], &links[j]) < 2.0 * r {
                        return Err(Refusal::SelfCollision);
                    }
                }
            }
        }
        if let (true, Some(reach)) = (ws.line_of_sight, &self.reach) {
            // The line stops a link radius short of the target: the reflector (the cable's
            // clamp) sits on the tool's surface, not inside it.
            let origin = reach.origin();
            let len = (target - origin).norm();
            if len > r {
                let end = origin + (target - origin) * ((len - r) / len);
                let line = (origin, end);
                if links[..links.len() - 1].iter().any(|l| segment_distance(l, &line) < r) {
                    return Err(Refusal::LineOfSight);
                }
            }
        }
        Ok(())
    }
}

fn pv(v: &Vector3<f64>) -> PVec {
    PVec::new(v.x, v.y, v.z)
}

/// The shortest distance between two segments, m (parry's closest points).
pub fn segment_distance(a: &(Vector3<f64>, Vector3<f64>), b: &(Vector3<f64>, Vector3<f64>)) -> f64 {
    let (a0, a1, b0, b1) = (pv(&a.0), pv(&a.1), pv(&b.0), pv(&b.1));
    let (la, lb) = closest_points_segment_segment_with_locations_nD((&a0, &a1), (&b0, &b1));
    let (sa, sb) = (Segment::new(a0, a1), Segment::new(b0, b1));
    (sa.point_at(&la) - sb.point_at(&lb)).length()
}

/// The distance between a capsule (axis `l`, radius `r`) and the box [lo, hi], m (≤ 0 when
/// they touch).
fn capsule_box_distance(l: &(Vector3<f64>, Vector3<f64>), r: f64, lo: &Vector3<f64>, hi: &Vector3<f64>) -> f64 {
    use rapier3d_f64::parry::math::Pose;
    let capsule = Capsule::new(pv(&l.0), pv(&l.1), r);
    let cuboid = Cuboid::new(pv(&((hi - lo) * 0.5)));
    let at = Pose::from_translation(pv(&((hi + lo) * 0.5)));
    rapier3d_f64::parry::query::distance(&Pose::IDENTITY, &capsule, &at, &cuboid).map_or(f64::INFINITY, |d| d.distance)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::Robot;

    fn cell(ws: Workspace, reach: Option<Reach>) -> Cell {
        Cell::new(Robot::irb120().error_chain(), Vector3::new(0.0, 0.0, 0.1), -10_000.0, reach, Some(ws))
    }

    #[test]
    fn segment_distance_of_crossing_and_parallel_segments() {
        let x = (Vector3::new(-1.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0));
        let y = (Vector3::new(0.0, -1.0, 0.3), Vector3::new(0.0, 1.0, 0.3));
        assert!((segment_distance(&x, &y) - 0.3).abs() < 1e-12);
        let far = (Vector3::new(2.0, 0.5, 0.0), Vector3::new(3.0, 0.5, 0.0));
        assert!((segment_distance(&x, &far) - (1.0f64 + 0.25).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn a_folded_arm_collides_and_a_stretched_one_does_not() {
        let c = cell(Workspace::default(), None);
        let mut fk = c.work();
        assert_eq!(c.check(&[0.0, 0.0, 0.0, 0.0, 0.5, 0.0], &mut fk), Ok(()));
        // Joint 2 tilts the upper arm forward and down, joint 3 folds the forearm back under
        // it: the forearm meets the base column.
        let folded = [0.0, 1.9, 1.2, 0.0, 0.0, 0.0];
        assert_eq!(c.check(&folded, &mut fk), Err(Refusal::SelfCollision));
        let off = Workspace { self_collision: false, ..Workspace::default() };
        assert_ne!(cell(off, None).check(&folded, &mut fk), Err(Refusal::SelfCollision));
    }

    #[test]
    fn a_keep_out_box_around_the_base_is_refused_by_name() {
        let base = Workspace {
            keep_out: vec![KeepOut { name: "pedestal".into(), min_mm: [-200.0, -200.0, -500.0], max_mm: [200.0, 200.0, 10.0] }],
            ..Workspace::default()
        };
        let e = base.validate().unwrap_err();
        assert!(e.contains("keep_out[0] (pedestal) holds the robot's fixed base"), "{e}");
        let beside = Workspace {
            keep_out: vec![KeepOut { name: "table".into(), min_mm: [400.0, -200.0, -500.0], max_mm: [900.0, 200.0, 100.0] }],
            ..Workspace::default()
        };
        assert!(beside.validate().is_ok());
    }

    #[test]
    fn floor_keep_out_and_line_of_sight_refuse_by_name() {
        let q = [0.0, 0.6, 0.3, 0.0, 0.5, 0.0];
        let c = cell(Workspace::default(), None);
        let mut fk = c.work();
        let tool = c.links(&q, &mut fk).last().unwrap().1;
        let floor = Workspace { floor_z_mm: Some(crate::units::to_mm(tool.z) - 10.0), ..Workspace::default() };
        assert_eq!(cell(floor, None).check(&q, &mut fk), Err(Refusal::Floor));
        let lo = tool.map(crate::units::to_mm) - Vector3::repeat(20.0);
        let hi = tool.map(crate::units::to_mm) + Vector3::repeat(20.0);
        let boxed = Workspace { keep_out: vec![KeepOut { name: "fixture".into(), min_mm: lo.into(), max_mm: hi.into() }], ..Workspace::default() };
        assert_eq!(cell(boxed, None).check(&q, &mut fk), Err(Refusal::KeepOut));
        // A tracker straight behind the base, level with the tool: the base column is in the way.
        let behind = Reach::Tracker { origin: Vector3::new(-3.0, 0.0, tool.z.min(0.2)), range_mm: None };
        assert_eq!(cell(Workspace::default(), Some(behind.clone())).check(&q, &mut fk), Err(Refusal::LineOfSight));
        let blind = Workspace { line_of_sight: false, ..Workspace::default() };
        assert_eq!(cell(blind, Some(behind)).check(&q, &mut fk), Ok(()));
        let front = Reach::Tracker { origin: Vector3::new(3.0, 0.0, 0.5), range_mm: Some([0.0, 1000.0]) };
        assert_eq!(cell(Workspace::default(), Some(front)).check(&q, &mut fk), Err(Refusal::OutOfRange));
    }
}
