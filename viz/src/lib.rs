//! twincal's visualisation: recordings for the [Rerun](https://rerun.io) viewer, behind plain types.
//!
//! This package is the only one that knows about Rerun. The rest of twincal passes plain
//! `f64` arrays and strings to a [`Recorder`]; with the default `rerun` cargo feature it writes an
//! `.rrd` file, without it [`Recorder::create`] returns an error and nothing else changes.
//!
//! # Conventions
//!
//! * **Units: millimetres.** Every position, translation and radius is in mm (Rerun itself is
//!   unit-less; the 3D view just shows numbers). Rerun stores positions as `f32`, which resolves
//!   ~0.1 µm at 1 m: plenty for display, but never read calibration results back from a recording.
//! * **Frames:** `world` is declared right-handed, Z-up (`ViewCoordinates::RIGHT_HAND_Z_UP`) once
//!   at creation. A [`Recorder::transform`] at an entity maps that entity's frame into its
//!   *parent entity's* frame (points logged at `world/arm/link_3/…` are expressed in link 3's frame).
//! * **Time:** data is stamped with the current value of every timeline set so far
//!   ([`Recorder::set_time_index`] for counters such as `pose`, `iteration`;
//!   [`Recorder::set_time_seconds`] for durations). A timeline must keep one kind. Static data
//!   ([`Recorder::static_text`]) has no time.
//! * **Entity paths** are `/`-separated (`world/tool_points`). The entities each command logs
//!   are described in `viz/README.md`.
//! * **Layout:** each scene sets its own [`Blueprint`] ([`Recorder::layout`]); views whose
//!   entities got no data are pruned when the recording finishes, so no view opens empty.
//!   Without one, a generic layout shows `world/**` (3D), `residuals/**` (bar charts),
//!   `calib/**` (time series), `docs/**` (markdown) and `log` (text log).
//! * **Plots:** [`plot::Plot`] draws scatter plots with real axes inside 2-D views.
//! * **Errors:** logging methods never panic and return nothing. The first problem (bad input
//!   such as a colour count that does not match the point count, or an I/O error) is remembered,
//!   later logging is skipped, and [`Recorder::finish`] returns that error. The file is written
//!   to a temporary file staged in a [`twincal::output::OutputSet`] next to the target: either the
//!   recorder's own ([`Recorder::create`], renamed into place by a successful `finish`) or the
//!   command's ([`Recorder::staged`], renamed with the command's other outputs). The target is
//!   either a complete recording or untouched. Dropping a `Recorder` without `finish` discards
//!   the recording.

// As in the library: numeric code indexes several arrays in step.
#![allow(clippy::needless_range_loop)]

use std::path::Path;

#[cfg(not(feature = "rerun"))]
#[path = "disabled.rs"]
mod backend;
#[cfg(feature = "rerun")]
#[path = "recorder.rs"]
mod backend;

pub mod artifact;
mod jobs;
pub mod layout;
pub mod plan;
pub mod plot;
pub mod results;
pub mod scenes;
pub mod study;

pub use jobs::Rerun;
pub use layout::{Blueprint, Layout, ViewKind, ViewSpec};

/// Rerun's SDK crates this package records with, for readers of its recordings (the command
/// line's integration tests decode them) at the very same version.
#[cfg(feature = "rerun")]
pub use {re_log_encoding, re_sdk, re_sdk_types};

/// A recording sink. With the `rerun` feature it writes an `.rrd` file; without it,
/// [`Recorder::create`] returns an error saying twincal was built without Rerun support.
///
/// All lengths are in millimetres. See the [module documentation](self) for the conventions.
pub struct Recorder {
    inner: backend::Backend,
    /// The recorder's own output set ([`Recorder::create`]); `None` when the caller's set holds
    /// the staged file ([`Recorder::staged`]).
    own: Option<twincal::output::OutputSet>,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Recorder")
    }
}

impl Recorder {
    /// Start a recording that will be written to `path` (conventionally `*.rrd`).
    ///
    /// `app_id` names the application in the viewer (e.g. `"twincal"`); the viewer remembers
    /// layouts per application id. Missing parent directories are created. Data goes to a hidden
    /// temporary file next to `path` until [`finish`](Self::finish) renames it into place.
    pub fn create(app_id: &str, path: &Path) -> twincal::error::Result<Recorder> {
        let mut own = twincal::output::OutputSet::new();
        let file = own.stage(path)?;
        Ok(Recorder { inner: backend::Backend::with_file(app_id, file, path)?, own: Some(own) })
    }

