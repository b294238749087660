//! A laser tracker following a 6-D probe on the flange (a T-Mac, a camera target): the probe's
//! position and orientation in the tracker's frame.
//!
//! A dataset file holds a pose as `x, y, z` (mm) and three Euler angles `rx, ry, rz` (degrees,
//! in the convention [`Euler`] names; intrinsic X-Y-Z unless told). A loaded row holds them in
//! intrinsic X-Y-Z (the loader turns another convention's angles into these). The model reads it as nine values
//! that are all lengths, so that every residual is a point residual and every Jacobian a point
//! Jacobian the chain already gives: the probe's origin `x, y, z`, and its x and y axes scaled
//! by a lever of [`LEVER_MM`], `ux, uy, uz` and `vx, vy, vz` (both in the tracker's frame). An
//! orientation error of δ rad moves an axis tip by δ·lever, so the lever is the weight of the
//! orientation against the position: 100 mm makes a T-Mac's stated orientation accuracy
//! (about 0.01°, 0.17 mrad → 0.017 mm) weigh like a tracker's position accuracy (15 µm + 6 µm/m).
//! Nine values carry six independent numbers (each axis has unit length and they are
//! orthogonal), so the axis values' residuals are smaller than their position ones by about
//! √(2/3) for the same angular error.
//!
//! Placement: the base-to-tracker transform as for a [`Point`]
//! (`y = R·p + t`, `R = Rx(a)·Ry(b)·Rz(c)`), then the probe's orientation on the flange
//! (`tool.rx, tool.ry, tool.rz`, the same convention) and its origin (`tool.x, tool.y, tool.z`).
//! The model carries three points of the probe's frame to the base (its origin and the tips of
//! its x and y axes at the lever), and the tracker reads the origin and the two axis vectors.

use super::point::{rotation, Point};
use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// The lever (mm) at which a pose's axes are read: the weight of an orientation error against
/// a position error (see the module docs).
pub const LEVER_MM: f64 = 100.0;
const LEVER_M: f64 = LEVER_MM * 1e-3;

/// Names of the pose tracker's placement parameters, in parameter order.
pub const POSE_PARAMS: [&str; 12] =
    ["tracker.x", "tracker.y", "tracker.z", "tracker.rx", "tracker.ry", "tracker.rz", "tool.rx", "tool.ry", "tool.rz", "tool.x", "tool.y", "tool.z"];

/// Number of the pose tracker's own placement parameters (all but the probe's origin).
const N_OWN: usize = POSE_PARAMS.len() - 3;

/// The probe's orientation on the flange of placement `own` (the pose tracker's own
/// parameters): `Rx(a)·Ry(b)·Rz(c)` of `tool.rx, tool.ry, tool.rz`.
pub fn probe_rotation(own: &[f64]) -> Matrix3<f64> {
    rotation(&own[6..9]).0
}

/// Farthest a pose probe's origin is placed from the flange's by the placement's start, m.
const MAX_PROBE_OFFSET_M: f64 = 1.0;
/// The weight, per row, with which the start holds a probe's origin to the flange's where the
/// rows would put it beyond [`MAX_PROBE_OFFSET_M`] (m of residual per m of origin).
const TOOL_HOLD: f64 = 1e-2;

/// Largest plausible |Euler angle| of a pose reading, degrees.
pub const MAX_ANGLE_DEG: f64 = 720.0;

/// An Euler-angle convention: three rotation axes, about the moving frame's axes (intrinsic,
/// written in capitals as `XYZ`) or the fixed frame's (extrinsic, `xyz`), as SciPy names them.
/// Intrinsic `XYZ` is `R = Rx(a)·Ry(b)·Rz(c)`; extrinsic `xyz` is `R = Rz(c)·Ry(b)·Rx(a)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Euler {
    /// The axes, 0 = x, 1 = y, 2 = z, in the order the angles are given.
    pub axes: [usize; 3],
    /// About the moving frame's axes (intrinsic) rather than the fixed frame's (extrinsic).
    pub intrinsic: bool,
}

