//! Scatter plots with real axes inside a 2-D view of the viewer.
//!
//! Rerun's 2-D view keeps x and y at the same scale, which squashes a residual of ±1 mm against
//! an angle of ±165° into a line. A [`Plot`] maps both data ranges onto a fixed 400 × 250 box and
//! draws the frame, tick marks with their values and the axis titles itself, so the view reads as
//! an ordinary scatter plot; every data point carries a label with its real values, which the
//! viewer shows on hover. The tick helpers ([`nice_ticks`], [`padded_range`]) are the HTML
//! report's ([`twincal::report::ticks`]).

use super::Recorder;

/// Width of the plot box in view units.
pub const PLOT_W: f64 = 400.0;
/// Height of the plot box in view units.
pub const PLOT_H: f64 = 250.0;

/// The rectangle a 2-D view shows around a plot: the box, its tick values and axis title.
pub const BOUNDS: [f64; 4] = [-56.0, PLOT_W + 16.0, -12.0, PLOT_H + 100.0];

const AXIS: [u8; 4] = [170, 170, 170, 255];
const GRID: [u8; 4] = [70, 70, 70, 255];
const ZERO: [u8; 4] = [120, 120, 120, 255];

pub use twincal::report::ticks::{nice_ticks, padded_range, tick_label};

/// A 2-D plot: data ranges mapped onto the [`PLOT_W`] × [`PLOT_H`] box.
#[derive(Clone, Debug)]
pub struct Plot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x: (f64, f64),
    pub y: (f64, f64),
    /// Names at x = 0, 1, 2, … instead of numeric x ticks (parameters, methods).
    pub x_names: Vec<String>,
}

impl Plot {
    /// A plot of x in `x` and y in `y` (each `(lo, hi)` with `lo < hi`).
    pub fn new(title: &str, x_label: &str, x: (f64, f64), y_label: &str, y: (f64, f64)) -> Plot {
        let fix = |(lo, hi): (f64, f64)| if lo.is_finite() && hi.is_finite() && hi > lo { (lo, hi) } else { (-1.0, 1.0) };
        Plot { title: title.into(), x_label: x_label.into(), y_label: y_label.into(), x: fix(x), y: fix(y), x_names: Vec::new() }
    }

    /// A plot of named categories along x (at 0, 1, 2, …) against y in `y`.
    pub fn categories(title: &str, names: &[String], y_label: &str, y: (f64, f64)) -> Plot {
        let mut p = Plot::new(title, "", (-0.6, names.len() as f64 - 0.4), y_label, y);
        p.x_names = names.to_vec();
        p
    }

    /// View coordinates of a data point (the viewer's 2-D y axis points down).
    pub fn map(&self, x: f64, y: f64) -> [f64; 2] {
        [(x - self.x.0) / (self.x.1 - self.x.0) * PLOT_W, PLOT_H - (y - self.y.0) / (self.y.1 - self.y.0) * PLOT_H]
    }

    /// Logs the frame, grid, zero line, tick values and the x axis title under `base/frame`.
    pub fn frame(&self, rec: &mut Recorder, base: &str) {
        let xt = if self.x_names.is_empty() { nice_ticks(self.x.0, self.x.1, 6) } else { (0..self.x_names.len()).map(|i| i as f64).collect() };
        let yt = nice_ticks(self.y.0, self.y.1, 5);
        let mut grid = Vec::new();
        for &x in &xt {
            grid.push(vec![self.map(x, self.y.0), self.map(x, self.y.1)]);
        }
        for &y in &yt {
            grid.push(vec![self.map(self.x.0, y), self.map(self.x.1, y)]);
        }
        rec.line_strips2d(&format!("{base}/frame/grid"), &grid, &[GRID], 0.5);
        if self.y.0 < 0.0 && self.y.1 > 0.0 {
            rec.line_strips2d(&format!("{base}/frame/zero"), &[vec![self.map(self.x.0, 0.0), self.map(self.x.1, 0.0)]], &[ZERO], 1.0);
        }
        let frame = vec![[0.0, 0.0], [PLOT_W, 0.0], [PLOT_W, PLOT_H], [0.0, PLOT_H], [0.0, 0.0]];
        rec.line_strips2d(&format!("{base}/frame/box"), &[frame], &[AXIS], 1.0);
        let mut pos = Vec::new();
        let mut labels = Vec::new();
        for (i, &x) in xt.iter().enumerate() {
            if self.x_names.is_empty() {
                pos.push([self.map(x, self.y.0)[0], PLOT_H + 14.0]);
                labels.push(tick_label(x, &xt));
            } else {
                // Names alternate between rows so neighbours do not overlap.
                let rows = if self.x_names.len() > 8 { 3 } else { 2 };
                pos.push([self.map(x, self.y.0)[0], PLOT_H + 12.0 + 16.0 * (i % rows) as f64]);
                labels.push(self.x_names[i].clone());
            }
        }
        for &y in &yt {
            pos.push([-26.0, self.map(self.x.0, y)[1]]);
            labels.push(tick_label(y, &yt));
        }
        rec.points2d(&format!("{base}/frame/ticks"), &pos, Some(&[AXIS]), Some(0.5), Some(&labels), true);
        // The view's own title names the plot and the y quantity; the x axis gets its title here.
        if !self.x_label.is_empty() {
            rec.points2d(
                &format!("{base}/frame/x_title"),
                &[[PLOT_W / 2.0, PLOT_H + 34.0]],
                Some(&[[230, 230, 230, 255]]),
                Some(0.5),
                Some(std::slice::from_ref(&self.x_label)),
                true,
            );
        }
    }

