//! What twincal draws: one recording per command, each with its own layout, built from plain
//! twincal data on top of [`super::Recorder`]. Entities and layouts are listed in `viz/README.md`.

use super::plot::{padded_range, Plot};
use super::{histogram, residual_color, Blueprint, Layout, Recorder, ViewKind as K};
use nalgebra::Vector3;
use std::path::Path;
use twincal::error::Result;
use twincal::output::OutputSet;
use twincal::report::{max_abs, Feature, InstrumentPose, Residual};
use twincal::sim::generate::Generated;

pub(super) const ARM: [u8; 4] = [200, 206, 218, 255];

pub(super) const JOINT: [u8; 4] = [255, 166, 50, 255];

pub(super) const CABLE: [u8; 4] = [255, 96, 40, 255];

pub(super) const TRACKER: [u8; 4] = [235, 60, 60, 255];

pub(super) const HIGHLIGHT: [u8; 4] = [255, 255, 255, 255];

pub(super) const BEFORE: [u8; 4] = [150, 150, 150, 255];

pub(super) const AFTER: [u8; 4] = [60, 190, 230, 255];

pub(super) const TRUTH: [u8; 4] = [240, 70, 70, 255];

/// Distinct colours for per-joint / per-parameter series.
pub(super) const PALETTE: [[u8; 4]; 10] = [
    [31, 119, 180, 255],
    [255, 127, 14, 255],
    [44, 160, 44, 255],
    [214, 39, 40, 255],
    [148, 103, 189, 255],
    [140, 86, 75, 255],
    [227, 119, 194, 255],
    [160, 160, 160, 255],
    [188, 189, 34, 255],
    [23, 190, 207, 255],
];

pub(super) fn mm(v: &Vector3<f64>) -> [f64; 3] {
    [v.x * 1e3, v.y * 1e3, v.z * 1e3]
}

pub(super) fn rows_of(m: &nalgebra::Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

/// Residual of the nominal model per row: measured length minus the length the nominal URDF
/// (no geometric errors, no effects) predicts with the scenario's sensor geometry, mm.
pub fn nominal_residuals(g: &Generated) -> Vec<f64> {
    let chain = &g.twin.chain;
    let zero = vec![0.0; chain.n_params()];
    let placement = twincal::sim::instrument::placement(&g.twin.draw_wire, &g.twin.instruments);
    let frame = placement.measurement.def().frame(&placement.own);
    g.dataset
        .rows
        .iter()
        .map(|r| {
            let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
            let p = chain.point(&q, &zero, 1.0, chain.flange(), &g.twin.draw_wire.tool_point_m());
            match (g.twin.instruments.active(), frame.axes) {
                (None, _) => r.l_mm().unwrap_or(f64::NAN) - twincal::sim::generate::nominal_length(chain, &g.twin.draw_wire, &q),
                // A point in the instrument's frame (a tracker's): how far the reading is from
                // the nominal arm's reflector.
                (Some(_), Some(axes)) => {
                    let nominal = twincal::units::to_mm(axes.transpose() * (p - frame.origin));
                    let lengths = placement.measurement.file_lengths().min(3);
                    (0..lengths).map(|k| (r.reading_mm[k] - nominal[k]).powi(2)).sum::<f64>().sqrt()
                }
                // Another reading of one value: measured minus the nominal arm's.
                (Some(_), None) => {
                    let mut y = [0.0; twincal::measurement::MAX_DIM];
                    placement.measurement.reading(&placement.own, &p, &mut y[..placement.measurement.dim()]);
                    r.reading_mm.first().map_or(f64::NAN, |v| v - twincal::units::to_mm(y[0]))
                }
            }
        })
        .collect()
}

/// The arm at one pose: a transform with axes per frame (`world/arm/frame_k`), the links as a
/// thick polyline through the frame origins to the tool point, the joints as balls.
/// `frames`: (origin mm, rotation) per frame. Axes are static and drawn once (`first`).
pub(super) fn draw_arm(rec: &mut Recorder, frames: &[([f64; 3], [[f64; 3]; 3])], tool: [f64; 3], first: bool) {
    for (k, (pos, rot)) in frames.iter().enumerate() {
        let e = format!("world/arm/frame_{k}");
        rec.transform(&e, *pos, *rot);
        if first {
            rec.axes(&e, 45.0);
        }
    }
    let mut links: Vec<[f64; 3]> = frames.iter().map(|f| f.0).collect();
    links.dedup_by(|a, b| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-6));
    let joints = links.clone();
    links.push(tool);
    rec.line_strips("world/arm/links", &[links], ARM, 9.0);
    rec.points("world/arm/joints", &joints, Some(&[JOINT]), Some(15.0), None);
}