impl Default for Euler {
    fn default() -> Self {
        Euler::XYZ
    }
}

impl Euler {
    /// Intrinsic X-Y-Z: `R = Rx(a)·Ry(b)·Rz(c)` (the twin's convention, and the UR10 data's).
    pub const XYZ: Euler = Euler { axes: [0, 1, 2], intrinsic: true };
    /// Intrinsic Z-Y-X: `R = Rz(a)·Ry(b)·Rx(c)` (KUKA's A, B, C).
    pub const ZYX: Euler = Euler { axes: [2, 1, 0], intrinsic: true };

    /// Reads a convention: three letters of `xyz` (extrinsic) or `XYZ` (intrinsic), no two
    /// consecutive ones the same (`ZYX`, `xyz`, `ZYZ`, ...).
    pub fn parse(s: &str) -> Result<Euler, String> {
        let bad = || {
            format!(
                "Euler convention '{s}' is not three axis letters: use capitals for rotations about the moving axes (intrinsic, e.g. XYZ, ZYX, ZYZ) \
                 or lower case for the fixed axes (extrinsic, e.g. xyz), no axis twice in a row"
            )
        };
        let b = s.trim().as_bytes();
        if b.len() != 3 {
            return Err(bad());
        }
        let upper = b.iter().all(|c| c.is_ascii_uppercase());
        if !upper && !b.iter().all(|c| c.is_ascii_lowercase()) {
            return Err(bad());
        }
        let mut axes = [0; 3];
        for (a, c) in axes.iter_mut().zip(b) {
            *a = match c.to_ascii_lowercase() {
                b'x' => 0,
                b'y' => 1,
                b'z' => 2,
                _ => return Err(bad()),
            };
        }
        if axes[0] == axes[1] || axes[1] == axes[2] {
            return Err(bad());
        }
        Ok(Euler { axes, intrinsic: upper })
    }

    /// The convention's name (`XYZ`, `xyz`).
    pub fn name(&self) -> String {
        self.axes.iter().map(|&a| if self.intrinsic { ['X', 'Y', 'Z'][a] } else { ['x', 'y', 'z'][a] }).collect()
    }

    /// The rotation of angles `a` (rad), in the order the convention gives them.
    pub fn matrix(&self, a: [f64; 3]) -> Matrix3<f64> {
        let r = |k: usize| Rotation3::from_axis_angle(&[Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()][self.axes[k]], a[k]).into_inner();
        if self.intrinsic {
            r(0) * r(1) * r(2)
        } else {
            r(2) * r(1) * r(0)
        }
    }
}

impl Euler {
    /// The angles (rad) of rotation `m` in this convention: the inverse of [`Self::matrix`],
    /// the middle angle in [−90°, 90°] (three different axes) or [0°, 180°] (the first axis
    /// repeated, as `ZYZ`); in gimbal lock the third angle is taken as 0.
    pub fn angles(&self, m: &Matrix3<f64>) -> [f64; 3] {
        // An extrinsic convention is the intrinsic one of the reversed axes, angles reversed.
        if !self.intrinsic {
            let rev = Euler { axes: [self.axes[2], self.axes[1], self.axes[0]], intrinsic: true };
            let [a, b, c] = rev.angles(m);
            return [c, b, a];
        }
        let [i, j, third] = self.axes;
        // k: the axis neither i nor j; s: +1 when (i, j, k) is a cyclic order of (x, y, z).
        let k = 3 - i - j;
        let s = if (j + 3 - i) % 3 == 1 { 1.0 } else { -1.0 };
        // Locked only where the entries that set the outer angles vanish (not within a band of
        // sin b ≈ ±1, where they are small but still exact).
        if third != i {
            let cb = m[(i, i)].hypot(m[(i, j)]);
            let b = (s * m[(i, k)]).atan2(cb);
            if cb < 1e-12 {
                return [(s * m[(k, j)]).atan2(m[(j, j)]), b, 0.0];
            }
            [(-s * m[(j, k)]).atan2(m[(k, k)]), b, (-s * m[(i, j)]).atan2(m[(i, i)])]
        } else {
            let sb = m[(i, j)].hypot(m[(i, k)]);
            let b = sb.atan2(m[(i, i)]);
            if sb < 1e-12 {
                // b = 0 turns by a + c about i, b = 180° by a − c.
                let t = if m[(i, i)] > 0.0 { -s } else { s };
                return [(t * m[(j, k)]).atan2(m[(j, j)]), b, 0.0];
            }
            [m[(j, i)].atan2(-s * m[(k, i)]), b, m[(i, j)].atan2(s * m[(i, k)])]
        }
    }
}