    /// A recording staged as one of a command's outputs: written to a temporary file of
    /// `outputs`, renamed into place by `outputs.commit()` after a successful
    /// [`finish`](Self::finish), removed when `outputs` is dropped uncommitted.
    pub fn staged(app_id: &str, outputs: &mut twincal::output::OutputSet, path: &Path) -> twincal::error::Result<Recorder> {
        let file = outputs.stage(path)?;
        Ok(Recorder { inner: backend::Backend::with_file(app_id, file, path)?, own: None })
    }

    /// Set the sequence timeline `timeline` (e.g. `"pose"`, `"iteration"`) to `idx` for all
    /// following temporal data.
    pub fn set_time_index(&mut self, timeline: &str, idx: i64) {
        self.inner.set_time_index(timeline, idx);
    }

    /// Set the duration timeline `timeline` to `secs` seconds (may be negative) for all following
    /// temporal data.
    pub fn set_time_seconds(&mut self, timeline: &str, secs: f64) {
        self.inner.set_time_seconds(timeline, secs);
    }

    /// A point cloud at `entity`, positions in mm.
    ///
    /// `colors` and `labels` hold one entry per point, or a single entry for all of them
    /// (RGBA; note that the viewer uses alpha as brightness, not transparency, for points).
    /// `radii_mm` is one radius for all points, in mm (> 0). Replaces the previous cloud at
    /// `entity` from the current time on.
    pub fn points(&mut self, entity: &str, pts_mm: &[[f64; 3]], colors: Option<&[[u8; 4]]>, radii_mm: Option<f32>, labels: Option<&[String]>) {
        self.inner.points(entity, pts_mm, colors, radii_mm, labels);
    }

    /// Like [`points`](Self::points), but the labels are not drawn in the scene: the viewer shows
    /// a point's label when the mouse is over it (and in the selection panel).
    pub fn points_hover(&mut self, entity: &str, pts_mm: &[[f64; 3]], colors: Option<&[[u8; 4]]>, radii_mm: Option<f32>, labels: &[String]) {
        self.inner.points_hover(entity, pts_mm, colors, radii_mm, labels);
    }

    /// 2-D points at `entity` (x, y in the 2-D view's units; y points *down* in the viewer).
    /// `radius` is in screen points. `labels`: one per point or one for all; `show_labels`:
    /// draw them next to the points, else only on hover.
    pub fn points2d(&mut self, entity: &str, pts: &[[f64; 2]], colors: Option<&[[u8; 4]]>, radius: Option<f32>, labels: Option<&[String]>, show_labels: bool) {
        self.inner.points2d(entity, pts, colors, radius, labels, show_labels);
    }

    /// 2-D polylines at `entity`, one colour per strip (or one for all), width in screen points.
    pub fn line_strips2d(&mut self, entity: &str, strips: &[Vec<[f64; 2]>], colors: &[[u8; 4]], width: f32) {
        self.inner.line_strips2d(entity, strips, colors, width);
    }

    /// 3-D polylines with one colour per strip (`colors.len() == strips.len()`, or one for all).
    pub fn segments(&mut self, entity: &str, strips: &[Vec<[f64; 3]>], colors: &[[u8; 4]], radius_mm: f32) {
        self.inner.segments(entity, strips, colors, radius_mm);
    }

    /// Draw the frame of `entity` (see [`transform`](Self::transform)) as red/green/blue axes of
    /// `length_mm`.
    pub fn axes(&mut self, entity: &str, length_mm: f32) {
        self.inner.axes(entity, length_mm);
    }

    /// How a time series at `entity` is drawn: its name in the legend, colour, and as markers
    /// (`points`, marker size in screen points) or as a line (`points == false`, width). Static.
    pub fn series_style(&mut self, entity: &str, name: &str, color: [u8; 4], points: bool, size: f32) {
        self.inner.series_style(entity, name, color, points, size);
    }

    /// Log everything that follows as static data (shown on every timeline at all times) while
    /// `on` is true; timed again with `false`.
    pub fn set_static(&mut self, on: bool) {
        self.inner.set_static(on);
    }

