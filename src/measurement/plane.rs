//! A face of an artifact (a flat, a gauge block's top, a step) touched by a probe on the flange
//! or read by a dial indicator on it. Each face is an unknown plane (a station of its own: the
//! rows say which face, on which placement of the artifact), the probe's stylus centre (or the
//! indicator's zero point) on the flange is the target. The model's reading is how far the
//! target lies below the plane's offset along its normal, `y = d − n·p`:
//!
//! - a touch-trigger probe ([`Plane`]) reads nothing, every row is a contact: `y = 0`, the
//!   stylus radius and the probe's mean pre-travel folded into the plane's offset `d` (its
//!   pre-travel's variation with the approach direction, "lobing", is what remains);
//! - a dial indicator ([`Indicator`]) reads its plunger's travel (`indicator` column, mm):
//!   pushed in by `y` when the zero point stands `y` below the offset.
//!
//! A face fixes the target along its normal only; several faces (or one face at several
//! placements) turned differently fix the arm; a known step between two parallel faces
//! ([`crate::calib::model::Spacing`]) alone gives it its scale, and no face sees the base frame.
//!
//! The normal is two angles about a pole no cell's face points along (the diagonal `(1,1,1)/√3`),
//! so horizontal and vertical faces alike sit far from the parametrisation's singular points.

use super::FeatureKind;
use nalgebra::{DMatrix, Matrix3, Vector3};

/// Names of the placement parameters: the face's normal (two angles) and offset, the target on
/// the flange.
pub const PLANE_PARAMS: [&str; 6] = ["plane.a", "plane.b", "plane.d", "tool.x", "tool.y", "tool.z"];

/// Least rows on one face to place it (and the target on the flange) from the data.
pub const MIN_ROWS_PER_FACE: usize = 6;

/// Largest plausible |dial indicator reading|, mm (a long-travel indicator reads 50 mm).
pub const MAX_INDICATOR_MM: f64 = 100.0;

/// The parametrisation's frame: its z axis is the pole (the diagonal), x and y complete it.
fn pole_frame() -> Matrix3<f64> {
    let s2 = std::f64::consts::SQRT_2;
    let s3 = 3f64.sqrt();
    let s6 = 6f64.sqrt();
    Matrix3::from_columns(&[Vector3::new(1.0 / s2, -1.0 / s2, 0.0), Vector3::new(1.0 / s6, 1.0 / s6, -2.0 / s6), Vector3::new(1.0 / s3, 1.0 / s3, 1.0 / s3)])
}

/// The unit normal of angles `a, b` and its derivatives with respect to them.
pub fn normal(a: f64, b: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let q = pole_frame();
    let (sa, ca, sb, cb) = (a.sin(), a.cos(), b.sin(), b.cos());
    (q * Vector3::new(cb * ca, cb * sa, sb), q * Vector3::new(-cb * sa, cb * ca, 0.0), q * Vector3::new(-sb * ca, -sb * sa, cb))
}

/// The angles `a, b` of unit normal `n` ([`normal`]'s inverse).
pub fn angles(n: &Vector3<f64>) -> (f64, f64) {
    let l = pole_frame().transpose() * n.normalize();
    (l.y.atan2(l.x), l.z.clamp(-1.0, 1.0).asin())
}

/// A plane's own parameters `[a, b, d]` of its unit normal and offset (m).
pub fn own_of(n: &Vector3<f64>, d: f64) -> Vec<f64> {
    let (a, b) = angles(n);
    vec![a, b, d]
}

/// The shared residual block: `y = d − n·p` and its derivatives.
fn block(own: &[f64], p: &Vector3<f64>, y: &mut [f64], grad: Option<(&mut [Vector3<f64>], &mut [f64])>) {
    let (n, da, db) = normal(own[0], own[1]);
    y[0] = own[2] - n.dot(p);
    if let Some((dy_dp, dy_down)) = grad {
        dy_dp[0] = -n;
        dy_down[0] = -da.dot(p);
        dy_down[1] = -db.dot(p);
        dy_down[2] = 1.0;
    }
}

