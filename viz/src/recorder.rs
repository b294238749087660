//! Rerun-backed implementation of [`super::Recorder`]. This is the only file in the crate that
//! names a `rerun` type.
//!
//! Design notes (rerun 0.36):
//! * We do **not** use rerun's own `FileSink`: its writer thread only *logs* I/O errors (and the
//!   footer is written when the sink is dropped, with the error discarded). Instead [`RrdSink`]
//!   drives rerun's `re_log_encoding::Encoder` itself over a `BufWriter<File>`, so every write
//!   error is kept and reported by `finish()`.
//! * Rerun keeps the "current time" per *thread*. A `Recorder` may be moved between threads, so we
//!   keep our own time point and re-apply it right before every temporal log call.

use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use re_log_encoding::{self, Encoder};
use re_sdk::sink::{LogSink, SinkFlushError};
use re_sdk::{AsComponents, RecordingStream, TimeCell, TimePoint, TimelineName};

use twincal::error::{Error, Result};

type RrdEncoder = Encoder<BufWriter<File>>;

/// What the sink shares with the [`Backend`]: the encoder (taken out by `finish`) and the first
/// write error.
struct SinkState {
    encoder: Option<RrdEncoder>,
    error: Option<String>,
}

fn lock(state: &Mutex<SinkState>) -> MutexGuard<'_, SinkState> {
    // A panic while holding the lock cannot leave the state inconsistent in a way we care about.
    state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A rerun log sink that encodes `.rrd` into our temporary file and remembers the first error.
struct RrdSink {
    state: Arc<Mutex<SinkState>>,
}

impl LogSink for RrdSink {
    fn send(&self, msg: re_sdk::log::LogMsg) {
        let mut st = lock(&self.state);
        if st.error.is_some() {
            return;
        }
        if let Some(encoder) = st.encoder.as_mut() {
            if let Err(err) = encoder.append(&msg) {
                st.error = Some(err.to_string());
            }
        }
    }

    fn flush_blocking(&self, _timeout: Duration) -> std::result::Result<(), SinkFlushError> {
        let mut st = lock(&self.state);
        if let Some(err) = &st.error {
            return Err(SinkFlushError::failed(err.clone()));
        }
        if let Some(encoder) = st.encoder.as_mut() {
            if let Err(err) = encoder.flush_blocking() {
                let msg = err.to_string();
                st.error = Some(msg.clone());
                return Err(SinkFlushError::failed(msg));
            }
        }
        Ok(())
    }

    fn defers_finalization_to_shutdown(&self) -> bool {
        // Like rerun's FileSink: the footer is only written by `finish()`.
        true
    }
}

/// The rerun-backed state behind a [`super::Recorder`].
pub(super) struct Backend {
    /// `None` once finished (or torn down by `Drop`).
    rec: Option<RecordingStream>,
    sink: Arc<Mutex<SinkState>>,
    /// The target file, for messages (the data goes to a staged temporary file).
    path: PathBuf,
    /// Our own notion of "now" on every timeline (see module docs).
    time: BTreeMap<TimelineName, TimeCell>,
    /// First error seen by any logging method.
    error: Option<Error>,
    /// Every entity that received data (with a leading `/`), to prune the layout.
    logged: BTreeSet<String>,
    /// Log as static data ([`Backend::set_static`]).
    static_mode: bool,
    /// The layout to send at `finish` (the generic default when `None`).
    layout: Option<super::Blueprint>,
}

fn write_err(path: &Path, what: &str, err: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("cannot write Rerun recording {}: {what}: {err}", path.display()))
}

fn f32x3(p: &[f64; 3]) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}