    /// The viewer layout sent with the recording (by [`finish`](Self::finish)). Views whose
    /// entities received no data are left out, and so are containers left empty; without a
    /// layout a generic default one is sent.
    pub fn layout(&mut self, blueprint: Blueprint) {
        self.inner.layout(blueprint);
    }

    /// Polylines at `entity` (vertices in mm), all drawn with one colour and radius (mm, > 0).
    pub fn line_strips(&mut self, entity: &str, strips: &[Vec<[f64; 3]>], color: [u8; 4], radius_mm: f32) {
        self.inner.line_strips(entity, strips, color, radius_mm);
    }

    /// The pose of `entity`'s frame in its parent entity's frame:
    /// `p_parent = R · p_entity + t`, with `R` given row-major (`R[row][col]`) and `t` in mm.
    /// `R` should be a rotation; it is not re-orthonormalised.
    pub fn transform(&mut self, entity: &str, translation_mm: [f64; 3], rotation_matrix_rowmajor: [[f64; 3]; 3]) {
        self.inner.transform(entity, translation_mm, rotation_matrix_rowmajor);
    }

    /// One sample of a time series (plotted against whichever timeline the viewer shows).
    /// `NaN` leaves a gap.
    pub fn scalar(&mut self, entity: &str, value: f64) {
        self.inner.scalar(entity, value);
    }

    /// A bar chart of `values`, bars at 0, 1, 2, …. For a histogram with real bin edges use
    /// [`histogram_chart`](Self::histogram_chart).
    pub fn bar_chart(&mut self, entity: &str, values: &[f64]) {
        self.inner.bar_chart(entity, values);
    }

    /// A histogram as returned by [`histogram`]: bar `i` spans `edges[i]..edges[i + 1]`
    /// (`edges.len() == counts.len() + 1`), so the x axis is in the data's units (e.g. mm).
    pub fn histogram_chart(&mut self, entity: &str, edges: &[f64], counts: &[f64]) {
        self.inner.histogram_chart(entity, edges, counts, None);
    }

    /// [`histogram_chart`](Self::histogram_chart) with a bar colour.
    pub fn histogram_colored(&mut self, entity: &str, edges: &[f64], counts: &[f64], color: [u8; 4]) {
        self.inner.histogram_chart(entity, edges, counts, Some(color));
    }

    /// A log entry (one line of a text log, stamped with the current time).
    pub fn text(&mut self, entity: &str, text: &str) {
        self.inner.text(entity, text);
    }

    /// A static markdown document (e.g. a legend, see [`colormap_legend`]), independent of time.
    pub fn static_text(&mut self, entity: &str, markdown: &str) {
        self.inner.static_text(entity, markdown);
    }

    /// Flush everything, write the `.rrd` footer, fsync, and (for [`Recorder::create`]) rename the
    /// temporary file into place. Returns the first error met while recording, if any (then
    /// nothing is written).
    pub fn finish(self) -> twincal::error::Result<()> {
        self.inner.finish()?;
        match self.own {
            Some(own) => own.commit(),
            None => Ok(()),
        }
    }
}

/// Viridis colormap: maps `|value|` in `[0, vmax]` to RGBA (opaque).
///
/// `0` is dark purple, `vmax/2` teal, `vmax` (and above) yellow. Perceptually uniform and
/// readable by colour-blind viewers. A `NaN` value gives mid grey; if `vmax` is not positive, any
/// non-zero value maps to the top colour.
pub fn colormap(value: f64, vmax: f64) -> [u8; 4] {
    let v = value.abs();
    if v.is_nan() {
        return [128, 128, 128, 255];
    }
    let t = if vmax > 0.0 {
        (v / vmax).clamp(0.0, 1.0) // vmax = inf gives 0
    } else if v > 0.0 {
        1.0
    } else {
        0.0
    };
    viridis(t)
}

/// Where residual colours start on viridis: its darkest purple disappears on the viewer's dark
/// background, so 0 maps to the blue-violet at 0.18 instead.
pub const RESIDUAL_FLOOR: f64 = 0.18;

/// Colour of a residual for the recordings: `|value|` from 0 to `vmax` on viridis from
/// [`RESIDUAL_FLOOR`] (blue-violet) to 1 (yellow); above `vmax` yellow, `NaN` grey.
pub fn residual_color(value: f64, vmax: f64) -> [u8; 4] {
    let v = value.abs();
    if v.is_nan() {
        return [128, 128, 128, 255];
    }
    let t = if vmax > 0.0 { (v / vmax).clamp(0.0, 1.0) } else { 1.0 };
    viridis(RESIDUAL_FLOOR + (1.0 - RESIDUAL_FLOOR) * t)
}