impl TryFrom<String> for Euler {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Euler::parse(&s)
    }
}

impl From<Euler> for String {
    fn from(e: Euler) -> String {
        e.name()
    }
}

impl std::fmt::Display for Euler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

impl std::str::FromStr for Euler {
    type Err = String;
    fn from_str(s: &str) -> Result<Euler, String> {
        Euler::parse(s)
    }
}

/// Intrinsic X-Y-Z angles (rad) of rotation `m`: the inverse of [`Euler::XYZ`]'s matrix, the
/// middle angle in [−90°, 90°].
pub fn xyz_angles(m: &Matrix3<f64>) -> [f64; 3] {
    let b = m[(0, 2)].clamp(-1.0, 1.0).asin();
    let a = (-m[(1, 2)]).atan2(m[(2, 2)]);
    let c = (-m[(0, 1)]).atan2(m[(0, 0)]);
    [a, b, c]
}

/// The rotation nearest to `m` (Frobenius norm), by its SVD.
pub fn nearest_rotation(m: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let d = (u * vt).determinant().signum();
    Some(u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt)
}

/// The probe's orientation of a nine-value reading (m or mm): its x and y axes, made
/// orthonormal.
pub fn reading_rotation(y: &[f64]) -> Option<Matrix3<f64>> {
    let u = Vector3::new(y[3], y[4], y[5]);
    let v = Vector3::new(y[6], y[7], y[8]);
    let w = u.cross(&v);
    nearest_rotation(&Matrix3::from_columns(&[u, v, w]).scale(1.0 / u.norm().max(1e-300)))
}

/// A 6-D probe's pose, read as its origin and two axis vectors at the lever.
pub struct Pose;

impl super::Block for Pose {
    fn name(&self) -> &'static str {
        "pose"
    }
    fn columns(&self) -> &'static [&'static str] {
        &["x", "y", "z", "ux", "uy", "uz", "vx", "vy", "vz"]
    }
    fn placement_names(&self) -> &'static [&'static str] {
        &POSE_PARAMS
    }
    fn placement_is_angle(&self, k: usize) -> bool {
        (3..9).contains(&k)
    }
    fn n_station(&self) -> usize {
        6
    }
    fn value_groups(&self) -> &'static [usize] {
        &[0, 0, 0, 1, 1, 1, 1, 1, 1]
    }
    fn n_targets(&self) -> usize {
        3
    }
    fn targets(&self, own: &[f64], tool: &Vector3<f64>, local: &mut [Vector3<f64>], dlocal: &mut [Vector3<f64>]) {
        let (r, dr) = rotation(&own[6..9]);
        local[0] = *tool;
        dlocal[..N_OWN].iter_mut().for_each(|v| *v = Vector3::zeros());
        for t in 1..3 {
            let e = Vector3::ith(t - 1, LEVER_M);
            local[t] = tool + r * e;
            let d = &mut dlocal[t * N_OWN..(t + 1) * N_OWN];
            d.iter_mut().for_each(|v| *v = Vector3::zeros());
            for m in 0..3 {
                d[6 + m] = dr[m] * e;
            }
        }
    }
    fn reading(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64]) {
        let (r, _) = rotation(&own[3..6]);
        let o = r * p[0] + Vector3::new(own[0], own[1], own[2]);
        let (u, v) = (r * (p[1] - p[0]), r * (p[2] - p[0]));
        y[..3].copy_from_slice(o.as_slice());
        y[3..6].copy_from_slice(u.as_slice());
        y[6..9].copy_from_slice(v.as_slice());
    }
    fn reading_grad(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]) {
        self.reading(own, p, y);
        let (r, dr) = rotation(&own[3..6]);
        let vecs = [p[0], p[1] - p[0], p[2] - p[0]];
        for block in 0..3 {
            for c in 0..3 {
                let i = 3 * block + c;
                let row = r.row(c).transpose();
                let g = &mut dy_dp[i * 3..i * 3 + 3];
                g.iter_mut().for_each(|v| *v = Vector3::zeros());
                if block == 0 {
                    g[0] = row;
                } else {
                    g[0] = -row;
                    g[block] = row;
                }
                let d = &mut dy_down[i * N_OWN..(i + 1) * N_OWN];
                d.iter_mut().for_each(|v| *v = 0.0);
                if block == 0 {
                    d[c] = 1.0;
                }
                for k in 0..3 {
                    d[3 + k] = (dr[k] * vecs[block])[c];
                }
            }
        }
    }
}

