//! Recordings of results: a calibration, a diagnosis, a comparison of methods, a replay; over
//! the drawing helpers of [`super::scenes`].

use super::plot::{padded_range, Plot};
use super::scenes::*;
use super::{Blueprint, Layout, Recorder, ViewKind as K};
use std::path::Path;
use twincal::error::Result;
use twincal::output::OutputSet;
use twincal::report::{max_abs, CalibFigures, DiagnosisFigures, Group, Residual};

/// The summary text of a calibration's recording: its metrics, the truth, what the colours say,
/// its warnings.
fn calibration_summary(r: &twincal::calib::pipeline::CalibResult, f: &CalibFigures, first: &Residual) -> String {
    let meas = f.measurement;
    let m = &r.evaluation.metrics;
    let mut doc = format!(
        "## {}\n\n{} train / {} test rows, {} iterations, {}.\n\n| residual (mm) | RMSE | STD | MAX |\n|---|---:|---:|---:|\n",
        f.title,
        r.provenance.n_train,
        r.provenance.n_test,
        r.solve.iterations,
        if r.solve.converged { "converged" } else { "**did not converge**" }
    );
    doc.push_str(&stats_line("train before", Some(&m.train_before)));
    doc.push_str(&stats_line("train after", Some(&m.train_after)));
    doc.push_str(&stats_line("test before", m.test_before.as_ref()));
    doc.push_str(&stats_line("test after", m.test_after.as_ref()));
    doc.push_str(&format!("\nNoise estimate {:.4} mm.", r.solve.noise_estimate_mm));
    if let Some(t) = &r.evaluation.truth_comparison {
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
    if let Some(a) = &f.artifact {
        doc.push_str(&crate::artifact::summary(a));
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
pub fn record_calibration(r: &twincal::calib::pipeline::CalibResult, f: &CalibFigures, outputs: &mut OutputSet, path: &Path) -> Result<()> {
    let mut rec = Recorder::staged("twincal", outputs, path)?;
    rec.set_static(true);
    let residuals = f.residuals();
    let (meas, first) = (f.measurement, &residuals[0]);
    let doc = calibration_summary(r, f, first);
    rec.static_text("docs/summary", &doc);
    let field = Field { arm: f.arm.as_ref(), instrument: &f.instrument, tools: &f.tool_mm, residuals: &residuals, train: &f.train };
    before_after(&mut rec, &field, ["before", "after"]);
    if let Some(a) = &f.artifact {
        crate::artifact::draw(&mut rec, a, f.arm.as_ref().map(|a| a.tool_mm));
    }

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
                        match &f.artifact {
                            Some(a) => Layout::Tabs([vec![crate::artifact::view(a)], series].concat()),
                            None => Layout::Tabs(series),
                        },
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
    if let Some(a) = &f.artifact {
        doc.push_str(&crate::artifact::summary(a));
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
    if let Some(a) = &f.artifact {
        crate::artifact::draw(&mut rec, a, f.arm.as_ref().map(|a| a.tool_mm));
    }
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
                        match (&f.artifact, evidence.is_empty()) {
                            (Some(a), true) => crate::artifact::view(a),
                            (Some(a), false) => Layout::Tabs(vec![Layout::Grid(evidence, 2), crate::artifact::view(a)]),
                            (None, _) => Layout::Grid(evidence, 2),
                        },
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
