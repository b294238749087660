//! A laser tracker following a reflector (target) on the flange: the target's position in the
//! tracker's frame, three values per row. The tracker's placement is the rigid transform from
//! the robot's base frame to the tracker's, `y = R(a, b, c)·p + t` with `R = Rx(a)·Ry(b)·Rz(c)`;
//! for data already expressed in the base frame it stays near the identity.

use nalgebra::{Matrix3, Rotation3, Vector3};

/// Names of the tracker's placement parameters, in parameter order.
pub const TRACKER_PARAMS: [&str; 9] = ["tracker.x", "tracker.y", "tracker.z", "tracker.rx", "tracker.ry", "tracker.rz", "tool.x", "tool.y", "tool.z"];

/// Largest plausible |coordinate| of a tracker reading, mm (a laser tracker reaches about 80 m).
pub const MAX_COORD_MM: f64 = 100_000.0;

/// A laser tracker's 3-D target position.
pub struct Point;

/// The base-to-tracker rotation of placement `own` (m, rad): `y = R·p + t`.
pub fn tracker_rotation(own: &[f64]) -> Matrix3<f64> {
    rotation(&own[3..6]).0
}

/// Rx(a)·Ry(b)·Rz(c) of `angles = [a, b, c]` and its derivatives with respect to a, b and c.
pub fn rotation(angles: &[f64]) -> (Matrix3<f64>, [Matrix3<f64>; 3]) {
    let (a, b, c) = (angles[0], angles[1], angles[2]);
    let (sa, ca, sb, cb, sc, cc) = (a.sin(), a.cos(), b.sin(), b.cos(), c.sin(), c.cos());
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, ca, -sa, 0.0, sa, ca);
    let ry = Matrix3::new(cb, 0.0, sb, 0.0, 1.0, 0.0, -sb, 0.0, cb);
    let rz = Matrix3::new(cc, -sc, 0.0, sc, cc, 0.0, 0.0, 0.0, 1.0);
    let drx = Matrix3::new(0.0, 0.0, 0.0, 0.0, -sa, -ca, 0.0, ca, -sa);
    let dry = Matrix3::new(-sb, 0.0, cb, 0.0, 0.0, 0.0, -cb, 0.0, -sb);
    let drz = Matrix3::new(-sc, -cc, 0.0, cc, -sc, 0.0, 0.0, 0.0, 0.0);
    (rx * ry * rz, [drx * ry * rz, rx * dry * rz, rx * ry * drz])
}

impl super::Block for Point {
    fn name(&self) -> &'static str {
        "point"
    }
    fn columns(&self) -> &'static [&'static str] {
        &["x", "y", "z"]
    }
    fn placement_names(&self) -> &'static [&'static str] {
        &TRACKER_PARAMS
    }
    fn placement_is_angle(&self, k: usize) -> bool {
        (3..6).contains(&k)
    }
    fn reading(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64]) {
        let (r, _) = rotation(&own[3..6]);
        let v = r * p[0] + Vector3::new(own[0], own[1], own[2]);
        y[..3].copy_from_slice(v.as_slice());
    }
    fn reading_grad(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]) {
        let (r, dr) = rotation(&own[3..6]);
        let p = &p[0];
        let v = r * p + Vector3::new(own[0], own[1], own[2]);
        y[..3].copy_from_slice(v.as_slice());
        let dv: [Vector3<f64>; 3] = [dr[0] * p, dr[1] * p, dr[2] * p];
        for i in 0..3 {
            dy_dp[i] = r.row(i).transpose();
            let row = &mut dy_down[i * 6..i * 6 + 6];
            row[..3].iter_mut().enumerate().for_each(|(k, v)| *v = if k == i { 1.0 } else { 0.0 });
            for k in 0..3 {
                row[3 + k] = dv[k][i];
            }
        }
    }
    fn exact_grad_reading(&self) -> bool {
        true
    }
}

impl super::FileRows for Point {
    fn describe(&self) -> &'static str {
        "laser-tracker target position"
    }
    fn implausible(&self, k: usize, v: f64) -> Option<String> {
        (v.abs() > MAX_COORD_MM).then(|| {
            format!("tracker coordinate {} = {} mm is implausible (|value| > {MAX_COORD_MM} mm)", super::Block::columns(self)[k], crate::error::shown(v))
        })
    }
}

impl super::Placing for Point {
    fn frame(&self, own: &[f64]) -> super::InstrumentFrame {
        // A tracker reads y = R·p + t: its origin (y = 0) is −Rᵀt in the base frame and its
        // axes are the columns of Rᵀ.
        let rt = tracker_rotation(own).transpose();
        super::InstrumentFrame { origin: -(rt * Vector3::new(own[0], own[1], own[2])), axes: Some(rt) }
    }
    fn panel_titles(&self) -> (&'static str, &'static str) {
        ("Tracker and reflector (mm)", "Tracker rotation (deg)")
    }
    /// The rigid transform that best maps the nominal target points onto the readings
    /// (least squares, by the SVD of their cross-covariance).
    fn locate(&self, p: &[Vector3<f64>], _rot: &[Matrix3<f64>], y: &[f64]) -> Option<(Vec<f64>, Vector3<f64>)> {
        if p.len() < 3 || y.len() != 3 * p.len() {
            return None;
        }
        let ys: Vec<Vector3<f64>> = y.chunks(3).map(|c| Vector3::new(c[0], c[1], c[2])).collect();
        let n = p.len() as f64;
        let pc = p.iter().sum::<Vector3<f64>>() / n;
        let yc = ys.iter().sum::<Vector3<f64>>() / n;
        let h = p.iter().zip(&ys).map(|(a, b)| (a - pc) * (b - yc).transpose()).sum::<Matrix3<f64>>();
        let svd = h.svd(true, true);
        let (u, vt) = (svd.u?, svd.v_t?);
        if svd.singular_values[1] < 1e-9 * svd.singular_values[0].max(1e-300) {
            return None;
        }
        let v = vt.transpose();
        let d = (v * u.transpose()).determinant().signum();
        let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
        let t = yc - r * pc;
        let rot = Rotation3::from_matrix_unchecked(r);
        let m = rot.matrix();
        let b = m[(0, 2)].clamp(-1.0, 1.0).asin();
        let a = (-m[(1, 2)]).atan2(m[(2, 2)]);
        let c = (-m[(0, 1)]).atan2(m[(0, 0)]);
        [t.x, t.y, t.z, a, b, c].iter().all(|v| v.is_finite()).then(|| (vec![t.x, t.y, t.z, a, b, c], Vector3::zeros()))
    }
}