impl super::FileRows for Pose {
    fn describe(&self) -> &'static str {
        "laser-tracker 6-D probe pose"
    }
    fn file_columns(&self) -> &'static [&'static str] {
        &["x", "y", "z", "rx", "ry", "rz"]
    }
    fn file_angles(&self) -> usize {
        3
    }
    fn implausible(&self, k: usize, v: f64) -> Option<String> {
        if k < 3 {
            return Point.implausible(k, v);
        }
        (v.abs() > MAX_ANGLE_DEG).then(|| {
            format!(
                "probe angle {} = {} degrees is implausible (|angle| > {MAX_ANGLE_DEG}; the angles must be in degrees)",
                self.file_columns()[k],
                crate::error::shown(v)
            )
        })
    }
    fn values_of_file(&self, file: &[f64], out: &mut [f64]) {
        out[..3].copy_from_slice(&file[..3]);
        let r = Euler::XYZ.matrix([file[3].to_radians(), file[4].to_radians(), file[5].to_radians()]);
        for (k, chunk) in out[3..9].chunks_mut(3).enumerate() {
            let a = r.column(k) * LEVER_MM;
            chunk.copy_from_slice(a.as_slice());
        }
    }
    fn file_of_values(&self, v: &[f64], euler: Euler) -> Vec<f64> {
        let angles = reading_rotation(v).map_or([f64::NAN; 3], |r| euler.angles(&r).map(f64::to_degrees));
        v[..3].iter().copied().chain(angles).collect()
    }
}