impl Backend {
    /// A recording encoded into `file` (a temporary file staged by the caller's
    /// [`twincal::output::OutputSet`]); `path` is the target the messages name.
    pub(super) fn with_file(app_id: &str, file: File, path: &Path) -> Result<Backend> {
        // rerun 0.36: only `&'static str` converts infallibly (and panics when empty).
        let app = re_sdk::ApplicationId::try_new(app_id).map_err(|e| Error::Invalid(format!("invalid Rerun application id {app_id:?}: {e}")))?;
        // Same encoding as rerun's own FileSink.
        let encoder = Encoder::new_eager(re_log_encoding::CrateVersion::LOCAL, re_log_encoding::EncodingOptions::PROTOBUF_COMPRESSED, BufWriter::new(file));
        let encoder = match encoder {
            Ok(enc) => enc,
            Err(e) => {
                return Err(write_err(path, "cannot start .rrd stream", e));
            }
        };
        let sink = Arc::new(Mutex::new(SinkState { encoder: Some(encoder), error: None }));

        // `enabled(true)`: an explicit recording request must not be silently turned off by the
        // `RERUN=off` environment variable.
        let rec = re_sdk::RecordingStreamBuilder::new(app).enabled(true).buffered().inspect(|rec| rec.set_sink(Box::new(RrdSink { state: Arc::clone(&sink) })));
        let rec = match rec {
            Ok(rec) => rec,
            Err(e) => {
                drop(lock(&sink).encoder.take());
                return Err(write_err(path, "cannot start Rerun recording stream", e));
            }
        };

        let mut backend = Backend {
            rec: Some(rec),
            sink,
            path: path.to_path_buf(),
            time: BTreeMap::new(),
            error: None,
            logged: BTreeSet::new(),
            static_mode: false,
            layout: None,
        };
        // We log in millimetres in a right-handed, Z-up world.
        backend.log("world", true, &re_sdk_types::archetypes::ViewCoordinates::RIGHT_HAND_Z_UP());
        backend.logged.clear(); // the coordinate system alone is not data worth a view
        if let Some(err) = backend.error.take() {
            return Err(err); // the caller's `OutputSet` removes the temporary file
        }
        Ok(backend)
    }

    /// Remember the first error only.
    fn fail(&mut self, err: Error) {
        if self.error.is_none() {
            self.error = Some(err);
        }
    }

    fn invalid(&mut self, entity: &str, msg: impl std::fmt::Display) {
        self.fail(Error::Invalid(format!("Rerun recording, entity {entity:?}: {msg}")));
    }

    fn log<AS: ?Sized + AsComponents>(&mut self, entity: &str, is_static: bool, data: &AS) {
        if self.error.is_some() {
            return; // the recording is already lost; do not waste time on it
        }
        let Some(rec) = &self.rec else { return };
        let is_static = is_static || self.static_mode;
        self.logged.insert(if entity.starts_with('/') { entity.to_string() } else { format!("/{entity}") });
        if !is_static {
            rec.reset_time();
            rec.set_timepoint(TimePoint::from(self.time.clone()));
        }
        if let Err(e) = rec.log_with_static(entity, is_static, data) {
            let e = write_err(&self.path, &format!("logging {entity:?} failed"), e);
            self.fail(e);
        }
    }

    /// The generic layout used when a scene sets none.
    fn default_layout() -> super::Blueprint {
        use super::{Layout, ViewKind as K};
        super::Blueprint {
            root: Layout::Horizontal(
                vec![
                    Layout::view(K::Spatial3d, "World (mm)", "/world"),
                    Layout::Vertical(
                        vec![
                            Layout::view(K::BarChart, "Residual histogram", "/residuals"),
                            Layout::view(K::TimeSeries, "Calibration parameters", "/calib"),
                            Layout::Tabs(vec![Layout::view(K::Text, "Docs", "/docs"), Layout::view(K::TextLog, "Log", "/log")]),
                        ],
                        vec![],
                    ),
                ],
                vec![],
            ),
            timeline: None,
            at_end: false,
        }
    }

