//! One self-contained HTML page per calibration or diagnosis (`--report FILE.html`): tables and
//! inline SVG plots, no scripts and no external resources, so it opens offline in any browser
//! and prints as it shows.

use super::artifact::ArtifactFigure;
use super::histogram;
use super::svg::{error_bars, esc, histograms, plot, strips, Series};
use super::verdict::Verdict;
use super::{max_abs, CalibFigures, DiagnosisFigures, Feature, Group, Residual};
use crate::calib::pipeline::CalibResult;
use crate::measurement::Measurement;
use crate::stats::metrics::ErrorStats;
use std::fmt::Write as _;

const BEFORE: &str = "#9a9a9a";
const TRAIN: &str = "#1f77b4";
const TEST: &str = "#ff7f0e";

fn head(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>\
         body{{font-family:sans-serif;max-width:1120px;margin:1.5em auto;padding:0 1em;color:#222}}\
         table{{border-collapse:collapse;margin:.5em 0 1.2em}}td,th{{border:1px solid #ccc;padding:3px 8px;text-align:right}}\
         th{{background:#f2f2f2}}td:first-child,th:first-child{{text-align:left}}.figs{{display:flex;flex-wrap:wrap;gap:8px}}\
         .pass{{color:#0a7a28;font-weight:bold}}.fail{{color:#b00020;font-weight:bold}}.note{{color:#555;font-size:90%}}\
         svg{{border:1px solid #eee}}</style></head><body>\n<h1>{}</h1>\n",
        esc(title),
        esc(title)
    )
}

fn verdict_html(v: Option<&Verdict>) -> String {
    let Some(v) = v else {
        return "<h2>Verdict</h2><p class=\"note\">No accuracy limits were given (--max-test-rmse-mm, --max-test-max-mm), so there is no pass/fail verdict.</p>\n".into();
    };
    let mut s = format!(
        "<h2>Verdict: <span class=\"{}\">{}</span></h2>\n<table><tr><th>check</th><th>limit (mm)</th><th>value (mm)</th><th>result</th><th>source</th></tr>",
        if v.pass { "pass" } else { "fail" },
        if v.pass { "PASS" } else { "FAIL" }
    );
    for c in &v.checks {
        let _ = write!(
            s,
            "<tr><td>{}</td><td>{:.4}</td><td>{}</td><td class=\"{}\">{}</td><td>{}</td></tr>",
            esc(&c.name),
            c.limit,
            c.value.map(|v| format!("{v:.4}")).unwrap_or_else(|| "–".into()),
            if c.pass { "pass" } else { "fail" },
            if c.pass { "pass" } else { "fail" },
            esc(&c.source)
        );
    }
    s.push_str("</table>\n");
    s
}

fn stats_row(label: &str, s: Option<&ErrorStats>) -> String {
    match s {
        Some(s) => format!("<tr><td>{label}</td><td>{}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:+.4}</td></tr>", s.n, s.rmse, s.std, s.max, s.mean),
        None => format!("<tr><td>{label}</td><td colspan=\"5\">no rows</td></tr>"),
    }
}

/// Residual `res` against each feature: before (grey) and after, train and test told apart.
fn feature_plots(out: &mut String, features: &[Feature], res: &Residual, train: &[bool], [before_name, after_name]: [&str; 2]) {
    let (before, after) = (&res.before_mm[..], &res.after_mm[..]);
    let ymax = max_abs(before).max(max_abs(after)) * 1.08;
    let title = res.title();
    out.push_str("<div class=\"figs\">");
    for f in features {
        let pick = |res: &[f64], want: Option<bool>| -> Vec<[f64; 2]> {
            f.values.iter().zip(res).enumerate().filter(|(i, _)| want.is_none_or(|w| train[*i] == w)).map(|(_, (x, y))| [*x, *y]).collect()
        };
        let mut series = vec![Series { name: before_name.into(), points: pick(before, None), color: BEFORE.into(), line: false, radius: 1.6 }];
        if train.iter().all(|t| *t) {
            series.push(Series { name: after_name.into(), points: pick(after, None), color: TRAIN.into(), line: false, radius: 1.8 });
        } else {
            series.push(Series { name: format!("{after_name}, train"), points: pick(after, Some(true)), color: TRAIN.into(), line: false, radius: 1.8 });
            series.push(Series { name: format!("{after_name}, test"), points: pick(after, Some(false)), color: TEST.into(), line: false, radius: 2.2 });
        }
        out.push_str(&plot(&format!("{title} vs {}", f.name), &f.label, &res.axis(), &series, Some(res.range(ymax))));
    }
    out.push_str("</div>\n");
}

/// Histograms of `res` before and after, each over its own range.
fn histogram_pair(res: &Residual, [before_name, after_name]: [&str; 2]) -> String {
    let (mut out, bins) = (String::from("<div class=\"figs\">"), 30);
    for (name, values, color) in [(before_name, &res.before_mm, BEFORE), (after_name, &res.after_mm, TRAIN)] {
        let (lo, hi) = res.range(max_abs(values));
        let (edges, counts) = histogram(values, bins, lo, hi);
        out.push_str(&histograms(&format!("{} (own range)", res.histogram_title(name)), &res.axis(), &[(name.to_string(), color.to_string(), edges, counts)]));
    }
    out.push_str("</div>\n");
    out
}

/// What the feature plots plot against, for their section titles.
fn against(m: Measurement) -> String {
    if m.dim() == 1 {
        "joint angles, length, time and temperature".into()
    } else {
        format!("joint angles, the measured {}, time and temperature", m.def().columns().join(", "))
    }
}

/// The residual figures of every quantity: the histograms, then each against the features.
fn residual_sections(s: &mut String, m: Measurement, residuals: &[Residual], features: &[Feature], train: &[bool], names: [&str; 2]) {
    s.push_str("<h2>Residual distributions</h2>\n");
    for res in residuals {
        s.push_str(&histogram_pair(res, names));
    }
    for res in residuals {
        let _ = writeln!(s, "<h2>{} against {}</h2>", esc(&res.title()), esc(&against(m)));
        feature_plots(s, features, res, train, names);
    }
}

/// For a reading of several values: the position error |Δp| and each value's RMS, per set of
/// rows, before and after.
fn per_row_table(residuals: &[Residual], sets: &[(&str, Vec<bool>)]) -> String {
    let mut s = String::from("<table><tr><th>rows</th><th>n</th>");
    for res in residuals {
        if res.distance {
            let _ = write!(s, "<th>RMS {0}</th><th>mean {0}</th><th>MAX {0}</th>", esc(&res.label));
        } else {
            let _ = write!(s, "<th>RMS {}</th>", esc(&res.label));
        }
    }
    s.push_str("</tr>");
    for (name, rows) in sets {
        for (side, pick) in [("before", 0), ("after", 1)] {
            let n = rows.iter().filter(|r| **r).count();
            let _ = write!(s, "<tr><td>{name}, {side}</td><td>{n}</td>");
            for res in residuals {
                let values: Vec<f64> = if pick == 0 { &res.before_mm } else { &res.after_mm }.iter().zip(rows).filter(|(_, r)| **r).map(|(v, _)| *v).collect();
                if n == 0 {
                    s.push_str(if res.distance { "<td>–</td><td>–</td><td>–</td>" } else { "<td>–</td>" });
                    continue;
                }
                let st = ErrorStats::of(&values);
                if res.distance {
                    let _ = write!(s, "<td>{:.4}</td><td>{:.4}</td><td>{:.4}</td>", st.rmse, st.mean, st.max);
                } else {
                    let _ = write!(s, "<td>{:.4}</td>", st.rmse);
                }
            }
            s.push_str("</tr>");
        }
    }
    s.push_str("</table>\n");
    s
}

/// Colours of an artifact's placements, in turn.
const PLACEMENTS: [&str; 6] = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2"];

/// The artifact's section: the target on the flange, each socket (face) with its rows'
/// residuals after the fit, the stated spacings against the fitted ones, and what the rows
/// cannot see.
fn artifact_section(s: &mut String, a: &ArtifactFigure) {
    let (feature, target) = a.words();
    let t = a.target_mm;
    let _ = writeln!(
        s,
        "<h2>The artifact: {} {feature}s</h2><p>The {target}'s centre on the flange as fitted: ({:.3}, {:.3}, {:.3}) mm.</p>",
        a.features.len(),
        t[0],
        t[1],
        t[2]
    );
    let place = if a.feature == crate::measurement::FeatureKind::Socket { "centre (mm)" } else { "normal" };
    let _ = write!(s, "<table><tr><th>{feature}</th><th>rows</th><th>{place}</th><th>scatter of the fit's rows (mm)</th><th>largest, every row (µm)</th></tr>");
    for f in &a.features {
        let (v, d) = match f.normal {
            Some(n) => (n, 4),
            None => (f.at_mm, 3),
        };
        let largest = f.after_um.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let _ = write!(
            s,
            "<tr><td>{}</td><td>{}</td><td>({:.d$}, {:.d$}, {:.d$})</td><td>{:.4}</td><td>{:.1}</td></tr>",
            esc(&f.label),
            f.rows.len(),
            v[0],
            v[1],
            v[2],
            f.scatter_mm,
            largest
        );
    }
    s.push_str("</table>\n");
    if !a.spacings.is_empty() {
        let what = if a.feature == crate::measurement::FeatureKind::Socket { "spacing" } else { "step" };
        let _ = write!(s, "<table><tr><th>{what}</th><th>stated (mm)</th><th>fitted (mm)</th><th>fitted − stated (µm)</th></tr>");
        for (i, j, stated, fitted) in &a.spacings {
            let _ = write!(
                s,
                "<tr><td>{} – {}</td><td>{stated:.4}</td><td>{fitted:.4}</td><td>{:+.1}</td></tr>",
                esc(&a.features[*i].label),
                esc(&a.features[*j].label),
                1e3 * (fitted - stated)
            );
        }
        s.push_str("</table>\n");
    }
    let groups: Vec<(String, Vec<f64>)> = a.features.iter().map(|f| (f.label.clone(), f.after_um.clone())).collect();
    let colors: Vec<String> = a.placement_numbers().iter().map(|k| PLACEMENTS[k % PLACEMENTS.len()].to_string()).collect();
    s.push_str("<div class=\"figs\">");
    s.push_str(&strips(&format!("Every row at its {feature} after the fit (colour: placement)"), a.residual_axis(), &groups, &colors));
    s.push_str("</div>\n");
    if !a.cannot_see.is_empty() {
        s.push_str("<p>What these rows cannot see:</p><ul>");
        for c in &a.cannot_see {
            let _ = write!(s, "<li>{}</li>", esc(c));
        }
        s.push_str("</ul>\n");
    }
}

/// The calibration page.
pub fn calibration_page(r: &CalibResult, f: &CalibFigures, verdict: Option<&Verdict>) -> String {
    let mut s = head(&format!("twincal calibration: {}", f.title));
    let m = &r.evaluation.metrics;
    let _ = writeln!(
        s,
        "<p>{} training rows, {} test rows; {} iterations, {} ({}), {:.2} s. twincal {}.</p>",
        r.provenance.n_train,
        r.provenance.n_test,
        r.solve.iterations,
        if r.solve.converged { "converged" } else { "did not converge" },
        esc(&r.solve.stop_reason),
        r.provenance.wall_time_s,
        esc(&r.provenance.twincal_version)
    );
    s.push_str(&verdict_html(verdict));
    let meas = f.measurement;
    let residuals = f.residuals();
    if meas.dim() == 1 {
        s.push_str("<h2>Residuals (measured − predicted cable length, mm)</h2>");
    } else {
        let _ = write!(s, "<h2>Residuals per coordinate (measured − predicted {}, mm; every value of every row)</h2>", esc(&meas.def().columns().join(", ")));
    }
    s.push_str("<table><tr><th>rows</th><th>n</th><th>RMSE</th><th>STD</th><th>MAX |r|</th><th>mean</th></tr>");
    s.push_str(&stats_row("train, before", Some(&m.train_before)));
    s.push_str(&stats_row("train, after", Some(&m.train_after)));
    s.push_str(&stats_row("test, before", m.test_before.as_ref()));
    s.push_str(&stats_row("test, after", m.test_after.as_ref()));
    s.push_str("</table>\n");
    if meas.dim() > 1 {
        let _ = write!(s, "<h2>Position error per row (mm)</h2><p class=\"note\">The rows read a {}: |Δp| is the distance between the measured and the predicted point; the RMS of each coordinate is over the rows.</p>", esc(meas.def().describe()));
        s.push_str(&per_row_table(&residuals, &[("train", f.train.clone()), ("test", f.test.clone())]));
    }
    let _ = write!(s, "<p class=\"note\">Noise estimate from the data: {:.4} mm.", r.solve.noise_estimate_mm);
    if let Some(t) = &r.evaluation.truth_comparison {
        let _ = write!(
            s,
            " Truth file: {}/{} identifiable parameters within 3σ of their truth-equivalent values (max |z| = {:.2}); sensor noise floor {:.4} mm.",
            t.within_3_sigma, t.identifiable, t.max_abs_z, t.noise_floor_mm
        );
    }
    s.push_str("</p>\n");
    for w in &r.warnings {
        let _ = writeln!(s, "<p class=\"fail\">Warning: {}</p>", esc(w));
    }
    if let Some(a) = &f.artifact {
        artifact_section(&mut s, a);
    }
    residual_sections(&mut s, meas, &residuals, &f.features, &f.train, ["before", "after"]);
    s.push_str("<h2>Convergence</h2><div class=\"figs\">");
    let it = |v: &[f64]| -> Vec<[f64; 2]> { v.iter().enumerate().map(|(i, y)| [i as f64, *y]).collect() };
    let mut conv = vec![Series { name: "train RMS".into(), points: it(&f.convergence.train_rms_mm), color: TRAIN.into(), line: true, radius: 2.0 }];
    if let Some(t) = &f.convergence.test_rms_mm {
        conv.push(Series { name: "test RMS".into(), points: it(t), color: TEST.into(), line: true, radius: 2.0 });
    }
    let per_value = if meas.dim() == 1 { "" } else { " per coordinate" };
    s.push_str(&plot(&format!("RMS residual{per_value} per iteration (0 = start)"), "iteration", "RMS (mm)", &conv, None));
    let cost = [Series { name: "½Σr²".into(), points: it(&f.convergence.cost_mm2), color: TRAIN.into(), line: true, radius: 2.0 }];
    s.push_str(&plot("Cost per iteration (training rows)", "iteration", "cost (mm²)", &cost, None));
    s.push_str("</div>\n<h2>Parameters: change from the start, ±1σ</h2><div class=\"figs\">");
    for g in Group::ALL {
        let items: Vec<(String, f64, Option<f64>, Option<f64>)> =
            f.params.iter().filter(|p| p.group == g).map(|p| (p.name.clone(), p.change, p.sigma, p.truth_change)).collect();
        if !items.is_empty() {
            s.push_str(&error_bars(g.title(meas), "change from start", &items));
        }
    }
    s.push_str(
        "</div>\n<table><tr><th>parameter</th><th>unit</th><th>start</th><th>calibrated</th><th>±1σ</th><th>truth-equivalent</th><th>z</th><th>fixed</th></tr>",
    );
    for p in &r.parameters {
        let o = |v: Option<f64>| v.map(|v| format!("{v:.5}")).unwrap_or_else(|| "–".into());
        let _ = write!(
            s,
            "<tr><td>{}</td><td>{}</td><td>{:.5}</td><td>{:.5}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&p.name),
            esc(&p.unit),
            p.nominal,
            p.value,
            o(p.std_uncertainty),
            o(p.truth),
            p.z.map(|z| format!("{z:+.2}")).unwrap_or_else(|| "–".into()),
            if p.fixed { "fixed (not identifiable)" } else { "" }
        );
    }
    s.push_str("</table>\n</body></html>\n");
    s
}

/// The diagnosis's causes as a table (or the sentence that none improves the fit).
fn causes_table(s: &mut String, d: &crate::diagnose::Diagnosis) {
    s.push_str("<h2>Causes</h2>");
    if d.causes.is_empty() {
        s.push_str("<p>No effect improves the held-out fit significantly: the geometric model explains the data.</p>\n");
    } else {
        s.push_str("<table><tr><th>cause</th><th>joint</th><th>quantity</th><th>size</th><th>±1σ</th><th>unit</th><th>held-out RMSE before → after (mm)</th><th>forward in time before → after (mm)</th><th>p</th></tr>");
        for c in &d.causes {
            let forward = c.forward_rmse_before_mm.zip(c.forward_rmse_after_mm).map_or("–".into(), |(b, a)| format!("{b:.4} → {a:.4}"));
            let _ = write!(
                s,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>{:.4}</td><td>{}</td><td>{:.4} → {:.4}</td><td>{forward}</td><td>{:.1e}</td></tr>",
                esc(c.cause.name()),
                c.joint.map(|j| j.to_string()).unwrap_or_else(|| "–".into()),
                esc(&c.quantity),
                c.magnitude,
                c.uncertainty,
                esc(&c.unit),
                c.heldout_rmse_before_mm,
                c.heldout_rmse_after_mm,
                c.p_value
            );
        }
        s.push_str("</table>\n");
    }
    remainder_section(s, d);
}

/// What remains after the causes: white or structured, each regressor's test, the apparent noise
/// beside what the instrument states.
fn remainder_section(s: &mut String, d: &crate::diagnose::Diagnosis) {
    let Some(r) = &d.remainder else { return };
    let _ = writeln!(s, "<h2>What remains</h2><p>{}</p>", esc(&r.summary()));
    if let Some(u) = &d.unexplained {
        let _ = writeln!(s, "<p class=\"note\"><b>Unexplained:</b> {}</p>", esc(u));
    }
    s.push_str("<table><tr><th>binned by</th><th>value it shows most in</th><th>share of its mean square</th><th>p (corrected)</th><th>structure</th></tr>");
    for t in &r.tests {
        let _ = write!(
            s,
            "<tr><td>{}</td><td>{}</td><td>{:.1} %</td><td>{:.1e}</td><td>{}</td></tr>",
            esc(&t.against),
            esc(&t.value),
            100.0 * t.share,
            t.p_value,
            if t.structured { "yes" } else { "–" }
        );
    }
    s.push_str("</table>\n");
}

/// The diagnosis page.
pub fn diagnosis_page(d: &crate::diagnose::Diagnosis, f: &DiagnosisFigures, verdict: Option<&Verdict>) -> String {
    let mut s = head(&format!("twincal {}", f.title));
    let _ = writeln!(
        s,
        "<p>Verdict of the diagnosis: <b>{}</b>. {} rows, {} outliers kept out. Noise floor {:.4} mm ({}). Geometric model held-out RMSE {:.4} mm, final {:.4} mm ({}). Judged on {} folds: {}. {:.1} s.</p>",
        esc(&d.verdict),
        d.rows,
        d.outliers.len(),
        d.noise_floor_mm,
        esc(&d.noise_floor_source),
        d.baseline.heldout_rmse_mm,
        d.final_heldout_rmse_mm,
        esc(&d.against_floor()),
        esc(&d.judged_on),
        esc(&d.judged_on_reason),
        d.seconds
    );
    let meas = f.measurement;
    if meas.dim() > 1 {
        let _ = writeln!(
            s,
            "<p class=\"note\">The rows read a {} ({}): every RMSE is per coordinate value; the figures also show each row's position error |Δp|.</p>",
            esc(meas.def().describe()),
            esc(&meas.def().columns().join(", "))
        );
    }
    s.push_str(&verdict_html(verdict));
    if !d.reading_steps.is_empty() {
        s.push_str("<h2>Reading steps</h2><p>Stretches of the acquisition whose readings sit one constant offset off (the reading jumped and stayed): corrected by the offset and kept.</p><table><tr><th>rows</th><th>offset (mm)</th><th>rows in the fit</th></tr>");
        for st in &d.reading_steps {
            let _ = write!(s, "<tr><td>{}–{}</td><td>{:+.3} ± {:.3}</td><td>{}</td></tr>", st.first_row, st.last_row, st.offset_mm, st.std_mm, st.rows);
        }
        s.push_str("</table>");
    }
    causes_table(&mut s, d);
    let top: Vec<String> = d.evidence.iter().take(6).map(|e| format!("{} (r = {:+.2})", esc(&e.feature), e.correlation)).collect();
    let _ = writeln!(s, "<p class=\"note\">Strongest correlations of the geometric model's residual: {}.</p>", top.join(", "));
    let x_label = if meas.dim() == 1 {
        "length change the cause predicts (mm)".to_string()
    } else {
        format!("change of {} the cause predicts (mm)", meas.def().columns().join(", "))
    };
    if !f.causes.is_empty() && meas.dim() == 1 {
        s.push_str("<h2>Evidence: residual against the length change each cause predicts</h2><p class=\"note\">Grey: residual without the cause (final model, cause removed); blue: with it. A cause that explains the data turns a slope-1 cloud into a flat one.</p><div class=\"figs\">");
    } else if !f.causes.is_empty() {
        let cols = meas.def().columns().join(", ");
        let _ = write!(
            s,
            "<h2>Evidence: residual against the change each cause predicts, per coordinate</h2><p class=\"note\">One point per coordinate value ({cols}) of every row. Grey: residual without the cause (final model, cause removed); blue: with it. A cause that explains the data turns a slope-1 cloud into a flat one.</p><div class=\"figs\">"
        );
    }
    if !f.causes.is_empty() {
        for c in &f.causes {
            let pts = |r: &[f64]| -> Vec<[f64; 2]> { c.contribution_mm.iter().zip(r).map(|(x, y)| [*x, *y]).collect() };
            let series = [
                Series { name: "without".into(), points: pts(&c.without_mm), color: BEFORE.into(), line: false, radius: 1.6 },
                Series { name: "with".into(), points: pts(&c.with_mm), color: TRAIN.into(), line: false, radius: 1.8 },
            ];
            s.push_str(&plot(&c.title.chars().take(70).collect::<String>(), &x_label, "residual (mm)", &series, None));
        }
        s.push_str("</div>\n");
    }
    let steps: Vec<[f64; 2]> = f.heldout_rmse_mm.iter().enumerate().map(|(i, v)| [i as f64, *v]).collect();
    s.push_str("<h2>Held-out RMSE per selection step</h2><div class=\"figs\">");
    s.push_str(&plot(
        "Held-out RMSE (0 = geometric model)",
        "step",
        "RMSE (mm)",
        &[Series { name: "held-out".into(), points: steps, color: TRAIN.into(), line: true, radius: 3.0 }],
        None,
    ));
    s.push_str("</div>\n");
    if let Some(a) = &f.artifact {
        artifact_section(&mut s, a);
    }
    let residuals = f.residuals();
    let all = vec![true; residuals.first().map_or(0, |r| r.after_mm.len())];
    residual_sections(&mut s, meas, &residuals, &f.features, &all, ["before", "with the causes"]);
    s.push_str("</body></html>\n");
    s
}

/// A page of `title` around `body` (HTML), in the reports' style.
pub fn page(title: &str, body: &str) -> String {
    let mut s = head(title);
    s.push_str(body);
    s.push_str("</body></html>\n");
    s
}

/// The page of a replay (`replay --report`): the summary's numbers, then the residual field
/// measured − twin beside the twin's own noise (grey), as histograms and against the joint
/// angles, the reading, time and temperature; judged rows (held out) in orange.
pub fn replay_page(f: &super::ReplayFigures) -> String {
    let mut s = head(&f.title);
    let _ = writeln!(s, "<p class=\"note\">{}</p>", esc(&f.judged_on));
    s.push_str("<table><tr><th>rows</th><th>n</th><th>RMSE</th><th>STD</th><th>MAX</th><th>mean</th></tr>");
    for (label, st) in &f.stats {
        s.push_str(&stats_row(label, st.as_ref()));
    }
    s.push_str("</table>\n");
    let _ = writeln!(s, "<p>{}</p>", esc(&f.ks_line));
    let residuals = Residual::of(f.measurement, &f.noise_mm, &f.residual_mm);
    let train: Vec<bool> = f.judged.iter().map(|j| !j).collect();
    residual_sections(&mut s, f.measurement, &residuals, &f.features, &train, ["the twin's own noise", "measured − twin"]);
    s.push_str("</body></html>\n");
    s
}
