//! The draw-wire sensor: the cable length from its exit point (base frame) to the tool point,
//! plus a constant length offset.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// Names of the draw-wire's placement parameters, in parameter order.
pub const CABLE_PARAMS: [&str; 7] = ["exit.x", "exit.y", "exit.z", "length_offset", "tool.x", "tool.y", "tool.z"];

/// Largest plausible cable length, mm (100 m: the longest draw-wire sensors made measure about
/// 60 m). Anything beyond is rejected.
pub const MAX_L_MM: f64 = 100_000.0;

/// A draw-wire's cable length: |tool point − exit point| + length offset.
pub struct Length;

impl super::Block for Length {
    fn name(&self) -> &'static str {
        "length"
    }
    fn columns(&self) -> &'static [&'static str] {
        &["L"]
    }
    fn placement_names(&self) -> &'static [&'static str] {
        &CABLE_PARAMS
    }
    fn offset_index(&self) -> Option<usize> {
        Some(3)
    }
    fn reading(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64]) {
        y[0] = (p[0] - Vector3::new(own[0], own[1], own[2])).norm() + own[3];
    }
    fn reading_grad(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]) {
        let d = p[0] - Vector3::new(own[0], own[1], own[2]);
        let dist = d.norm().max(1e-12);
        let u = d / dist;
        y[0] = dist + own[3];
        dy_dp[0] = u;
        dy_down[..4].copy_from_slice(&[-u.x, -u.y, -u.z, 1.0]);
    }
}

impl super::FileRows for Length {
    fn describe(&self) -> &'static str {
        "draw-wire cable length"
    }
    fn implausible(&self, _k: usize, l: f64) -> Option<String> {
        if l <= 0.0 {
            return Some(format!("cable length must be positive, found {l}"));
        }
        (l > MAX_L_MM).then(|| format!("cable length {} mm is implausible (no draw-wire sensor measures more than {MAX_L_MM} mm)", crate::error::shown(l)))
    }
}

impl super::Placing for Length {
    fn frame(&self, own: &[f64]) -> super::InstrumentFrame {
        super::InstrumentFrame { origin: Vector3::new(own[0], own[1], own[2]), axes: None }
    }
    fn panel_titles(&self) -> (&'static str, &'static str) {
        ("Sensor (mm)", "Sensor angles (deg)")
    }
    fn locate(&self, p: &[Vector3<f64>], _rot: &[Matrix3<f64>], y: &[f64]) -> Option<(Vec<f64>, Vector3<f64>)> {
        let (e, c) = multilaterate(p, y)?;
        Some((vec![e[0], e[1], e[2], c], Vector3::zeros()))
    }
}

/// Exit point and length offset by linear multilateration from known tool points (m):
/// (L − c)² = |p − e|² is linear in (e, c, |e|² − c²).
pub fn multilaterate(points: &[Vector3<f64>], lengths: &[f64]) -> Option<([f64; 3], f64)> {
    let m = points.len();
    if m < 6 {
        return None;
    }
    let a = DMatrix::from_fn(m, 5, |i, k| match k {
        0..=2 => -2.0 * points[i][k],
        3 => 2.0 * lengths[i],
        _ => 1.0,
    });
    let b = DVector::from_fn(m, |i, _| lengths[i] * lengths[i] - points[i].norm_squared());
    let sol = a.svd(true, true).solve(&b, 1e-12).ok()?;
    Some(([sol[0], sol[1], sol[2]], sol[3]))
}