    /// The rerun blueprint of `layout`; the visible rectangles of 2-D views go to `bounds`
    /// (blueprint entity path of the view, rectangle), which rerun's Rust API cannot set.
    fn to_rerun(layout: &super::Layout, bounds: &mut Vec<(String, [f64; 4])>) -> re_sdk::blueprint::ContainerLike {
        use super::{Layout, ViewKind as K};
        use re_sdk::blueprint::{
            BarChartView, ContainerLike, Grid, Horizontal, Spatial2DView, Spatial3DView, Tabs, TextDocumentView, TextLogView, TimeSeriesView, Vertical,
        };
        let mut rec = |c: &[Layout]| -> Vec<ContainerLike> { c.iter().map(|l| Self::to_rerun(l, bounds)).collect() };
        match layout {
            Layout::View(v) => {
                let contents: Vec<String> = if v.contents.is_empty() { vec!["$origin/**".to_string()] } else { v.contents.clone() };
                let origin = v.origin.as_str();
                let view: ContainerLike = match v.kind {
                    K::Spatial3d => Spatial3DView::new(v.name.clone()).with_origin(origin).with_contents(contents).into(),
                    K::Spatial2d => Spatial2DView::new(v.name.clone()).with_origin(origin).with_contents(contents).into(),
                    K::TimeSeries => TimeSeriesView::new(v.name.clone()).with_origin(origin).with_contents(contents).into(),
                    K::BarChart => BarChartView::new(v.name.clone()).with_origin(origin).with_contents(contents).into(),
                    K::Text => TextDocumentView::new(v.name.clone()).with_origin(origin).with_contents(contents).into(),
                    K::TextLog => TextLogView::new(v.name.clone()).with_origin(origin).with_contents(contents).into(),
                };
                if let (Some(b), ContainerLike::View(inner)) = (v.bounds, &view) {
                    bounds.push((inner.blueprint_path().to_string(), b));
                }
                view
            }
            Layout::Horizontal(c, shares) => {
                let h = Horizontal::new(rec(c));
                if shares.len() == c.len() {
                    h.with_column_shares(shares.clone()).into()
                } else {
                    h.into()
                }
            }
            Layout::Vertical(c, shares) => {
                let h = Vertical::new(rec(c));
                if shares.len() == c.len() {
                    h.with_row_shares(shares.clone()).into()
                } else {
                    h.into()
                }
            }
            Layout::Grid(c, cols) => Grid::new(rec(c)).with_grid_columns(*cols).into(),
            Layout::Tabs(c) => Tabs::new(rec(c)).into(),
        }
    }

    /// Sends the layout (pruned to the views that have data), with the blueprint and selection
    /// panels folded away and the time panel on the chosen timeline.
    fn send_blueprint(&mut self) {
        use re_sdk::blueprint::components::{PanelState, PlayState};
        use re_sdk::blueprint::{Blueprint, BlueprintActivation, BlueprintPanel, SelectionPanel, TimePanel};
        let Some(rec) = &self.rec else { return };
        // rerun 0.36's `Blueprint::send` builds the blueprint through an internal recording that
        // honours the `RERUN` env var, and panics when that disables it. Skip the layout then.
        if !re_sdk::decide_logging_enabled(true) {
            return;
        }
        let wanted = self.layout.take().unwrap_or_else(Self::default_layout);
        let Some(root) = wanted.root.prune(&self.logged) else { return };
        let mut time = TimePanel::new().with_state(PanelState::Collapsed);
        if let Some(t) = &wanted.timeline {
            time = time.with_timeline(t.clone());
        }
        time = time.with_play_state(if wanted.at_end { PlayState::Following } else { PlayState::Paused });
        let mut bounds = Vec::new();
        let blueprint = Blueprint::new(Self::to_rerun(&root, &mut bounds))
            .with_auto_views(false)
            .with_auto_layout(false)
            .with_blueprint_panel(BlueprintPanel::new().with_state(PanelState::Collapsed))
            .with_selection_panel(SelectionPanel::new().with_state(PanelState::Collapsed))
            .with_time_panel(time);
        let activation = BlueprintActivation { make_active: true, make_default: true };
        let sent = if bounds.is_empty() { blueprint.send(rec, activation) } else { Self::send_with_bounds(rec, &blueprint, activation, &bounds) };
        if let Err(e) = sent {
            let e = write_err(&self.path, "cannot send the viewer layout", e);
            self.fail(e);
        }
    }

