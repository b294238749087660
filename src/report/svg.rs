//! Static SVG plots for the HTML report: scatter, line, histogram and error-bar plots with
//! real axes. Plain text, no scripts, no external resources; they print as they show.

use super::ticks::{nice_ticks, padded_range, tick_label};
use std::fmt::Write as _;

const W: f64 = 520.0;
const H: f64 = 300.0;
const ML: f64 = 62.0;
const MR: f64 = 14.0;
const MT: f64 = 30.0;
const MB: f64 = 46.0;

/// Escapes text for HTML / SVG.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// A series of a scatter or line plot.
#[derive(Clone, Debug)]
pub struct Series {
    /// Name in the legend.
    pub name: String,
    /// The points, `[x, y]` in data units.
    pub points: Vec<[f64; 2]>,
    /// CSS colour.
    pub color: String,
    /// Draw a line through the points (in order) as well as markers.
    pub line: bool,
    /// Marker radius, px (0: no markers).
    pub radius: f64,
}

struct Frame {
    x: (f64, f64),
    y: (f64, f64),
}

impl Frame {
    fn px(&self, x: f64) -> f64 {
        ML + (x - self.x.0) / (self.x.1 - self.x.0) * (W - ML - MR)
    }
    fn py(&self, y: f64) -> f64 {
        H - MB - (y - self.y.0) / (self.y.1 - self.y.0) * (H - MT - MB)
    }
    /// Axes, grid, tick labels and titles; `x_names` replaces numeric x ticks by names at 0, 1, ….
    fn draw(&self, out: &mut String, title: &str, x_label: &str, y_label: &str, x_names: Option<&[String]>) {
        let _ = write!(out, r##"<rect x="{ML}" y="{MT}" width="{}" height="{}" fill="#fff" stroke="#888"/>"##, W - ML - MR, H - MT - MB);
        let yt = nice_ticks(self.y.0, self.y.1, 5);
        for &t in &yt {
            let y = self.py(t);
            let _ = write!(
                out,
                r##"<line x1="{ML}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="{}"/><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"##,
                W - MR,
                if t == 0.0 { "#999" } else { "#e4e4e4" },
                ML - 4.0,
                y + 4.0,
                tick_label(t, &yt)
            );
        }
        match x_names {
            Some(names) => {
                // Names alternate between two rows so neighbours do not overlap.
                for (i, n) in names.iter().enumerate() {
                    let _ = write!(
                        out,
                        r##"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="9">{}</text>"##,
                        self.px(i as f64),
                        H - MB + 13.0 + 12.0 * (i % 2) as f64,
                        esc(&n.replace("joint_", "j"))
                    );
                }
            }
            None => {
                let xt = nice_ticks(self.x.0, self.x.1, 6);
                for &t in &xt {
                    let x = self.px(t);
                    let _ = write!(
                        out,
                        r##"<line x1="{x:.1}" y1="{MT}" x2="{x:.1}" y2="{:.1}" stroke="#eee"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"##,
                        H - MB,
                        H - MB + 15.0,
                        tick_label(t, &xt)
                    );
                }
                let _ = write!(out, r##"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"##, (ML + W - MR) / 2.0, H - 8.0, esc(x_label));
            }
        }
        let _ = write!(out, r##"<text x="{ML}" y="18" font-weight="bold">{}</text>"##, esc(title));
        let _ = write!(out, r##"<text transform="translate(14 {:.1}) rotate(-90)" text-anchor="middle">{}</text>"##, (MT + H - MB) / 2.0, esc(y_label));
    }
}

fn open() -> String {
    format!(r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {H}" width="{W}" height="{H}" font-family="sans-serif" font-size="11">"##)
}

fn legend(out: &mut String, series: &[(String, String)]) {
    let mut x = W - MR - 6.0;
    for (name, color) in series.iter().rev() {
        let w = 7.0 * name.chars().count() as f64 + 18.0;
        x -= w;
        let _ = write!(
            out,
            r##"<circle cx="{:.1}" cy="{:.1}" r="4" fill="{color}"/><text x="{:.1}" y="{:.1}">{}</text>"##,
            x + 5.0,
            MT - 10.0,
            x + 12.0,
            MT - 6.0,
            esc(name)
        );
    }
}

/// A scatter / line plot of `series`; `y_range` fixes the y axis (else from the data).
pub fn plot(title: &str, x_label: &str, y_label: &str, series: &[Series], y_range: Option<(f64, f64)>) -> String {
    let xs = series.iter().flat_map(|s| s.points.iter().map(|p| p[0]));
    let ys = series.iter().flat_map(|s| s.points.iter().map(|p| p[1]));
    let f = Frame { x: padded_range(xs, 0.03).unwrap_or((0.0, 1.0)), y: y_range.or_else(|| padded_range(ys, 0.08)).unwrap_or((-1.0, 1.0)) };
    let mut out = open();
    f.draw(&mut out, title, x_label, y_label, None);
    for s in series {
        let pts: Vec<(f64, f64)> =
            s.points.iter().filter(|p| p[0].is_finite() && p[1].is_finite()).map(|p| (f.px(p[0]), f.py(p[1].clamp(f.y.0, f.y.1)))).collect();
        if s.line && pts.len() > 1 {
            let d: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
            let _ = write!(out, r##"<polyline fill="none" stroke="{}" stroke-width="1.5" points="{}"/>"##, s.color, d.join(" "));
        }
        if s.radius > 0.0 {
            let _ = write!(out, r##"<g fill="{}" fill-opacity="0.75">"##, s.color);
            for (x, y) in &pts {
                let _ = write!(out, r##"<circle cx="{x:.1}" cy="{y:.1}" r="{}"/>"##, s.radius);
            }
            out.push_str("</g>");
        }
    }
    legend(&mut out, &series.iter().map(|s| (s.name.clone(), s.color.clone())).collect::<Vec<_>>());
    out.push_str("</svg>");
    out
}

/// Histograms on one x axis: `(name, colour, edges, counts)`, drawn as outlined bars.
pub fn histograms(title: &str, x_label: &str, hists: &[(String, String, Vec<f64>, Vec<f64>)]) -> String {
    let xs = hists.iter().flat_map(|h| h.2.iter().copied());
    let top = hists.iter().flat_map(|h| h.3.iter().copied()).fold(0.0f64, f64::max).max(1.0);
    let f = Frame { x: padded_range(xs, 0.0).unwrap_or((0.0, 1.0)), y: (0.0, top * 1.1) };
    let mut out = open();
    f.draw(&mut out, title, x_label, "rows per bin", None);
    for (_, color, edges, counts) in hists {
        for (i, c) in counts.iter().enumerate() {
            if *c > 0.0 {
                let (x0, x1) = (f.px(edges[i]), f.px(edges[i + 1]));
                let y = f.py(*c);
                let _ = write!(
                    out,
                    r##"<rect x="{x0:.1}" y="{y:.1}" width="{:.1}" height="{:.1}" fill="{color}" fill-opacity="0.45" stroke="{color}"/>"##,
                    (x1 - x0).max(0.5),
                    f.py(0.0) - y
                );
            }
        }
    }
    legend(&mut out, &hists.iter().map(|h| (h.0.clone(), h.1.clone())).collect::<Vec<_>>());
    out.push_str("</svg>");
    out
}

/// Parameter changes with ±1σ error bars and, where known, the truth-equivalent change.
pub fn error_bars(title: &str, y_label: &str, items: &[(String, f64, Option<f64>, Option<f64>)]) -> String {
    let ys = items.iter().flat_map(|(_, v, s, t)| [Some(v + s.unwrap_or(0.0)), Some(v - s.unwrap_or(0.0)), *t, Some(0.0)].into_iter().flatten());
    let f = Frame { x: (-0.7, items.len() as f64 - 0.3), y: padded_range(ys, 0.1).unwrap_or((-1.0, 1.0)) };
    let mut out = open();
    let names: Vec<String> = items.iter().map(|i| i.0.clone()).collect();
    f.draw(&mut out, title, "", y_label, Some(&names));
    for (i, (_, v, s, t)) in items.iter().enumerate() {
        let x = f.px(i as f64);
        if let Some(s) = s {
            let _ = write!(out, r##"<line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}" stroke="#1f77b4" stroke-width="2"/>"##, f.py(v - s), f.py(v + s));
        }
        let _ = write!(out, r##"<circle cx="{x:.1}" cy="{:.1}" r="3.5" fill="#1f77b4"/>"##, f.py(*v));
        if let Some(t) = t {
            let y = f.py(*t);
            let _ = write!(out, r##"<path d="M{:.1},{:.1}l8,8m0,-8l-8,8" stroke="#d62728" stroke-width="2"/>"##, x - 4.0, y - 4.0);
        }
    }
    let mut keys = vec![("change ±1σ".to_string(), "#1f77b4".to_string())];
    if items.iter().any(|i| i.3.is_some()) {
        keys.push(("truth-equivalent (×)".to_string(), "#d62728".to_string()));
    }
    legend(&mut out, &keys);
    out.push_str("</svg>");
    out
}

/// One strip of points per named group (a socket's or a face's rows), spread a little sideways
/// so that equal values stay apart; `colors` per group.
pub fn strips(title: &str, y_label: &str, groups: &[(String, Vec<f64>)], colors: &[String]) -> String {
    let ys = groups.iter().flat_map(|g| g.1.iter().copied()).chain([0.0]);
    let f = Frame { x: (-0.7, groups.len() as f64 - 0.3), y: padded_range(ys, 0.08).unwrap_or((-1.0, 1.0)) };
    let mut out = open();
    let names: Vec<String> = groups.iter().map(|g| g.0.clone()).collect();
    f.draw(&mut out, title, "", y_label, Some(&names));
    for (i, (_, values)) in groups.iter().enumerate() {
        let color = colors.get(i % colors.len().max(1)).map_or("#1f77b4", |c| c.as_str());
        for (k, v) in values.iter().enumerate().filter(|(_, v)| v.is_finite()) {
            // A fixed spread by the row's place (golden-ratio steps), the same on every run.
            let dx = ((k as f64 * 0.618_034).fract() - 0.5) * 0.5;
            let _ = write!(out, r##"<circle cx="{:.1}" cy="{:.1}" r="2.2" fill="{color}" fill-opacity="0.7"/>"##, f.px(i as f64 + dx), f.py(*v));
        }
    }
    out.push_str("</svg>");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plots_are_well_formed_and_escape_text() {
        let s = Series { name: "a<b".into(), points: vec![[0.0, 1.0], [1.0, f64::NAN], [2.0, -1.0]], color: "#123".into(), line: true, radius: 2.0 };
        let svg = plot("t & u", "x (mm)", "y", &[s], None);
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
        assert!(svg.contains("t &amp; u") && svg.contains("a&lt;b") && !svg.contains("a<b"));
        assert_eq!(svg.matches("<circle").count(), 2 + 1, "two finite points and a legend marker");
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        let h = histograms("h", "mm", &[("before".into(), "#999".into(), vec![0.0, 1.0, 2.0], vec![3.0, 0.0])]);
        assert_eq!(h.matches("<rect").count(), 2, "frame and one non-empty bar");
        let e = error_bars("p", "mm", &[("j1.dx".into(), 0.1, Some(0.02), Some(0.12)), ("j2.dx".into(), -0.3, None, None)]);
        assert!(e.contains("j1.dx") && e.contains("truth-equivalent") && e.matches("<path").count() == 1);
        let st = strips("s", "µm", &[("p1/A".into(), vec![1.0, 2.0, f64::NAN]), ("p1/B".into(), vec![3.0])], &["#123".into()]);
        assert!(st.contains("p1/A") && st.contains("p1/B") && st.matches("<circle").count() == 3 && !st.contains("NaN"));
    }
}