    /// Data points at `entity` (`labels`: shown on hover); points outside the ranges are drawn
    /// on the border (clamped) so nothing silently disappears.
    pub fn scatter(&self, rec: &mut Recorder, entity: &str, xy: &[[f64; 2]], colors: &[[u8; 4]], radius: f32, labels: &[String]) {
        let pts: Vec<[f64; 2]> = xy.iter().map(|p| self.map(p[0].clamp(self.x.0, self.x.1), p[1].clamp(self.y.0, self.y.1))).collect();
        rec.points2d(entity, &pts, Some(colors), Some(radius), Some(labels), false);
    }

    /// Vertical bars from `(x, lo)` to `(x, hi)` (error bars), one colour for all.
    pub fn bars(&self, rec: &mut Recorder, entity: &str, bars: &[(f64, f64, f64)], color: [u8; 4], width: f32) {
        let strips: Vec<Vec<[f64; 2]>> =
            bars.iter().map(|(x, lo, hi)| vec![self.map(*x, lo.clamp(self.y.0, self.y.1)), self.map(*x, hi.clamp(self.y.0, self.y.1))]).collect();
        rec.line_strips2d(entity, &strips, &[color], width);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_inside() {
        assert_eq!(nice_ticks(-1.3, 1.3, 5), vec![-1.0, -0.5, 0.0, 0.5, 1.0]);
        assert_eq!(nice_ticks(0.0, 600.0, 6), vec![0.0, 100.0, 200.0, 300.0, 400.0, 500.0, 600.0]);
        let t = nice_ticks(-170.0, 170.0, 6);
        assert!(t.len() >= 4 && t.iter().all(|v| (-170.0..=170.0).contains(v) && (v / 50.0).fract() == 0.0), "{t:?}");
        assert!(nice_ticks(1.0, 1.0, 5).is_empty() && nice_ticks(f64::NAN, 1.0, 5).is_empty());
        assert_eq!(tick_label(0.5, &[0.0, 0.5, 1.0]), "0.5");
        assert_eq!(tick_label(200.0, &[0.0, 100.0, 200.0]), "200");
        assert_eq!(tick_label(0.02, &[0.0, 0.01, 0.02]), "0.02");
    }

    #[test]
    fn ranges_and_mapping() {
        assert_eq!(padded_range([1.0, 3.0, f64::NAN], 0.5), Some((0.0, 4.0)));
        assert_eq!(padded_range([2.0, 2.0], 0.1), Some((1.8, 2.2)));
        assert_eq!(padded_range([0.0], 0.1), Some((-0.5, 0.5)));
        assert_eq!(padded_range([f64::NAN], 0.1), None);
        let p = Plot::new("t", "x", (0.0, 10.0), "y", (-1.0, 1.0));
        assert_eq!(p.map(0.0, -1.0), [0.0, PLOT_H]);
        assert_eq!(p.map(10.0, 1.0), [PLOT_W, 0.0]);
        assert_eq!(p.map(5.0, 0.0), [PLOT_W / 2.0, PLOT_H / 2.0]);
        // A degenerate range falls back to ±1 instead of dividing by zero.
        assert_eq!(Plot::new("t", "x", (1.0, 1.0), "y", (0.0, 1.0)).x, (-1.0, 1.0));
    }
}
