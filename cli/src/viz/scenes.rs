//! What twincal draws: one recording per command, each with its own layout, built from plain
//! twincal data on top of [`super::Recorder`]. Entities and layouts are listed in `viz/README.md`.

use super::plot::{padded_range, Plot};
use super::{histogram, residual_color, Blueprint, Layout, Recorder, ViewKind as K};
use nalgebra::Vector3;
use std::path::Path;
use twincal::error::Result;
use twincal::io::OutputSet;
use twincal::report::{max_abs, CalibFigures, DiagnosisFigures, Feature, Group, InstrumentPose, Residual};
use twincal::sim::generate::Generated;

const ARM: [u8; 4] = [200, 206, 218, 255];
const JOINT: [u8; 4] = [255, 166, 50, 255];
const CABLE: [u8; 4] = [255, 96, 40, 255];
const TRACKER: [u8; 4] = [235, 60, 60, 255];
const HIGHLIGHT: [u8; 4] = [255, 255, 255, 255];
const BEFORE: [u8; 4] = [150, 150, 150, 255];
const AFTER: [u8; 4] = [60, 190, 230, 255];
const TRUTH: [u8; 4] = [240, 70, 70, 255];
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

fn mm(v: &Vector3<f64>) -> [f64; 3] {
    [v.x * 1e3, v.y * 1e3, v.z * 1e3]
}