impl super::Placing for Pose {
    fn frame(&self, own: &[f64]) -> super::InstrumentFrame {
        super::point::Point.frame(own)
    }
    fn target_rotation(&self, own: &[f64]) -> Matrix3<f64> {
        probe_rotation(own)
    }
    fn panel_titles(&self) -> (&'static str, &'static str) {
        ("Tracker and probe (mm)", "Tracker and probe rotations (deg)")
    }
    /// The tracker's rotation and the probe's from the orientations alone: the rotation
    /// between two readings is the rotation between the same two flange orientations seen
    /// through the tracker (`M_i·M_jᵀ = R·F_i·F_jᵀ·Rᵀ`), so the tracker's rotation maps the
    /// flange's rotation axes onto the readings' (a rigid fit of axis vectors); the probe's is
    /// then the mean of `F_iᵀ·Rᵀ·M_i`, and a few alternations polish both. The translations
    /// follow by linear least squares: `y_i = R·(p_i + F_i·tool) + t`.
    fn locate(&self, p: &[Vector3<f64>], rot: &[Matrix3<f64>], y: &[f64]) -> Option<(Vec<f64>, Vector3<f64>)> {
        let n = p.len();
        if n < 3 || rot.len() != n || y.len() != 9 * n {
            return None;
        }
        let m: Vec<Matrix3<f64>> = y.chunks(9).map(reading_rotation).collect::<Option<_>>()?;
        // Axis pairs: each reading with the one half a data set later (spread orientations).
        let (mut src, mut dst) = (Vec::new(), Vec::new());
        for i in 0..n {
            let j = (i + n / 2) % n;
            let f = Rotation3::from_matrix_unchecked(rot[i] * rot[j].transpose()).scaled_axis();
            let g = Rotation3::from_matrix_unchecked(m[i] * m[j].transpose()).scaled_axis();
            if f.norm() > 1e-3 && g.norm() > 1e-3 {
                src.push(f);
                dst.push(g);
            }
        }
        let mut r_tr = if src.len() >= 3 {
            let h: Matrix3<f64> = src.iter().zip(&dst).map(|(a, b)| b * a.transpose()).sum();
            nearest_rotation(&h)?
        } else {
            // Too little rotation in the data: start from the origins' rigid fit.
            let origins: Vec<f64> = y.chunks(9).flat_map(|c| c[..3].to_vec()).collect();
            let (own, _) = Point.locate(p, rot, &origins)?;
            rotation(&own[3..6]).0
        };
        let mut r_tool = Matrix3::identity();
        for _ in 0..20 {
            r_tool = nearest_rotation(&rot.iter().zip(&m).map(|(f, mi)| f.transpose() * r_tr.transpose() * mi).sum())?;
            r_tr = nearest_rotation(&rot.iter().zip(&m).map(|(f, mi)| mi * r_tool.transpose() * f.transpose()).sum())?;
        }
        // y_i − R·p_i = R·F_i·tool + t: linear in (tool, t). Where the flange's orientation
        // hardly changes (a line, a surface scan), F_i·tool is a constant t absorbs, and the
        // rows' small errors put the origin anywhere: one farther from the flange than any probe
        // sits is solved again with three rows holding it to the flange's origin (the directions
        // the data do not see stay there instead of kilometres away).
        let solve = |hold: f64| -> Option<nalgebra::DVector<f64>> {
            let mut a = nalgebra::DMatrix::zeros(3 * n + 3, 6);
            let mut b = nalgebra::DVector::zeros(3 * n + 3);
            for c in 0..3 {
                a[(3 * n + c, c)] = hold * (n as f64).sqrt();
            }
            for i in 0..n {
                let rf = r_tr * rot[i];
                let rhs = Vector3::new(y[9 * i], y[9 * i + 1], y[9 * i + 2]) - r_tr * p[i];
                for c in 0..3 {
                    for k in 0..3 {
                        a[(3 * i + c, k)] = rf[(c, k)];
                    }
                    a[(3 * i + c, 3 + c)] = 1.0;
                    b[3 * i + c] = rhs[c];
                }
            }
            a.svd(true, true).solve(&b, 1e-12).ok()
        };
        let free = solve(0.0)?;
        let far = |s: &nalgebra::DVector<f64>| !(s[0].hypot(s[1]).hypot(s[2]) <= MAX_PROBE_OFFSET_M);
        let sol = if far(&free) { solve(TOOL_HOLD)? } else { free };
        let tool = Vector3::new(sol[0], sol[1], sol[2]);
        let (ta, tt) = (xyz_angles(&r_tr), xyz_angles(&r_tool));
        let own = vec![sol[3], sol[4], sol[5], ta[0], ta[1], ta[2], tt[0], tt[1], tt[2]];
        (own.iter().all(|v| v.is_finite()) && tool.iter().all(|v| v.is_finite())).then_some((own, tool))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn euler_angles_invert_every_convention() {
        use super::*;
        let mut n = 0;
        for name in ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX", "XYX", "XZX", "YXY", "YZY", "ZXZ", "ZYZ"] {
            for e in [Euler::parse(name).unwrap(), Euler::parse(&name.to_lowercase()).unwrap()] {
                let proper = e.axes[0] == e.axes[2];
                for a in [[0.3f64, 0.7, -1.2], [-2.9, -1.1, 2.5], [1.0, 0.0, 0.5], [0.4, 0.6, 0.0]] {
                    // The middle angle in the convention's range; also at gimbal lock.
                    let near = std::f64::consts::FRAC_PI_2 - 1e-7;
                    let mids: Vec<f64> = if proper {
                        vec![a[1].abs(), 0.0, std::f64::consts::PI, 1e-7, std::f64::consts::PI - 1e-7]
                    } else {
                        vec![a[1], std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2, near, -near]
                    };
                    for b in mids {
                        let m = e.matrix([a[0], b, a[2]]);
                        let back = e.angles(&m);
                        assert!((e.matrix(back) - m).norm() < 1e-8, "{name} {:?}: {a:?} b {b} -> {back:?}", e.intrinsic);
                        if b.abs() < 1.5 && b > 0.1 {
                            assert!((back[1] - b).abs() < 1e-12 && (back[0] - a[0]).abs() < 1e-9, "{} {a:?} -> {back:?}", e.name());
                        }
                        n += 1;
                    }
                }
            }
        }
        assert_eq!(n, 12 * 2 * 4 * 5);
        // Intrinsic XYZ as the readers take it.
        let m = Euler::XYZ.matrix([0.1, -0.2, 0.3]);
        assert_eq!(Euler::XYZ.angles(&m), xyz_angles(&m));
    }