    /// Sends `blueprint` with the visible rectangles of some 2-D views: the blueprint's messages
    /// are built in memory, the `VisualBounds2D` view properties are logged into the same
    /// blueprint store, and everything goes to `rec` followed by the activation command.
    fn send_with_bounds(
        rec: &RecordingStream,
        blueprint: &re_sdk::blueprint::Blueprint,
        activation: re_sdk::blueprint::BlueprintActivation,
        bounds: &[(String, [f64; 4])],
    ) -> re_sdk::RecordingStreamResult<()> {
        use re_sdk::log::LogMsg;
        use re_sdk_types::blueprint::archetypes::VisualBounds2D;
        use re_sdk_types::datatypes::{Range1D, Range2D};
        let app = rec.store_info().map(|i| i.application_id().clone()).unwrap_or_else(|| re_sdk::ApplicationId::from("twincal"));
        let (mem, storage) = re_sdk::RecordingStreamBuilder::new(app.clone()).enabled(true).memory()?;
        blueprint.send(&mem, activation)?;
        let mut msgs = Vec::new();
        let mut command = None;
        for m in storage.take() {
            match m {
                LogMsg::BlueprintActivationCommand(c) => command = Some(c),
                m if m.store_id().is_blueprint() => msgs.push(m),
                _ => {}
            }
        }
        drop(mem);
        let Some(command) = command else { return Ok(()) };
        let (props, props_storage) =
            re_sdk::RecordingStreamBuilder::new(app).recording_id(command.blueprint_id.recording_id().clone()).blueprint().enabled(true).memory()?;
        props.set_time_sequence("blueprint", 0);
        for (view, b) in bounds {
            let range = Range2D { x_range: Range1D([b[0], b[1]]), y_range: Range1D([b[2], b[3]]) };
            props.log(format!("{view}/VisualBounds2D"), &VisualBounds2D::new(range))?;
        }
        msgs.extend(props_storage.take().into_iter().filter(|m| matches!(m, LogMsg::ArrowMsg(..))));
        drop(props);
        rec.send_blueprint(msgs, command);
        Ok(())
    }

    pub(super) fn layout(&mut self, blueprint: super::Blueprint) {
        self.layout = Some(blueprint);
    }

    pub(super) fn set_static(&mut self, on: bool) {
        self.static_mode = on;
    }

    fn set_time_cell(&mut self, timeline: &str, cell: TimeCell) {
        // rerun 0.36: `From` only for `&'static str`; dynamic names go through `try_new`.
        let name = match TimelineName::try_new(timeline) {
            Ok(name) => name,
            Err(e) => return self.fail(Error::Invalid(format!("Rerun recording: invalid timeline name {timeline:?}: {e}"))),
        };
        if let Some(old) = self.time.get(&name) {
            if old.typ() != cell.typ() {
                self.fail(Error::Invalid(format!("Rerun recording: timeline {timeline:?} used both as a sequence and as seconds")));
                return;
            }
        }
        self.time.insert(name, cell);
    }

    pub(super) fn set_time_index(&mut self, timeline: &str, idx: i64) {
        self.set_time_cell(timeline, TimeCell::from_sequence(idx));
    }

    pub(super) fn set_time_seconds(&mut self, timeline: &str, secs: f64) {
        let nanos = (secs * 1e9).round();
        if !nanos.is_finite() || nanos.abs() >= i64::MAX as f64 {
            self.fail(Error::Invalid(format!("Rerun recording: timeline {timeline:?}: time {secs} s is not representable")));
            return;
        }
        self.set_time_cell(timeline, TimeCell::from_duration_nanos(nanos as i64));
    }