fn viridis(t: f64) -> [u8; 4] {
    // Polynomial fit of matplotlib's viridis (Matt Zucker, CC0); max error ~1/255 per channel.
    const C: [[f64; 3]; 7] = [
        [0.277_727_327_223_417_7, 0.005_407_344_544_966_578, 0.334_099_805_335_306_1],
        [0.105_093_043_108_577_4, 1.404_613_529_898_575, 1.384_590_162_594_685],
        [-0.330_861_828_725_556_3, 0.214_847_559_468_213, 0.095_095_163_028_236_59],
        [-4.634_230_498_983_486, -5.799_100_973_351_585, -19.332_440_956_279_87],
        [6.228_269_936_347_081, 14.179_933_366_805_09, 56.690_552_600_681_05],
        [4.776_384_997_670_288, -13.745_145_377_746_01, -65.353_032_633_372_34],
        [-5.435_455_855_934_631, 4.645_852_612_178_535, 26.312_435_249_583_2],
    ];
    let mut rgba = [0u8, 0, 0, 255];
    for (ch, out) in rgba.iter_mut().take(3).enumerate() {
        let c = C.iter().rev().fold(0.0, |acc, k| acc * t + k[ch]);
        *out = (c.clamp(0.0, 1.0) * 255.0).round() as u8;
    }
    rgba
}

/// A markdown legend for [`colormap`] with `vmax` in `unit`, for [`Recorder::static_text`]:
/// a table of `steps + 1` evenly spaced values with their colour (hex and a plain name).
pub fn colormap_legend(title: &str, vmax: f64, unit: &str, steps: usize) -> String {
    let steps = steps.max(1);
    let mut s = format!(
        "## {title}\n\nColour = |value| on the viridis scale from 0 to {vmax:.3} {unit} \
         (values above are clamped to the top colour; grey = not available).\n\n\
         | value ({unit}) | colour |\n|---:|---|\n"
    );
    for i in 0..=steps {
        let v = vmax * i as f64 / steps as f64;
        let [r, g, b, _] = colormap(v, vmax);
        let name = match (i as f64 / steps as f64 * 4.0).round() as i32 {
            0 => "dark purple",
            1 => "blue",
            2 => "teal",
            3 => "green",
            _ => "yellow",
        };
        let ge = if i == steps { "≥ " } else { "" };
        s.push_str(&format!("| {ge}{v:.3} | `#{r:02x}{g:02x}{b:02x}` {name} |\n"));
    }
    s
}