fn rows_of(m: &nalgebra::Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

/// Residual of the nominal model per row: measured length minus the length the nominal URDF
/// (no geometric errors, no effects) predicts with the scenario's sensor geometry, mm.
pub fn nominal_residuals(g: &Generated) -> Vec<f64> {
    let chain = &g.twin.chain;
    let zero = vec![0.0; chain.n_params()];
    g.dataset
        .rows
        .iter()
        .map(|r| {
            let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
            match &g.twin.tracker {
                // A tracker's point: how far the reading is from the nominal arm's reflector.
                Some(t) => {
                    let nominal = t.ideal_mm(&chain.point(&q, &zero, 1.0, chain.flange(), &g.twin.sensor.tool_point_m()));
                    (0..3).map(|k| (r.reading_mm[k] - nominal[k]).powi(2)).sum::<f64>().sqrt()
                }
                None => r.l_mm().unwrap_or(f64::NAN) - twincal::sim::generate::nominal_length(chain, &g.twin.sensor, &q),
            }
        })
        .collect()
}

/// The arm at one pose: a transform with axes per frame (`world/arm/frame_k`), the links as a
/// thick polyline through the frame origins to the tool point, the joints as balls.
/// `frames`: (origin mm, rotation) per frame. Axes are static and drawn once (`first`).
fn draw_arm(rec: &mut Recorder, frames: &[([f64; 3], [[f64; 3]; 3])], tool: [f64; 3], first: bool) {
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
fn colorbar(rec: &mut Recorder, entity: &str, base: [f64; 3], height: f64, vmax: f64, title: &str) {
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
fn bbox(pts: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
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
fn colorbar_beside(rec: &mut Recorder, entity: &str, pts: &[[f64; 3]], vmax: f64, title: &str) {
    let (lo, hi) = bbox(pts);
    if lo[0].is_finite() {
        colorbar(rec, entity, [hi[0] + 180.0, 0.5 * (lo[1] + hi[1]), lo[2]], (hi[2] - lo[2]).max(200.0), vmax, title);
    }
}

/// Residual `res` (mm) against each feature, one 2-D plot per feature at `plots/<name>`.
/// The residual `res` against each feature, on `y` (mm) labelled `y_label`.
fn feature_plots(rec: &mut Recorder, features: &[Feature], res: &[f64], vmax: f64, what: &str, y: (f64, f64), y_label: &str) {
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

fn feature_grid(features: &[Feature], what: &str) -> Layout {
    let views: Vec<Layout> = features.iter().map(|f| Layout::plot(&format!("{what} vs {}", f.name), &format!("/plots/{}", f.name))).collect();
    Layout::Grid(views, 3)
}

/// The blueprint of a dataset's recording: the 3-D view and the effects' series on the left,
/// the residual against each feature and its histogram on the right.
fn dataset_blueprint(features: &[twincal::report::Feature], tracker: bool) -> Blueprint {
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
struct EffectSeries {
    deflection: bool,
    backlash: bool,
    /// The structure's expansion coefficient (1/K) when the thermal drift is on.
    thermal: Option<f64>,
    joints: usize,
}

impl EffectSeries {
    fn of(g: &Generated) -> Self {
        EffectSeries {
            deflection: g.truth.poses.iter().any(|p| p.deflection_mdeg.iter().any(|d| *d != 0.0)),
            backlash: g.truth.effects.backlash.is_some(),
            thermal: g.truth.effects.thermal.as_ref().map(|t| t.alpha_per_k),
            joints: g.dataset.n_joints(),
        }
    }

    /// The series' names and styles (static).
    fn declare(&self, rec: &mut Recorder) {
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
    fn log(&self, rec: &mut Recorder, p: &twincal::sim::generate::PoseTruth) {
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
    let instrument = twincal::report::InstrumentPose::of(&twincal::sim::instrument::placement(&g.twin.sensor, g.twin.tracker.as_ref()));
    let tracker = g.twin.tracker.is_some();
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
struct Field<'a> {
    arm: Option<&'a twincal::report::ArmPose>,
    instrument: &'a InstrumentPose,
    tools: &'a [[f64; 3]],
    /// The per-row quantities ([`Residual::of`]): the first colours the rows (the residual of a
    /// one-value reading, a point's |Δp|), every one has its histograms.
    residuals: &'a [Residual],
    train: &'a [bool],
}

/// What colours the rows, for titles: `|residual|` or `|Δp|`.
fn colour_quantity(res: &Residual) -> String {
    if res.label.is_empty() {
        "|residual|".into()
    } else {
        res.label.clone()
    }
}

/// The instrument as placed in the base frame, with its line to the target at `tool` (mm):
/// the draw-wire's exit point and cable, or a laser tracker (its frame's axes and a head at its
/// origin) and its line of sight to the reflector.
fn draw_instrument(rec: &mut Recorder, inst: &InstrumentPose, tool: Option<[f64; 3]>) {
    let o = inst.origin_mm;
    match (inst.measurement, inst.axes) {
        (twincal::measurement::Measurement::Point | twincal::measurement::Measurement::Pose, Some(axes)) => {
            rec.transform("world/sensor/tracker", o, rows_of(&axes));
            rec.axes("world/sensor/tracker", 150.0);
            rec.points("world/sensor/tracker/head", &[[0.0; 3]], Some(&[TRACKER]), Some(40.0), Some(&["laser tracker".to_string()]));
        }
        _ => {
            rec.points("world/sensor/cable_exit", &[o], Some(&[CABLE]), Some(14.0), Some(&["cable exit".to_string()]));
        }
    }
    if let Some(t) = tool {
        instrument_line(rec, inst, t);
    }
}

/// The instrument's line to the target at `tool` (mm): the tracker's line of sight, or the cable.
fn instrument_line(rec: &mut Recorder, inst: &InstrumentPose, tool: [f64; 3]) {
    match (inst.measurement, inst.axes) {
        (twincal::measurement::Measurement::Point | twincal::measurement::Measurement::Pose, Some(_)) => {
            rec.line_strips("world/line_of_sight", &[vec![inst.origin_mm, tool]], TRACKER, 2.0)
        }
        _ => rec.line_strips("world/cable", &[vec![inst.origin_mm, tool]], CABLE, 2.0),
    }
}

/// Hover text of row `i` on side `k` (0: before, 1: after) named `names[k]`: its value and the
/// other side's; for a reading of several values each value too.
fn row_label(residuals: &[Residual], i: usize, set: &str, k: usize, names: [&str; 2]) -> String {
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
fn before_after(rec: &mut Recorder, f: &Field, names: [&str; 2]) {
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
fn histogram_views(residuals: &[Residual], side: &str, name: &str) -> Layout {
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

fn world_pair(titles: [&str; 2]) -> [Layout; 2] {
    [
        Layout::view_of(K::Spatial3d, titles[0], "/world", &["+ /world/**", "- /world/after/**"]),
        Layout::view_of(K::Spatial3d, titles[1], "/world", &["+ /world/**", "- /world/before/**"]),
    ]
}

/// For a reading of several values, the position error |Δp| per set of rows before and after,
/// as markdown table lines.
fn distance_lines(dist: &Residual, sets: &[(&str, &[bool])]) -> String {
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

fn stats_line(label: &str, s: Option<&twincal::stats::metrics::ErrorStats>) -> String {
    match s {
        Some(s) => format!("| {label} | {:.4} | {:.4} | {:.4} |\n", s.rmse, s.std, s.max),
        None => format!("| {label} | – | – | – |\n"),
    }
}

/// The summary text of a calibration's recording: its metrics, the truth, what the colours say,
/// its warnings.
fn calibration_summary(r: &twincal::calib::run::CalibResult, f: &CalibFigures, first: &Residual) -> String {
    let meas = f.measurement;
    let m = &r.metrics;
    let mut doc = format!(
        "## {}\n\n{} train / {} test rows, {} iterations, {}.\n\n| residual (mm) | RMSE | STD | MAX |\n|---|---:|---:|---:|\n",
        f.title,
        r.n_train,
        r.n_test,
        r.iterations,
        if r.converged { "converged" } else { "**did not converge**" }
    );
    doc.push_str(&stats_line("train before", Some(&m.train_before)));
    doc.push_str(&stats_line("train after", Some(&m.train_after)));
    doc.push_str(&stats_line("test before", m.test_before.as_ref()));
    doc.push_str(&stats_line("test after", m.test_after.as_ref()));
    doc.push_str(&format!("\nNoise estimate {:.4} mm.", r.noise_estimate_mm));
    if let Some(t) = &r.truth_comparison {
        doc.push_str(&format!(" Truth: {}/{} parameters within 3σ (max |z| {:.2}).", t.within_3_sigma, t.identifiable, t.max_abs_z));
    }
    if meas.dim() == 1 {
        doc.push_str(&format!(
            "\n\nColour = |measured − predicted length|, own scale per side: before 0–{:.3} mm, after 0–{:.3} mm. Small points: training rows; large: test rows. Hover a point for its residuals.",
            max_abs(&first.before_mm),
            max_abs(&first.after_mm)
        ));
    } else {
        doc.push_str(&format!(" The rows read a {}: the table's residuals are per coordinate value.\n", meas.def().describe()));
        doc.push_str(&distance_lines(first, &[("train", &f.train), ("test", &f.test)]));
        doc.push_str(&format!(
            "\nColour = position error {} (distance between the measured and the predicted point), own scale per side: before 0–{:.3} mm, after 0–{:.3} mm. Small points: training rows; large: test rows. Hover a point for its residuals per coordinate.",
            first.label,
            max_abs(&first.before_mm),
            max_abs(&first.after_mm)
        ));
    }
    for w in &r.warnings {
        doc.push_str(&format!("\n\n**Warning:** {w}"));
    }
    doc
}

/// A parameter group's final change from the start, ±1σ, and the truth-equivalent change.
fn final_changes(rec: &mut Recorder, f: &CalibFigures, g: Group) {
    let meas = f.measurement;
    let ps: Vec<&twincal::report::ParamChange> = f.params.iter().filter(|p| p.group == g).collect();
    if ps.is_empty() {
        return;
    }
    let names: Vec<String> = ps.iter().map(|p| p.name.replace("joint_", "j").replace("theta", "θ").replace("alpha", "α").replace("beta", "β")).collect();
    let ys = ps
        .iter()
        .flat_map(|p| [Some(p.change + p.sigma.unwrap_or(0.0)), Some(p.change - p.sigma.unwrap_or(0.0)), p.truth_change, Some(0.0)].into_iter().flatten());
    let y = padded_range(ys, 0.1).unwrap_or((-1.0, 1.0));
    let plot = Plot::categories(
        &format!("{}: change from start ±1σ{}", g.title(meas), if ps.iter().any(|p| p.truth_change.is_some()) { ", red = truth" } else { "" }),
        &names,
        "change",
        y,
    );
    let base = format!("final/{}", g.name());
    plot.frame(rec, &base);
    let bars: Vec<(f64, f64, f64)> = ps.iter().enumerate().filter_map(|(i, p)| p.sigma.map(|s| (i as f64, p.change - s, p.change + s))).collect();
    plot.bars(rec, &format!("{base}/sigma"), &bars, AFTER, 2.0);
    let xy: Vec<[f64; 2]> = ps.iter().enumerate().map(|(i, p)| [i as f64, p.change]).collect();
    let labels: Vec<String> =
        ps.iter().map(|p| format!("{}: {:+.5} ± {} {}", p.name, p.change, p.sigma.map(|s| format!("{s:.5}")).unwrap_or("–".into()), p.unit)).collect();
    plot.scatter(rec, &format!("{base}/change"), &xy, &[AFTER], 4.0, &labels);
    let truth: Vec<(usize, f64)> = ps.iter().enumerate().filter_map(|(i, p)| p.truth_change.map(|t| (i, t))).collect();
    if !truth.is_empty() {
        let xy: Vec<[f64; 2]> = truth.iter().map(|(i, t)| [*i as f64, *t]).collect();
        let labels: Vec<String> = truth.iter().map(|(i, t)| format!("{}: truth-equivalent {:+.5} {}", ps[*i].name, t, ps[*i].unit)).collect();
        plot.scatter(rec, &format!("{base}/truth"), &xy, &[TRUTH], 3.0, &labels);
    }
}

/// Recording of a calibration. Static: the calibrated arm at row 1, the tool points of every row
/// coloured by the residual before and after (side by side, own colour scales; test rows larger),
/// histograms, the numbers, and each parameter group's final change with ±1σ and the
/// truth-equivalent value. Timeline `iteration` (0 = start): RMS and cost, parameter changes.
pub fn record_calibration(r: &twincal::calib::run::CalibResult, f: &CalibFigures, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    rec.set_static(true);
    let residuals = f.residuals();
    let (meas, first) = (f.measurement, &residuals[0]);
    let doc = calibration_summary(r, f, first);
    rec.static_text("docs/summary", &doc);
    let field = Field { arm: f.arm.as_ref(), instrument: &f.instrument, tools: &f.tool_mm, residuals: &residuals, train: &f.train };
    before_after(&mut rec, &field, ["before", "after"]);

    // Final change of each parameter group with ±1σ and the truth-equivalent change.
    for g in Group::ALL {
        final_changes(&mut rec, f, g);
    }
    rec.series_style("convergence/rms/train", "train RMS (mm)", PALETTE[0], false, 2.0);
    rec.series_style("convergence/rms/test", "test RMS (mm)", PALETTE[1], false, 2.0);
    rec.series_style("convergence/cost", "½Σr² train (mm²)", PALETTE[2], false, 2.0);
    for (i, p) in f.params.iter().enumerate() {
        rec.series_style(&format!("params/{}/{}", p.group.name(), p.name), &format!("{} ({})", p.name, p.unit), PALETTE[i % PALETTE.len()], false, 1.5);
    }
    rec.set_static(false);

    let c = &f.convergence;
    for it in 0..c.train_rms_mm.len() {
        rec.set_time_index("iteration", it as i64);
        rec.scalar("convergence/rms/train", c.train_rms_mm[it]);
        if let Some(t) = &c.test_rms_mm {
            rec.scalar("convergence/rms/test", t[it]);
        }
        rec.scalar("convergence/cost", c.cost_mm2[it]);
        for p in &f.params {
            if let Some(v) = p.history.get(it) {
                rec.scalar(&format!("params/{}/{}", p.group.name(), p.name), *v);
            }
        }
    }

    let q = colour_quantity(first);
    let [wb, wa] = world_pair([&format!("Before calibration: {q} (mm)"), &format!("After calibration: {q} (mm), own scale")]);
    let finals: Vec<Layout> = Group::ALL.iter().map(|g| Layout::plot(&format!("{} change ±1σ", g.title(meas)), &format!("/final/{}", g.name()))).collect();
    let mut series = vec![
        Layout::view(K::TimeSeries, "RMS residual (mm) per iteration", "/convergence/rms"),
        Layout::view(K::TimeSeries, "Cost ½Σr² (mm²) per iteration", "/convergence/cost"),
    ];
    series.extend(Group::ALL.iter().map(|g| Layout::view(K::TimeSeries, &format!("{} change per iteration", g.title(meas)), &format!("/params/{}", g.name()))));
    rec.layout(Blueprint {
        root: Layout::Vertical(
            vec![
                Layout::Horizontal(vec![wb, wa, Layout::view(K::Text, "Numbers", "/docs")], vec![2.0, 2.0, 1.2]),
                Layout::Horizontal(
                    vec![
                        Layout::Vertical(vec![histogram_views(&residuals, "before", "before"), histogram_views(&residuals, "after", "after")], vec![]),
                        Layout::Tabs(series),
                        Layout::Grid(finals, 4),
                    ],
                    vec![1.0, 1.3, 2.2],
                ),
            ],
            vec![1.4, 1.0],
        ),
        timeline: Some("iteration".into()),
        at_end: true,
    });
    rec.finish()
}

/// The summary text of a diagnosis's recording: the verdict, the causes and what the plots show.
fn diagnosis_summary(d: &twincal::diagnose::Diagnosis, f: &DiagnosisFigures, first: &Residual) -> String {
    let mut doc = format!(
        "## {}\n\nVerdict: **{}**. {} rows, {} outliers kept out. Noise floor {:.4} mm ({}). Held-out RMSE: geometric {:.4} mm, final {:.4} mm.\n\n",
        f.title,
        d.verdict,
        d.rows,
        d.outliers.len(),
        d.noise_floor_mm,
        d.noise_floor_source,
        d.baseline.heldout_rmse_mm,
        d.final_heldout_rmse_mm
    );
    if d.causes.is_empty() {
        doc.push_str("No effect improves the held-out fit significantly.\n");
    } else {
        doc.push_str("| cause | size ± 1σ | held-out RMSE (mm) |\n|---|---:|---|\n");
        for c in &d.causes {
            doc.push_str(&format!(
                "| {}{} | {:.4} ± {:.4} {} | {:.4} → {:.4} |\n",
                c.cause,
                c.joint.map(|j| format!(" j{j}")).unwrap_or_default(),
                c.magnitude,
                c.uncertainty,
                c.unit,
                c.heldout_rmse_before_mm,
                c.heldout_rmse_after_mm
            ));
        }
    }
    let meas = f.measurement;
    let q = colour_quantity(first);
    let (dim, cols) = (meas.dim(), meas.def().columns());
    if dim == 1 {
        doc.push_str(&format!(
            "\nEvidence plots: residual (mm) against the length change each cause predicts; grey without the cause, blue with it. \
             3D: |residual| without the causes (0–{:.3} mm) and with them (0–{:.3} mm), own colour scales; hover a point for its values.",
            max_abs(&first.before_mm),
            max_abs(&first.after_mm)
        ));
    } else {
        doc.push_str(&format!(
            "\nThe rows read a {} ({}): every RMSE is per coordinate value. Evidence plots: residual (mm) against the change each cause predicts, one point per coordinate value; grey without the cause, blue with it. \
             3D: position error {q} without the causes (0–{:.3} mm) and with them (0–{:.3} mm), own colour scales; hover a point for its values.",
            meas.def().describe(),
            cols.join(", "),
            max_abs(&first.before_mm),
            max_abs(&first.after_mm)
        ));
    }
    doc
}

/// Cause `k`'s evidence plot: the residual against the change the cause predicts, without and
/// with it.
fn cause_evidence(rec: &mut Recorder, k: usize, c: &twincal::report::CauseEvidence, x_label: &str, meas: twincal::measurement::Measurement) {
    let (dim, cols) = (meas.dim(), meas.def().columns());
    let x = padded_range(c.contribution_mm.iter().copied(), 0.05).unwrap_or((-1.0, 1.0));
    let y = padded_range(c.without_mm.iter().chain(&c.with_mm).copied(), 0.05).unwrap_or((-1.0, 1.0));
    let plot = Plot::new(&c.title.chars().take(60).collect::<String>(), x_label, x, "residual (mm)", y);
    let base = format!("evidence/cause_{}", k + 1);
    plot.frame(rec, &base);
    for (name, res, color) in [("without", &c.without_mm, BEFORE), ("with", &c.with_mm, AFTER)] {
        let xy: Vec<[f64; 2]> = c.contribution_mm.iter().zip(res.iter()).map(|(x, y)| [*x, *y]).collect();
        let labels: Vec<String> = xy
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let value = if dim == 1 { String::new() } else { format!(" {}", cols.get(i % dim).copied().unwrap_or("?")) };
                format!("row {}{value}: predicted change {:+.4} mm, residual {name} the cause {:+.4} mm", i / dim + 1, p[0], p[1])
            })
            .collect();
        plot.scatter(rec, &format!("{base}/{name}"), &xy, &[color], 2.0, &labels);
    }
}

/// Recording of a diagnosis. Static: per cause, the residual against the length change that
/// cause predicts, without and with it; the residual field without the causes and with them
/// (side by side, own colour scales), histograms, the summary. Timeline `step`: held-out RMSE
/// after each selection step (0 = geometric model).
pub fn record_diagnosis(d: &twincal::diagnose::Diagnosis, f: &DiagnosisFigures, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    rec.set_static(true);
    let residuals = f.residuals();
    let (meas, first) = (f.measurement, &residuals[0]);
    let q = colour_quantity(first);
    let (dim, cols) = (meas.dim(), meas.def().columns());
    let x_label = if dim == 1 { "length change the cause predicts (mm)".to_string() } else { format!("change of {} the cause predicts (mm)", cols.join(", ")) };
    let doc = diagnosis_summary(d, f, first);
    rec.static_text("docs/summary", &doc);
    let train = vec![true; first.after_mm.len()];
    let field = Field { arm: f.arm.as_ref(), instrument: &f.instrument, tools: &f.tool_mm, residuals: &residuals, train: &train };
    before_after(&mut rec, &field, ["without causes", "with causes"]);
    for (k, c) in f.causes.iter().enumerate() {
        cause_evidence(&mut rec, k, c, &x_label, meas);
    }
    rec.series_style("steps/heldout_rmse_mm", "held-out RMSE (mm)", PALETTE[0], false, 2.0);
    rec.set_static(false);
    for (k, v) in f.heldout_rmse_mm.iter().enumerate() {
        rec.set_time_index("step", k as i64);
        rec.scalar("steps/heldout_rmse_mm", *v);
    }
    let [wb, wa] = world_pair([&format!("Without the causes: {q} (mm)"), &format!("With the causes: {q} (mm), own scale")]);
    let evidence: Vec<Layout> = f
        .causes
        .iter()
        .enumerate()
        .map(|(k, c)| Layout::plot(&format!("Cause {}: {}", k + 1, c.title.split(':').next().unwrap_or("")), &format!("/evidence/cause_{}", k + 1)))
        .collect();
    rec.layout(Blueprint {
        root: Layout::Vertical(
            vec![
                Layout::Horizontal(vec![wb, wa, Layout::view(K::Text, "Diagnosis", "/docs")], vec![2.0, 2.0, 1.2]),
                Layout::Horizontal(
                    vec![
                        Layout::Grid(evidence, 2),
                        Layout::Vertical(
                            vec![histogram_views(&residuals, "before", "without the causes"), histogram_views(&residuals, "after", "with the causes")],
                            vec![],
                        ),
                        Layout::view(K::TimeSeries, "Held-out RMSE (mm) per step", "/steps"),
                    ],
                    vec![2.2, 1.0, 1.0],
                ),
            ],
            vec![1.4, 1.0],
        ),
        timeline: Some("step".into()),
        at_end: true,
    });
    rec.finish()
}

/// One calibration of a comparison: method, seed, test RMSE, test MAX (mm).
pub struct CompareRow<'a> {
    pub method: &'a str,
    pub seed: u64,
    pub test_rmse_mm: f64,
    pub test_max_mm: f64,
}

/// Recording of `compare`: the accuracy table, and per method the spread over seeds of the test
/// RMSE and test MAX (every seed a point, mean ± 1 standard deviation as a bar). Static.
pub fn record_comparison(table_markdown: &str, methods: &[String], rows: &[CompareRow], outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    rec.set_static(true);
    rec.static_text("docs/table", table_markdown);
    let seeds = rows.iter().map(|r| r.seed).max().unwrap_or(0) + 1;
    for (what, name, pick) in [("test_rmse", "Test RMSE (mm) per seed", 0), ("test_max", "Test MAX (mm) per seed", 1)] {
        let val = |r: &CompareRow| if pick == 0 { r.test_rmse_mm } else { r.test_max_mm };
        let Some(y) = padded_range(rows.iter().map(val), 0.15) else { continue };
        let plot = Plot::categories(name, methods, "mm", y);
        let base = format!("spread/{what}");
        plot.frame(&mut rec, &base);
        let mut xy = Vec::new();
        let mut colors = Vec::new();
        let mut labels = Vec::new();
        let mut bars = Vec::new();
        for (i, m) in methods.iter().enumerate() {
            let v: Vec<&CompareRow> = rows.iter().filter(|r| r.method == m).collect();
            for r in &v {
                // Seeds spread across the method's column so equal values stay visible.
                xy.push([i as f64 - 0.3 + 0.6 * (r.seed as f64 + 0.5) / seeds as f64, val(r)]);
                colors.push(PALETTE[i % PALETTE.len()]);
                labels.push(format!("{m}, seed {}: {:.4} mm", r.seed, val(r)));
            }
            let (mean, sd) = twincal::stats::mean_std(&v.iter().map(|r| val(r)).collect::<Vec<_>>());
            if mean.is_finite() {
                bars.push((i as f64 + 0.36, mean - sd.max(0.0), mean + sd.max(0.0)));
            }
        }
        plot.scatter(&mut rec, &format!("{base}/seeds"), &xy, &colors, 3.0, &labels);
        plot.bars(&mut rec, &format!("{base}/mean_sd"), &bars, HIGHLIGHT, 3.0);
    }
    rec.set_static(false);
    rec.layout(Blueprint {
        root: Layout::Vertical(
            vec![
                Layout::view(K::Text, "Accuracy table", "/docs"),
                Layout::Horizontal(
                    vec![
                        Layout::plot("Test RMSE per seed (mm); bar = mean ± 1 sd", "/spread/test_rmse"),
                        Layout::plot("Test MAX per seed (mm); bar = mean ± 1 sd", "/spread/test_max"),
                    ],
                    vec![],
                ),
            ],
            vec![1.0, 1.5],
        ),
        timeline: None,
        at_end: false,
    });
    rec.finish()
}

/// Recording of a replay (`twincal replay --rrd`). Static: the twin's instrument, the tool
/// points of every replayed row coloured by the twin's own noise and by measured − twin (side
/// by side, own colour scales; judged rows larger), their histograms, and the numbers.
pub fn record_replay(f: &twincal::report::ReplayFigures, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    rec.set_static(true);
    let mut doc = format!("## {}\n\n{}\n\n| rows | RMSE | STD | MAX |\n|---|---:|---:|---:|\n", f.title, f.judged_on);
    for (label, st) in &f.stats {
        doc.push_str(&stats_line(label, st.as_ref()));
    }
    doc.push_str(&format!(
        "\n{}\n\nColour = the twin's own noise (left) and measured − twin (right), own scale per side. Large points: judged rows.",
        f.ks_line
    ));
    rec.static_text("docs/summary", &doc);
    let residuals = Residual::of(f.measurement, &f.noise_mm, &f.residual_mm);
    let train: Vec<bool> = f.judged.iter().map(|j| !j).collect();
    let names = ["the twin's noise", "measured − twin"];
    let field = Field { arm: None, instrument: &f.instrument, tools: &f.tools_mm, residuals: &residuals, train: &train };
    before_after(&mut rec, &field, names);
    let q = colour_quantity(&residuals[0]);
    let [wb, wa] = world_pair([&format!("The twin's own noise: {q} (mm)"), &format!("Measured − twin: {q} (mm), own scale")]);
    rec.layout(Blueprint {
        root: Layout::Vertical(
            vec![
                Layout::Horizontal(vec![wb, wa, Layout::view(K::Text, "Numbers", "/docs")], vec![2.0, 2.0, 1.2]),
                Layout::Horizontal(vec![histogram_views(&residuals, "before", names[0]), histogram_views(&residuals, "after", names[1])], vec![]),
            ],
            vec![1.4, 1.0],
        ),
        timeline: None,
        at_end: true,
    });
    rec.finish()
}
