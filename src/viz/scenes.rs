//! What twincal draws: scenes built from plain twincal data on top of [`super::Recorder`].

use super::{colormap, histogram, Recorder};
use crate::error::Result;
use crate::generate::Generated;
use crate::io::OutputSet;
use nalgebra::Vector3;
use std::path::Path;

fn mm(v: &Vector3<f64>) -> [f64; 3] {
    [v.x * 1e3, v.y * 1e3, v.z * 1e3]
}

/// Residual of the nominal model per row: measured length minus the length the nominal URDF
/// (no geometric errors, no effects) predicts with the scenario's sensor geometry, mm.
pub fn nominal_residuals(g: &Generated) -> Vec<f64> {
    let chain = &g.twin.chain;
    g.dataset
        .rows
        .iter()
        .map(|r| {
            let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
            r.l_mm.unwrap_or(f64::NAN) - crate::generate::nominal_length(chain, &g.twin.sensor, &q)
        })
        .collect()
}

/// Recording of a generated dataset: per pose (timeline `pose`) the arm's link frames and skeleton,
/// the cable, and all tool points so far coloured by the nominal model's length residual.
/// Staged in `outputs` as `path` (renamed into place by `outputs.commit()`).
pub fn record_dataset(g: &Generated, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    let res = nominal_residuals(g);
    let vmax = res.iter().fold(0.0f64, |m, r| m.max(r.abs())).max(1e-6);
    rec.static_text(
        "legend",
        &format!(
            "# twincal dataset `{}`\n\nUnits: millimetres, base frame, Z up.\n\n\
             * `world/arm`: link frames and skeleton of the true (simulated) arm at each pose\n\
             * `world/cable`: the draw wire from its exit point to the tool point\n\
             * `world/tool_points`: every tool point so far, coloured by |L measured − L nominal| \
             from 0 (dark) to {vmax:.3} mm (bright)\n\
             * `residuals/histogram`: nominal-model length residuals, mm\n",
            g.truth.scenario
        ),
    );
    let exit = g.twin.sensor.exit_point_mm;
    rec.points("world/cable_exit", &[exit], Some(&[[255, 80, 0, 255]]), Some(8.0), None);
    let mut tool_pts: Vec<[f64; 3]> = Vec::with_capacity(g.frames.len());
    let mut colors: Vec<[u8; 4]> = Vec::with_capacity(g.frames.len());
    for (i, frames) in g.frames.iter().enumerate() {
        rec.set_time_index("pose", i as i64);
        if let Some(t) = g.dataset.rows[i].t_s {
            rec.set_time_seconds("acquisition_time", t);
        }
        for (k, f) in frames.iter().enumerate() {
            let rot =
                [[f.rot[(0, 0)], f.rot[(0, 1)], f.rot[(0, 2)]], [f.rot[(1, 0)], f.rot[(1, 1)], f.rot[(1, 2)]], [f.rot[(2, 0)], f.rot[(2, 1)], f.rot[(2, 2)]]];
            rec.transform(&format!("world/arm/frame_{k}"), mm(&f.pos), rot);
        }
        let tool = mm(&g.truth_tool(i));
        let mut skeleton: Vec<[f64; 3]> = frames.iter().map(|f| mm(&f.pos)).collect();
        skeleton.push(tool);
        rec.line_strips("world/arm/skeleton", &[skeleton], [200, 200, 200, 255], 6.0);
        rec.line_strips("world/cable", &[vec![exit, tool]], [255, 80, 0, 255], 1.0);
        tool_pts.push(tool);
        colors.push(colormap(res[i].abs(), vmax));
        rec.points("world/tool_points", &tool_pts, Some(&colors), Some(4.0), None);
        rec.scalar("residuals/nominal_mm", res[i]);
    }
    let (edges, counts) = histogram(&res, 30, -vmax, vmax);
    rec.histogram_chart("residuals/histogram", &edges, &counts);
    rec.finish()
}

impl Generated {
    /// True tool point of dataset row `i`, m.
    pub fn truth_tool(&self, i: usize) -> Vector3<f64> {
        let p = self.truth.poses[i].tool_mm;
        Vector3::new(p[0], p[1], p[2]) * 1e-3
    }
}