/// Histograms are figure data, shared with the HTML reports: they live in [`twincal::report`].
pub use twincal::report::histogram;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colormap_endpoints() {
        // matplotlib viridis(0) = #440154, viridis(1) = #fde725 (within the fit's error).
        let near = |a: [u8; 4], b: [u8; 4]| a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= 4);
        assert!(near(colormap(0.0, 5.0), [0x44, 0x01, 0x54, 255]), "{:?}", colormap(0.0, 5.0));
        assert!(near(colormap(5.0, 5.0), [0xfd, 0xe7, 0x25, 255]), "{:?}", colormap(5.0, 5.0));
        // |value|, clamping above vmax, degenerate inputs.
        assert_eq!(colormap(-5.0, 5.0), colormap(5.0, 5.0));
        assert_eq!(colormap(50.0, 5.0), colormap(5.0, 5.0));
        assert_eq!(colormap(f64::NAN, 5.0), [128, 128, 128, 255]);
        assert_eq!(colormap(1.0, 0.0), colormap(5.0, 5.0));
        assert_eq!(colormap(0.0, 0.0), colormap(0.0, 5.0));
        // Luminance increases monotonically along viridis.
        let lum = |c: [u8; 4]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
        let mut prev = -1.0;
        for i in 0..=50 {
            let l = lum(colormap(i as f64, 50.0));
            assert!(l > prev, "luminance not increasing at {i}");
            prev = l;
        }
        let legend = colormap_legend("Cable residual", 2.0, "mm", 4);
        let rows: Vec<&str> = legend.lines().filter(|l| l.contains("`#")).collect();
        assert_eq!(rows.len(), 5, "{legend}");
        assert!(rows[0].starts_with("| 0.000 |") && rows[4].contains("≥ 2.000"), "{legend}");
    }

    #[test]
    fn histogram_counts() {
        let values = [0.0, 0.1, 0.5, 0.99, 1.0, 2.5, 3.0, -0.1, 3.1, f64::NAN];
        let (edges, counts) = histogram(&values, 3, 0.0, 3.0);
        assert_eq!(edges, vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(counts, vec![4.0, 1.0, 2.0]); // 1.0 -> bin 1, 3.0 -> last bin
        assert_eq!(counts.iter().sum::<f64>(), 7.0); // -0.1, 3.1, NaN are out of range

        // Every in-range value is counted exactly once, whatever the rounding.
        let values: Vec<f64> = (0..=1000).map(|i| i as f64 * 0.001 * 0.7).collect();
        let (edges, counts) = histogram(&values, 7, 0.0, 0.7);
        assert_eq!(edges.len(), 8);
        assert_eq!(counts.iter().sum::<f64>(), values.len() as f64);

        assert_eq!(histogram(&values, 0, 0.0, 1.0), (vec![], vec![]));
        let (e, c) = histogram(&values, 2, 1.0, 1.0);
        assert_eq!((e.len(), c), (3, vec![0.0, 0.0]));
    }

    #[cfg(not(feature = "rerun"))]
    #[test]
    fn create_without_rerun_fails() {
        let dir = tempfile::tempdir().unwrap();
        let err = Recorder::create("twincal_test", &dir.path().join("x.rrd")).unwrap_err();
        assert!(err.to_string().contains("without the `rerun` feature"), "{err}");
    }

    #[cfg(feature = "rerun")]
    mod with_rerun {
        use super::super::*;
        use std::path::Path;

        fn files_in(dir: &Path) -> Vec<String> {
            let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
            v.sort();
            v
        }

        fn log_a_bit_of_everything(rec: &mut Recorder) {
            rec.static_text("docs/legend", &colormap_legend("Cable residual", 2.0, "mm", 4));
            for pose in 0..3 {
                rec.set_time_index("pose", pose);
                rec.set_time_seconds("sim_time", pose as f64 * 0.5);
                let c = (pose as f64).cos();
                let s = (pose as f64).sin();
                for k in 0..2 {
                    rec.transform(&format!("world/arm/link_{k}"), [100.0 * k as f64, 0.0, 400.0], [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]);
                }
                rec.line_strips("world/arm/skeleton", &[vec![[0.0, 0.0, 0.0], [0.0, 0.0, 400.0], [300.0, 0.0, 600.0]]], [200, 200, 200, 255], 8.0);
                rec.line_strips("world/cable", &[vec![[500.0, 0.0, 0.0], [300.0, 0.0, 600.0]]], [255, 128, 0, 255], 1.0);
                let pts = [[300.0, 0.0, 600.0], [310.0, 5.0, 590.0]];
                let res = [0.2, 1.7];
                let colors: Vec<[u8; 4]> = res.iter().map(|r| colormap(*r, 2.0)).collect();
                let labels: Vec<String> = res.iter().map(|r| format!("{r:.2} mm")).collect();
                rec.points("world/tool_points", &pts, Some(&colors), Some(3.0), Some(&labels));
                rec.points("world/targets", &pts, None, None, None);
                rec.text("log", &format!("pose {pose} done"));
            }
            for it in 0..4 {
                rec.set_time_index("iteration", it);
                rec.scalar("calib/param/l0", 1000.0 + it as f64);
                rec.scalar("calib/rms_mm", 1.0 / (1.0 + it as f64));
            }
            let residuals = [0.1, -0.3, 0.5, 1.2, -0.8];
            let (edges, counts) = histogram(&residuals, 4, -1.0, 1.0);
            rec.histogram_chart("residuals/histogram", &edges, &counts);
            rec.bar_chart("residuals/raw", &counts);
        }

        #[test]
        fn records_whole_file_and_no_temporary() {
            let dir = tempfile::tempdir().unwrap();
            // The target directory does not exist yet: it is created.
            let path = dir.path().join("out/sub/run.rrd");
            let mut rec = Recorder::create("twincal_test", &path).unwrap();
            log_a_bit_of_everything(&mut rec);
            assert!(!path.exists(), "target must not appear before finish()");
            rec.finish().unwrap();

            let len = std::fs::metadata(&path).unwrap().len();
            assert!(len > 0, "empty recording");
            assert_eq!(files_in(&dir.path().join("out/sub")), vec!["run.rrd".to_owned()]);

            // Decode it back: valid .rrd with a footer and our entities.
            use re_log_encoding::DecoderApp;
            use re_sdk::log::{Chunk, LogMsg};
            let bytes = std::fs::read(&path).unwrap();
            let mut it = DecoderApp::decode_lazy(bytes.as_slice());
            let mut entities = std::collections::BTreeSet::new();
            let mut blueprint_activations = 0;
            for msg in it.by_ref() {
                match msg.expect("decodable .rrd") {
                    LogMsg::ArrowMsg(store, arrow) if store.is_recording() => {
                        let chunk = Chunk::from_arrow_msg(&arrow).unwrap();
                        entities.insert(chunk.entity_path().to_string());
                    }
                    LogMsg::BlueprintActivationCommand(_) => blueprint_activations += 1,
                    _ => {}
                }
            }
            if re_sdk::decide_logging_enabled(true) {
                assert_eq!(blueprint_activations, 1, "default layout missing");
            }
            assert!(!it.rrd_manifests().unwrap().is_empty(), "no footer/manifest");
            for e in [
                "/world",
                "/world/arm/link_0",
                "/world/arm/link_1",
                "/world/arm/skeleton",
                "/world/cable",
                "/world/tool_points",
                "/calib/param/l0",
                "/residuals/histogram",
                "/docs/legend",
                "/log",
            ] {
                assert!(entities.contains(e), "{e} missing from {entities:?}");
            }
        }

        #[test]
        fn replaces_existing_file_atomically() {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("run.rrd");
            std::fs::write(&path, b"old").unwrap();
            let mut rec = Recorder::create("twincal_test", &path).unwrap();
            rec.scalar("calib/x", 1.0);
            assert_eq!(std::fs::read(&path).unwrap(), b"old");
            rec.finish().unwrap();
            assert!(std::fs::metadata(&path).unwrap().len() > 3);
            assert_eq!(files_in(dir.path()), vec!["run.rrd".to_owned()]);
        }

        #[test]
        fn first_error_is_returned_and_nothing_written() {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("bad.rrd");
            let mut rec = Recorder::create("twincal_test", &path).unwrap();
            rec.points("world/p", &[[0.0; 3]; 3], Some(&[[0, 0, 0, 255]; 2]), None, None);
            rec.line_strips("world/l", &[], [0; 4], -1.0); // second error: ignored
            rec.scalar("calib/x", 1.0);
            let err = rec.finish().unwrap_err().to_string();
            assert!(err.contains("world/p") && err.contains("2 colours for 3 points"), "{err}");
            assert!(files_in(dir.path()).is_empty(), "{:?}", files_in(dir.path()));

            // Mixing timeline kinds is an error too.
            let mut rec = Recorder::create("twincal_test", &path).unwrap();
            rec.set_time_index("pose", 1);
            rec.set_time_seconds("pose", 1.0);
            assert!(rec.finish().unwrap_err().to_string().contains("pose"));
            assert!(files_in(dir.path()).is_empty());
        }

        #[test]
        fn drop_without_finish_leaves_nothing() {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("dropped.rrd");
            let mut rec = Recorder::create("twincal_test", &path).unwrap();
            rec.scalar("calib/x", 1.0);
            assert_eq!(files_in(dir.path()).len(), 1, "temporary file exists while recording");
            drop(rec);
            assert!(files_in(dir.path()).is_empty(), "{:?}", files_in(dir.path()));
        }

        #[test]
        fn bad_target_is_an_error_not_a_panic() {
            let dir = tempfile::tempdir().unwrap();
            let blocker = dir.path().join("file");
            std::fs::write(&blocker, b"x").unwrap();
            // Parent "directory" is a regular file.
            let err = Recorder::create("twincal_test", &blocker.join("x.rrd")).unwrap_err();
            assert!(err.to_string().starts_with(&format!("cannot create folder {}", blocker.display())), "{err}");
        }

        #[test]
        fn recorder_is_send() {
            fn is_send<T: Send>() {}
            is_send::<Recorder>();
        }
    }
}