    pub(super) fn points2d(
        &mut self,
        entity: &str,
        pts: &[[f64; 2]],
        colors: Option<&[[u8; 4]]>,
        radius: Option<f32>,
        labels: Option<&[String]>,
        show_labels: bool,
    ) {
        let n = pts.len();
        let mut arch = re_sdk_types::archetypes::Points2D::new(pts.iter().map(|p| [p[0] as f32, p[1] as f32]));
        if let Some(colors) = colors {
            if colors.len() != n && colors.len() != 1 {
                return self.invalid(entity, format!("{} colours for {n} points", colors.len()));
            }
            arch = arch.with_colors(colors.iter().copied());
        }
        if let Some(r) = radius {
            if !(r.is_finite() && r > 0.0) {
                return self.invalid(entity, format!("point radius {r} must be > 0"));
            }
            arch = arch.with_radii([re_sdk_types::components::Radius::new_ui_points(r)]);
        }
        if let Some(labels) = labels {
            if labels.len() != n && labels.len() != 1 {
                return self.invalid(entity, format!("{} labels for {n} points", labels.len()));
            }
            arch = arch.with_labels(labels.iter().map(String::as_str)).with_show_labels(show_labels);
        }
        self.log(entity, false, &arch);
    }

    pub(super) fn line_strips2d(&mut self, entity: &str, strips: &[Vec<[f64; 2]>], colors: &[[u8; 4]], width: f32) {
        if !(width.is_finite() && width > 0.0) {
            return self.invalid(entity, format!("line width {width} must be > 0"));
        }
        if colors.len() != strips.len() && colors.len() != 1 {
            return self.invalid(entity, format!("{} colours for {} lines", colors.len(), strips.len()));
        }
        let arch = re_sdk_types::archetypes::LineStrips2D::new(
            strips.iter().map(|s| re_sdk_types::components::LineStrip2D::from_iter(s.iter().map(|p| [p[0] as f32, p[1] as f32]))),
        )
        .with_colors(colors.iter().copied())
        .with_radii([re_sdk_types::components::Radius::new_ui_points(width / 2.0)]);
        self.log(entity, false, &arch);
    }

    pub(super) fn segments(&mut self, entity: &str, strips: &[Vec<[f64; 3]>], colors: &[[u8; 4]], radius_mm: f32) {
        if !(radius_mm.is_finite() && radius_mm > 0.0) {
            return self.invalid(entity, format!("line radius {radius_mm} mm must be > 0"));
        }
        if colors.len() != strips.len() && colors.len() != 1 {
            return self.invalid(entity, format!("{} colours for {} lines", colors.len(), strips.len()));
        }
        let arch = re_sdk_types::archetypes::LineStrips3D::new(strips.iter().map(|s| re_sdk_types::components::LineStrip3D::from_iter(s.iter().map(f32x3))))
            .with_colors(colors.iter().copied())
            .with_radii([re_sdk_types::components::Radius::new_scene_units(radius_mm)]);
        self.log(entity, false, &arch);
    }

    pub(super) fn axes(&mut self, entity: &str, length_mm: f32) {
        if !(length_mm.is_finite() && length_mm > 0.0) {
            return self.invalid(entity, format!("axis length {length_mm} mm must be > 0"));
        }
        self.log(entity, true, &re_sdk_types::archetypes::TransformAxes3D::new(length_mm));
    }

    pub(super) fn series_style(&mut self, entity: &str, name: &str, color: [u8; 4], points: bool, size: f32) {
        if !(size.is_finite() && size > 0.0) {
            return self.invalid(entity, format!("series marker size / width {size} must be > 0"));
        }
        if points {
            self.log(entity, true, &re_sdk_types::archetypes::SeriesPoints::new().with_names([name]).with_colors([color]).with_marker_sizes([size]));
        } else {
            self.log(entity, true, &re_sdk_types::archetypes::SeriesLines::new().with_names([name]).with_colors([color]).with_widths([size]));
        }
    }