/// Recording of a calibration: tool points (nominal model, tool at the calibrated tool point)
/// coloured by the residual before (`stage` 0) and after (`stage` 1) calibration, residual
/// histograms, and each parameter's convergence on the `iteration` timeline. Staged in `outputs`
/// as `path`.
pub fn record_calibration(
    r: &crate::calib::run::CalibResult,
    data: &crate::dataset::Dataset,
    opts: &crate::calib::run::CalibOptions,
    outputs: &mut OutputSet,
    path: &Path,
) -> Result<()> {
    use crate::calib::problem::LengthFit;
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    let all: Vec<usize> = (0..data.rows.len()).collect();
    let (train_idx, _) = crate::calib::run::split_rows(data, opts.test_fraction, opts.seed)?;
    let samples = crate::calib::run::samples(data, &all);
    let fit = LengthFit { model: &r.model, data: &samples };
    let x0: Vec<f64> = r.parameters.iter().enumerate().map(|(k, p)| p.nominal / r.model.kinds[k].display()).collect();
    let before = fit.residuals_mm(&x0);
    let after: Vec<f64> = data.rows.iter().zip(r.predict_rows(data)).map(|(row, p)| row.l_mm.unwrap_or(f64::NAN) - p).collect();
    let mut w = r.model.work();
    let pts: Vec<[f64; 3]> = samples.q.iter().map(|q| mm(&r.model.tool_point(&r.x, q, &mut w))).collect();
    let vmax = before.iter().chain(&after).fold(0.0f64, |m, v| m.max(v.abs())).max(1e-6);
    let train: std::collections::HashSet<usize> = train_idx.into_iter().collect();
    let labels: Vec<String> = (0..pts.len()).map(|i| format!("row {} ({})", i + 1, if train.contains(&i) { "train" } else { "test" })).collect();
    rec.static_text(
        "legend",
        &format!(
            "# twincal calibration: {} / {}\n\nTool points of every row (mm, base frame), coloured by |measured − predicted \
             cable length| from 0 to {vmax:.3} mm. Timeline `stage`: 0 = before calibration (nominal), 1 = after. \
             `calib/param/*` shows each free parameter per iteration (mm or degrees).",
            r.method.name(),
            r.model_name
        ),
    );
    let exit = [r.x[r.model.n_chain()] * 1e3, r.x[r.model.n_chain() + 1] * 1e3, r.x[r.model.n_chain() + 2] * 1e3];
    rec.points("world/cable_exit", &[exit], Some(&[[255, 80, 0, 255]]), Some(8.0), None);
    for (stage, res) in [(0i64, &before), (1, &after)] {
        rec.set_time_index("stage", stage);
        let colors: Vec<[u8; 4]> = res.iter().map(|v| colormap(v.abs(), vmax)).collect();
        rec.points("world/tool_points", &pts, Some(&colors), Some(4.0), Some(&labels));
        let (edges, counts) = histogram(res, 40, -vmax, vmax);
        rec.histogram_chart("residuals/histogram", &edges, &counts);
    }
    for (it, xs) in r.history.iter().enumerate() {
        rec.set_time_index("iteration", it as i64);
        for (k, p) in r.parameters.iter().enumerate() {
            if !p.fixed {
                if let Some(v) = xs.get(k) {
                    rec.scalar(&format!("calib/param/{}", p.name), *v);
                }
            }
        }
    }
    rec.finish()
}

