//! Stand-in for [`super::Recorder`]'s backend when twincal is built without the `rerun` feature:
//! `create` always fails, so no value of this type can exist and the other methods are unreachable.

use std::path::Path;

use crate::error::{Error, Result};

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
    pub(super) fn points2d(&mut self, _entity: &str, _pts: &[[f64; 2]], _colors: Option<&[[u8; 4]]>, _radius: Option<f32>) {
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
    pub(super) fn histogram_chart(&mut self, _entity: &str, _edges: &[f64], _counts: &[f64]) {
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