/// A vertical colour bar for [`residual_color`] with `vmax`, standing at `base` (mm), with its
/// values written beside it.
pub(super) fn colorbar(rec: &mut Recorder, entity: &str, base: [f64; 3], height: f64, vmax: f64, title: &str) {
    let n = 16;
    let strips: Vec<Vec<[f64; 3]>> = (0..n)
        .map(|i| {
            let z0 = base[2] + height * i as f64 / n as f64;
            let z1 = base[2] + height * (i + 1) as f64 / n as f64;
            vec![[base[0], base[1], z0], [base[0], base[1], z1]]
        })
        .collect();
    let colors: Vec<[u8; 4]> = (0..n).map(|i| residual_color(vmax * (i as f64 + 0.5) / n as f64, vmax)).collect();
    rec.segments(&format!("{entity}/bar"), &strips, &colors, 18.0);
    let ticks = [0.0, 0.25, 0.5, 0.75, 1.0];
    let pts: Vec<[f64; 3]> = ticks.iter().map(|t| [base[0] + 30.0, base[1], base[2] + height * t]).collect();
    let labels: Vec<String> = ticks.iter().map(|t| format!("{}{:.3} mm", if *t == 1.0 { "≥ " } else { "" }, vmax * t)).collect();
    let colors: Vec<[u8; 4]> = ticks.iter().map(|t| residual_color(vmax * t, vmax)).collect();
    rec.points(&format!("{entity}/values"), &pts, Some(&colors), Some(2.0), Some(&labels));
    rec.points(&format!("{entity}/title"), &[[base[0], base[1], base[2] + height + 60.0]], Some(&[HIGHLIGHT]), Some(2.0), Some(&[title.to_string()]));
}