/// Recording of a diagnosis: for every selection step (timeline `step`), the held-out residual
/// of each kept row against the regressor of the effect that step kept, before (grey) and after
/// (coloured) it was added, and the residual field on the tool points; the held-out RMSE per step.
pub fn record_diagnosis(
    d: &crate::diagnose::Diagnosis,
    result: &crate::calib::run::CalibResult,
    data: &crate::dataset::Dataset,
    outputs: &mut OutputSet,
    path: &Path,
) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    let ev = &d.evidence;
    let causes: Vec<String> = d.causes.iter().map(|c| format!("- {}", c.summary())).collect();
    rec.static_text(
        "legend",
        &format!(
            "# twincal diagnosis of {}\n\nVerdict: **{}**. Noise floor {:.4} mm ({}). Geometric held-out RMSE {:.4} mm, final {:.4} mm.\n\n{}\n\nStrongest residual correlations: {}.\n\nTimeline `step`: 0 = geometric model, k = after the k-th cause. `evidence/*`: held-out residual (mm, y) against the feature of each cause (x); `world/tool_points`: residual on the tool points (colour = |residual| from 0 to the geometric model's largest). `calib/diagnose/heldout_rmse_mm` per step (Calibration parameters view).",
            d.data,
            d.verdict,
            d.noise_floor_mm,
            d.noise_floor_source,
            d.baseline.heldout_rmse_mm,
            d.final_heldout_rmse_mm,
            if causes.is_empty() { "No effect improves the held-out fit significantly.".to_string() } else { causes.join("\n") },
            ev.iter().take(5).map(|e| format!("{} (r = {:+.2})", e.feature, e.correlation)).collect::<Vec<_>>().join(", ")
        ),
    );
    // Residuals of the final model and of the geometric part alone (effect parameters at their
    // starting values), on every row.
    let all: Vec<usize> = (0..data.rows.len()).collect();
    let mut samples = crate::calib::run::samples(data, &all);
    samples.inputs = crate::calib::inputs::row_inputs(data, result.torque_model.as_ref());
    let fit = crate::calib::problem::LengthFit { model: &result.model, data: &samples };
    let after = fit.residuals_mm(&result.x);
    let mut x_geo = result.x.clone();
    let first = result.model.first_effect();
    x_geo[first..].copy_from_slice(&result.model.nominal[first..]);
    let before = fit.residuals_mm(&x_geo);
    let mut w = result.model.work();
    let pts: Vec<[f64; 3]> = samples.q.iter().map(|q| mm(&result.model.tool_point(&result.x, q, &mut w))).collect();
    let vmax = before.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-6);
    for (step, res) in [(0i64, &before), (d.causes.len() as i64, &after)] {
        rec.set_time_index("step", step);
        let colors: Vec<[u8; 4]> = res.iter().map(|v| colormap(v.abs(), vmax)).collect();
        rec.points("world/tool_points", &pts, Some(&colors), Some(4.0), None);
        let (edges, counts) = histogram(res, 40, -vmax, vmax);
        rec.histogram_chart("residuals/histogram", &edges, &counts);
    }
    for (k, s) in d.steps.iter().enumerate() {
        rec.set_time_index("step", k as i64);
        rec.scalar("calib/diagnose/heldout_rmse_mm", s.heldout_rmse_before_mm);
    }
    rec.set_time_index("step", d.steps.len() as i64);
    rec.scalar("calib/diagnose/heldout_rmse_mm", d.final_heldout_rmse_mm);
    // Evidence per cause: the residual against the change of length the cause predicts per unit
    // of its parameters (its regressor), before and after.
    for (k, b) in result.model.effects.iter().enumerate() {
        let range = result.model.effect_params(k);
        let mut g = vec![0.0; result.model.n_params()];
        let feature: Vec<f64> = (0..samples.len())
            .map(|i| {
                result.model.predict_grad_with(&result.x, &samples.q[i], &samples.inputs[i], &mut w, &mut g);
                range.clone().map(|p| g[p] * result.x[p] * 1e3).sum::<f64>()
            })
            .collect();
        let name = format!("evidence/{}", b.label());
        rec.set_time_index("step", k as i64);
        let pre: Vec<[f64; 2]> = feature.iter().zip(&before).map(|(f, r)| [*f, *r]).collect();
        rec.points2d(&name, &pre, Some(&[[150, 150, 150, 255]]), Some(2.0));
        rec.set_time_index("step", k as i64 + 1);
        let post: Vec<[f64; 2]> = feature.iter().zip(&after).map(|(f, r)| [*f, *r]).collect();
        let colors: Vec<[u8; 4]> = after.iter().map(|v| colormap(v.abs(), vmax)).collect();
        rec.points2d(&name, &post, Some(&colors), Some(2.0));
    }
    rec.finish()
}