    pub(super) fn points_hover(&mut self, entity: &str, pts_mm: &[[f64; 3]], colors: Option<&[[u8; 4]]>, radii_mm: Option<f32>, labels: &[String]) {
        self.points_impl(entity, pts_mm, colors, radii_mm, Some(labels), Some(false));
    }

    pub(super) fn points(&mut self, entity: &str, pts_mm: &[[f64; 3]], colors: Option<&[[u8; 4]]>, radii_mm: Option<f32>, labels: Option<&[String]>) {
        self.points_impl(entity, pts_mm, colors, radii_mm, labels, None);
    }

    fn points_impl(
        &mut self,
        entity: &str,
        pts_mm: &[[f64; 3]],
        colors: Option<&[[u8; 4]]>,
        radii_mm: Option<f32>,
        labels: Option<&[String]>,
        show: Option<bool>,
    ) {
        let n = pts_mm.len();
        let mut arch = re_sdk_types::archetypes::Points3D::new(pts_mm.iter().map(f32x3));
        if let Some(colors) = colors {
            if colors.len() != n && colors.len() != 1 {
                return self.invalid(entity, format!("{} colours for {n} points", colors.len()));
            }
            arch = arch.with_colors(colors.iter().copied());
        }
        if let Some(r) = radii_mm {
            if !(r.is_finite() && r > 0.0) {
                return self.invalid(entity, format!("point radius {r} mm must be > 0"));
            }
            arch = arch.with_radii([re_sdk_types::components::Radius::new_scene_units(r)]);
        }
        if let Some(labels) = labels {
            if labels.len() != n && labels.len() != 1 {
                return self.invalid(entity, format!("{} labels for {n} points", labels.len()));
            }
            arch = arch.with_labels(labels.iter().map(String::as_str));
            if let Some(show) = show {
                arch = arch.with_show_labels(show);
            }
        }
        self.log(entity, false, &arch);
    }

    pub(super) fn line_strips(&mut self, entity: &str, strips: &[Vec<[f64; 3]>], color: [u8; 4], radius_mm: f32) {
        if !(radius_mm.is_finite() && radius_mm > 0.0) {
            return self.invalid(entity, format!("line radius {radius_mm} mm must be > 0"));
        }
        let arch = re_sdk_types::archetypes::LineStrips3D::new(strips.iter().map(|s| re_sdk_types::components::LineStrip3D::from_iter(s.iter().map(f32x3))))
            .with_colors([color])
            .with_radii([re_sdk_types::components::Radius::new_scene_units(radius_mm)]);
        self.log(entity, false, &arch);
    }

    pub(super) fn transform(&mut self, entity: &str, translation_mm: [f64; 3], rotation_matrix_rowmajor: [[f64; 3]; 3]) {
        let finite = translation_mm.iter().chain(rotation_matrix_rowmajor.iter().flatten());
        if !finite.into_iter().all(|v| v.is_finite()) {
            return self.invalid(entity, "transform has non-finite entries");
        }
        let r = rotation_matrix_rowmajor;
        // Careful: rerun's `Mat3x3` is COLUMN-major, and `From<[[f32; 3]; 3]>` takes *columns*.
        #[rustfmt::skip]
        let col_major = [
            r[0][0] as f32, r[1][0] as f32, r[2][0] as f32, // column 0
            r[0][1] as f32, r[1][1] as f32, r[2][1] as f32, // column 1
            r[0][2] as f32, r[1][2] as f32, r[2][2] as f32, // column 2
        ];
        let arch = re_sdk_types::archetypes::Transform3D::from_translation_mat3x3(f32x3(&translation_mm), re_sdk_types::datatypes::Mat3x3(col_major));
        self.log(entity, false, &arch);
    }