/// The face through points `x` (base frame, m) whose readings `y` (m) say how far below it each
/// stands: its unit normal (pointing to the side `side` lies on) and offset, `n·x + y = d` by
/// least squares (the normal from the points' scatter, the readings in the offset).
fn fit_face(x: &[Vector3<f64>], y: &[f64], side: &Vector3<f64>) -> Option<(Vector3<f64>, f64)> {
    let m = x.len() as f64;
    // The points moved up by their readings lie on the face: the normal of their scatter, with
    // the readings applied along the last one found.
    let mut n = Vector3::zeros();
    for _ in 0..20 {
        let shifted: Vec<Vector3<f64>> = x.iter().zip(y).map(|(v, yi)| v + n * *yi).collect();
        let c = shifted.iter().sum::<Vector3<f64>>() / m;
        let eig = shifted.iter().map(|v| (v - c) * (v - c).transpose()).sum::<Matrix3<f64>>().symmetric_eigen();
        let k = (0..3).min_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]))?;
        let mut next: Vector3<f64> = eig.eigenvectors.column(k).into_owned();
        if next.dot(side) < 0.0 {
            next = -next;
        }
        let done = (next - n).norm() < 1e-14;
        n = next;
        if done {
            break;
        }
    }
    let d = x.iter().zip(y).map(|(v, yi)| n.dot(v) + yi).sum::<f64>() / m;
    (n.iter().all(|v| v.is_finite()) && d.is_finite()).then_some((n, d))
}

/// Given a face (`n`, `d`), the target `b` on the flange by least squares with a new offset:
/// `n·(p_i + R_i·b) + y_i = d`.
fn target_on(n: &Vector3<f64>, p: &[Vector3<f64>], rot: &[Matrix3<f64>], y: &[f64]) -> Option<(Vector3<f64>, f64)> {
    let mut a = DMatrix::zeros(p.len(), 4);
    let mut rhs = nalgebra::DVector::zeros(p.len());
    for (i, (pi, ri)) in p.iter().zip(rot).enumerate() {
        let g = ri.transpose() * n;
        a.row_mut(i).copy_from_slice(&[g.x, g.y, g.z, -1.0]);
        rhs[i] = -y[i] - n.dot(pi);
    }
    let z = a.svd(true, true).solve(&rhs, 1e-10).ok()?;
    Some((Vector3::new(z[0], z[1], z[2]), z[3]))
}

/// The face and the target on the flange from the flange's origins `p`, rotations `rot` and
/// readings `y` (m): linear in `M = n·bᵀ`, `n` and `d` (`Σ R_i∘M + n·p_i − d = −y_i`, the
/// smallest singular vector with `|n| = 1`), then refined by turns (the face given the target,
/// the target given the face).
fn locate_face(p: &[Vector3<f64>], rot: &[Matrix3<f64>], y: &[f64]) -> Option<(Vector3<f64>, f64, Vector3<f64>)> {
    let rows = p.len();
    if rows < MIN_ROWS_PER_FACE || rot.len() != rows || y.len() != rows || super::socket::turn_spread(rot) < super::socket::MIN_TURN_RAD {
        return None;
    }
    // (An indicator's readings are a column of their own, their coefficient the scale's.)
    let cols = if y.iter().any(|v| *v != 0.0) { 14 } else { 13 };
    if rows < cols {
        // Fewer contacts than the linear start's unknowns: no start from this face alone (a
        // face of other contacts gives the stylus, and this one is placed about it).
        return None;
    }
    let mut a = DMatrix::zeros(rows, cols);
    for (i, (pi, ri)) in p.iter().zip(rot).enumerate() {
        for j in 0..3 {
            for k in 0..3 {
                a[(i, 3 * j + k)] = ri[(j, k)];
            }
            a[(i, 9 + j)] = pi[j];
        }
        a[(i, 12)] = -1.0;
        if cols == 14 {
            a[(i, 13)] = y[i];
        }
    }
    let svd = a.svd(false, true);
    let vt = svd.v_t?;
    let k = (0..cols).min_by(|&i, &j| svd.singular_values[i].total_cmp(&svd.singular_values[j]))?;
    let z = vt.row(k).transpose();
    let n = Vector3::new(z[9], z[10], z[11]);
    let scale = n.norm();
    if !(scale > 1e-12) {
        return None;
    }
    let n = n / scale;
    let m = Matrix3::from_row_slice(&z.as_slice()[..9]) / scale;
    let mut b = m.transpose() * n;
    // The target sits on the face's far side from the flange: the face's normal points back
    // toward the flange.
    let side = |b: &Vector3<f64>| -> Vector3<f64> { rot.iter().map(|ri| -(ri * b)).sum::<Vector3<f64>>() / rows as f64 };
    let (mut n, mut d) = (n, 0.0);
    for _ in 0..50 {
        let x: Vec<Vector3<f64>> = p.iter().zip(rot).map(|(pi, ri)| pi + ri * b).collect();
        let s = side(&b);
        let face = fit_face(&x, y, &if s.norm() > 1e-6 { s } else { n })?;
        n = face.0;
        let (nb, nd) = target_on(&n, p, rot, y)?;
        let step = (nb - b).norm();
        (b, d) = (nb, nd);
        if step < 1e-12 {
            break;
        }
    }
    (b.iter().all(|v| v.is_finite()) && d.is_finite()).then_some((n, d, b))
}