    use super::*;

    #[test]
    fn euler_conventions_parse_and_compose_as_named() {
        let a = [0.3, -0.2, 0.5];
        let r = |axis: usize, v: f64| Rotation3::from_axis_angle(&[Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()][axis], v).into_inner();
        let xyz = Euler::parse("XYZ").unwrap();
        assert_eq!(xyz, Euler::XYZ);
        assert!((xyz.matrix(a) - r(0, a[0]) * r(1, a[1]) * r(2, a[2])).norm() < 1e-15);
        let ext = Euler::parse("xyz").unwrap();
        assert!((ext.matrix(a) - r(2, a[2]) * r(1, a[1]) * r(0, a[0])).norm() < 1e-15);
        // Extrinsic x-y-z is intrinsic Z-Y-X with the angles reversed.
        let zyx = Euler::parse("ZYX").unwrap();
        assert!((ext.matrix(a) - zyx.matrix([a[2], a[1], a[0]])).norm() < 1e-15);
        assert_eq!(Euler::parse("ZYZ").unwrap().name(), "ZYZ");
        for bad in ["XXY", "XyZ", "XY", "abc", "XYZW", "xxz"] {
            assert!(Euler::parse(bad).is_err(), "{bad}");
        }
        let back = xyz_angles(&xyz.matrix(a));
        assert!(back.iter().zip(&a).all(|(u, v)| (u - v).abs() < 1e-12), "{back:?}");
    }

    #[test]
    fn a_file_pose_becomes_its_origin_and_two_axes_at_the_lever() {
        let mut out = [0.0; 9];
        super::super::FileRows::values_of_file(&Pose, &[10.0, -20.0, 30.0, 0.0, 0.0, 90.0], &mut out);
        let want = [10.0, -20.0, 30.0, 0.0, LEVER_MM, 0.0, -LEVER_MM, 0.0, 0.0];
        assert!(out.iter().zip(&want).all(|(a, b)| (a - b).abs() < 1e-12), "{out:?}");
        let r = reading_rotation(&out).unwrap();
        assert!((r - Euler::XYZ.matrix([0.0, 0.0, 90f64.to_radians()])).norm() < 1e-12);
    }
}