/// Bounding box of points (mm).
pub(super) fn bbox(pts: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pts {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    (lo, hi)
}

/// A colour bar beside a cloud of points.
pub(super) fn colorbar_beside(rec: &mut Recorder, entity: &str, pts: &[[f64; 3]], vmax: f64, title: &str) {
    let (lo, hi) = bbox(pts);
    if lo[0].is_finite() {
        colorbar(rec, entity, [hi[0] + 180.0, 0.5 * (lo[1] + hi[1]), lo[2]], (hi[2] - lo[2]).max(200.0), vmax, title);
    }
}

/// Residual `res` (mm) against each feature, one 2-D plot per feature at `plots/<name>`.
/// The residual `res` against each feature, on `y` (mm) labelled `y_label`.
pub(super) fn feature_plots(rec: &mut Recorder, features: &[Feature], res: &[f64], vmax: f64, what: &str, y: (f64, f64), y_label: &str) {
    for f in features {
        let Some(x) = padded_range(f.values.iter().copied(), 0.03) else { continue };
        let plot = Plot::new(&format!("{what} vs {}", f.name), &f.label, x, y_label, y);
        let base = format!("plots/{}", f.name);
        plot.frame(rec, &base);
        let xy: Vec<[f64; 2]> = f.values.iter().zip(res).map(|(x, r)| [*x, *r]).collect();
        let colors: Vec<[u8; 4]> = res.iter().map(|r| residual_color(*r, vmax)).collect();
        let labels: Vec<String> = xy.iter().enumerate().map(|(i, p)| format!("row {}: {} = {:.4}, residual {:+.4} mm", i + 1, f.name, p[0], p[1])).collect();
        plot.scatter(rec, &format!("{base}/points"), &xy, &colors, 2.0, &labels);
    }
}

pub(super) fn feature_grid(features: &[Feature], what: &str) -> Layout {
    let views: Vec<Layout> = features.iter().map(|f| Layout::plot(&format!("{what} vs {}", f.name), &format!("/plots/{}", f.name))).collect();
    Layout::Grid(views, 3)
}

/// The blueprint of a dataset's recording: the 3-D view and the effects' series on the left,
/// the residual against each feature and its histogram on the right.
pub(super) fn dataset_blueprint(features: &[twincal::report::Feature], tracker: bool) -> Blueprint {
    let plots = feature_grid(features, if tracker { "|Δp| (mm)" } else { "Residual (mm)" });
    Blueprint {
        root: Layout::Horizontal(
            vec![
                Layout::Vertical(
                    vec![
                        Layout::view(
                            K::Spatial3d,
                            if tracker {
                                "Arm, tracker, tool points: colour = |Δp| from the nominal arm (mm)"
                            } else {
                                "Arm, cable, tool points: colour = |nominal residual| (mm)"
                            },
                            "/world",
                        ),
                        Layout::Tabs(vec![
                            Layout::view(K::TimeSeries, "Deflection per joint (mdeg, truth)", "/effects/deflection"),
                            Layout::view(K::TimeSeries, "Backlash approach side (joint ± 0.3, truth)", "/effects/backlash"),
                            Layout::view(K::TimeSeries, "Thermal scale α·ΔT (ppm, truth)", "/effects/thermal"),
                            Layout::view(K::Text, "Legend", "/docs"),
                        ]),
                    ],
                    vec![3.0, 1.6],
                ),
                Layout::Vertical(
                    vec![
                        plots,
                        Layout::view(
                            K::BarChart,
                            if tracker { "Nominal |Δp| histogram (mm)" } else { "Nominal residual histogram (mm)" },
                            "/residuals/histogram",
                        ),
                    ],
                    vec![3.0, 1.0],
                ),
            ],
            vec![1.0, 1.1],
        ),
        timeline: Some("pose".into()),
        at_end: true,
    }
}

/// The truth's per-pose effects a dataset's recording plots: joint deflections, backlash
/// approach sides, the thermal scale.
pub(super) struct EffectSeries {
    pub(super) deflection: bool,
    pub(super) backlash: bool,
    /// The structure's expansion coefficient (1/K) when the thermal drift is on.
    pub(super) thermal: Option<f64>,
    pub(super) joints: usize,
}

impl EffectSeries {
    pub(super) fn of(g: &Generated) -> Self {
        EffectSeries {
            deflection: g.truth.poses.iter().any(|p| p.deflection_mdeg.iter().any(|d| *d != 0.0)),
            backlash: g.truth.effects.backlash.is_some(),
            thermal: g.truth.effects.thermal.as_ref().map(|t| t.alpha_per_k),
            joints: g.dataset.n_joints(),
        }
    }

    /// The series' names and styles (static).
    pub(super) fn declare(&self, rec: &mut Recorder) {
        for j in 0..self.joints {
            if self.deflection {
                rec.series_style(&format!("effects/deflection/j{}", j + 1), &format!("joint {}", j + 1), PALETTE[j % PALETTE.len()], true, 2.5);
            }
            if self.backlash {
                rec.series_style(&format!("effects/backlash/j{}", j + 1), &format!("joint {} ± side", j + 1), PALETTE[j % PALETTE.len()], true, 2.5);
            }
        }
        if self.thermal.is_some() {
            rec.series_style("effects/thermal/scale_ppm", "α·ΔT (ppm)", PALETTE[3], true, 2.5);
        }
    }

    /// One pose's values.
    pub(super) fn log(&self, rec: &mut Recorder, p: &twincal::sim::generate::PoseTruth) {
        for j in 0..self.joints {
            if self.deflection {
                rec.scalar(&format!("effects/deflection/j{}", j + 1), p.deflection_mdeg[j]);
            }
            if self.backlash {
                rec.scalar(&format!("effects/backlash/j{}", j + 1), (j + 1) as f64 + 0.3 * p.approach_side[j]);
            }
        }
        if let Some(alpha) = self.thermal {
            rec.scalar("effects/thermal/scale_ppm", alpha * p.delta_t_k * 1e6);
        }
    }
}

/// Recording of a generated dataset. Timeline `pose` (and `acquisition_time`): the arm with its
/// frames, the instrument's line to the tool (the cable, or a tracker's line of sight) and the
/// current tool point highlighted, the per-pose effects from the truth. Static: the instrument,
/// every tool point coloured by the nominal model's residual (a point's |Δp|) with a colour bar,
/// that residual against each joint angle, the reading, time and temperature, its histogram. Staged in
/// `outputs` as `path` (renamed into place by `outputs.commit()`).
pub fn record_dataset(g: &Generated, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    let res = nominal_residuals(g);
    let vmax = max_abs(&res);
    let n = res.len();
    let split: Vec<&str> = g.truth.poses.iter().map(|p| if p.split == twincal::dataset::Split::Test { "test" } else { "train" }).collect();
    let tools: Vec<[f64; 3]> = (0..n).map(|i| mm(&g.truth_tool(i))).collect();
    let instrument = twincal::report::InstrumentPose::of(&twincal::sim::instrument::placement(&g.twin.draw_wire, &g.twin.instruments));
    let tracker = g.twin.instruments.active().is_some();
    let (quantity, what, instrument_text) = if tracker {
        (
            "|Δp|",
            "|p measured − p nominal| (the tracker's reading against the nominal arm's reflector)",
            "the laser tracker (its axes and red head) and its line of sight (red) to the reflector",
        )
    } else {
        ("|L − L nominal|", "|L measured − L nominal|", "the draw wire (orange) from its exit point")
    };
    let features = twincal::report::features(&g.dataset);

    rec.set_static(true);
    rec.static_text(
        "docs/legend",
        &format!(
            "# twincal dataset `{}` (seed {})\n\n{n} poses, units mm, base frame, Z up.\n\n\
             * **3D**: the true (simulated) arm at the current pose with its joint frames (red x, green y, blue z), \
             {instrument_text}, the current tool point (white ring); every tool point coloured by \
             {what} (colour bar beside the cloud, 0 to {vmax:.3} mm). Hover a point for its residual.\n\
             * **Residual vs …**: the nominal model's residual (mm) against each joint angle, the reading, time and temperature; \
             the white point is the current pose.\n\
             * **Effects (truth.json)**: joint deflection, backlash approach side and thermal scale of every pose; \
             the time cursor marks the current pose.\n\nColours: blue-violet = 0 mm, teal, green, yellow = {vmax:.3} mm and above.",
            g.truth.scenario, g.truth.seed,
        ),
    );
    draw_instrument(&mut rec, &instrument, None);
    let colors: Vec<[u8; 4]> = res.iter().map(|r| residual_color(*r, vmax)).collect();
    let labels: Vec<String> = (0..n).map(|i| format!("pose {i} ({}): residual {:+.4} mm", split[i], res[i])).collect();
    rec.points_hover("world/tool_points", &tools, Some(&colors), Some(5.0), &labels);
    colorbar_beside(&mut rec, "world/colorbar", &tools, vmax, quantity);
    // A point's |Δp| is never negative: its plots start at zero.
    let y = if tracker { (-0.04 * vmax, 1.08 * vmax) } else { (-1.08 * vmax, 1.08 * vmax) };
    feature_plots(&mut rec, &features, &res, vmax, "Nominal residual", y, if tracker { "|Δp| (mm)" } else { "residual (mm)" });
    let (edges, counts) = histogram(&res, 30, if tracker { 0.0 } else { -vmax }, vmax);
    rec.histogram_colored("residuals/histogram", &edges, &counts, [90, 160, 220, 255]);

    let effects = EffectSeries::of(g);
    effects.declare(&mut rec);
    rec.set_static(false);

    for (i, frames) in g.frames.iter().enumerate() {
        rec.set_time_index("pose", i as i64);
        if let Some(t) = g.dataset.rows[i].t_s {
            rec.set_time_seconds("acquisition_time", t);
        }
        let fr: Vec<([f64; 3], [[f64; 3]; 3])> = frames.iter().map(|f| (mm(&f.pos), rows_of(&f.rot))).collect();
        draw_arm(&mut rec, &fr, tools[i], i == 0);
        instrument_line(&mut rec, &instrument, tools[i]);
        rec.points("world/current", &[tools[i]], Some(&[HIGHLIGHT]), Some(12.0), Some(&[format!("pose {i}: {:+.4} mm", res[i])]));
        for f in &features {
            let Some(x) = padded_range(f.values.iter().copied(), 0.03) else { continue };
            let plot = Plot::new("", "", x, "", y);
            rec.points2d(&format!("plots/{}/current", f.name), &[plot.map(f.values[i], res[i].clamp(y.0, y.1))], Some(&[HIGHLIGHT]), Some(5.0), None, false);
        }
        effects.log(&mut rec, &g.truth.poses[i]);
    }

    rec.layout(dataset_blueprint(&features, tracker));
    rec.finish()
}

/// The residual field of every row before and after (calibration or diagnosis).
pub(super) struct Field<'a> {
    pub(super) arm: Option<&'a twincal::report::ArmPose>,
    pub(super) instrument: &'a InstrumentPose,
    pub(super) tools: &'a [[f64; 3]],
    /// The per-row quantities ([`Residual::of`]): the first colours the rows (the residual of a
    /// one-value reading, a point's |Δp|), every one has its histograms.
    pub(super) residuals: &'a [Residual],
    pub(super) train: &'a [bool],
}