/// The face alone for a known target `tool` on the flange.
fn face_about(p: &[Vector3<f64>], rot: &[Matrix3<f64>], y: &[f64], tool: &Vector3<f64>) -> Option<Vec<f64>> {
    if p.len() < 3 {
        return None;
    }
    let x: Vec<Vector3<f64>> = p.iter().zip(rot).map(|(pi, ri)| pi + ri * tool).collect();
    let side = p.iter().zip(&x).map(|(pi, xi)| pi - xi).sum::<Vector3<f64>>();
    let (n, d) = fit_face(&x, y, &side)?;
    Some(own_of(&n, d))
}

/// One face's rows as the locating functions take them: the flange's origins, rotations and the
/// readings (m).
pub type FaceRows = (Vec<Vector3<f64>>, Vec<Matrix3<f64>>, Vec<f64>);

/// The target on the flange that every face's rows `faces` agree on, and its RMS misfit (m):
/// from each face's own start ([`locate_face`]), by turns (each face given the target, the target
/// given every face), the best of those starts.
fn shared_target(faces: &[FaceRows]) -> Option<Vector3<f64>> {
    let starts: Vec<Vector3<f64>> = faces.iter().filter_map(|(p, r, y)| locate_face(p, r, y).map(|f| f.2)).collect();
    let mut best: Option<(f64, Vector3<f64>)> = None;
    for start in starts {
        let mut b = start;
        let mut misfit = f64::INFINITY;
        for _ in 0..30 {
            let normals: Option<Vec<Vector3<f64>>> = faces.iter().map(|(p, r, y)| face_about(p, r, y, &b).map(|o| normal(o[0], o[1]).0)).collect();
            let Some(normals) = normals else { break };
            // The target and every face's offset, linear given the normals.
            let (rows, k) = (faces.iter().map(|f| f.0.len()).sum::<usize>(), faces.len());
            let mut a = DMatrix::zeros(rows, 3 + k);
            let mut rhs = nalgebra::DVector::zeros(rows);
            let mut i = 0;
            for (f, ((p, rot, y), n)) in faces.iter().zip(&normals).enumerate() {
                for ((pi, ri), yi) in p.iter().zip(rot).zip(y) {
                    let g = ri.transpose() * n;
                    a[(i, 0)] = g.x;
                    a[(i, 1)] = g.y;
                    a[(i, 2)] = g.z;
                    a[(i, 3 + f)] = -1.0;
                    rhs[i] = -yi - n.dot(pi);
                    i += 1;
                }
            }
            let Ok(z) = a.clone().svd(true, true).solve(&rhs, 1e-10) else { break };
            b = Vector3::new(z[0], z[1], z[2]);
            misfit = ((&a * &z - &rhs).norm_squared() / rows.max(1) as f64).sqrt();
        }
        if misfit.is_finite() && best.is_none_or(|(m, _)| misfit < m) {
            best = Some((misfit, b));
        }
    }
    best.map(|(_, b)| b)
}

/// A touch-trigger probe's contacts with a face: no reading.
pub struct Plane;

/// A dial indicator on the flange reading a face: its plunger's travel.
pub struct Indicator;