    pub(super) fn scalar(&mut self, entity: &str, value: f64) {
        self.log(entity, false, &re_sdk_types::archetypes::Scalars::single(value));
    }

    pub(super) fn bar_chart(&mut self, entity: &str, values: &[f64]) {
        self.log(entity, false, &re_sdk_types::archetypes::BarChart::new(values.to_vec()));
    }

    pub(super) fn histogram_chart(&mut self, entity: &str, edges: &[f64], counts: &[f64], color: Option<[u8; 4]>) {
        if edges.len() != counts.len() + 1 {
            return self.invalid(entity, format!("histogram has {} edges for {} bins", edges.len(), counts.len()));
        }
        // The bar chart view draws bar i over [abscissa[i], abscissa[i] + widths[i]].
        let left: Vec<f64> = edges[..counts.len()].to_vec();
        let widths: Vec<f32> = edges.windows(2).map(|w| (w[1] - w[0]) as f32).collect();
        let mut arch = re_sdk_types::archetypes::BarChart::new(counts.to_vec()).with_abscissa(left).with_widths(widths);
        if let Some(c) = color {
            arch = arch.with_color(c);
        }
        self.log(entity, false, &arch);
    }

    pub(super) fn text(&mut self, entity: &str, text: &str) {
        self.log(entity, false, &re_sdk_types::archetypes::TextLog::new(text));
    }

    pub(super) fn static_text(&mut self, entity: &str, markdown: &str) {
        self.log(entity, true, &re_sdk_types::archetypes::TextDocument::from_markdown(markdown));
    }

    /// Writes the footer and syncs the file; the caller's `OutputSet` renames it into place (or
    /// removes it when this fails).
    pub(super) fn finish(mut self) -> Result<()> {
        self.finish_inner()
    }

    fn finish_inner(&mut self) -> Result<()> {
        let path = self.path.clone();
        if self.error.is_none() {
            self.send_blueprint();
        }
        if let Some(rec) = self.rec.take() {
            let flushed = rec.flush_blocking();
            // Dropping the last handle flushes the batcher and joins rerun's sink thread, so
            // everything logged is in our encoder afterwards.
            drop(rec);
            if let Err(e) = flushed {
                self.fail(write_err(&path, "flushing failed", e));
            }
        }
        let (encoder, sink_error) = {
            let mut st = lock(&self.sink);
            (st.encoder.take(), st.error.take())
        };
        if let Some(err) = self.error.take() {
            return Err(err);
        }
        if let Some(err) = sink_error {
            return Err(write_err(&path, "encoding failed", err));
        }
        let Some(mut encoder) = encoder else {
            return Err(write_err(&path, "internal error", "recording already finished"));
        };
        // End-of-stream marker + footer (chunk manifest), then flush and fsync.
        encoder.finish().map_err(|e| write_err(&path, "cannot write footer", e))?;
        let writer = encoder.into_inner().map_err(|e| write_err(&path, "internal error", e))?;
        let file = writer.into_inner().map_err(|e| write_err(&path, "cannot flush", e.error()))?;
        file.sync_all().map_err(|e| write_err(&path, "cannot sync", e))?;
        drop(file);
        Ok(())
    }
}

impl Drop for Backend {
    /// Dropped without a successful `finish()`: discard everything (the staged temporary file is
    /// removed by its `OutputSet`).
    fn drop(&mut self) {
        drop(self.rec.take());
        let encoder = lock(&self.sink).encoder.take();
        if let Some(encoder) = encoder {
            // `into_inner` skips the footer that `Encoder`'s own `Drop` would try to write.
            drop(encoder.into_inner());
        }
    }
}

#[allow(dead_code)]
fn assert_send() {
    fn is_send<T: Send>() {}
    is_send::<Backend>();
}
