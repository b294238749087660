//! The recording of a measurement plan (`twincal plan --rrd`): the cell (the instrument, the
//! keep-out boxes), every feasible candidate's tool point, the planned tool points in tour
//! order and the path between them, and on the `pose` timeline the nominal arm at each planned
//! pose with its link capsules and the instrument's line to the target.

use super::scenes::{draw_instrument, instrument_line, mm, AFTER, ARM, BEFORE, HIGHLIGHT};
use super::{Blueprint, Layout, Recorder, ViewKind as K};
use std::path::Path;
use twincal::error::Result;
use twincal::output::OutputSet;
use twincal::plan::Plan;
use twincal::robot::Robot;
use twincal::sim::scenario::Scenario;

/// The 12 edges of the box [lo, hi] (mm).
fn box_edges(lo: [f64; 3], hi: [f64; 3]) -> Vec<Vec<[f64; 3]>> {
    let c = |i: usize| [if i & 1 == 0 { lo[0] } else { hi[0] }, if i & 2 == 0 { lo[1] } else { hi[1] }, if i & 4 == 0 { lo[2] } else { hi[2] }];
    let mut out = Vec::new();
    for i in 0..8 {
        for bit in [1, 2, 4] {
            if i & bit == 0 {
                out.push(vec![c(i), c(i | bit)]);
            }
        }
    }
    out
}

/// Writes the plan's recording to `path` (staged in `outputs`).
pub fn record_plan(p: &Plan, s: &Scenario, robot: &Robot, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    let cell = s.cell(robot);
    let mut fk = cell.work();
    let tool = |q: &[f64], fk: &mut twincal::robot::kinematics::FkWork| mm(&cell.links(q, fk).last().map_or(nalgebra::Vector3::zeros(), |l| l.1));
    let radius = s.workspace.as_ref().map_or(twincal::sim::workspace::Workspace::default().link_radius_mm, |w| w.link_radius_mm);
    rec.set_static(true);
    rec.static_text(
        "docs/legend",
        &format!(
            "# twincal plan: {} poses of {} feasible candidates\n\nScenario `{}`, robot {}, instrument {}, {} parametrisation, criterion {} ({}).\n\n\
             * grey points: every feasible candidate's tool point; blue: the planned ones, joined in tour order ({:.0} s of acquisition);\n\
             * on the `pose` timeline: the nominal arm at each planned pose, its link capsules ({radius} mm radius) and the instrument's line to the target{}",
            p.poses.len(),
            p.candidates.q.len(),
            p.scenario,
            p.robot,
            p.measurement,
            p.parametrisation,
            p.criterion,
            p.criterion_describe,
            p.tour.total_s,
            if s.workspace.as_ref().is_some_and(|w| !w.keep_out.is_empty()) { ";\n* red boxes: the scenario's keep-out boxes." } else { "." }
        ),
    );
    let instrument = twincal::report::InstrumentPose::of(&twincal::sim::instrument::placement(&s.draw_wire, &s.instruments));
    draw_instrument(&mut rec, &instrument, None);
    let pool: Vec<[f64; 3]> = p.candidates.q.iter().map(|q| tool(q, &mut fk)).collect();
    rec.points("world/candidates", &pool, Some(&[BEFORE]), Some(2.0), None);
    let planned: Vec<[f64; 3]> = p.poses.iter().map(|q| tool(q, &mut fk)).collect();
    let labels: Vec<String> = (0..planned.len()).map(|i| format!("pose {}", i + 1)).collect();
    rec.points_hover("world/planned", &planned, Some(&[AFTER]), Some(9.0), &labels);
    rec.line_strips("world/tour", std::slice::from_ref(&planned), [60, 190, 230, 120], 1.5);
    if let Some(ws) = &s.workspace {
        for (k, b) in ws.keep_out.iter().enumerate() {
            rec.segments(&format!("world/keep_out/{k}"), &box_edges(b.min_mm, b.max_mm), &[[235, 60, 60, 255]], 3.0);
        }
    }
    rec.set_static(false);
    for (i, q) in p.poses.iter().enumerate() {
        rec.set_time_index("pose", i as i64);
        let links: Vec<[f64; 3]> = cell.links(q, &mut fk).iter().flat_map(|l| [mm(&l.0), mm(&l.1)]).collect();
        rec.line_strips("world/arm/capsules", &[links], [ARM[0], ARM[1], ARM[2], 90], radius as f32);
        instrument_line(&mut rec, &instrument, planned[i]);
        rec.points("world/current", &[planned[i]], Some(&[HIGHLIGHT]), Some(14.0), Some(&[labels[i].clone()]));
    }
    rec.layout(Blueprint {
        root: Layout::Horizontal(
            vec![
                Layout::view(K::Spatial3d, "Planned poses: candidates (grey), plan in tour order (blue), arm capsules", "/world"),
                Layout::view(K::Text, "Legend", "/docs"),
            ],
            vec![3.0, 1.0],
        ),
        timeline: Some("pose".into()),
        at_end: false,
    });
    rec.finish()
}