/// The residual block and the placing both share.
macro_rules! face_instrument {
    ($t:ty) => {
        impl super::Block for $t {
            fn name(&self) -> &'static str {
                <$t>::NAME
            }
            fn columns(&self) -> &'static [&'static str] {
                <$t>::COLUMNS
            }
            fn placement_names(&self) -> &'static [&'static str] {
                &PLANE_PARAMS
            }
            fn placement_is_angle(&self, k: usize) -> bool {
                k < 2
            }
            fn reading(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64]) {
                block(own, &p[0], y, None);
            }
            fn reading_grad(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]) {
                block(own, &p[0], y, Some((dy_dp, dy_down)));
            }
            fn exact_grad_reading(&self) -> bool {
                true
            }
        }

        impl super::Placing for $t {
            fn frame(&self, own: &[f64]) -> super::InstrumentFrame {
                let n = normal(own[0], own[1]).0;
                super::InstrumentFrame { origin: n * own[2], axes: None }
            }
            fn panel_titles(&self) -> (&'static str, &'static str) {
                ("Faces and target (mm)", "Face normals (deg)")
            }
            fn locate(&self, p: &[Vector3<f64>], rot: &[Matrix3<f64>], y: &[f64]) -> Option<(Vec<f64>, Vector3<f64>)> {
                let (n, d, b) = locate_face(p, rot, y)?;
                Some((own_of(&n, d), b))
            }
            fn locate_about(&self, p: &[Vector3<f64>], rot: &[Matrix3<f64>], y: &[f64], tool: &Vector3<f64>) -> Option<Vec<f64>> {
                face_about(p, rot, y, tool)
            }
            fn locate_target(&self, stations: &[FaceRows]) -> Option<Vector3<f64>> {
                shared_target(stations)
            }
        }
    };
}

impl Plane {
    const NAME: &'static str = "plane";
    const COLUMNS: &'static [&'static str] = &["depth"];
}

impl Indicator {
    const NAME: &'static str = "indicator";
    const COLUMNS: &'static [&'static str] = &["indicator"];
}

face_instrument!(Plane);
face_instrument!(Indicator);

impl super::FileRows for Plane {
    fn describe(&self) -> &'static str {
        "touch probe on a face"
    }
    super::reads_nothing!();
    fn feature(&self) -> Option<FeatureKind> {
        Some(FeatureKind::Plane)
    }
}

impl super::FileRows for Indicator {
    fn describe(&self) -> &'static str {
        "dial indicator on a face"
    }
    fn implausible(&self, _k: usize, v: f64) -> Option<String> {
        (v.abs() > MAX_INDICATOR_MM).then(|| format!("indicator = {} mm is implausible (|value| > {MAX_INDICATOR_MM} mm)", crate::error::shown(v)))
    }
    fn feature(&self) -> Option<FeatureKind> {
        Some(FeatureKind::Plane)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn normal_angles_round_trip_on_horizontal_and_vertical_faces() {
        for n in [Vector3::z(), -Vector3::z(), Vector3::x(), -Vector3::y(), Vector3::new(0.3, -0.2, 0.9).normalize()] {
            let (a, b) = angles(&n);
            assert!((normal(a, b).0 - n).norm() < 1e-12, "{n:?}");
            assert!(b.abs() < 1.2, "far from the pole: {b}");
        }
    }

    #[test]
    fn a_face_and_the_stylus_are_found_from_contacts_alone() {
        let (n, d, b) = (Vector3::new(0.1, -0.05, 1.0).normalize(), 0.21, Vector3::new(0.01, -0.02, 0.12));
        let (mut p, mut rot, mut y) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..30 {
            let f = i as f64;
            let r = Rotation3::from_euler_angles(std::f64::consts::PI + 0.4 * (0.7 * f).sin(), 0.4 * (1.3 * f).cos(), 2.1 * f).into_inner();
            // The contact point spread over the face; the flange above it.
            let on = Vector3::new(0.4 + 0.02 * (0.9 * f).sin(), 0.1 + 0.02 * (0.5 * f).cos(), 0.0);
            let on = on + n * (d - n.dot(&on));
            let reading = if i % 2 == 0 { 0.0 } else { 0.001 * (f * 0.3).sin() };
            p.push(on - n * reading - r * b);
            rot.push(r);
            y.push(reading);
        }
        let (fn_, fd, fb) = locate_face(&p, &rot, &y).expect("located");
        assert!((fn_ - n).norm() < 1e-9 && (fd - d).abs() < 1e-9 && (fb - b).norm() < 1e-9, "{fn_:?} {fd} {fb:?}");
        let own = face_about(&p, &rot, &y, &b).expect("placed");
        assert!((normal(own[0], own[1]).0 - n).norm() < 1e-9 && (own[2] - d).abs() < 1e-9);
        assert!(locate_face(&p[..4], &rot[..4], &y[..4]).is_none(), "too few contacts");
    }
}