/// What colours the rows, for titles: `|residual|` or `|Δp|`.
pub(super) fn colour_quantity(res: &Residual) -> String {
    if res.label.is_empty() {
        "|residual|".into()
    } else {
        res.label.clone()
    }
}

/// The instrument as placed in the base frame, with its line to the target at `tool` (mm):
/// the draw-wire's exit point and cable, or a laser tracker (its frame's axes and a head at its
/// origin) and its line of sight to the reflector; nothing for an artifact's rows.
pub(super) fn draw_instrument(rec: &mut Recorder, inst: &InstrumentPose, tool: Option<[f64; 3]>) {
    // An artifact is drawn from its own figure (super::artifact).
    if inst.measurement.feature().is_some() {
        return;
    }
    let o = inst.origin_mm;
    match (inst.measurement, inst.axes) {
        (twincal::measurement::Measurement::Point | twincal::measurement::Measurement::Pose, Some(axes)) => {
            rec.transform("world/instrument/tracker", o, rows_of(&axes));
            rec.axes("world/instrument/tracker", 150.0);
            rec.points("world/instrument/tracker/head", &[[0.0; 3]], Some(&[TRACKER]), Some(40.0), Some(&["laser tracker".to_string()]));
        }
        _ => {
            rec.points("world/instrument/cable_exit", &[o], Some(&[CABLE]), Some(14.0), Some(&["cable exit".to_string()]));
        }
    }
    if let Some(t) = tool {
        instrument_line(rec, inst, t);
    }
}

