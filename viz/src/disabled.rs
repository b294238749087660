//! Stand-in for [`super::Recorder`]'s backend when twincal is built without the `rerun` feature:
//! `create` always fails, so no value of this type can exist and the other methods are unreachable.

use std::path::Path;

use twincal::error::{Error, Result};

pub(super) enum Backend {}

impl Backend {
    pub(super) fn with_file(_app_id: &str, _file: std::fs::File, path: &Path) -> Result<Backend> {
        Err(Error::Invalid(format!(
            "cannot write {}: twincal was built without the `rerun` feature \
             (rebuild with `cargo build --features rerun`, which is on by default)",
            path.display()
        )))
    }
    pub(super) fn set_time_index(&mut self, _timeline: &str, _idx: i64) {
        match *self {}
    }
    pub(super) fn set_time_seconds(&mut self, _timeline: &str, _secs: f64) {
        match *self {}
    }
    pub(super) fn points2d(&mut self, _e: &str, _p: &[[f64; 2]], _c: Option<&[[u8; 4]]>, _r: Option<f32>, _l: Option<&[String]>, _s: bool) {
        match *self {}
    }
    pub(super) fn points_hover(&mut self, _e: &str, _p: &[[f64; 3]], _c: Option<&[[u8; 4]]>, _r: Option<f32>, _l: &[String]) {
        match *self {}
    }
    pub(super) fn line_strips2d(&mut self, _e: &str, _s: &[Vec<[f64; 2]>], _c: &[[u8; 4]], _w: f32) {
        match *self {}
    }
    pub(super) fn segments(&mut self, _e: &str, _s: &[Vec<[f64; 3]>], _c: &[[u8; 4]], _r: f32) {
        match *self {}
    }
    pub(super) fn axes(&mut self, _e: &str, _l: f32) {
        match *self {}
    }
    pub(super) fn series_style(&mut self, _e: &str, _n: &str, _c: [u8; 4], _p: bool, _s: f32) {
        match *self {}
    }
    pub(super) fn set_static(&mut self, _on: bool) {
        match *self {}
    }
    pub(super) fn layout(&mut self, _b: super::Blueprint) {
        match *self {}
    }
    pub(super) fn points(&mut self, _entity: &str, _pts_mm: &[[f64; 3]], _colors: Option<&[[u8; 4]]>, _radii_mm: Option<f32>, _labels: Option<&[String]>) {
        match *self {}
    }
    pub(super) fn line_strips(&mut self, _entity: &str, _strips: &[Vec<[f64; 3]>], _color: [u8; 4], _radius_mm: f32) {
        match *self {}
    }
    pub(super) fn transform(&mut self, _entity: &str, _t: [f64; 3], _r: [[f64; 3]; 3]) {
        match *self {}
    }
    pub(super) fn scalar(&mut self, _entity: &str, _value: f64) {
        match *self {}
    }
    pub(super) fn bar_chart(&mut self, _entity: &str, _values: &[f64]) {
        match *self {}
    }
    pub(super) fn histogram_chart(&mut self, _entity: &str, _edges: &[f64], _counts: &[f64], _color: Option<[u8; 4]>) {
        match *self {}
    }
    pub(super) fn text(&mut self, _entity: &str, _text: &str) {
        match *self {}
    }
    pub(super) fn static_text(&mut self, _entity: &str, _markdown: &str) {
        match *self {}
    }
    pub(super) fn finish(self) -> Result<()> {
        match self {}
    }
}