/// The instrument's line to the target at `tool` (mm): the tracker's line of sight, or the cable.
pub(super) fn instrument_line(rec: &mut Recorder, inst: &InstrumentPose, tool: [f64; 3]) {
    if inst.measurement.feature().is_some() {
        return;
    }
    match (inst.measurement, inst.axes) {
        (twincal::measurement::Measurement::Point | twincal::measurement::Measurement::Pose, Some(_)) => {
            rec.line_strips("world/line_of_sight", &[vec![inst.origin_mm, tool]], TRACKER, 2.0)
        }
        _ => rec.line_strips("world/cable", &[vec![inst.origin_mm, tool]], CABLE, 2.0),
    }
}

/// Hover text of row `i` on side `k` (0: before, 1: after) named `names[k]`: its value and the
/// other side's; for a reading of several values each value too.
pub(super) fn row_label(residuals: &[Residual], i: usize, set: &str, k: usize, names: [&str; 2]) -> String {
    let first = &residuals[0];
    let side = |k: usize| if k == 0 { &first.before_mm } else { &first.after_mm };
    if residuals.len() == 1 {
        return format!("row {} ({set}): {} {:+.4} mm, {} {:+.4} mm", i + 1, names[k], side(k)[i], names[1 - k], side(1 - k)[i]);
    }
    let values = |k: usize| -> String {
        let v: Vec<String> = residuals[1..].iter().map(|r| format!("{} {:+.4}", r.label, if k == 0 { r.before_mm[i] } else { r.after_mm[i] })).collect();
        format!("{} {} {:.4} mm ({})", names[k], first.label, side(k)[i], v.join(", "))
    };
    format!("row {} ({set}): {}; {}", i + 1, values(k), values(1 - k))
}

/// The static scene shared by calibration and diagnosis: the arm at one row, the instrument, and
/// the tool points coloured by the residual before (`world/before/…`) and after
/// (`world/after/…`), each with its own colour bar; the histograms over their own ranges (the
/// colouring quantity's at `residuals/{before,after}`, the others' at
/// `residuals/<name>/{before,after}`).
pub(super) fn before_after(rec: &mut Recorder, f: &Field, names: [&str; 2]) {
    let Field { arm, instrument, tools, residuals, train } = *f;
    if let Some(a) = arm {
        let fr: Vec<([f64; 3], [[f64; 3]; 3])> = a.frames.iter().map(|f| ([f.pos.x, f.pos.y, f.pos.z], rows_of(&f.rot))).collect();
        draw_arm(rec, &fr, a.tool_mm, true);
    }
    draw_instrument(rec, instrument, arm.map(|a| a.tool_mm));
    let Some(first) = residuals.first() else { return };
    let quantity = colour_quantity(first);
    for (k, (side, res, name)) in [("before", &first.before_mm, names[0]), ("after", &first.after_mm, names[1])].into_iter().enumerate() {
        let vmax = max_abs(res);
        for (set, want, radius) in [("train", true, 4.5), ("test", false, 8.0)] {
            let idx: Vec<usize> = (0..res.len()).filter(|i| train[*i] == want).collect();
            if idx.is_empty() {
                continue;
            }
            let pts: Vec<[f64; 3]> = idx.iter().map(|&i| tools[i]).collect();
            let colors: Vec<[u8; 4]> = idx.iter().map(|&i| residual_color(res[i], vmax)).collect();
            let labels: Vec<String> = idx.iter().map(|&i| row_label(residuals, i, set, k, names)).collect();
            rec.points_hover(&format!("world/{side}/{set}"), &pts, Some(&colors), Some(radius), &labels);
        }
        colorbar_beside(rec, &format!("world/{side}/colorbar"), tools, vmax, &format!("{quantity} {name}"));
        let color = if side == "before" { [170, 170, 170, 255] } else { [60, 190, 230, 255] };
        for (j, r) in residuals.iter().enumerate() {
            let values = if k == 0 { &r.before_mm } else { &r.after_mm };
            let (lo, hi) = r.range(max_abs(values));
            let (edges, counts) = histogram(values, 30, lo, hi);
            let entity = if j == 0 { format!("residuals/{side}") } else { format!("residuals/{}/{side}", r.name) };
            rec.histogram_colored(&entity, &edges, &counts, color);
        }
    }
}

/// The histogram views of `residuals` on one side (`before` / `after`, named `name` in titles):
/// one view for a one-value reading, tabs of every quantity for several.
pub(super) fn histogram_views(residuals: &[Residual], side: &str, name: &str) -> Layout {
    let views: Vec<Layout> = residuals
        .iter()
        .enumerate()
        .map(|(j, r)| {
            let origin = if j == 0 { format!("/residuals/{side}") } else { format!("/residuals/{}/{side}", r.name) };
            Layout::view(K::BarChart, &format!("{} (mm)", r.histogram_title(name)), &origin)
        })
        .collect();
    if views.len() == 1 {
        views.into_iter().next().unwrap_or_else(|| Layout::Tabs(Vec::new()))
    } else {
        Layout::Tabs(views)
    }
}

pub(super) fn world_pair(titles: [&str; 2]) -> [Layout; 2] {
    [
        Layout::view_of(K::Spatial3d, titles[0], "/world", &["+ /world/**", "- /world/after/**"]),
        Layout::view_of(K::Spatial3d, titles[1], "/world", &["+ /world/**", "- /world/before/**"]),
    ]
}

/// For a reading of several values, the position error |Δp| per set of rows before and after,
/// as markdown table lines.
pub(super) fn distance_lines(dist: &Residual, sets: &[(&str, &[bool])]) -> String {
    // A pipe inside a cell would end it: |Δp| is written \|Δp\|.
    let mut s = format!("\n| position error {} (mm) | RMS | mean | MAX |\n|---|---:|---:|---:|\n", dist.label.replace('|', "\\|"));
    for (set, rows) in sets {
        for (side, values) in [("before", &dist.before_mm), ("after", &dist.after_mm)] {
            let v: Vec<f64> = values.iter().zip(rows.iter()).filter(|(_, r)| **r).map(|(v, _)| *v).collect();
            if v.is_empty() {
                s.push_str(&format!("| {set} {side} | – | – | – |\n"));
            } else {
                let st = twincal::stats::metrics::ErrorStats::of(&v);
                s.push_str(&format!("| {set} {side} | {:.4} | {:.4} | {:.4} |\n", st.rmse, st.mean, st.max));
            }
        }
    }
    s
}

pub(super) fn stats_line(label: &str, s: Option<&twincal::stats::metrics::ErrorStats>) -> String {
    match s {
        Some(s) => format!("| {label} | {:.4} | {:.4} | {:.4} |\n", s.rmse, s.std, s.max),
        None => format!("| {label} | – | – | – |\n"),
    }
}
